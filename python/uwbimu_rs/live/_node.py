"""The live node's estimator loop, free of any transport: records in, poses and diagnostics out.

A :class:`LiveNode` owns one streaming filter (``best`` unless the replay file or the command
names another). Sources hand it decoded records (:meth:`LiveNode.feed`) or raw messages of a
mapped topic (:meth:`LiveNode.feed_message`); after each call the new steps go to the sinks
(:class:`Sink`: DDS, Foxglove, an MCAP file), and with ``live.lag_s`` the fixed-lag smoothed pose
(:meth:`Sink.smoothed_pose`). :meth:`LiveNode.tick` runs the wall-clock duties: silent sensors
and diagnostics. The model choice of ``best`` (``live.choose_after_s``) runs inside the filter
(its ``choose_after_s``); the node only says what it did.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import OrderedDict, deque
from dataclasses import dataclass, field
from typing import Any, Protocol, cast

import numpy as np

from uwbimu_rs import _native
from uwbimu_rs._typing import MethodName

log = logging.getLogger("uwbimu.live")


@dataclass(frozen=True)
class Pose:
    """One estimate to publish: the filter's newest step with its full covariance."""

    t: float
    position: np.ndarray
    velocity: np.ndarray
    quaternion: np.ndarray
    """[w, x, y, z], body → navigation."""
    angular_rate: np.ndarray
    """Body rate of the last IMU sample less the gyro bias, rad/s."""
    covariance: np.ndarray
    """(15, 15): δp, δv, δθ (body), δb_a, δb_g."""


@dataclass(frozen=True)
class RangeUpdate:
    """One range update of the filter, with the signal powers of its range when the source
    gave them (a LinkTrack ``NodeFrame2``)."""

    t: float
    anchor: int
    nis: float
    """Normalised innovation squared."""
    accepted: bool
    fp_power_dbm: float | None = None
    """First-path power."""
    rx_power_dbm: float | None = None
    """Total received power; ``rx − fp`` large is a (weak, docs/power-gap.md) NLOS cue."""


class Sink(Protocol):
    """Where the estimate goes (DDS publisher, Foxglove server, MCAP file)."""

    def steps(self, rows: dict[str, np.ndarray]) -> None:
        """Every new step (the columns of ``run_filter``)."""

    def pose(self, pose: Pose) -> None:
        """The newest pose, at most ``live.publish_rate_hz`` times a second."""

    def smoothed_pose(self, pose: Pose) -> None:
        """With ``live.lag_s``: the newest fixed-lag smoothed estimate, once per smoothing pass
        (every ``lag_s / 2`` of sensor time) and at most ``live.publish_rate_hz`` times a
        second, ``lag_s`` to ``1.5 * lag_s`` old; ``angular_rate`` is zero (not smoothed). A
        sink without this method does not get it."""

    def diagnostics(self, t: float, statuses: list[dict[str, Any]]) -> None:
        """The health of the node and each sensor, every ``live.diagnostics_period_s``."""

    def range_update(self, u: RangeUpdate) -> None:
        """One range update: its NIS, whether accepted, the range's signal powers."""

    def close(self) -> None:
        """Flush and close (the node is stopping)."""


@dataclass
class SensorWatch:
    """What one input (a topic or a port) has delivered."""

    name: str
    kind: str
    since: float
    """When the node started watching it (wall clock)."""
    last_arrival: float | None = None
    messages: int = 0
    records: int = 0
    rejected: int = 0
    silent: bool = False
    extra: dict[str, Any] = field(default_factory=dict)
    """More counts of the input (a serial decoder's checksum errors, …)."""


def streaming_class(method: str) -> type:
    """The streaming class of ``method`` (``best`` → :class:`uwbimu_rs.Best`)."""
    cls = getattr(_native, method.capitalize(), None)
    if cls is None or not hasattr(cls, "add_imu"):
        streaming = sorted(m for m in _native.METHODS if hasattr(getattr(_native, m.capitalize(), None), "add_imu"))
        raise ValueError(f"method {method!r} has no streaming class; the live node runs one of {streaming}")
    return cls


def apply_record(f: Any, r: tuple[Any, ...]) -> list[Any]:
    """Give one record (a tuple of :meth:`MessageDecoder.decode` or :func:`linktrack_records`)
    to the streaming filter ``f``; returns the update reports of the call. An IMU sample and a
    range have their own calls; any other sensor's record, ``(name, t, values...)``, is one row
    of its table and goes to ``f.add_sensor(name, row)``. Raises ``ValueError`` as the call does
    (a sensor the filter does not take among them)."""
    kind = r[0]
    if kind == "imu":
        return list(f.add_imu(r[1], r[2], r[3]))
    if kind == "range":
        return list(f.add_range(r[1], r[2], r[3], r[4]))
    return list(f.add_sensor(kind, list(r[1:])))


class LiveNode:
    """The estimator of ``uwbimu-live``: feeds records to a streaming filter and the estimate to
    the sinks; thread-safe (sources may call from their own threads).

    Parameters
    ----------
    setup
        :func:`uwbimu_rs._native.live_setup` of the replay file.
    anchors
        (K, 3) anchor positions in filter-index order.
    method
        Overrides the file's ``method`` (default ``best``).
    sinks
        Where the estimate goes.
    clock
        Wall clock, s (the arrival times; a test may give its own).
    """

    def __init__(
        self,
        setup: dict[str, Any],
        anchors: np.ndarray,
        *,
        method: str | None = None,
        sinks: list[Sink] | None = None,
        clock: Any = time.monotonic,
    ) -> None:
        self.method = method or setup["method"] or "best"
        self.live: dict[str, Any] = setup["live"]
        self.anchors = np.asarray(anchors, dtype=np.float64)
        self.sinks = sinks or []
        self.clock = clock
        self._cls = streaming_class(self.method)
        self._lock = threading.RLock()
        choose = float(self.live["choose_after_s"])
        chooses = _native.METHODS[cast(MethodName, self.method)]["chooses_model"] and choose > 0
        self._filter = self._cls(
            self.anchors,
            initial=setup["initial"],
            config=setup["config"],
            reorder_window_s=setup["reorder_window_s"],
            lag_s=self.live.get("lag_s"),
            choose_after_s=choose if chooses else None,
        )
        self._watches: dict[str, SensorWatch] = {}
        self._last_gyro = np.zeros(3)
        self._last_publish = -np.inf
        self._last_smoothed_publish = -np.inf
        self.smoothed_poses_published = 0
        self._last_diagnostics = clock()
        self._errors: dict[str, int] = {}
        self._powers: OrderedDict[tuple[float, int], tuple[float, float]] = OrderedDict()
        self._initialized = False
        self.chosen: str | None = None
        """Label of the chosen model (None: the configuration as given)."""
        self._choice_started = False
        self._choice_told = False
        self.poses_published = 0
        self._waiting: deque[tuple[float, float]] = deque()
        self.latencies: deque[float] = deque(maxlen=1_000_000)
        """Seconds from each IMU message's arrival to the first step that includes it."""
        log.info(
            "method %s, %d anchors; %s",
            self.method,
            len(self.anchors),
            f"choosing the model after {choose:g} s of data" if self._filter.choosing else "model as configured",
        )
        log.info("waiting for IMU data (the filter initialises itself once still, then moving)")

    # ---------------------------------------------------------------------------------------
    # Input
    # ---------------------------------------------------------------------------------------

    def watch(self, name: str, kind: str) -> SensorWatch:
        """The watch of input ``name``, what it carries being ``kind`` (created on first use):
        silence and counts."""
        w = self._watches.get(name)
        if w is None:
            w = self._watches[name] = SensorWatch(name, kind, self.clock())
        w.kind = kind
        return w

    def feed_message(self, decoder: Any, topic: str, data: bytes, *, log_time_s: float | None = None) -> int:
        """Decode one message of ``topic`` with ``decoder`` (:class:`MessageDecoder`) and feed
        its records; returns how many it held. A message without a header stamp (or a mapping
        that reads log times) is stamped ``log_time_s``, else the wall-clock time of now."""
        records = decoder.decode(topic, time.time() if log_time_s is None else log_time_s, data)
        return self.feed(topic, records)

    def feed(self, source: str, records: list[tuple[Any, ...]], arrival: float | None = None) -> int:
        """Feed decoded records (the tuples of :meth:`MessageDecoder.decode`) from ``source``."""
        now = self.clock() if arrival is None else arrival
        with self._lock:
            w = self._watches.get(source) or self.watch(source, records[0][0] if records else "?")
            w.messages += 1
            w.last_arrival = now
            if w.silent:
                w.silent = False
                log.info("%s: receiving again", source)
            for r in records:
                w.records += 1
                if r[0] == "imu":
                    self._waiting.append((r[1], now))
                if not self._apply(r):
                    w.rejected += 1
            self._emit()
        return len(records)

    def _apply(self, r: tuple[Any, ...]) -> bool:
        """Give one record to the filter; a refused one is counted and logged once per reason."""
        kind = r[0]
        try:
            reports = apply_record(self._filter, r)
            if kind == "imu":
                self._last_gyro = np.asarray(r[3], dtype=np.float64)
            if kind == "range" and len(r) >= 7:
                self._powers[(r[1], r[2])] = (r[5], r[6])
                if len(self._powers) > 4096:
                    self._powers.popitem(last=False)
            self._range_updates(reports)
        except ValueError as e:
            reason = str(e).split(":")[0]
            n = self._errors.get(reason, 0)
            self._errors[reason] = n + 1
            if n == 0:
                log.warning("refused %s (counted, not logged again): %s", kind, e)
            return False
        return True

    def _range_updates(self, reports: list[Any]) -> None:
        if not self.sinks:
            return
        for rep in reports:
            if rep.anchor is not None and rep.sensor == "range":
                fp, rx = self._powers.get((rep.t, rep.anchor), (None, None))
                u = RangeUpdate(rep.t, rep.anchor, rep.nis, rep.accepted, fp, rx)
                for s in self.sinks:
                    s.range_update(u)

    def wait_for_choice(self, timeout_s: float) -> bool:
        """Block until a model choice that has started is made and applied (for trials and
        tests: a robot does not wait; the filter applies it at the next record). Returns whether
        one was waited for."""
        waited = bool(self._filter.wait_for_choice(timeout_s))
        with self._lock:
            self._follow_choice()
        return waited

    def _follow_choice(self) -> None:
        """Say what the filter's model choice did since the last call: its start, then what it
        chose and whether the filter switched (it then replayed every record so far, every sensor
        and tag, with the chosen model; the replayed past is not published again)."""
        if self._choice_told:
            return
        f = self._filter
        if f.choosing:
            window = f.choice_window
            if window is not None and not self._choice_started:
                self._say_choosing(window)
            return
        self._choice_told = True
        made = f.model_choice
        if made is None:  # no choice asked
            return
        if not self._choice_started:
            self._say_choosing(made["window"])
        self.chosen = made["chosen"]
        if made["chosen"] is None:
            log.warning("model choice failed, keeping the configured model: %s", made["reason"])
        elif made["switched"]:
            log.info("model chosen: %s (%s); switching: %s", made["chosen"], made["reason"], made["overrides"])
            self._initialized = False
        elif made["overrides"]:
            log.warning("model chosen: %s (%s)", made["chosen"], made["reason"])
        else:
            log.info("model chosen: %s (%s) — the configured model, kept", made["chosen"], made["reason"])

    def _say_choosing(self, window: dict[str, Any]) -> None:
        self._choice_started = True
        log.info(
            "choosing the model on %.0f s of data (%d IMU samples, %d ranges, %d other readings)",
            window["duration_s"],
            window["imu"],
            window["ranges"],
            window["observations"],
        )

    # ---------------------------------------------------------------------------------------
    # Output
    # ---------------------------------------------------------------------------------------

    def _emit(self) -> None:
        self._follow_choice()
        f = self._filter
        if not f.initialized:
            return
        if f.lag_s is not None:
            self._emit_smoothed()
        steps = f.steps()
        if steps.height == 0:
            return
        if not self._initialized:
            self._initialized = True
            log.info("initialised: %s", f.init_info)
            start = steps["t"][-1]
            while self._waiting and self._waiting[0][0] <= start:  # waited for the start, not the filter
                self._waiting.popleft()
        rows = {c: steps[c].to_numpy() for c in steps.columns}
        for s in self.sinks:
            s.steps(rows)
        now = self.clock()
        last_t = rows["t"][-1]
        while self._waiting and self._waiting[0][0] <= last_t:
            self.latencies.append(now - self._waiting.popleft()[1])
        rate = float(self.live["publish_rate_hz"])
        if rate > 0 and now - self._last_publish < 1.0 / rate:
            return
        self._last_publish = now
        state = f.state
        pose = Pose(
            t=float(rows["t"][-1]),
            position=np.array([rows["x"][-1], rows["y"][-1], rows["z"][-1]]),
            velocity=np.array([rows["vx"][-1], rows["vy"][-1], rows["vz"][-1]]),
            quaternion=np.array([rows["qw"][-1], rows["qx"][-1], rows["qy"][-1], rows["qz"][-1]]),
            angular_rate=self._last_gyro - state["gyro_bias"],
            covariance=f.covariance,
        )
        self.poses_published += 1
        for s in self.sinks:
            s.pose(pose)

    def _emit_smoothed(self) -> None:
        """The newest fixed-lag row, if a pass emitted any, to the sinks that take it."""
        f = self._filter
        lagged = f.lagged_steps()
        if lagged.height == 0:
            return
        now = self.clock()
        rate = float(self.live["publish_rate_hz"])
        if rate > 0 and now - self._last_smoothed_publish < 1.0 / rate:
            return
        self._last_smoothed_publish = now
        row = lagged.row(-1, named=True)
        pose = Pose(
            t=float(row["t"]),
            position=np.array([row["x"], row["y"], row["z"]]),
            velocity=np.array([row["vx"], row["vy"], row["vz"]]),
            quaternion=np.array([row["qw"], row["qx"], row["qy"], row["qz"]]),
            angular_rate=np.zeros(3),
            covariance=f.lagged_covariance,
        )
        self.smoothed_poses_published += 1
        for s in self.sinks:
            publish = getattr(s, "smoothed_pose", None)
            if publish is not None:
                publish(pose)

    def tick(self) -> None:
        """The wall-clock duties: silent sensors, diagnostics (and the log of the model choice)."""
        now = self.clock()
        with self._lock:
            self._follow_choice()
            silent_after = float(self.live["silent_after_s"])
            for w in self._watches.values():
                last = w.since if w.last_arrival is None else w.last_arrival
                if not w.silent and now - last > silent_after:
                    w.silent = True
                    if w.last_arrival is None:
                        log.warning("%s: nothing received in %.1f s", w.name, now - last)
                    else:
                        log.warning("%s: silent for %.1f s", w.name, now - last)
            if now - self._last_diagnostics >= float(self.live["diagnostics_period_s"]):
                self._last_diagnostics = now
                t = self._filter.time if self._filter.time is not None else 0.0
                statuses = self.statuses(now)
                for s in self.sinks:
                    s.diagnostics(t, statuses)

    def statuses(self, now: float | None = None) -> list[dict[str, Any]]:
        """The diagnostics: one status for the estimator, one per input."""
        now = self.clock() if now is None else now
        f = self._filter
        health = f.health
        values: dict[str, Any] = {
            "method": self.method,
            "model": self.chosen or ("choosing" if f.choosing else "as configured"),
            "initialized": f.initialized,
            "poses_published": self.poses_published,
            "smoothed_poses_published": self.smoothed_poses_published,
            "late_dropped": health["late_dropped"],
            "reordered": health["reordered"],
            "numerical_repairs": health["numerical_repairs"],
        }
        values.update({f"latency_{k}_ms": round(v, 2) for k, v in self.latency_ms().items()})
        values.update({f"rejected.{k}": v for k, v in health["rejected"].items() if v})
        values.update({f"refused.{k}": v for k, v in self._errors.items()})
        level = "ok" if f.initialized else "warn"
        message = f"initialised ({f.init_info['from']})" if f.initialized and f.init_info else "waiting to initialise"
        out = [{"level": level, "name": "uwbimu: estimator", "message": message, "hardware_id": self.method, "values": values}]
        for w in self._watches.values():
            age = now - (w.since if w.last_arrival is None else w.last_arrival)
            out.append(
                {
                    "level": "warn" if w.silent else "ok",
                    "name": f"uwbimu: {w.kind}",
                    "message": (f"silent for {age:.1f} s" if w.last_arrival is not None else f"nothing received in {age:.1f} s")
                    if w.silent
                    else "receiving",
                    "hardware_id": w.name,
                    "values": {"messages": w.messages, "records": w.records, "rejected": w.rejected, **w.extra},
                }
            )
        return out

    def latency_ms(self) -> dict[str, float]:
        """Percentiles (p50, p99, max) of :attr:`latencies`, ms (NaN before the first step)."""
        if not self.latencies:
            return {"p50": float("nan"), "p99": float("nan"), "max": float("nan")}
        lat = np.fromiter(self.latencies, dtype=np.float64) * 1e3
        return {"p50": float(np.percentile(lat, 50)), "p99": float(np.percentile(lat, 99)), "max": float(lat.max())}

    @property
    def filter(self) -> Any:
        """The streaming filter in use."""
        return self._filter

    def close(self) -> None:
        """Flush what the filter still holds to the sinks and close them."""
        with self._lock:
            self._waiting.clear()  # what the flush releases waited for the end, not the filter
            self._filter.flush()
            self._emit()
            for s in self.sinks:
                s.close()
