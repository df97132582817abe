"""Type stubs of the native extension module ``uwbimu_rs._native`` (PyO3, ``src/bindings``).

Private module: the public API is ``uwbimu_rs``, ``uwbimu_rs.metrics`` and ``uwbimu_rs.sim``,
which wrap these functions (e.g. into polars DataFrames). Kept in step with the runtime module by
``tests/python/test_stubs.py`` (``python -m mypy.stubtest uwbimu_rs._native``).

Conventions: navigation frame ENU (z up), metres, seconds; accelerometer = specific force in the
body frame (m/s²), gyroscope rad/s; quaternions Hamilton ``[w, x, y, z]`` rotating body →
navigation; error-state order δp, δv, δθ, δb_a, δb_g. Every returned array is a fresh float64
NumPy array (``range_labels``: uint8) owned by the caller.
"""

import os
from collections.abc import Mapping, Sequence
from typing import Any, Literal, TypedDict, TypeVar, final

import numpy as np
from numpy.typing import ArrayLike, NDArray
import polars as pl

__all__ = [
    "Ukf",
    "sds_twr",
    "ss_twr",
    "dw1000_elapsed",
    "calibration_fit",
    "calibration_fit_anchors",
    "calibration_apply",
    "calibrate_ranges",
    "DW1000_TICK_S",
    "SPEED_OF_LIGHT_MPS",
    "Shaf",
    "Shfaf",
    "run_filters",
    "Eskf",
    "Ackf",
    "Arckf",
    "Ckf",
    "posterior_crlb",
    "survey_anchors",
    "Criekf",
    "Best",
    "Iekf",
    "Rekf",
    "Riekf",
    "Rukf",
    "UwbImuError",
    "ConfigError",
    "NumericalError",
    "MappingError",
    "FormatError",
    "read_mcap",
    "replay",
    "read_truth",
    "TRUTH_COLUMNS",
    "replay_main",
    "write_mcap",
    "LinkTrackDecoder",
    "encode_linktrack_node_frame2",
    "DwmDecoder",
    "encode_dwm_loc_get",
    "UWB_RANGE_JSON",
    "UWB_RANGE_MSG",
    "ros_uwb_range_from_json",
    "live_setup",
    "live_subscriptions",
    "ros_definition",
    "ros_fields",
    "MessageDecoder",
    "ros_pose_messages",
    "ros_diagnostics_message",
    "TrajectoryWriter",
    "FilterConfig",
    "Ekf",
    "UpdateReport",
    "run_filter",
    "initialize_state",
    "FILTERS",
    "METHODS",
    "SENSORS",
    "INPUTS",
    "calibrate_log",
    "tune_noise",
    "choose_model",
    "evaluate",
    "nees",
    "cdf",
    "interpolate_positions",
    "chi2_quantile",
    "Trajectory",
    "sim_preset",
    "simulate",
    "SIM_PRESET_NAMES",
    "SIM_PRESET_ALIASES",
    "SIM_OVERRIDE_KEYS",
    "SIM_ZOO_NAMES",
    "sim_zoo",
    "sim_zoo_matrix",
]

_F64 = NDArray[np.float64]
# A configuration or initial-state value: a number, or a sequence / 1-D array of numbers (not a
# bool).
_ConfigValue = float | Sequence[float] | NDArray[Any]
# The ``config`` argument: None (defaults), a FilterConfig, or a dict of FilterConfig keys.
_ConfigArg = FilterConfig | dict[str, Any] | None
# Simulator overrides: a bool switches a feature, a number sets a value.
_Override = float | bool

# --------------------------------------------------------------------------------------------
# Exceptions (src/bindings/errors.rs)
# --------------------------------------------------------------------------------------------

_S = TypeVar("_S", bound="_StreamingFilter")

class UwbImuError(ValueError):
    """Base class of uwbimu_rs errors (a ValueError).

    Raised for invalid input data: wrong array shape, NaN/inf, decreasing time, anchor index out
    of range; the message names the array, row and column.
    """

class ConfigError(UwbImuError):
    """Invalid configuration, method or option (unknown key, preset or method; invalid value).

    The message lists the allowed keys or names.
    """

class NumericalError(UwbImuError):
    """A matrix that must be positive definite was not (e.g. a covariance in ``nees``)."""

class MappingError(UwbImuError):
    """A topic/field mapping that does not fit the recording (missing topic, unknown field)."""

class FormatError(OSError):
    """A file that is not well-formed (bad magic, truncation, CRC mismatch, unknown encoding)."""

# --------------------------------------------------------------------------------------------
# Filters (src/bindings/filters.rs)
# --------------------------------------------------------------------------------------------

_MethodName = Literal[
    "uwb_ls", "ekf", "iekf", "rekf", "riekf", "criekf", "ckf", "arckf", "ackf", "eskf", "shaf", "shfaf", "ukf",
    "rukf", "ekf2d", "ukf2d", "cekf2d", "best",
]
"""A method name: the rows of the registry (``crates/uwbimu-app/src/registry.rs``), in its order
(tests/python/test_registry.py holds this list to :data:`FILTERS`)."""

class _MethodRow(TypedDict):
    """What the registry says of one method."""

    takes: list[str]
    """The measurements it takes besides IMU samples: names of :data:`INPUTS`."""
    smoothing: Literal["never", "on_request", "by_default"]
    """Whether and when :func:`run_filter` RTS-smooths its run."""
    streaming_class: str | None
    """The name of its streaming class in ``uwbimu_rs``, if it has one."""
    chooses_model: bool
    """Whether :func:`run_filter` chooses its range-error model, NLOS skew and range noise on the
    log first (:func:`choose_model`); its streaming class takes the choice as ``config``."""
    summary: str
    """One sentence: what it is and where it comes from."""

FILTERS: list[_MethodName]
"""Every method name accepted by :func:`run_filter`, :func:`replay` and the CLI, in registry order."""

METHODS: dict[_MethodName, _MethodRow]
"""The method registry, one row per name of :data:`FILTERS`: what each takes, its smoothing, its
streaming class and its summary."""

class _SensorRow(TypedDict):
    """What the sensor registry says of one sensor besides the IMU and the ranges."""

    keyword: str
    """The keyword argument of its array in :func:`run_filter` (``mag``, ``tdoa``)."""
    label: str
    """What it measures, in messages."""
    columns: list[list[str]]
    """The columns of its array, one list per accepted layout; column 0 is the time (s)."""
    rank: int
    """Its rank among measurements at one time (the IMU first, ranges last)."""
    doc: str
    """What it is: its columns, units, noise keys and docs page (the row's doc comment)."""

SENSORS: dict[str, _SensorRow]
"""The sensor registry (``crates/uwbimu-vocabulary/src/sensors.rs``), one row per sensor besides
the IMU and the ranges, by the name :data:`METHODS` lists under ``takes``."""

INPUTS: list[str]
"""Every input a method may take (``METHODS[name]["takes"]``): ``ranges``, ``tags`` (ranges from
several tags), then each sensor of :data:`SENSORS`."""

@final
class FilterConfig:
    """Filter configuration, built from keyword arguments (immutable).

    Unset keys keep their defaults; unknown keys or invalid values raise :class:`ConfigError`.

    Keyword arguments are sections, each a dict of its fields
    (``FilterConfig(ranging={"range_std": 0.2}, mounting={"lever_arm": [0, 0, 0.05]})``), or
    ``section.field`` keys (``FilterConfig(**{"ranging.range_std": 0.2})``), or
    ``range_calibration={anchor: [c0, c1, c2, c3]}``. :meth:`keys` lists every key; each key's
    unit, default and rule are in ``docs/configuration.md``, generated from the Rust declaration.

    Raises
    ------
    ConfigError
        Unknown key or invalid value.
    ValueError
        A value of the wrong kind: a string, or a bool where a number is expected (and the
        reverse).
    """

    def __new__(cls, **kwargs: _ConfigValue | dict[int, Sequence[float]]) -> FilterConfig: ...
    @staticmethod
    def keys() -> list[str]:
        """The accepted keyword names (in a fixed order).

        Returns
        -------
        list of str
        """

    def to_dict(self) -> dict[str, Any]:
        """The full configuration as a plain dict.

        Returns
        -------
        dict
            Every key of :meth:`keys`: scalars as ``float``, vectors as 1-D float64 arrays
            (``lever_arm`` (3,) m, ``imu_rotation`` (4,) w, x, y, z, ``gravity`` (3,) m/s²),
            ``range_calibration`` as a dict ``{anchor: [c0, c1, c2, c3]}``.
        """

@final
class UpdateReport:
    """The outcome of one update, of a range or of another sensor (read-only; returned by
    :meth:`Ekf.add_range`, :meth:`Ekf.update_range` and the other streaming calls)."""

    @property
    def t(self) -> float:
        """Measurement time, s."""

    @property
    def epoch_t(self) -> float:
        """Time at which it was applied (a range epoch's reference time; another sensor's own
        time), s."""

    @property
    def sensor(self) -> str:
        """``"range"`` or the name of the sensor in :data:`SENSORS`."""

    @property
    def anchor(self) -> int | None:
        """A range's anchor index (a TDoA's anchor i); None for a sensor without anchors."""

    @property
    def anchor_j(self) -> int | None:
        """A TDoA's anchor j; None for the others."""

    @property
    def tag(self) -> int | None:
        """A range's tag (0 on a one-tag rig); None for the other sensors."""

    @property
    def axis(self) -> int | None:
        """An odometry reading's body axis (0 = x); None for the others."""

    @property
    def value(self) -> float:
        """The value as measured: a range (before alignment to the epoch's reference time) or a
        TDoA's ``d_ij``, m; an altitude, m; an odometry speed, m/s; a magnetometer sample's field
        norm; a pose fix's distance from the origin, m (its report is the fix as a whole:
        docs/pose-fix.md)."""

    @property
    def innovation(self) -> float:
        """Innovation z − h(x⁻), in the measurement's unit."""

    @property
    def nis(self) -> float:
        """γ: squared Mahalanobis distance of the innovation (Li & Wang 2020 eqs. (37), (39))."""

    @property
    def accepted(self) -> bool:
        """Whether the measurement changed the state."""

    @property
    def weight(self) -> float:
        """Weight relative to the nominal noise, R / R_used (1 = full)."""

    @property
    def inflation(self) -> float:
        """R_used / R (≥ 1; Li & Wang 2020 eq. (40))."""

    @property
    def down_weighted(self) -> bool:
        """Whether the noise policy down-weighted the measurement (inflation > 1)."""

    @property
    def iterations(self) -> int:
        """Iterations of the (iterated) update the measurement took part in."""

    @property
    def prior_fading(self) -> float:
        """Factor by which the epoch's prior covariance was inflated (the ARCKF paper's eq. (42), ARCKF); 1 if not."""

    @property
    def reacquired(self) -> bool:
        """Whether the epoch was applied as its UWB-only fix (re-acquisition after an outage, a
        poor start or a divergence)."""

    @property
    def bias(self) -> float:
        """The anchor's estimated range bias b_a + b_c after the update, m (NaN without
        ``range_bias.states``)."""

    @property
    def bias_std(self) -> float:
        """Its standard deviation, m (NaN without ``range_bias.states``)."""

class _StreamingFilter:
    """Streaming API shared by the 15-state filter classes (documented once here; each class below
    is one named composition of the shared pieces). Constructed as ``Cls(anchors, *,
    initial=None, config=None, record=False, reorder_window_s=None, strict=False,
    keep_steps=10000, lag_s=None, choose_after_s=None)``.

    A robot loop feeds whatever arrives, in any order within the reorder window, and reads the
    state::

        f = uwbimu_rs.Best(anchors)                      # initialises itself
        for msg in bus:                                  # IMU and UWB, as they arrive
            if msg.kind == "imu": f.add_imu(msg.t, msg.accel, msg.gyro)
            else: f.add_range(msg.t, msg.anchor, msg.range)
            if f.initialized: publish(f.state["position"])
        track = f.steps()                                # what it estimated since the last call

    Every input goes through a reorder buffer: it is applied once it is ``reorder_window_s``
    older than the newest input, in the batch order (time; IMU, magnetometer, TDoA, range at
    equal times), so data late by less than the window gives the same result as data in order;
    older data is counted (``health["late_dropped"]``) and dropped, or refused with
    ``strict=True``. Then the plausibility gate (``gate.*`` config keys): impossible
    measurements are counted in ``health["rejected"]``. Fed a whole log and flushed, a stream
    equals :func:`run_filter` bit for bit, self-initialisation included (for ``best``, whose
    batch run chooses its model on the log first, with the configuration
    :func:`choose_model` returns: docs/model-selection.md).

    Parameters
    ----------
    anchors : array_like, shape (K, 3)
        Anchor positions in the navigation frame, m (finite).
    initial : dict, optional
        Initial state valid at the first IMU time: ``position`` (3,) m, ``velocity`` (3,) m/s,
        ``orientation`` (4,) w, x, y, z, and optional ``position_std`` (m), ``velocity_std``
        (m/s), ``orientation_std`` (rad) (each a scalar or 3 values), ``accel_bias`` (3,) m/s²,
        ``gyro_bias`` (3,) rad/s, ``accel_bias_std`` (m/s²), ``gyro_bias_std`` (rad/s),
        ``levelled`` (bool: the tilt was levelled at rest, its error correlated with the
        accelerometer bias; :func:`initialize` sets it). None: the
        filter keeps the data until the self-initialisation of the batch API decides (see
        :func:`initialize`; ``init.heading_timeout_s`` bounds the wait), then starts from it and
        replays what it kept (``initialized`` says when).
    config : FilterConfig or dict, optional
        Filter settings (see :class:`FilterConfig`); None for the defaults.
    record : bool
        Keep what :meth:`smooth` needs.
    reorder_window_s : float, optional
        Inputs up to this much older than the newest are put back in order, s; the filter lags
        the newest input by this much (0: apply at once, for data that arrives in order). None:
        the replay's default, 0.5 s.
    strict : bool
        Raise on an input older than the window allows instead of counting and dropping it.
    keep_steps : int
        Steps (one per IMU sample) kept for :meth:`steps` between its calls, the oldest dropped
        beyond; 0 keeps none. Bounds the rows waiting for :meth:`lagged_steps` too.
    lag_s : float, optional
        Fixed-lag smoothing: beside the causal steps, every ``lag_s / 2`` of filter time the
        filter RTS-smooths the last ``1.5 * lag_s`` of its run and emits the estimates at least
        ``lag_s`` old (:meth:`lagged_steps`), in bounded memory (docs/streaming.md,
        "Fixed-lag smoothing"). None: off. Not with ``record=True``.
    choose_after_s : float, optional
        Only for a class whose method chooses its model (``METHODS[name]["chooses_model"]``:
        :class:`Best`): once an IMU sample this many seconds after the first one is in, the
        filter chooses its model on everything it was given so far, as :func:`choose_model`
        does on the same data, in a thread of its own while it runs on with the configured
        model; when the choice is made, the next call that feeds it applies it (a model change
        replays every input so far, every sensor and tag, through a new filter of the chosen
        model, whose steps and lagged rows of the past are not given again). See
        :attr:`choosing`, :attr:`choice_window`, :attr:`model_choice`, :meth:`wait_for_choice`
        and docs/streaming.md, "Choosing the model while running". None: the model as
        configured (also with ``model_selection.enabled`` off). While the choice is pending,
        :meth:`apply_ranges_now` raises.

    Raises
    ------
    ConfigError
        Unknown or invalid ``initial`` / ``config`` key.
    ValueError
        Bad anchor shape or values, ``initial`` / ``config`` not a dict, a negative window, a
        negative, infinite or NaN ``lag_s``, or ``lag_s`` with ``record=True`` or
        ``keep_steps=0``; ``choose_after_s`` for a class whose method does not choose its model
        (the message names those that do), or not finite and above 0.
    """

    def __new__(
        cls: type[_S],
        anchors: ArrayLike,
        *,
        initial: dict[str, Any] | None = None,
        config: _ConfigArg = None,
        record: bool = False,
        reorder_window_s: float | None = None,
        strict: bool = False,
        keep_steps: int = 10000,
        lag_s: float | None = None,
        choose_after_s: float | None = None,
    ) -> _S: ...
    def steps(self) -> pl.DataFrame:
        """The steps made since the previous call (or the start), one row per IMU sample, oldest
        first, at most ``keep_steps`` of them. A sample's step is complete, and comes, once data
        after its time has arrived.

        Returns
        -------
        polars.DataFrame
            The columns of :func:`uwbimu_rs.run_filter`'s frame (t, x, y, z, vx, vy, vz, qw, qx, qy,
            qz, std_x, std_y, std_z, still, status): fed a whole log and flushed, the frames of
            the calls together equal ``run_filter(..., smooth=False)`` but its last row."""

    @property
    def steps_dropped(self) -> int:
        """Steps dropped because :meth:`steps` was not called within ``keep_steps`` IMU samples."""

    def smooth(self) -> pl.DataFrame:
        """RTS-smooth everything recorded (``record=True``).

        Returns
        -------
        polars.DataFrame
            The columns of :func:`uwbimu_rs.run_filter`'s frame (t, x, y, z, vx, vy, vz, qw, qx, qy,
            qz, std_x, std_y, std_z, still, status), one row per propagation start (each IMU
            sample and each epoch time between samples) plus the current time. The plain RTS
            pass: the batch ``best``'s robust smoothing (``smoothing.outlier_passes``) needs the
            whole log again."""

    def lagged_steps(self) -> pl.DataFrame:
        """The fixed-lag smoothed estimates emitted since the previous call (needs ``lag_s``).

        Each row is the node of the full RTS pass over the run up to the moment it was emitted
        (:meth:`smooth` of a ``record=True`` twin fed the same data, bit for bit): smoothed over
        at least ``lag_s`` and at most ``1.5 * lag_s`` of later data (more when one call brings
        more, as a flush of the reorder window does). :meth:`flush` emits the
        rest, the current time last; fed a whole log and flushed, the frames together equal
        :meth:`smooth` of the twin. At most ``keep_steps`` rows wait between calls, the oldest
        dropped beyond (:attr:`lagged_steps_dropped`).

        Returns
        -------
        polars.DataFrame
            The columns of :meth:`steps`, one row per propagation start (each IMU sample and each
            epoch time between samples, as :meth:`smooth`), oldest first; ``still`` false,
            ``status`` 0.

        Raises
        ------
        UwbImuError
            The filter was created without ``lag_s``."""

    @property
    def lagged_steps_dropped(self) -> int:
        """Fixed-lag rows dropped because :meth:`lagged_steps` was not called within
        ``keep_steps`` rows (0 without ``lag_s``)."""

    @property
    def lag_s(self) -> float | None:
        """The lag of the fixed-lag smoothing, s (None: off)."""

    @property
    def lagged_covariance(self) -> _F64 | None:
        """The (15, 15) smoothed error covariance (δp, δv, δθ, δb_a, δb_g) of the newest
        fixed-lag row emitted, a copy; None before the first. Raises ``UwbImuError`` without
        ``lag_s``."""

    @property
    def choosing(self) -> bool:
        """Whether the model choice (``choose_after_s``) is pending: waiting for its data,
        running, or made and applied at the next call that feeds the filter. False without
        ``choose_after_s`` and with ``model_selection.enabled`` off."""

    @property
    def choice_window(self) -> dict[str, Any] | None:
        """The data the model choice runs on, from its start until it is applied (None
        otherwise): ``duration_s`` (first to last IMU sample, s), ``imu``, ``ranges`` (every
        tag's) and ``observations`` (the other sensors' readings), counts."""

    @property
    def model_choice(self) -> dict[str, Any] | None:
        """The model choice once applied (None before, and without ``choose_after_s``): the
        dict of :func:`choose_model` — ``config`` (nested dict of the chosen configuration),
        ``overrides`` (``{key: value}`` it changes), ``chosen`` (label; None when no selection
        ran), ``reason``, ``candidates`` (a list of dicts: ``label``, ``score``, ``per_anchor``,
        ``overrides``) — with ``switched`` (whether the filter now runs with the chosen model:
        false when it kept the configured one, the reason saying why) and ``window`` (as
        :attr:`choice_window`)."""

    def wait_for_choice(self, timeout_s: float) -> bool:
        """Block, without the GIL, until the model choice that has started is made or
        ``timeout_s`` (s, finite, >= 0) has passed, then apply it (for tests and trials: a robot
        does not wait; the next call that feeds the filter applies it). Returns whether a choice
        was waited for (False when none was running)."""

    def add_imu(self, t: float, accel: ArrayLike, gyro: ArrayLike) -> list[UpdateReport]:
        """Take the IMU sample at time ``t``.

        Parameters
        ----------
        t : float
            Sample time, s.
        accel : array_like, shape (3,)
            Specific force in the IMU frame, m/s².
        gyro : array_like, shape (3,)
            Angular rate in the IMU frame, rad/s.

        Returns
        -------
        list of UpdateReport
            The updates this call applied (usually none; many when it completed the
            self-initialisation).

        Raises
        ------
        UwbImuError
            Wrong shape or non-finite values (the message names ``add_imu`` and the argument), or
            with ``strict=True`` a time older than the window allows.
        """

    def add_range(self, t: float, anchor: int, range: float, tag: int | None = None) -> list[UpdateReport]:
        """Take one UWB range: the one way to give a range. It joins an epoch by the batch API's
        epoch rule: ranges of one tag within ``epoch_window_s`` of the epoch's first range, one
        per anchor, are applied jointly once the epoch closes (every anchor in it, a range that
        does not fit, or an IMU sample past the window), aligned to the epoch's reference time.
        ``tag`` is the tag the range came from (None: tag 0), its lever arm row ``tag`` of
        ``mounting.lever_arm`` (ValueError for a tag the configuration does not give).

        Returns
        -------
        list of UpdateReport
            The updates this call applied (an epoch it closed, if any).

        Raises
        ------
        UwbImuError
            An anchor index that does not exist or a non-finite value (the message names
            ``add_range`` and the argument), or with ``strict=True`` a time older than the window
            allows. A negative or impossible range is not an error: the gate counts it.
        """

    def add_tdoa(self, t: float, i: int, j: int, d_ij: float) -> list[UpdateReport]:
        """Take one TDoA ``d_ij = |p − a_j| − |p − a_i|`` (m) between anchor indices ``i`` and
        ``j`` measured at ``t`` (s), applied at its own time through the filter's noise policy
        (σ = ``tdoa_std``); a report has ``anchor`` = i, ``anchor_j`` = j and ``value`` = d_ij.
        The loosely coupled filters (:class:`Eskf`, :class:`Shaf`, :class:`Shfaf`) raise
        ``UwbImuError``; so do an unknown or repeated anchor and a non-finite value."""

    def add_magnetometer(self, t: float, field: ArrayLike) -> list[UpdateReport]:
        """Take one magnetometer sample (3,) in the IMU frame measured at ``t`` (s). Only
        :class:`Ackf` uses a magnetometer (the ACKF paper); the others raise ``UwbImuError``."""

    def add_altitude(self, t: float, z: float) -> list[UpdateReport]:
        """Take one altitude ``z`` (m, navigation frame, up) of the body origin measured at
        ``t`` (s), applied at its own time (σ = ``altitude.std``; docs/altitude.md). The methods
        whose ``METHODS[name]["takes"]`` lacks ``"altitude"`` raise ``UwbImuError``; so does a
        non-finite value. An impossible height (outside the anchors' box grown by
        ``gate.hall_margin_m``) is counted by the gate, not applied."""

    def add_odometry(self, t: float, speed: float | ArrayLike) -> list[UpdateReport]:
        """Take one wheel odometry reading measured at ``t`` (s): a speed along the body x axis
        (m/s), or the body-frame velocity (3,) with NaN for an axis not measured; each axis
        measured is applied at its own time (σ = ``odometry.std``; docs/odometry.md), its report
        with ``axis`` set. The methods whose ``METHODS[name]["takes"]`` lacks ``"odometry"``
        raise ``UwbImuError``; so do a reading with no axis, a wrong length or an infinite
        value. A speed beyond ``gate.speed_range`` is counted by the gate, not applied."""

    def add_sensor(self, name: str, row: ArrayLike) -> list[UpdateReport]:
        """Take one reading of the sensor ``name`` (a key of :data:`SENSORS`) as one row of its
        table, time first — a row of the array :func:`run_filter` takes for it, in one of
        ``SENSORS[name]["columns"]`` — checked as those rows are and applied at its own time
        (e.g. ``f.add_sensor("pose_fix", [t, x, y, z, sx, sy, sz])``). The methods whose
        ``METHODS[name]["takes"]`` lacks the sensor raise ``UwbImuError``; so do an unknown
        sensor and a row the array would refuse. A reading the gate finds impossible is
        counted, not applied."""

    def apply_ranges_now(self, t: float, anchors: Sequence[int], ranges: Sequence[float]) -> list[UpdateReport]:
        """Apply ranges all measured at ``t`` jointly, at once — bypassing the epoch rule, the
        reorder window and the gate (for a caller that gathers its own epochs). The inputs
        buffered up to ``t`` and the open epoch are applied first.

        Parameters
        ----------
        t : float
            Measurement time, s.
        anchors : sequence of int, length M
            Anchor indices.
        ranges : sequence of float, length M
            Measured ranges, m.

        Returns
        -------
        list of UpdateReport
            The updates this call applied: the buffered ones, then one per range given.

        Raises
        ------
        UwbImuError
            Before the filter is initialised, a time older than the data applied, an unknown
            anchor or a non-finite value.
        """

    def flush(self) -> list[UpdateReport]:
        """The end of the input so far: apply everything buffered (the reorder window and the
        open epoch; initialise on what was seen when still waiting). Returns the reports."""

    @property
    def pending(self) -> int:
        """Number of ranges waiting in the open epoch."""

    @property
    def buffered(self) -> int:
        """Inputs waiting in the reorder buffer or kept for the self-initialisation."""

    @property
    def initialized(self) -> bool:
        """Whether the filter has an initial state (given, or found from the data)."""

    @property
    def init_info(self) -> dict[str, Any] | None:
        """None while waiting; else ``{"from": "initial"}`` or ``{"from": "self", "still_start":
        bool, "heading_from": "motion" | "tags" | "fallback"}``."""

    @property
    def health(self) -> dict[str, Any]:
        """What the stream counted: ``rejected`` ({``imu_beyond_range``, ``negative_range``,
        ``range_beyond_hall``, ``tdoa_beyond_baseline``: count}), ``numerical_repairs``
        (numerical failures repaired, their measurement skipped), ``ranges_before_start``,
        ``reordered`` (late inputs put back in order), ``late_dropped``."""

    @property
    def time(self) -> float | None:
        """Filter time, s (None before the first IMU sample is applied; it lags the newest input
        by the reorder window)."""

    @property
    def state(self) -> dict[str, _F64]:
        """Snapshot of the nominal state (copies); raises ``UwbImuError`` before the filter is
        initialised (see :attr:`initialized`).

        Keys: ``position`` (3,) m, ``velocity`` (3,) m/s, ``orientation`` (4,) w, x, y, z
        (body → navigation), ``accel_bias`` (3,) m/s², ``gyro_bias`` (3,) rad/s.
        """

    @property
    def covariance(self) -> _F64:
        """Error-state covariance, shape (15, 15), order δp, δv, δθ, δb_a, δb_g (a copy); raises
        before the filter is initialised. With ``ins.covariance_interval_s`` set, the covariance
        as of its last propagation (up to that interval of IMU samples behind the state)."""



@final
class Ekf(_StreamingFilter):
    """The tightly coupled error-state EKF (Li & Wang 2020), fed sample by sample."""

@final
class Iekf(_StreamingFilter):
    """The iterated EKF (Li & Wang 2020 Algorithm 1 without re-weighting), fed sample by sample; API of :class:`_StreamingFilter`."""

@final
class Rekf(_StreamingFilter):
    """The robust EKF of Li & Wang 2020 (eqs. (37)–(40)), fed sample by sample; API of :class:`_StreamingFilter`."""

@final
class Riekf(_StreamingFilter):
    """The robust iterated EKF of Li & Wang 2020 (Algorithm 1), fed sample by sample; API of :class:`_StreamingFilter`."""

@final
class Criekf(_StreamingFilter):
    """RIEKF with zero-velocity, pseudo-velocity and plane constraints (Li & Wang 2020 CRIEKF); API of :class:`_StreamingFilter`."""

@final
class Best(_StreamingFilter):
    """``best`` (ours): RIEKF with its range test skewed against long ranges, updates in the invariant error, the zero-velocity constraint while still and a heading watch; API of :class:`_StreamingFilter`."""

@final
class Ckf(_StreamingFilter):
    """The complementary Kalman filter of the ARCKF paper (Markov biases, Q of eq. (28)); API of :class:`_StreamingFilter`."""

@final
class Arckf(_StreamingFilter):
    """The adaptive-robust complementary Kalman filter of the ARCKF paper (ARCKF, Algorithm 1); API of :class:`_StreamingFilter`."""

@final
class Ackf(_StreamingFilter):
    """The adaptive complementary Kalman filter of the ACKF paper (gravity and geomagnetic aiding); API of :class:`_StreamingFilter`."""

@final
class Eskf(_StreamingFilter):
    """The loosely coupled error-state filter of Liu et al. 2019 (least-squares fix + differenced velocity); API of :class:`_StreamingFilter`."""

@final
class Shaf(_StreamingFilter):
    """The Sage–Husa adaptive ESKF of Liu et al. 2019; API of :class:`_StreamingFilter`."""

@final
class Shfaf(_StreamingFilter):
    """The Sage–Husa fuzzy adaptive ESKF of Liu et al. 2019; API of :class:`_StreamingFilter`."""

@final
class Ukf(_StreamingFilter):
    """The 15-state error-state UKF (Wang et al. 2018 eqs. (11)–(14) over the INS error state), fed sample by
    sample; API of :class:`_StreamingFilter`."""

@final
class Rukf(_StreamingFilter):
    """The robust 15-state error-state UKF (ours): :class:`Ukf`'s update with :class:`Rekf`'s χ²
    inflation, fed sample by sample; API of :class:`_StreamingFilter`."""

# --------------------------------------------------------------------------------------------
# Ranging (src/bindings/ranging.rs): Wang et al. 2018 §2
# --------------------------------------------------------------------------------------------

DW1000_TICK_S: float
"""One DW1000 timestamp tick, 1/(128·499.2 MHz) ≈ 15.65 ps, in s."""

SPEED_OF_LIGHT_MPS: float
"""Speed of light, m/s."""

def sds_twr(
    t_round1: ArrayLike, t_reply1: ArrayLike, t_round2: ArrayLike, t_reply2: ArrayLike, *, antenna_delay_s: float = 0.0
) -> _F64:
    """SDS-TWR distances (m), Wang et al. 2018 eqs. (1)–(2), element-wise over same-shaped arrays of
    intervals (s); ``antenna_delay_s`` is the sum of both devices' antenna delays."""

def ss_twr(t_round: ArrayLike, t_reply: ArrayLike, *, antenna_delay_s: float = 0.0) -> _F64:
    """SS-TWR distances (m), ``C·((T_round − T_reply)/2 − antenna_delay_s)``, element-wise."""

def dw1000_elapsed(start_ticks: ArrayLike, end_ticks: ArrayLike) -> _F64:
    """Seconds between DW1000 40-bit timestamps (whole ticks), one wrap-around undone."""

def calibration_fit(measured: ArrayLike, true_range: ArrayLike) -> list[float]:
    """Least-squares cubic ``[c0, c1, c2, c3]`` (ascending) mapping measured to true ranges."""

def calibration_fit_anchors(anchor: ArrayLike, measured: ArrayLike, true_range: ArrayLike) -> dict[int, list[float]]:
    """One cubic per anchor index from labelled (measured, true) pairs."""

def calibration_apply(coefficients: Sequence[float], measured: ArrayLike) -> _F64:
    """Evaluates the cubic ``[c0, c1, c2, c3]`` at measured ranges, element-wise."""

def calibrate_ranges(ranges: ArrayLike, calibration: dict[int, Sequence[float]], anchor_count: int) -> NDArray[np.float64]:
    """Applies per-anchor cubics to a range table (M, 3) = t, anchor index, range; returns a copy."""

def survey_anchors(
    pairs: ArrayLike,
    *,
    fixed: Mapping[int, ArrayLike] | None = None,
    heights: ArrayLike | None = None,
) -> dict[str, Any]:
    """Survey the anchors from ranges measured between them, without a tape measure
    (docs/anchors.md).

    Parameters
    ----------
    pairs : array_like, shape (M, 3)
        anchor i, anchor j (indices), range (m); a pair may be measured any number of times, some
        of them in NLOS (a robust M-estimator weighs them down: Huber, then Tukey's biweight).
    fixed : dict, optional
        ``{index: [x, y, z]}``: anchors pinned at known positions (at least three, not on a line).
    heights : array_like, shape (K,), optional
        Known mounting heights, m (NaN where unknown).

    Returns
    -------
    dict
        ``positions`` (K, 3) m; ``covariances`` (K, 3, 3) m²; ``residuals`` (M,) m (survey
        distance minus range); ``sigma`` (robust scale of the residuals, m); ``warnings`` (a
        mirror left open, a near-coplanar or collinear layout, pairs that look NLOS);
        ``frame``: anchor 0 at the origin, anchor 1 on +x, anchor 2 on the +y side, z the normal
        of their plane (with heights: z the heights), unless anchors are pinned.

    Raises
    ------
    ValueError
        A range that is NaN or negative, a pair of one anchor, an anchor without any pair, a pair
        graph in pieces, fewer distinct pairs than the geometry needs.
    """

def posterior_crlb(
    imu: ArrayLike,
    ranges: ArrayLike,
    anchors: ArrayLike,
    truth: ArrayLike,
    *,
    biases: ArrayLike | None = None,
    initial: dict[str, Any] | None = None,
    config: _ConfigArg = None,
) -> dict[str, _F64]:
    """Posterior CRLB (the ARCKF paper's eqs. (43)–(44)) along ``truth`` (N, 11) = t, x, y, z, vx, vy, vz,
    qw, qx, qy, qz; ``biases`` (N, 6). Returns columns t, crlb_x, crlb_y, crlb_z (std, m)."""

def run_filters(
    method: str,
    runs: Sequence[tuple[ArrayLike, ArrayLike, ArrayLike] | tuple[ArrayLike, ArrayLike, ArrayLike, Mapping[str, ArrayLike | None]]],
    *,
    initial: Sequence[dict[str, Any] | None] | None = None,
    config: _ConfigArg = None,
    covariance: bool = False,
    smooth: bool | None = None,
    progress: bool = False,
) -> list[tuple[dict[str, _F64], None, dict[str, Any]]]:
    """Run one method over many ``(imu, ranges, anchors)`` or ``(imu, ranges, anchors, sensors)``
    recordings in parallel (rayon, GIL released), ``sensors`` a dict of the other sensors' arrays
    by their :data:`SENSORS` keyword; one ``(columns, None, info)`` per run, in order.
    ``progress`` draws a bar of the IMU samples processed (over all runs) on stderr."""

def calibrate_log(
    imu: ArrayLike,
    ranges: ArrayLike,
    anchors: ArrayLike,
    *,
    truth: ArrayLike | None = None,
    method: str = "riekf",
    initial: dict[str, Any] | None = None,
    config: _ConfigArg = None,
    iterations: int = 8,
    offsets: bool = False,
    refine_anchors: bool = False,
    anchor_std: float | ArrayLike | None = None,
    range_bias_std: float | None = None,
) -> dict[str, Any]:
    """Estimate a constant range bias per anchor from a log (with the tag's truth (N, 4) = t, x, y,
    z, else by EM over the smoothed track of ``method``), with ``offsets`` also the time offset
    and the lever arm; the GIL is released. Returns ``biases`` (anchor, bias, std, used, ranges),
    ``common_offset``, ``common_std``, ``iterations``, ``range_calibration``; with ``offsets`` also
    ``time_offset``, ``time_offset_std``, ``lever_arm``, ``lever_arm_std``, ``residual_rms``,
    ``config``; with ``refine_anchors`` (σ ``anchor_std`` of the given anchors, a bias per anchor
    with prior σ ``range_bias_std`` when given) also ``anchors``, ``anchor_std``,
    ``anchor_covariances``, ``directions``, ``biases_estimated``, ``moves``, ``converged``,
    ``warnings``, ``residual_rms``,
    ``config``."""

def choose_model(
    method: str,
    imu: ArrayLike,
    ranges: ArrayLike,
    anchors: ArrayLike,
    *,
    initial: dict[str, Any] | None = None,
    config: _ConfigArg = None,
) -> dict[str, Any]:
    """The range-error model, NLOS skew and range noise ``method`` chooses on a log by
    leave-anchors-out prediction; the GIL is released. Returns ``config``, ``overrides``,
    ``chosen``, ``reason``, ``candidates`` (dicts: label, score, per_anchor, overrides)."""

def tune_noise(
    method: str,
    imu: ArrayLike,
    ranges: ArrayLike,
    anchors: ArrayLike,
    *,
    truth: ArrayLike | None = None,
    initial: dict[str, Any] | None = None,
    config: _ConfigArg = None,
    smooth: bool | None = None,
    rounds: int = 2,
) -> dict[str, Any]:
    """Tune the noise settings of ``method`` on a log by the held-out range RMS (or the RMSE
    against the tag's truth (N, 4)); the GIL is released. Returns ``config``, ``objective``,
    ``initial_score``, ``score``, ``keys``, ``trials`` columns."""

def run_filter(
    method: str,
    imu: ArrayLike,
    ranges: ArrayLike,
    anchors: ArrayLike,
    *,
    initial: dict[str, Any] | None = None,
    config: _ConfigArg = None,
    covariance: bool = False,
    updates: bool = False,
    smooth: bool | None = None,
    progress: bool = False,
    **sensors: ArrayLike | None,
) -> tuple[dict[str, _F64], dict[str, _F64] | None, dict[str, Any]]:
    """Run one method over whole recordings (the GIL is released while Rust runs).

    Parameters
    ----------
    method : str
        One of :data:`FILTERS`.
    imu : array_like, shape (N, 7)
        t (s, strictly increasing), ax, ay, az (m/s², body specific force), gx, gy, gz (rad/s).
    ranges : array_like, shape (M, 3)
        t (s, non-decreasing), anchor index (row of ``anchors``), range (m).
    anchors : array_like, shape (K, 3)
        Anchor positions in the navigation frame, m.
    initial : dict, optional
        Initial state as for :class:`Ekf`; None: self-initialisation (:func:`initialize_state`).
    config : FilterConfig or dict, optional
        Filter settings; None for the defaults.
    covariance : bool, default False
        Add position covariance columns ``cov_xx, cov_xy, cov_xz, cov_yy, cov_yz, cov_zz`` (m²).
    updates : bool, default False
        Also return one row per range update (inertial methods only).
    progress : bool, default False
        Draw a one-line bar of the IMU samples processed on stderr while the run goes on.
    **sensors : array_like, optional
        The arrays of the other sensors by their :data:`SENSORS` keyword (``mag``, ``tdoa``), each
        in one of its layouts; a sensor the method does not take raises ``ValueError``.

    Returns
    -------
    columns : dict of str to ndarray, each shape (R,)
        Inertial methods: one row per IMU sample, ``t`` (s), ``x, y, z`` (m), ``vx, vy, vz``
        (m/s), ``qw, qx, qy, qz``, ``std_x, std_y, std_z`` (m). ``uwb_ls``: one row per solvable
        UWB epoch, ``t, x, y, z, std_x, std_y, std_z, n_ranges, residual_rms`` (m).
    updates : dict of str to ndarray, each shape (U,), or None
        With ``updates=True`` for inertial methods: ``t`` (s), ``anchor``, ``range`` (m),
        ``innovation`` (m), ``nis``, ``accepted`` (0.0/1.0), ``weight``; otherwise None.
    info : dict
        Inertial methods: ``ranges_before_start`` (int, ranges dropped before the first IMU
        sample), ``health`` (the counts of :attr:`Ekf.health`, with ``smoothing_left_out``),
        after self-initialisation ``still_start`` (bool) and ``heading_from`` (``"motion"``,
        ``"tags"`` or ``"fallback"``), and for a method that chose its model on the log (``best``) ``model``,
        the dict of :func:`choose_model`. ``uwb_ls``: empty.

    Raises
    ------
    ConfigError
        Unknown method or config / initial key, invalid value.
    UwbImuError
        Wrong shape, NaN/inf, decreasing time, anchor index out of range.
    ValueError
        An input that cannot be converted to a float64 array, or a non-dict config / initial.
    """

def initialize_state(
    imu: ArrayLike, ranges: ArrayLike, anchors: ArrayLike, *, config: _ConfigArg = None
) -> tuple[dict[str, _F64], dict[str, Any]]:
    """Self-initialisation from the start of a recording.

    Roll, pitch and gyro bias from the first ``init.still_s`` seconds; position from UWB
    multilateration; heading from a Gaussian-sum bank of inertial filters fed the UWB, taken
    when its σ is at most ``init.heading_std`` (fallback after ``init.heading_timeout_s``: the
    bank's heading with its σ). See docs/heading.md.

    Parameters
    ----------
    imu : array_like, shape (N, 7)
        t (s), ax, ay, az (m/s²), gx, gy, gz (rad/s).
    ranges : array_like, shape (M, 3)
        t (s), anchor index, range (m).
    anchors : array_like, shape (K, 3)
        Anchor positions, m.
    config : FilterConfig or dict, optional
        Filter settings; None for the defaults.

    Returns
    -------
    initial : dict of str to ndarray
        Usable as ``initial``: ``position`` (3,) m, ``velocity`` (3,) m/s, ``orientation`` (4,)
        w, x, y, z, ``position_std`` (3,) m, ``velocity_std`` (3,) m/s, ``orientation_std``
        (3,) rad, ``gyro_bias`` (3,) rad/s.
    info : dict
        ``still_start`` (bool) and ``heading_from`` (``"motion"``, ``"tags"`` or ``"fallback"``).

    Raises
    ------
    ValueError
        As :func:`run_filter`, or too little data to initialise.
    """

# --------------------------------------------------------------------------------------------
# Metrics (src/bindings/metrics.rs). Inputs must be float64 NumPy arrays (no conversion).
# --------------------------------------------------------------------------------------------

def evaluate(est_t: _F64, est_xyz: _F64, truth_t: _F64, truth_xyz: _F64, align: bool) -> dict[str, Any]:
    """Compare estimated positions with the truth (linearly interpolated at the estimate times).

    Parameters
    ----------
    est_t : ndarray of float64, shape (N,)
        Estimate times, s.
    est_xyz : ndarray of float64, shape (N, 3)
        Estimated positions, m.
    truth_t : ndarray of float64, shape (M,)
        Truth times, s (non-decreasing; repeated times count as one sample at the mean of their
        positions).
    truth_xyz : ndarray of float64, shape (M, 3)
        True positions, m.
    align : bool
        First map the estimate through the least-squares rigid transform onto the truth.

    Returns
    -------
    dict
        ``horizontal``, ``three_d``: dicts of ``n`` (int) and ``rmse, mean, median, p90, p95,
        max`` (float, m); ``errors``: dict of 1-D columns ``t`` (s), ``e_h``, ``e_3d`` (m) over
        the estimates inside the truth span; ``rotation``: (3, 3) array or None; ``translation``:
        (3,) array (m) or None (None unless ``align``).

    Raises
    ------
    UwbImuError
        Bad shapes, non-finite values, a truth time that decreases, or no estimate inside the
        truth span.
    TypeError
        An input that is not a float64 NumPy array.
    """

def nees(errors: _F64, covariances: _F64) -> _F64:
    """Normalised estimation error squared ``e^T P^-1 e`` per row.

    Parameters
    ----------
    errors : ndarray of float64, shape (N, 3)
        Position errors, m.
    covariances : ndarray of float64, shape (N, 6)
        Position covariances ``xx, xy, xz, yy, yz, zz``, m².

    Returns
    -------
    ndarray of float64, shape (N,)
        NEES values (dimensionless).

    Raises
    ------
    UwbImuError
        Bad shapes or row counts.
    NumericalError
        A covariance that is not positive definite.
    """

def cdf(errors: _F64) -> tuple[_F64, _F64]:
    """Empirical CDF of error magnitudes.

    Parameters
    ----------
    errors : ndarray of float64, shape (N,)
        Errors, m.

    Returns
    -------
    x : ndarray of float64, shape (N,)
        The errors sorted ascending, m.
    p : ndarray of float64, shape (N,)
        ``i / N`` for the i-th sorted error (1-based).
    """

def chi2_quantile(dof: int, alpha: float) -> float:
    """The χ² quantile with ``dof`` (≥ 1) degrees of freedom exceeded with probability ``alpha``
    (0 < alpha < 1): ``chi2_quantile(1, 0.05)`` ≈ 3.841. Raises :class:`ConfigError` otherwise."""

def interpolate_positions(truth_t: _F64, truth_xyz: _F64, t: _F64) -> _F64:
    """Truth positions linearly interpolated at the times ``t``.

    Parameters
    ----------
    truth_t : ndarray of float64, shape (M,)
        Truth times, s (non-decreasing; repeated times count as one sample at the mean of their
        positions).
    truth_xyz : ndarray of float64, shape (M, 3)
        True positions, m.
    t : ndarray of float64, shape (N,)
        Query times, s.

    Returns
    -------
    ndarray of float64, shape (N, 3)
        Positions, m; rows outside the truth time span are NaN.
    """

# --------------------------------------------------------------------------------------------
# Simulator (src/bindings/sim.rs)
# --------------------------------------------------------------------------------------------

SIM_PRESET_NAMES: list[str]
"""Preset names accepted by :func:`sim_preset` (``"hall_vehicle_nlos"``, ``"hall_vehicle"``, ...)."""

SIM_PRESET_ALIASES: list[str]
"""The former name of each of :data:`SIM_PRESET_NAMES` (same index), also accepted."""

SIM_OVERRIDE_KEYS: list[str]
"""Override keys accepted by :func:`sim_preset` and :func:`simulate` (``"nlos"``, ...)."""

SIM_ZOO_NAMES: list[str]
"""Scenario names accepted by :func:`sim_zoo` (``"agv_loop"``, ``"stop_and_go"``, ...)."""

def sim_zoo(
    name: str, seed: int = 0, overrides: dict[str, _Override] | None = None, **kwargs: _Override
) -> dict[str, Any]:
    """Simulate a scenario of the zoo with optional overrides (as :func:`sim_preset`): the dict of
    :func:`sim_preset` with the scenario's filter ``config`` (its ``tdoa_std`` matched to an
    overridden TDoA model) and ``default_sensors`` (bool). Raises ``ConfigError`` for an unknown
    name or override."""

def sim_zoo_matrix(
    methods: Sequence[str],
    scenarios: Sequence[str],
    seeds: Sequence[int],
    start: str,
    settings: str,
    config: _ConfigArg = None,
) -> dict[str, Any]:
    """The generality matrix over every (scenario, seed, method), in parallel with the GIL
    released: columns ``scenario``, ``seed``, ``method``, ``rmse``, ``uwb_ls_rmse``, ``ratio``,
    ``finite``, ``outage_max_error``. ``start`` is ``"given"`` or ``"self"``; ``settings``
    ``"matched"``, ``"defaults"`` or ``"custom"`` (with ``config``)."""

@final
class Trajectory:
    """An analytic ground-vehicle trajectory (immutable); build it with a static constructor.

    Not constructible directly. All constructors start with a still period of ``still_s`` seconds and raise
    :class:`ConfigError` for invalid values (e.g. non-positive sizes or times).
    """

    @staticmethod
    def figure_eight(
        centre: ArrayLike, a_m: float, b_m: float, lap_time_s: float, laps: int, still_s: float = 2.0
    ) -> Trajectory:
        """Figure-8 (lemniscate of Gerono) laps about ``centre``.

        Parameters
        ----------
        centre : array_like, shape (3,)
            Centre, m.
        a_m, b_m : float
            Half-extents along x and y, m.
        lap_time_s : float
            Duration of one lap, s.
        laps : int
            Number of laps (≥ 0).
        still_s : float, default 2.0
            Initial still period, s.
        """

    @staticmethod
    def ellipse(
        centre: ArrayLike, a_m: float, b_m: float, lap_time_s: float, laps: int, still_s: float = 2.0
    ) -> Trajectory:
        """Counter-clockwise ellipse laps about ``centre``.

        Parameters
        ----------
        centre : array_like, shape (3,)
            Centre, m.
        a_m, b_m : float
            Semi-axes along x and y, m.
        lap_time_s : float
            Duration of one lap, s.
        laps : int
            Number of laps (≥ 0).
        still_s : float, default 2.0
            Initial still period, s.
        """

    @staticmethod
    def waypoints(
        points: ArrayLike,
        speed_mps: float = 0.5,
        ramp_s: float = 1.0,
        dwell_s: float = 1.0,
        turn_time_s: float = 2.0,
        still_s: float = 2.0,
    ) -> Trajectory:
        """Straight legs through ``points``, stopping and turning in place at each one.

        Parameters
        ----------
        points : array_like, shape (N, 3)
            Waypoints, m.
        speed_mps : float, default 0.5
            Cruise speed, m/s.
        ramp_s : float, default 1.0
            Acceleration / deceleration time per leg, s.
        dwell_s : float, default 1.0
            Stop at each waypoint, s.
        turn_time_s : float, default 2.0
            Turn in place at each waypoint, s.
        still_s : float, default 2.0
            Initial still period, s.
        """

    @staticmethod
    def rectangle(
        corner: ArrayLike,
        width_m: float,
        height_m: float,
        laps: int = 1,
        speed_mps: float = 0.5,
        ramp_s: float = 1.0,
        dwell_s: float = 1.0,
        turn_time_s: float = 2.0,
        still_s: float = 2.0,
    ) -> Trajectory:
        """Counter-clockwise laps of an axis-aligned rectangle from its lower-left ``corner``.

        Parameters
        ----------
        corner : array_like, shape (3,)
            Lower-left corner, m.
        width_m, height_m : float
            Extents along x and y, m.
        laps : int, default 1
            Number of laps (≥ 0).
        speed_mps, ramp_s, dwell_s, turn_time_s, still_s : float
            As for :meth:`waypoints` (m/s, s).
        """

    @staticmethod
    def diagonal(
        start: ArrayLike, end: ArrayLike, speed_mps: float = 0.5, ramp_s: float = 1.0, still_s: float = 2.0
    ) -> Trajectory:
        """One straight leg from ``start`` to ``end``.

        Parameters
        ----------
        start, end : array_like, shape (3,)
            End points, m.
        speed_mps : float, default 0.5
            Cruise speed, m/s.
        ramp_s : float, default 1.0
            Acceleration / deceleration time, s.
        still_s : float, default 2.0
            Initial still period, s.
        """

    @property
    def duration_s(self) -> float:
        """Total duration, s."""

    def sample(self, t_s: float) -> dict[str, Any]:
        """Exact kinematic state at ``t_s`` (s).

        Returns
        -------
        dict
            ``t`` (float, s), ``position`` (3,) m, ``velocity`` (3,) m/s, ``acceleration`` (3,)
            m/s², ``orientation`` (4,) w, x, y, z, ``angular_rate_body`` (3,) rad/s.
        """

    def sample_many(self, t_s: ArrayLike) -> dict[str, _F64]:
        """States at the times ``t_s``.

        Parameters
        ----------
        t_s : array_like, shape (N,)
            Times, s.

        Returns
        -------
        dict of str to ndarray, each shape (N,)
            ``t`` (s), ``x, y, z`` (m), ``vx, vy, vz`` (m/s), ``qw, qx, qy, qz``.
        """

def sim_preset(
    name: str, seed: int = 0, overrides: dict[str, _Override] | None = None, **kwargs: _Override
) -> dict[str, Any]:
    """Simulate a named preset (the GIL is released while Rust runs).

    Parameters
    ----------
    name : str
        One of :data:`SIM_PRESET_NAMES`.
    seed : int, default 0
        Seed of all random draws (≥ 0); the same seed gives identical output.
    overrides : dict, optional
        Keys of :data:`SIM_OVERRIDE_KEYS`: a bool switches a feature (``nlos``,
        ``magnetometer``, ``imu_noise``), a number sets a value (e.g. ``range_std_m``).
    **kwargs : float or bool
        Further overrides, applied after ``overrides``.

    Returns
    -------
    dict
        ``imu`` (N, 7) t, ax, ay, az, gx, gy, gz (s, m/s², rad/s); ``ranges`` (M, 3) t, anchor,
        range (s, -, m); ``range_labels`` (M,) uint8 (0 LOS, 1 NLOS, 2 outlier); ``anchors``
        (K, 3) m; ``truth``: dict of 1-D columns t, x, y, z, vx, vy, vz, qw, qx, qy, qz;
        ``mag`` (N, 4) t, mx, my, mz or None; ``accel_bias`` (N, 3) m/s²; ``gyro_bias`` (N, 3)
        rad/s; ``nlos_windows`` (W, 4) anchor, start (s), end (s), bias (m); ``true_anchors``
        (K, 3) m; ``config``: the filter configuration matched to the sensors (dict);
        ``initial``: the true state at the first IMU sample (dict for ``initial=``).

    Raises
    ------
    ConfigError
        Unknown preset or override key, or an invalid value.
    """

def simulate(
    trajectory: Trajectory,
    anchors: ArrayLike,
    seed: int = 0,
    lever_arm_m: ArrayLike | None = None,
    imu_rotation: ArrayLike | None = None,
    overrides: dict[str, _Override] | None = None,
    **kwargs: _Override,
) -> dict[str, Any]:
    """Simulate IMU, UWB ranges and truth along ``trajectory`` (GIL released).

    Default configuration: 100 Hz consumer-MEMS IMU, 2 Hz LOS ranging with σ = 0.1 m.

    Parameters
    ----------
    trajectory : Trajectory
        The path of the body (IMU) origin.
    anchors : array_like, shape (K, 3)
        Anchor positions, m (K ≥ 1).
    seed : int, default 0
        Seed of all random draws (≥ 0).
    lever_arm_m : array_like, shape (3,), optional
        UWB antenna position in the body frame, m (None: ``[0, 0, 0.05]``).
    imu_rotation : array_like, shape (4,), optional
        IMU → body mounting rotation ``[w, x, y, z]`` (None: identity).
    overrides : dict, optional
        Keys of :data:`SIM_OVERRIDE_KEYS`, as for :func:`sim_preset`.
    **kwargs : float or bool
        Further overrides, applied after ``overrides``.

    Returns
    -------
    dict
        As :func:`sim_preset`.

    Raises
    ------
    ConfigError
        Unknown override key, invalid value or zero-norm ``imu_rotation``.
    UwbImuError
        Bad array shape or non-finite values.
    """

# --------------------------------------------------------------------------------------------
# MCAP reading and replay (src/bindings/io.rs)
# --------------------------------------------------------------------------------------------

def read_mcap(path: str, *, mapping: str | None = None, config_file: str | None = None) -> dict[str, Any]:
    """Read an MCAP file through a mapping (JSON text of the ``[mapping]`` table) and/or a replay
    TOML file. Returns ``imu``, ``ranges``, ``tdoa`` (``t, i, j, d_ij``: anchor indices i, j and
    d_ij = |p − a_j| − |p − a_i| in m), ``anchors``, ``ground_truth`` (dicts of float64 columns),
    ``anchor_ids`` (list of str) and ``stats`` (dict). Raises OSError (``FormatError``)
    for unreadable or corrupt files and ``MappingError`` for a mapping that does not fit."""

def replay(
    path: str,
    method: str | None = None,
    *,
    mapping: str | None = None,
    config_file: str | None = None,
    config: _ConfigArg = None,
    overrides: dict[str, Any] | None = None,
    initial: dict[str, Any] | None = None,
    smooth: bool | None = None,
    ground_truth: str | None = None,
    progress: bool = False,
) -> tuple[dict[str, _F64], dict[str, Any]]:
    """Read an MCAP file and replay it through ``method`` (the ``uwbimu-replay`` core) from
    ``initial`` (None: the config file's ``[initial]``, else self-initialisation from the
    ranges or, without ranges, the TDoA). ``mapping`` merges into the config file's
    ``[mapping]`` key by key; ``config`` replaces its ``[config]`` and ``overrides`` sets its
    keys over the result; ``ground_truth`` is a truth CSV (the CLI's ``--ground-truth``);
    ``progress`` draws bars on stderr. Returns ``(columns, info)``: the run_filter columns and
    the keys of the CLI's ``--json`` summary (method, smoothed, counts, per-anchor statistics,
    ``tdoa`` counts when the recording has TDoA, mean NIS, RMSE against ground truth when
    mapped) plus ``stats``, ``health`` and ``warnings``."""

def read_truth(path: str) -> dict[str, _F64]:
    """Read a ground-truth CSV (header ``t,x,y,z`` or ``t_s,x_m,y_m,z_m``, or none) into
    float64 columns ``t, x, y, z`` (s, m), sorted by time. Raises ``FileNotFoundError`` for a
    missing file and ``FormatError`` (an OSError) naming the line of a bad one."""

TRUTH_COLUMNS: list[list[str]]
"""The accepted names of the truth columns t, x, y, z: one list of spellings per column."""

def replay_main(argv: list[str]) -> int:
    """Run the ``uwbimu-replay`` command line with ``argv`` (``sys.argv``: the program, then its
    arguments) with the GIL released; returns the exit status (0 success, 2 error)."""

def write_mcap(
    path: str,
    imu: ArrayLike,
    ranges: ArrayLike,
    anchors: ArrayLike,
    *,
    range_std: float | None = None,
    **sensors: ArrayLike | None,
) -> None:
    """Write a recording as MCAP: CDR ``sensor_msgs/msg/Imu`` on ``/imu``, JSON
    ``uwbimu.UwbRange`` on ``/uwb`` (anchor ids ``A0``, ``A1``, ...; ranges ``(M, 4)`` with a tag
    column write the tag), and the other sensors' arrays by their :data:`SENSORS` keyword: TDoA
    as CDR ``uwbimu_msgs/msg/Tdoa`` on ``/tdoa`` (``idA``, ``idB``, ``distanceDiff``), heights as
    ``sensor_msgs/msg/Range`` on ``/altitude``, body velocities as ``nav_msgs/msg/Odometry`` on
    ``/odom`` (the magnetometer raises ValueError); anchor positions in the ``uwbimu.anchors``
    metadata record; zstd chunks."""

# --------------------------------------------------------------------------------------------
# Nooploop LinkTrack serial frames (src/bindings/linktrack.rs, docs/linktrack.md)
# --------------------------------------------------------------------------------------------

class _LinkTrackNode(TypedDict):
    """One node a ``NodeFrame2`` ranged to."""

    id: int
    """The node's id."""
    role: int
    """Its role: 0 node, 1 anchor, 2 tag, 3 console, 4 DT master, 5 DT slave, 6 monitor."""
    range: float
    """The measured distance, m (1 mm steps)."""
    fp_rssi: float
    """First-path received power, dBm (0.5 dB steps)."""
    rx_rssi: float
    """Total received power, dBm (0.5 dB steps)."""
    system_time_ms: int
    """The network time of this measurement, ms."""

class _LinkTrackFrameBase(TypedDict):
    """The keys both LinkTrack frame kinds have."""

    id: int
    """The sending node's id."""
    role: int
    """The sending node's role (2 for a tag)."""
    local_time_ms: int
    """The node's own clock since power-up, ms."""
    system_time_ms: int
    """The network (system) time, ms."""
    position: list[float]
    """Position x, y, z in the LinkTrack frame, m."""
    velocity: list[float]
    """Velocity x, y, z, m/s."""
    gyro: list[float]
    """Gyroscope x, y, z, rad/s."""
    accel: list[float]
    """Accelerometer x, y, z, m/s²."""
    angle: list[float]
    """Euler angles roll, pitch, yaw, degrees."""
    quaternion: list[float]
    """Attitude quaternion w, x, y, z."""
    eop: list[float]
    """Estimated precision of the position per axis, m."""
    voltage: float
    """Supply voltage, V."""

class _LinkTrackNodeFrame2(_LinkTrackFrameBase):
    """A decoded ``NodeFrame2`` (function mark 0x04)."""

    kind: Literal["node_frame2"]
    nodes: list[_LinkTrackNode]
    """The nodes ranged to, in frame order."""

class _LinkTrackTagFrame0(_LinkTrackFrameBase):
    """A decoded ``TagFrame0`` (function mark 0x01)."""

    kind: Literal["tag_frame0"]
    distances: list[float]
    """Distances to anchors 0 to 7, m (0 where there is none)."""

class _LinkTrackCounts(TypedDict):
    """What a :class:`LinkTrackDecoder` has seen. ``bytes_received`` = bytes of decoded frames +
    ``bytes_skipped`` + ``LinkTrackDecoder.buffered``."""

    bytes_received: int
    frames: int
    """Frames decoded (``node_frame2`` + ``tag_frame0``)."""
    node_frame2: int
    tag_frame0: int
    checksum_errors: int
    """Candidate frames whose last byte was not their checksum."""
    unknown_frames: int
    """``0x55`` bytes followed by a function mark the decoder does not read."""
    bad_lengths: int
    """``NodeFrame2`` candidates with an impossible length field."""
    bytes_skipped: int
    """Bytes dropped while resynchronising."""

@final
class LinkTrackDecoder:
    """A decoder of the Nooploop LinkTrack serial stream (``NodeFrame2`` and ``TagFrame0``).

    Feed it the bytes read from the port, cut anywhere; it keeps an incomplete frame for the next
    call, skips what is not a frame and resynchronises one byte after a bad checksum or an unknown
    function mark. It never raises on data, and holds at most one incomplete frame.
    """

    def __init__(self) -> None: ...
    def feed(self, data: bytes) -> list[_LinkTrackNodeFrame2 | _LinkTrackTagFrame0]:
        """Append ``data`` and return the frames it completed, oldest first, each a dict with
        ``kind`` (``"node_frame2"`` or ``"tag_frame0"``), ``id``, ``role``, ``local_time_ms``,
        ``system_time_ms``, ``position``, ``velocity``, ``gyro``, ``accel``, ``angle``,
        ``quaternion``, ``eop``, ``voltage``, and ``nodes`` (``NodeFrame2``: dicts ``id``,
        ``role``, ``range``, ``fp_rssi``, ``rx_rssi``, ``system_time_ms``) or ``distances``
        (``TagFrame0``: 8 floats)."""

    @property
    def counts(self) -> _LinkTrackCounts:
        """What was decoded and skipped so far."""

    @property
    def buffered(self) -> int:
        """Bytes held back: the start of a frame not yet complete."""

def encode_linktrack_node_frame2(
    id: int,
    local_time_ms: int,
    gyro: Sequence[float],
    accel: Sequence[float],
    nodes: Sequence[tuple[int, float, float, float]],
    *,
    role: int = 2,
    system_time_ms: int = 0,
    position: Sequence[float] | None = None,
    velocity: Sequence[float] | None = None,
    quaternion: Sequence[float] | None = None,
    angle: Sequence[float] | None = None,
    eop: Sequence[float] | None = None,
    voltage: float = 5.0,
) -> bytes:
    """Encode one LinkTrack ``NodeFrame2`` (checksum included), as a tag sends it.

    Parameters
    ----------
    id : int
        The sending node's id (0–255).
    local_time_ms : int
        The node's clock, ms.
    gyro, accel : sequence of 3 floats
        Gyroscope (rad/s) and accelerometer (m/s²) x, y, z.
    nodes : sequence of (anchor_id, range_m, fp_rssi_dbm, rx_rssi_dbm)
        The ranges to anchors (role 1, measured at ``system_time_ms``); at most 255.
    role : int, default 2
        The sending node's role (2 tag).
    system_time_ms : int, default 0
        The network time, ms.
    position, velocity, angle, eop : sequence of 3 floats, optional
        m, m/s, degrees, m; zeros when left out.
    quaternion : sequence of 4 floats, optional
        w, x, y, z; the identity when left out.
    voltage : float, default 5.0
        Supply voltage, V.

    Values are rounded to the wire's steps (1 mm, 0.5 dB, …) and saturate at a field's limits.
    Raises ``UwbImuError`` (a ValueError) for more than 255 nodes.
    """

# --------------------------------------------------------------------------------------------
# DWM1001 UART TLV dwm_loc_get responses (src/bindings/dwm1001.rs, docs/dwm1001.md)
# --------------------------------------------------------------------------------------------

class _DwmRange(TypedDict):
    """One distance of a ``dwm_loc_get`` response."""

    anchor_id: int
    """The other node's UWB address: 16-bit short address (tag node) or 64-bit address (anchor
    node)."""
    range: float
    """The distance, m (1 mm steps)."""
    quality: int
    """The distance quality factor (0–100)."""
    anchor_position: list[float] | None
    """The anchor's x, y, z, m (tag node); None from an anchor node."""

class _DwmLocation(TypedDict):
    """One decoded ``dwm_loc_get`` response."""

    status: int
    """The return value: 0 ok; otherwise the call failed and nothing else is set."""
    position: list[float] | None
    """The node's own x, y, z, m; None if the response has no position frame."""
    position_quality: int | None
    """The position's quality factor (0–100); None with ``position``."""
    ranges: list[_DwmRange]
    """The distances, in wire order."""

class _DwmCounts(TypedDict):
    """What a :class:`DwmDecoder` has seen. ``bytes_received`` = bytes of responses +
    ``bytes_skipped`` + ``DwmDecoder.buffered``."""

    bytes_received: int
    responses: int
    """Responses handed out (successful and failed calls)."""
    failed_calls: int
    """Of ``responses``, those with a non-zero return value."""
    errors: int
    """Candidates rejected: a position not 13 bytes, a range block whose length disagrees with
    its count, a response running past the longest possible."""
    bytes_skipped: int
    """Bytes dropped while resynchronising."""

@final
class DwmDecoder:
    """A decoder of DWM1001 ``dwm_loc_get`` responses (UART TLV API) from a serial stream.

    Feed it the bytes read from the port after sending ``b"\\x0c\\x00"``, cut anywhere. A response
    starts at ``0x40 0x01``; it ends after its ``0x49``/``0x48`` range block or before the next
    ``0x40 0x01``. The decoder keeps an incomplete response for the next call, skips what is not
    a response and resynchronises one byte after a rejected one. It never raises on data, and
    holds at most one incomplete response.
    """

    def __init__(self) -> None: ...
    def feed(self, data: bytes) -> list[_DwmLocation]:
        """Append ``data`` and return the responses it completed, oldest first, each a dict with
        ``status``, ``position`` ([x, y, z] m or None), ``position_quality`` and ``ranges``
        (dicts ``anchor_id``, ``range``, ``quality``, ``anchor_position``)."""

    @property
    def counts(self) -> _DwmCounts:
        """What was decoded and skipped so far."""

    @property
    def buffered(self) -> int:
        """Bytes held back: the start of a response not yet complete."""

def encode_dwm_loc_get(
    position: tuple[float, float, float, int] | None,
    ranges: Sequence[tuple[int, float, int, tuple[float, float, float, int] | None]],
    *,
    tag: bool = True,
) -> bytes:
    """Encode one successful DWM1001 ``dwm_loc_get`` response, as the module answers it.

    Parameters
    ----------
    position : (x, y, z, quality) or None
        The node's own position, m, and quality factor; None leaves the position frame out.
    ranges : sequence of (anchor_id, range_m, quality, anchor_position)
        The distances; ``anchor_position`` is (x, y, z, quality) or None (zeros on the wire).
    tag : bool, default True
        A tag node's ``0x49`` block (16-bit addresses, at most 12 ranges) or, if False, an
        anchor node's ``0x48`` block (64-bit addresses, no positions, at most 19 ranges).

    Values are rounded to whole millimetres and saturate at a field's limits. Raises
    ``UwbImuError`` (a ValueError) for too many ranges.
    """

# --------------------------------------------------------------------------------------------
# The live node's core (src/bindings/live.rs, docs/live.md)
# --------------------------------------------------------------------------------------------

_TopicEntry = tuple[str, str, str, str, str]

UWB_RANGE_JSON: str
"""Schema name of the JSON range message the recordings write (``uwbimu.UwbRange``)."""

UWB_RANGE_MSG: str
"""ROS 2 type of our CDR range message (``uwbimu_msgs/msg/UwbRange``: header, ``anchor_id``,
``range``, ``variance`` (NaN: none), ``tag`` (empty: the first tag))."""

def ros_uwb_range_from_json(data: bytes) -> bytes:
    """One ``uwbimu.UwbRange`` JSON message as the XCDR1 payload of ``uwbimu_msgs/msg/UwbRange``."""

def live_setup(config: str | os.PathLike[str] | None = None, *, mapping: str | None = None) -> dict[str, Any]:
    """The replay file ``config`` (with the mapping JSON ``mapping`` merged in) as the live node
    starts from it: ``method``, ``config`` (FilterConfig), ``initial``, ``live`` (the ``[live]``
    table with its defaults), ``reorder_window_s`` and ``outputs`` (``(topic, type, definition,
    dds_topic, dds_type)`` of the pose, odometry, diagnostics and fixed-lag smoothed pose
    topics; the last published only with ``live.lag_s``)."""

def live_subscriptions(config: str | os.PathLike[str] | None = None, *, mapping: str | None = None) -> dict[str, Any]:
    """``topics``: ``(topic, type, definition, dds_topic, dds_type)`` of each topic the node
    subscribes to (the IMU topic, then the UWB, TDoA, altitude and odometry topics of the
    mapping; ``type`` None for a UWB topic without a type in ``live.types``, ``definition`` None
    when the type is None or its ``.msg`` is found nowhere: the node learns them from the
    graph); ``discover``: whether it also takes every other topic the mapping can read (the
    mapping names no UWB or TDoA topic)."""

def ros_definition(type_name: str, msg_paths: Sequence[str | os.PathLike[str]] = ...) -> str:
    """The full ``.msg`` definition of ``type_name`` with its dependencies (bundled, or found as
    ``<dir>/<pkg>/msg/<Type>.msg`` in ``msg_paths``)."""

def ros_fields(type_name: str, definition: str) -> list[tuple[str, list[tuple[str, str, str, int]]]]:
    """The types of a definition, root first: ``(name, [(field, element, array, length)])``."""

@final
class MessageDecoder:
    """Messages decoded one at a time through the mapping of a replay file (which must give the
    anchor positions)."""

    def __new__(
        cls,
        config: str | os.PathLike[str] | None = None,
        *,
        mapping: str | None = None,
        recording: str | os.PathLike[str] | None = None,
    ) -> MessageDecoder: ...
    @property
    def anchor_ids(self) -> list[str]:
        """Anchor ids in filter-index order."""
    @property
    def anchors(self) -> NDArray[np.float64]:
        """Anchor positions (K, 3), m, in filter-index order."""
    def add_topic(self, topic: str, schema_name: str, schema_text: str, encoding: str = "cdr") -> str | None:
        """Announce a topic; its role when it feeds the filter (``imu``, ``uwb`` or a sensor's
        name), else None."""
    def decode(self, topic: str, arrival_s: float, data: bytes) -> list[tuple[Any, ...]]:
        """The records of one message: ``("imu", t, accel, gyro)``, ``("range", t, anchor, range,
        tag)``, or ``(sensor, t, values...)``: a sensor's name and one row of its table, as
        ``add_sensor`` takes it (``("tdoa", t, i, j, d_ij)``, ``("magnetometer", t, mx, my,
        mz)``, ...); none for a message that does not decode (counted)."""
    @property
    def counts(self) -> dict[str, dict[str, Any]]:
        """Per topic: ``messages``, ``records``, ``errors``, ``arrival_stamps``, ``last_error``."""

def ros_pose_messages(
    t: float,
    position: ArrayLike,
    velocity: ArrayLike,
    quaternion: ArrayLike,
    angular_rate: ArrayLike,
    covariance: ArrayLike,
    *,
    parent: str = "map",
    child: str = "base_link",
) -> tuple[bytes, bytes]:
    """``(PoseWithCovarianceStamped, Odometry)`` XCDR1 payloads of the estimate at ``t``
    (covariance (15, 15) in the filter's order, carried in the messages' conventions)."""

def ros_diagnostics_message(t: float, statuses: list[dict[str, Any]]) -> bytes:
    """A ``diagnostic_msgs/DiagnosticArray`` XCDR1 payload of status dicts (``level``: ok, warn,
    error, stale; ``name``, ``message``, ``hardware_id``, ``values``)."""

@final
class TrajectoryWriter:
    """The trajectory as ``uwbimu-replay --out`` writes it, written as it goes."""

    def __new__(cls, path: str | os.PathLike[str]) -> TrajectoryWriter: ...
    def push(self, t: float, position: ArrayLike, quaternion: ArrayLike) -> None:
        """Write the pose at ``t``: position (3,) m, quaternion [w, x, y, z]."""
    def close(self) -> None:
        """Write the summary and close the file."""
