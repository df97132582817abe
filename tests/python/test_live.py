"""The live node (docs/live.md): its estimator loop in process (what it publishes, silent sensors,
impossible data, the model choice), then end to end — a recording played over DDS on loopback
through the node to a subscriber, against ``replay`` of the same log, and a simulated LinkTrack
module through a pseudo-terminal, against the truth. The oracles are the truth of the simulator
and the batch/streaming result of the same inputs, never the node's earlier output."""

# Under xdist this file's tests share one worker (conftest.py, ONE_WORKER).
from __future__ import annotations

import json
import logging
import os
import re
import signal
import subprocess
import sys
import time
import tty
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
import pytest

import uwbimu_rs
from uwbimu_rs import _native, sim
from uwbimu_rs.live import apply_record
from shared_data import ISAS, needs_isas

ROOT = Path(__file__).resolve().parents[2]
PY = sys.executable


def records_of(run: Any, t_end: float) -> list[tuple[Any, ...]]:
    """The records of a simulated run up to ``t_end``, in time order (IMU first at equal times)."""
    imu = run.imu[run.imu[:, 0] <= t_end]
    ranges = run.ranges[run.ranges[:, 0] <= t_end]
    recs = [((r[0], 0), ("imu", r[0], r[1:4], r[4:7])) for r in imu]
    recs += [((r[0], 1), ("range", r[0], int(r[1]), r[2], None)) for r in ranges]
    recs.sort(key=lambda x: x[0])
    return [r for _, r in recs]


class Collect:
    """A sink that keeps everything."""

    def __init__(self) -> None:
        self.rows: list[dict[str, np.ndarray]] = []
        self.poses: list[Any] = []
        self.diag_batches: list[list[dict[str, Any]]] = []
        self.updates: list[Any] = []
        self.closed = False

    def steps(self, rows):
        self.rows.append(rows)

    def pose(self, pose):
        self.poses.append(pose)

    def diagnostics(self, t, statuses):
        self.diag_batches.append(statuses)

    def range_update(self, u):
        self.updates.append(u)

    def close(self):
        self.closed = True

    def track(self) -> np.ndarray:
        return np.column_stack([np.concatenate([r[c] for r in self.rows]) for c in ("t", "x", "y", "z")])


class Clock:
    """A wall clock the test moves."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def node_for(anchors, *, choose_after_s=0.0, clock=None, sinks=None, method=None, **live):
    from uwbimu_rs.live import LiveNode

    setup = _native.live_setup(None)
    setup["live"]["choose_after_s"] = choose_after_s
    setup["live"].update(live)
    return LiveNode(setup, anchors, sinks=sinks or [], clock=clock or Clock(), method=method)


def horizontal_rmse(track: np.ndarray, run: Any, after_s: float) -> float:
    truth = run.truth.to_numpy()
    keep = track[:, 0] > track[0, 0] + after_s
    tr = track[keep]
    e = np.hypot(tr[:, 1] - np.interp(tr[:, 0], truth[:, 0], truth[:, 1]), tr[:, 2] - np.interp(tr[:, 0], truth[:, 0], truth[:, 2]))
    return float(np.sqrt(np.mean(e**2)))


def test_importing_uwbimu_rs_loads_none_of_the_live_extras():
    code = (
        "import sys, uwbimu_rs; "
        "print(sorted({m.split('.')[0] for m in sys.modules} & {'cyclonedds', 'foxglove', 'serial', 'mcap', 'uwbimu_rs.live'}))"
    )
    out = subprocess.run([PY, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "[]"


@pytest.mark.parametrize("method", ["best", "riekf"])
def test_the_node_publishes_what_the_streaming_filter_estimates_and_tracks(method):
    # stop_and_go, 40 s, self-initialised: every step the node gives its sinks equals the
    # streaming class of the method fed the same records, and the track follows the truth.
    run = sim.zoo("stop_and_go", seed=2)
    recs = records_of(run, run.imu[0, 0] + 40.0)
    clock, sink = Clock(), Collect()
    node = node_for(run.anchors, clock=clock, sinks=[sink], method=method)
    for r in recs:
        clock.now = r[1]
        node.feed("sim", [r])
        node.tick()
    node.close()
    ref = getattr(uwbimu_rs, method.capitalize())(run.anchors, reorder_window_s=0.5)
    for r in recs:
        apply_record(ref, r)
    ref.flush()
    expected = ref.steps()
    track = sink.track()
    assert sink.closed and len(track) == expected.height
    np.testing.assert_array_equal(track[:, 1], expected["x"].to_numpy())
    assert horizontal_rmse(track, run, 5.0) < 0.2
    # One pose per call that made steps (the start's batch of kept data gives one), each with a
    # covariance the messages can carry.
    assert len(sink.poses) > 0.9 * (len(track) - len(sink.rows[0]["t"]))
    p = sink.poses[-1]
    assert p.covariance.shape == (15, 15) and np.all(np.linalg.eigvalsh(p.covariance) > 0)
    assert sink.updates and all(u.anchor in range(len(run.anchors)) and u.fp_power_dbm is None for u in sink.updates)
    # Latency in sensor time (the test's clock): the reorder window, plus the sample or two a
    # step waits for data after its time.
    lat = np.array(node.latencies)
    dt = float(np.median(np.diff(run.imu[:, 0])))
    assert lat.min() >= 0.5 - 1e-9 and lat.max() <= 0.5 + 3 * dt


class CollectSmoothed(Collect):
    """A sink that also takes the fixed-lag smoothed poses."""

    def __init__(self) -> None:
        super().__init__()
        self.smoothed: list[Any] = []

    def smoothed_pose(self, pose):
        self.smoothed.append(pose)


def test_with_lag_s_the_node_publishes_the_fixed_lag_smoothed_pose():
    # stop_and_go, 30 s, lag 1 s: each smoothed pose is the newest row of a pass of the streaming
    # class fed the same records, with its smoothed covariance; the last comes at the close,
    # at the filter's time; a sink without `smoothed_pose` still works.
    run = sim.zoo("stop_and_go", seed=2)
    recs = records_of(run, run.imu[0, 0] + 30.0)
    clock, sink, plain = Clock(), CollectSmoothed(), Collect()
    node = node_for(run.anchors, clock=clock, sinks=[sink, plain], lag_s=1.0)
    ref = uwbimu_rs.Best(run.anchors, reorder_window_s=0.5, lag_s=1.0)
    newest = []
    for r in recs:
        clock.now = r[1]
        node.feed("sim", [r])
        apply_record(ref, r)
        rows = ref.lagged_steps()
        if rows.height:
            newest.append((rows.row(-1, named=True), ref.lagged_covariance))
    node.close()
    ref.flush()
    newest.append((ref.lagged_steps().row(-1, named=True), ref.lagged_covariance))
    assert len(sink.smoothed) == len(newest) > 25 and node.smoothed_poses_published == len(newest)
    for pose, (row, cov) in zip(sink.smoothed, newest):
        assert pose.t == row["t"] and list(pose.position) == [row["x"], row["y"], row["z"]]
        np.testing.assert_array_equal(pose.covariance, cov)
    assert np.all(np.linalg.eigvalsh(sink.smoothed[-1].covariance) > 0)
    assert sink.smoothed[-1].t == ref.time and len(plain.poses) == len(sink.poses)
    assert node.statuses()[0]["values"]["smoothed_poses_published"] == len(newest)


def test_a_silent_sensor_is_reported_and_its_return_too(caplog):
    run = sim.zoo("stop_and_go", seed=1)
    recs = records_of(run, run.imu[0, 0] + 20.0)
    clock, sink = Clock(), Collect()
    node = node_for(run.anchors, clock=clock, sinks=[sink], silent_after_s=1.0, diagnostics_period_s=0.5)
    t0 = recs[0][1]
    with caplog.at_level(logging.INFO, logger="uwbimu.live"):
        for r in recs:
            clock.now = r[1]
            gap = 10.0 <= r[1] - t0 < 13.0
            if r[0] == "range" and gap:
                continue  # the UWB goes quiet for 3 s
            node.feed("/uwb" if r[0] == "range" else "/imu", [r])
            node.tick()
    messages = [rec.getMessage() for rec in caplog.records]
    silent = [m for m in messages if m.startswith("/uwb: silent")]
    assert len(silent) == 1 and not any(m.startswith("/imu: silent") for m in messages)
    # An input that never sends anything is reported too.
    clock.now += 0.5
    node.watch("/altitude", "altitude")
    clock.now += 1.5
    with caplog.at_level(logging.INFO, logger="uwbimu.live"):
        node.tick()
    assert "/altitude: nothing received in 1.5 s" in [rec.getMessage() for rec in caplog.records]
    assert "/uwb: receiving again" in messages
    warned = [s for batch in sink.diag_batches for s in batch if s["hardware_id"] == "/uwb" and s["level"] == "warn"]
    assert warned and warned[0]["message"].startswith("silent for")
    assert any(m.startswith("initialised") for m in messages)


def test_impossible_and_corrupt_data_are_counted_never_fatal(tmp_path):
    # A recording written by the simulator, its messages fed as DDS delivers them, with a cut
    # message, garbage, a range 1 km long and an IMU sample from the past mixed in.
    run = sim.zoo("stop_and_go", seed=3)
    path = tmp_path / "run.mcap"
    sim.write_mcap(run, path)
    t_end = run.imu[0, 0] + 30.0
    config = tmp_path / "live.toml"
    anchors = "\n".join(f'A{k} = [{a[0]}, {a[1]}, {a[2]}]' for k, a in enumerate(run.anchors))
    config.write_text(f'[mapping]\nimu_topic = "/imu"\n[mapping.uwb]\ntopics = ["/uwb"]\n[mapping.anchors.positions]\n{anchors}\n')
    decoder = _native.MessageDecoder(config)
    from uwbimu_rs.live._sources import mcap_messages

    clock, sink = Clock(), Collect()
    node = node_for(decoder.anchors, clock=clock, sinks=[sink])
    roles = {}
    for k, (schema, channel, message) in enumerate(mcap_messages(str(path))):
        if channel.topic not in roles:
            roles[channel.topic] = decoder.add_topic(channel.topic, schema.name, schema.data.decode(), channel.message_encoding)
        if roles[channel.topic] is None:
            continue
        clock.now = message.log_time * 1e-9
        if clock.now > t_end:
            break
        data = message.data
        if k == 500:
            data = data[: len(data) // 2]  # cut
        elif k == 700:
            data = b"\x00\x01\x00\x00garbage"
        node.feed_message(decoder, channel.topic, data)
        if k == 900:
            node.feed("/uwb", [("range", clock.now, 0, 1000.0, None)])  # beyond any hall
        if k == 1100:
            node.feed("/imu", [("imu", clock.now - 5.0, [0, 0, 9.8], [0, 0, 0])])  # 5 s late
    node.close()
    counts = decoder.counts
    assert counts["/imu"]["errors"] + counts["/uwb"]["errors"] == 2
    health = node.filter.health
    assert health["rejected"]["range_beyond_hall"] >= 1
    assert health["late_dropped"] >= 1
    assert horizontal_rmse(sink.track(), run, 5.0) < 0.25


def test_the_node_chooses_its_model_on_its_first_seconds_and_says_so(caplog):
    run = sim.zoo("agv_loop", seed=0)  # 8 anchors: the choice runs
    recs = records_of(run, run.imu[0, 0] + 45.0)
    clock, sink = Clock(), Collect()
    node = node_for(run.anchors, choose_after_s=20.0, clock=clock, sinks=[sink])
    with caplog.at_level(logging.INFO, logger="uwbimu.live"):
        for r in recs:
            clock.now = r[1]
            node.feed("sim", [r])
            node.wait_for_choice(120)  # the test waits for the choice where a robot would not
            node.tick()
        node.close()
    messages = [rec.getMessage() for rec in caplog.records]
    assert any(m.startswith("choosing the model on 20 s of data") for m in messages)
    chosen = [m for m in messages if m.startswith("model chosen: ")]
    assert len(chosen) == 1 and node.chosen is not None
    assert node.statuses()[0]["values"]["model"] == node.chosen
    track = sink.track()
    assert np.all(np.diff(track[:, 0]) > 0)  # the switch re-emits nothing
    assert horizontal_rmse(track, run, 5.0) < 0.2


def test_linktrack_signal_powers_reach_the_range_updates():
    # Each NodeFrame2 range carries its powers to the update it makes (the Foxglove NIS channel).
    from uwbimu_rs.live import linktrack_frames, linktrack_records

    run = sim.zoo("stop_and_go", seed=1)
    ids = [str(20 + k) for k in range(len(run.anchors))]
    imu = run.imu[run.imu[:, 0] <= run.imu[0, 0] + 15.0]
    clock, sink = Clock(), Collect()
    node = node_for(run.anchors, clock=clock, sinks=[sink])
    index = {a: k for k, a in enumerate(ids)}
    for frame in _native.LinkTrackDecoder().feed(b"".join(linktrack_frames(imu, run.ranges, ids))):
        clock.now = frame["local_time_ms"] * 1e-3
        node.feed("linktrack", linktrack_records(frame, index))
    node.close()
    assert len(sink.updates) > 50
    assert {(u.fp_power_dbm, u.rx_power_dbm) for u in sink.updates} == {(-80.0, -78.0)}


def test_a_discovered_type_is_written_back_as_its_msg_definition():
    # A type built from a definition with every kind of field, read back as .msg text: the
    # same types, fields, elements and array kinds.
    from uwbimu_rs.live import idl_type
    from uwbimu_rs.live._graph import msg_definition

    text = (
        "std_msgs/Header header\nuint16 id\nfloat32[3] pos\nstring name\nbool ok\nint8 k\n"
        "Item[] items\nItem[<=4] few\nItem[2] pair\nfloat64[] values\n"
        f"{'=' * 80}\nMSG: my_pkg/Item\nuint32 code\ngeometry_msgs/Point p\n"
        f"{'=' * 80}\nMSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n"
    )
    full = text + f"{'=' * 80}\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
    name, back = msg_definition(idl_type("my_pkg/msg/Thing", full))
    assert name == "my_pkg/msg/Thing"
    expected = {t: sorted(f) for t, f in _native.ros_fields("my_pkg/msg/Thing", full)}
    got = {t: sorted(f) for t, f in _native.ros_fields(name, back)}
    assert got == expected


def test_a_method_without_a_streaming_class_is_refused():
    with pytest.raises(ValueError, match="'uwb_ls' has no streaming class; the live node runs one of"):
        node_for(np.eye(4, 3), method="uwb_ls")


def test_cli_errors_exit_2_with_one_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[live]\ndomian_id = 3\n")
    p = subprocess.run([PY, "-m", "uwbimu_rs.live", "--config", str(bad), "--no-ros", "--mcap", "x.mcap"], capture_output=True, text=True)
    assert p.returncode == 2 and "unknown field `domian_id`" in p.stderr and len(p.stderr.strip().splitlines()) == 1
    noanchors = tmp_path / "noanchors.toml"
    noanchors.write_text('[mapping.uwb]\ntopics = ["/uwb"]\n')
    p = subprocess.run([PY, "-m", "uwbimu_rs.live", "--config", str(noanchors)], capture_output=True, text=True)
    assert p.returncode == 2 and "anchor positions" in p.stderr
    p = subprocess.run([PY, "-m", "uwbimu_rs.live", "--no-ros", "--mcap", "x.mcap", "--lag", "nan"], capture_output=True, text=True)
    assert p.returncode == 2 and "--lag nan: must be finite" in p.stderr and len(p.stderr.strip().splitlines()) == 1


def _sensor_rig(tmp_path: Path) -> tuple[Any, Path, Path]:
    """stop_and_go with a magnetometer and pose fixes with a yaw (2 Hz), written by
    ``sim.write_mcap``, and a replay file for ``ackf`` (it takes both) that reads them with the
    anchors of the run. Its reorder window is 2 s of log time (0.5 s of wall time at the 4×
    pace the tests play it at), the default's 0.125 s of wall time being short for four topics on
    a loaded machine; the replay orders the file whatever the window. Its inputs are reliable
    (``live.reliable_inputs``): with best-effort readers a node starved of CPU (three busy loops
    beside it on two cores) lost up to a fifth of the IMU and magnetometer messages, and its
    poses went millimetres off the replay's."""
    run = sim.zoo("stop_and_go", seed=5, magnetometer=True, pose_fix=True, pose_fix_yaw_std_rad=0.05)
    mcap = tmp_path / "sensors.mcap"
    sim.write_mcap(run, mcap)
    anchors = "\n".join(f"A{k} = [{a[0]}, {a[1]}, {a[2]}]" for k, a in enumerate(run.anchors))
    cfg = tmp_path / "sensors.toml"
    cfg.write_text(
        'method = "ackf"\n[mapping]\nreorder_window_s = 2.0\n[mapping.magnetometer]\ntopics = ["/mag"]\n[mapping.pose_fix]\ntopics = ["/pose_fix"]\n'
        f"[mapping.anchors.positions]\n{anchors}\n[live]\nchoose_after_s = 0\nreliable_inputs = true\n"
    )
    return run, mcap, cfg


def test_magnetometer_and_pose_fix_messages_become_their_rows_and_reach_the_filter(tmp_path):
    # The recording's MagneticField and PoseWithCovarianceStamped messages, decoded through the
    # mapping as the node decodes what DDS delivers: each gives one record, the sensor's name and
    # its table row — the run's own row (fields, positions and σ bit for bit, yaw to 1e-12 rad,
    # stamps to the nanosecond) — and the node feeds every one to ackf's add_sensor, refusing
    # none.
    from uwbimu_rs.live._sources import mcap_messages

    run, mcap, cfg = _sensor_rig(tmp_path)
    decoder = _native.MessageDecoder(cfg)
    clock = Clock()
    node = node_for(decoder.anchors, clock=clock, method="ackf")
    t_end = run.imu[0, 0] + 20.0
    roles: dict[str, str | None] = {}
    rows: dict[str, list[tuple[Any, ...]]] = {"magnetometer": [], "pose_fix": []}
    for schema, channel, message in mcap_messages(str(mcap)):
        if channel.topic not in roles:
            roles[channel.topic] = decoder.add_topic(channel.topic, schema.name, schema.data.decode(), channel.message_encoding)
        clock.now = message.log_time * 1e-9
        if roles[channel.topic] is None or clock.now > t_end:
            continue
        records = decoder.decode(channel.topic, clock.now, message.data)
        for r in records:
            if r[0] in rows:
                rows[r[0]].append(r[1:])
        node.feed(channel.topic, records)
    node.close()
    assert (roles["/mag"], roles["/pose_fix"]) == ("magnetometer", "pose_fix")
    mag, fixes = np.array(rows["magnetometer"]), np.array(rows["pose_fix"])
    assert len(mag) > 1000 and len(fixes) > 30 and fixes.shape[1] == 9
    np.testing.assert_allclose(mag[:, 0], run.mag[: len(mag), 0], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(mag[:, 1:], run.mag[: len(mag), 1:])
    want = run.pose_fix[: len(fixes)]
    np.testing.assert_allclose(fixes[:, 0], want[:, 0], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(fixes[:, 1:7], want[:, 1:7])
    yaw_error = np.angle(np.exp(1j * (fixes[:, 7] - want[:, 7])))
    assert np.abs(yaw_error).max() < 1e-12 and np.array_equal(fixes[:, 8], want[:, 8])
    watches = {s["hardware_id"]: s for s in node.statuses()[1:]}
    for topic, n in [("/mag", len(mag)), ("/pose_fix", len(fixes))]:
        values = watches[topic]["values"]
        assert (values["records"], values["rejected"]) == (n, 0), (topic, values)
    assert not any(k.startswith("refused.") for k in node.statuses()[0]["values"])
    assert node.filter.initialized


# ---------------------------------------------------------------------------------------------
# End to end
# ---------------------------------------------------------------------------------------------

pytest.importorskip("cyclonedds", reason="the live extra (cyclonedds) is not installed")


def test_the_smoothed_pose_goes_out_on_its_own_topic_over_dds():
    # With live.lag_s the ROS sink publishes the smoothed pose on smoothed_pose_topic, as a
    # PoseWithCovarianceStamped with the pose's covariance; without, it publishes nothing there.
    from uwbimu_rs.live import DdsBus, Pose, RosSink, idl_type

    os.environ.setdefault("CYCLONEDDS_URI", _native_loopback())
    setup = _native.live_setup(None)
    setup["live"]["lag_s"] = 1.0
    smoothed = setup["outputs"][3]
    assert smoothed[0] == "/uwbimu/pose_smoothed"
    pose_type = idl_type(smoothed[1], smoothed[2])
    bus = DdsBus(23)
    got: list[Any] = []
    try:
        bus.subscribe(smoothed[3], pose_type, lambda data, _ts: got.append(pose_type.deserialize(data)))
        sink = RosSink(bus, setup)
        cov = np.diag(np.arange(1.0, 16.0)) * 1e-3
        pose = Pose(2.5, np.array([1.0, 2.0, 0.5]), np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3), cov)
        end = time.monotonic() + 10.0
        while not got and time.monotonic() < end:
            sink.smoothed_pose(pose)
            bus.spin_once(0.1)
        assert got, "no smoothed pose received"
        m = got[0]
        assert (m.header.stamp.sec, m.header.stamp.nanosec) == (2, 500_000_000)
        assert (m.pose.pose.position.x, m.pose.pose.position.y) == (1.0, 2.0)
        assert np.isclose(m.pose.covariance[0], 1e-3) and np.isclose(m.pose.covariance[7], 2e-3)
        setup["live"]["lag_s"] = None
        assert RosSink(bus, setup)._smoothed is None
    finally:
        bus.close()


def _native_loopback() -> str:
    from uwbimu_rs.live import loopback_config

    return loopback_config()


def _loopback_env(domain: int) -> dict[str, str]:
    from uwbimu_rs.live import loopback_config

    return {**os.environ, "CYCLONEDDS_URI": loopback_config(), "ROS_DOMAIN_ID": str(domain)}


def _isas_config(tmp_path: Path) -> Path:
    """The replay file of isas-walk1 with the anchors of its file and no model choice; the UWB
    topic's type is left for the node to learn from the graph."""
    base = (ROOT / "examples" / "isas-walk1.toml").read_text().replace('anchor_position = "ranges[].pos"\n', "")
    cfg = tmp_path / "isas-live.toml"
    cfg.write_text(
        base
        + "\n[config.model_selection]\nenabled = false\n"
        + f'\n[mapping.anchors]\nfile = "{ISAS / "anchors.csv"}"\n'
        + "\n[live]\nchoose_after_s = 0\nreliable_inputs = true\n"
    )
    return cfg


def _through_the_node(
    tmp_path: Path, mcap: Path, cfg: Path, domain: int, t_wait: float, topics: list[str] | None = None
) -> tuple[np.ndarray, np.ndarray, str]:
    """Play ``mcap`` over DDS (loopback, domain ``domain``) through a node run with ``cfg``
    until its pose of time ``t_wait`` came (or 5 s without a pose); returns the poses this
    process received and the steps of the node's MCAP output (t, x, y, z each), and the node's
    log, once SIGTERM stopped it."""
    from uwbimu_rs.live import DdsBus, idl_type

    env = _loopback_env(domain)
    out = tmp_path / "live.mcap"
    node = subprocess.Popen(
        [PY, "-m", "uwbimu_rs.live", "--config", str(cfg), "--out", str(out), "--domain-id", str(domain)],
        env=env, stderr=subprocess.PIPE, text=True,
    )
    os.environ["CYCLONEDDS_URI"] = env["CYCLONEDDS_URI"]
    pose_topic = _native.live_setup(cfg)["outputs"][0]
    pose_type = idl_type(pose_topic[1], pose_topic[2])
    bus = DdsBus(domain)
    got: list[tuple[float, float, float, float]] = []

    def on_pose(data: bytes, _ts: int) -> None:
        m = pose_type.deserialize(data)
        p = m.pose.pose.position
        got.append((m.header.stamp.sec + m.header.stamp.nanosec * 1e-9, p.x, p.y, p.z))

    bus.subscribe(pose_topic[3], pose_type, on_pose)
    play = [PY, "-m", "uwbimu_rs.live._player", str(mcap), "--rate", "4", "--domain-id", str(domain), "--wait-subscribers", "10"]
    player = subprocess.Popen(play + (["--topics", *topics] if topics else []), env=env, stderr=subprocess.PIPE, text=True)
    try:
        while player.poll() is None:
            bus.spin_once(0.1)
        # The player has ended once the node's reliable readers hold every message; the node may
        # still be working through them on a loaded machine: wait for its pose of the last time
        # (or 5 s without a pose, this subscriber being best effort).
        quiet_since = time.monotonic()
        while not (got and got[-1][0] >= t_wait - 1e-6) and time.monotonic() - quiet_since < 5.0:
            if bus.spin_once(0.1):
                quiet_since = time.monotonic()
        bus.spin_once(0.5)
    finally:
        node.send_signal(signal.SIGTERM)
        _, err = node.communicate(timeout=30)
        bus.close()
    assert player.returncode == 0, player.stderr.read()
    assert node.returncode == 0, err
    assert "stopped (SIGTERM)" in err
    # The MCAP output was closed on SIGTERM with its summary.
    from mcap.reader import make_reader

    with open(out, "rb") as f:
        poses = [json.loads(m.data) for _, _, m in make_reader(f).iter_messages(topics=["/uwbimu/pose"])]
    track = np.array(
        [(p["timestamp"]["sec"] + p["timestamp"]["nsec"] * 1e-9, *(p["pose"]["position"][k] for k in "xyz")) for p in poses]
    )
    return np.array(got), track, err


def _replay(mcap: Path, cfg: Path) -> tuple[np.ndarray, np.ndarray]:
    """The forward replay of ``mcap`` with ``cfg``: its step times and positions."""
    replay, _ = uwbimu_rs.replay(mcap, config_file=cfg, smooth=False)
    return replay["t"].to_numpy(), np.column_stack([replay["x"].to_numpy(), replay["y"].to_numpy(), replay["z"].to_numpy()])


def _live_and_replay(tmp_path: Path, mcap: Path, cfg: Path, domain: int, topics: list[str] | None = None) -> str:
    """Runs ``mcap`` through the node (:func:`_through_the_node`) and checks it against the
    forward replay of the same file and mapping: the node's MCAP output holds every step, each
    equal to the replay's — but the last sample's when no data came after it, as a stream gives
    a step only once data after it arrives (docs/streaming.md) — and each pose received over
    DDS equals the replay's step of the same time. Returns the node's log."""
    t, ref = _replay(mcap, cfg)
    # The node holds the last reorder window's steps until it stops (it flushes then).
    t_wait = float(t[-1]) - _native.live_setup(cfg)["reorder_window_s"] - 0.05
    live, track, err = _through_the_node(tmp_path, mcap, cfg, domain, t_wait, topics)
    assert len(track) in (len(t) - 1, len(t)), (len(track), len(t))
    np.testing.assert_allclose(track[:, 0], t[: len(track)], rtol=0, atol=1e-6)
    assert np.abs(track[:, 1:] - ref[: len(track)]).max() < 1e-9
    nearest = np.abs(t[None, :] - live[:, :1]).argmin(axis=1)
    matched = np.abs(t[nearest] - live[:, 0]) < 1e-6
    # The replay starts at the first IMU sample (the self-initialisation replays from there); the
    # node publishes from the moment it decided (isas-walk1: 30 s into the 59 s walk). This
    # subscriber is best effort and the node's writer keeps the last 100 poses: most steps from
    # the first pose on arrive (measured 91 % on isas-walk1, 98 % on the simulated recording on an
    # idle machine; 68 % with three busy loops beside it on two cores).
    assert matched.mean() > 0.99 and len(live) > 0.5 * np.sum(t >= live[0, 0])
    assert np.abs(live[matched, 1:] - ref[nearest[matched]]).max() < 1e-9
    return err


@needs_isas
def test_isas_walk1_over_dds_equals_the_replay(tmp_path):
    # The player sends the recording over DDS (loopback), the node learns the vendor's UWB type
    # from the player's type information and estimates live, this process subscribes to its
    # poses: each equals the forward replay's step of the same time.
    mcap = ISAS / "isas-walk1.mcap"
    cfg = _isas_config(tmp_path)
    err = _live_and_replay(tmp_path, mcap, cfg, 17, ["/waveshare_sense_hat_b", "/rtls_flares"])
    assert "/rtls_flares: learnt fraunhofer_rtls_flare/msg/RTLSStick from its publisher" in err


def test_a_simulated_recording_over_dds_equals_the_replay(tmp_path):
    # Our own recording (JSON ranges, sent as uwbimu_msgs/msg/UwbRange; its first samples
    # stamped 0) through the player and the node, with only the anchors configured: the node
    # takes the topics it can read from the graph, as a file read takes the channels.
    run = sim.zoo("handheld_walk", seed=6, stagger_s=0.02, jitter_s=0.005)
    mcap = tmp_path / "sim.mcap"
    sim.write_mcap(run, mcap)
    cfg = tmp_path / "sim.toml"
    anchors = "\n".join(f"A{k} = [{a[0]}, {a[1]}, {a[2]}]" for k, a in enumerate(run.anchors))
    cfg.write_text(
        '[config.model_selection]\nenabled = false\n'
        f"[mapping.anchors.positions]\n{anchors}\n[live]\nchoose_after_s = 0\nreliable_inputs = true\n"
    )
    err = _live_and_replay(tmp_path, mcap, cfg, 18)
    assert "late_dropped': 0" in err
    assert "no UWB topic named: taking every topic on the graph that the mapping reads" in err
    assert "subscribed to /uwb (uwbimu_msgs/msg/UwbRange) as uwb" in err
    assert "subscribed to /imu (sensor_msgs/msg/Imu) as imu" in err


def test_magnetometer_and_pose_fixes_over_dds_equal_the_replay(tmp_path):
    # The recording of _sensor_rig played over DDS (MagneticField on /mag,
    # PoseWithCovarianceStamped on /pose_fix) through a node running ackf: it subscribes both
    # with their types, feeds every message to the filter (none refused), and each pose it
    # publishes equals the forward replay's step of the same time, the replay reading the same
    # file through the same mapping.
    run, mcap, cfg = _sensor_rig(tmp_path)
    err = _live_and_replay(tmp_path, mcap, cfg, 19)
    assert "subscribed to /mag (sensor_msgs/msg/MagneticField) as magnetometer" in err
    assert "subscribed to /pose_fix (geometry_msgs/msg/PoseWithCovarianceStamped) as pose_fix" in err
    for topic, n in [("/mag", len(run.mag)), ("/pose_fix", len(run.pose_fix))]:
        # The node's last status of the topic (silent by then: the player has finished).
        counts = re.search(rf"\[{topic}\] [^:]+: \{{'messages': (\d+), 'records': (\d+), 'rejected': (\d+)", err)
        assert counts is not None and tuple(map(int, counts.groups())) == (n, n, 0), (topic, counts)
    assert "refused." not in err


def test_a_simulated_linktrack_through_a_pseudo_terminal(tmp_path):
    # A simulated run as the frames of a LinkTrack tag (IMU and ranges on one cable), written to
    # a pseudo-terminal with garbage between some frames; the node reads the other end. Its
    # steps equal the streaming filter fed the same frames decoded here, and follow the truth.
    run = sim.zoo("stop_and_go", seed=4)
    from uwbimu_rs.live import linktrack_frames, linktrack_records

    ids = [10 + k for k in range(len(run.anchors))]
    imu = run.imu[run.imu[:, 0] <= run.imu[0, 0] + 30.0]
    frames = linktrack_frames(imu, run.ranges, [str(i) for i in ids], tag_id=7)
    stream = b"".join(f + (b"\x55\x04\xff" if k % 97 == 5 else b"") for k, f in enumerate(frames))
    master, slave = os.openpty()
    tty.setraw(slave)
    cfg = tmp_path / "linktrack.toml"
    anchors = "\n".join(f'"{i}" = [{a[0]}, {a[1]}, {a[2]}]' for i, a in zip(ids, run.anchors))
    cfg.write_text(f"[mapping.anchors.positions]\n{anchors}\n[live]\nchoose_after_s = 0\n")
    out = tmp_path / "linktrack.mcap"
    node = subprocess.Popen(
        [PY, "-m", "uwbimu_rs.live", "--config", str(cfg), "--linktrack", os.ttyname(slave), "--no-ros", "--out", str(out)],
        stderr=subprocess.PIPE, text=True,
    )
    time.sleep(1.5)  # the node opens the port
    for k in range(0, len(stream), 4096):  # blocks while the node has not read what came before
        os.write(master, stream[k : k + 4096])
    time.sleep(2.0)
    node.send_signal(signal.SIGINT)
    _, err = node.communicate(timeout=30)
    os.close(master)
    os.close(slave)
    assert node.returncode == 0, err
    assert re.search(r"linktrack \[linktrack:/dev/pts/\d+\] .*'checksum_errors': 0, .*'bytes_skipped': [1-9]", err), err[-1500:]
    decoder = _native.LinkTrackDecoder()
    decoded = decoder.feed(stream)
    assert len(decoded) == len(frames) and decoder.counts["bytes_skipped"] > 0
    ref = uwbimu_rs.Best(run.anchors, reorder_window_s=0.5)
    index = {str(i): k for k, i in enumerate(ids)}
    for frame in decoded:
        for r in linktrack_records(frame, index):
            apply_record(ref, r)
    ref.flush()
    expected = ref.steps()
    from mcap.reader import make_reader

    with open(out, "rb") as f:
        poses = [json.loads(m.data) for _, _, m in make_reader(f).iter_messages(topics=["/uwbimu/pose"])]
    track = np.array([(p["timestamp"]["sec"] + p["timestamp"]["nsec"] * 1e-9, p["pose"]["position"]["x"], p["pose"]["position"]["y"]) for p in poses])
    assert len(track) == expected.height
    np.testing.assert_allclose(track[:, 0], expected["t"].to_numpy(), atol=1e-6)
    np.testing.assert_allclose(track[:, 1], expected["x"].to_numpy(), atol=1e-9)
    assert horizontal_rmse(np.column_stack([track, np.zeros(len(track))]), run, 5.0) < 0.2


def _ws_frames(sock: Any, n: int, timeout: float = 5.0) -> list[bytes]:
    """The payloads of the next ``n`` WebSocket frames from ``sock`` (server frames: unmasked)."""
    sock.settimeout(timeout)
    buf = b""
    out: list[bytes] = []

    def need(k: int) -> None:
        nonlocal buf
        while len(buf) < k:
            chunk = sock.recv(65536)
            if not chunk:
                raise ConnectionError("closed")
            buf += chunk

    while len(out) < n:
        need(2)
        length, head = buf[1] & 0x7F, 2
        if length == 126:
            need(4)
            length, head = int.from_bytes(buf[2:4], "big"), 4
        elif length == 127:
            need(10)
            length, head = int.from_bytes(buf[2:10], "big"), 10
        need(head + length)
        out.append(buf[head : head + length])
        buf = buf[head + length :]
    return out


def test_the_foxglove_view_serves_pose_path_and_nis():
    # A WebSocket client does Foxglove's handshake (subprotocol foxglove.sdk.v1) and sees the
    # server advertise the node's channels.
    import base64
    import socket

    from uwbimu_rs.live import FoxgloveSink, Pose, RangeUpdate

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    sink = FoxgloveSink(_native.live_setup(None), port=port)
    try:
        pose = Pose(1.0, np.zeros(3), np.zeros(3), np.array([1.0, 0, 0, 0]), np.zeros(3), np.eye(15))
        sink.pose(pose)
        sink.range_update(RangeUpdate(1.0, 2, 0.5, True, -80.0, -78.5))
        with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
            key = base64.b64encode(os.urandom(16)).decode()
            s.sendall(
                (
                    f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                    f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n"
                ).encode()
            )
            head = b""
            while b"\r\n\r\n" not in head:
                head += s.recv(1)
            assert head.startswith(b"HTTP/1.1 101") and b"foxglove.sdk.v1" in head
            messages = [json.loads(f) for f in _ws_frames(s, 2) if f[:1] == b"{"]
            assert messages[0]["op"] == "serverInfo"
            advertised = {c["topic"] for m in messages if m["op"] == "advertise" for c in m["channels"]}
            assert {"/uwbimu/pose", "/uwbimu/path", "/tf", "/uwbimu/nis"} <= advertised
    finally:
        sink.close()


def test_docs_list_every_live_key():
    # docs/live.md's table of [live] keys is checked against the keys the Rust struct declares.
    text = (ROOT / "docs" / "live.md").read_text()
    table = {line.split("|")[1].strip().strip("`") for line in text.splitlines() if line.startswith("| `")}
    assert set(_native.live_setup(None)["live"]) <= table


def biased_sensor_records(end_after_s: float) -> tuple[Any, list[tuple[Any, ...]]]:
    """A zoo run with TDoA, heights, wheel speeds and two tags whose ranges have steady biases
    per anchor (the model choice changes the model), and its records up to ``end_after_s`` after
    the start, in time order."""
    # Noisy TDoA: beside precise TDoA of the same anchors the biased ranges hardly move the
    # track, and the choice (on every sensor of the window) rightly keeps the configured model.
    run = sim.zoo("agv_loop", seed=0, tag_separation_m=0.6, tdoa=True, tdoa_std_m=1.0, altimeter=True, odometer=True)
    end = run.imu[0, 0] + end_after_s
    ranges = run.ranges.copy()
    ranges[:, 2] += np.array([0.4, -0.3, 0.5, 0.0, -0.4, 0.3, 0.0, 0.2])[ranges[:, 1].astype(int)]
    keyed = [((r[0], 0), ("imu", r[0], r[1:4], r[4:7])) for r in run.imu[run.imu[:, 0] <= end]]
    keyed += [((r[0], 1), ("range", r[0], int(r[1]), r[2], int(r[3]))) for r in ranges[ranges[:, 0] <= end]]
    keyed += [((r[0], 2), ("tdoa", r[0], int(r[1]), int(r[2]), r[3])) for r in run.tdoa[run.tdoa[:, 0] <= end]]
    keyed += [((r[0], 3), ("altitude", r[0], r[1])) for r in run.altitude[run.altitude[:, 0] <= end]]
    keyed += [((r[0], 4), ("odometry", r[0], r[1])) for r in run.odometry[run.odometry[:, 0] <= end]]
    return run, [r for _, r in sorted(keyed, key=lambda x: x[0])]


def test_a_model_change_refeeds_every_sensor_and_tag_of_the_window():
    # The node's filter after the model change equals a filter of the chosen model fed every
    # record from the start (the replay of the same input): TDoA, heights, wheel speeds and the
    # second tag of the choice window included, and what came while the choice ran.
    from uwbimu_rs.live import LiveNode

    run, records = biased_sensor_records(30.0)
    setup = _native.live_setup(None)
    setup["live"]["choose_after_s"] = 15.0
    setup["config"] = run.config
    clock, sink = Clock(), Collect()
    node = LiveNode(setup, run.anchors, sinks=[sink], clock=clock)
    switched_at = None
    for r in records:
        clock.now = r[1]
        node.feed("sim", [r])
        if r[0] == "imu" and r[1] >= run.imu[0, 0] + 20.0 and switched_at is None:
            assert node.wait_for_choice(120)  # the choice applied 5 s after it started
            node.tick()
            switched_at = r[1]
    node.close()
    assert node.chosen is not None and node.chosen.startswith("steady bias"), node.chosen
    made = node.filter.model_choice
    assert made["switched"] and made["chosen"] == node.chosen
    replay = uwbimu_rs.Best(run.anchors, initial=setup["initial"], config=made["config"], reorder_window_s=setup["reorder_window_s"])
    for r in records:
        apply_record(replay, r)
    replay.flush()
    expected = replay.steps()
    track = sink.track()
    after = track[track[:, 0] > switched_at]
    assert len(after) > 500
    t = expected["t"].to_numpy()
    want = expected.select("t", "x", "y", "z").to_numpy()[t > switched_at][: len(after)]
    np.testing.assert_array_equal(after[:, :4], want)


def test_a_model_change_drives_the_fixed_lag_smoother_over_the_replay_too():
    # With lag_s, the rows the smoother emits after the model change are those of a filter of the
    # chosen model fed every record from the start; none of the replayed past comes again.
    run, records = biased_sensor_records(30.0)
    f = uwbimu_rs.Best(run.anchors, config=run.config, lag_s=1.0, choose_after_s=15.0)
    before, after, switched = [], [], False
    for r in records:
        apply_record(f, r)
        (after if switched else before).append(f.lagged_steps())
        if r[0] == "imu" and r[1] >= run.imu[0, 0] + 20.0 and not switched:
            assert f.wait_for_choice(120) and f.model_choice is not None  # applied by the wait
            switched = True
    f.flush()
    after.append(f.lagged_steps())
    made = f.model_choice
    assert made["switched"] and made["chosen"].startswith("steady bias"), made["reason"]
    replay = uwbimu_rs.Best(run.anchors, config=made["config"], lag_s=1.0)
    for r in records:
        apply_record(replay, r)
    replay.flush()
    want = replay.lagged_steps()
    got, past = pl.concat(after), pl.concat(before)
    assert got.height > 500 and got["t"][0] > past["t"][-1]
    assert want.filter(pl.col("t") > past["t"][-1]).height == got.height  # nor a gap
    np.testing.assert_array_equal(got.to_numpy(), want.tail(got.height).to_numpy())
