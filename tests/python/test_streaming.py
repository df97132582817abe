"""The streaming classes, every one of them, driven sample by sample in the documented way (IMU
samples through ``predict``, ranges through ``add_range``, magnetometer samples through
``update_magnetometer``, in time order, then ``flush``) reproduce ``run_filter`` bit for bit; the
smoothers of the streaming classes reproduce ``run_filter(..., smooth=True)``."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

import uwbimu_rs
from uwbimu_rs import sim

CLASSES = {
    "ekf": uwbimu_rs.Ekf,
    "iekf": uwbimu_rs.Iekf,
    "rekf": uwbimu_rs.Rekf,
    "riekf": uwbimu_rs.Riekf,
    "criekf": uwbimu_rs.Criekf,
    "ckf": uwbimu_rs.Ckf,
    "arckf": uwbimu_rs.Arckf,
    "ackf": uwbimu_rs.Ackf,
    "eskf": uwbimu_rs.Eskf,
    "shaf": uwbimu_rs.Shaf,
    "shfaf": uwbimu_rs.Shfaf,
    "ukf": uwbimu_rs.Ukf,
    "best": uwbimu_rs.Best,
}
STATE = ["t", "x", "y", "z", "vx", "vy", "vz", "qw", "qx", "qy", "qz"]


@pytest.fixture(scope="module")
def staggered():
    """20 s of a zoo run with staggered, jittered ranges from five anchors at mixed rates, an IMU
    at 200 Hz and (for ackf) a magnetometer at 30 Hz whose times fall between IMU samples."""
    run = sim.zoo("mixed_rates", seed=3)
    imu = run.imu[run.imu[:, 0] <= run.imu[0, 0] + 20.0]
    ranges = run.ranges[run.ranges[:, 0] <= imu[-1, 0]]
    t = np.arange(imu[0, 0] + 0.013, imu[-1, 0], 1.0 / 30.0)
    mag = np.column_stack([t, np.tile([20.0, 0.5, -40.0], (t.size, 1)) + 0.3 * np.sin(t)[:, None]])
    return run, imu, ranges, mag


def stream(f, imu, ranges, mag=None):
    """Feeds a streaming filter in the batch event order; returns its per-IMU-sample states and
    the reports it produced, in order."""
    mag = np.zeros((0, 4)) if mag is None else mag
    rows, reports, j, k = [], [], 0, 0

    def feed(t, inclusive):
        nonlocal j, k
        due = (lambda x: x <= t) if inclusive else (lambda x: x < t)
        while True:
            r_next = ranges[j, 0] if j < len(ranges) and due(ranges[j, 0]) else None
            m_next = mag[k, 0] if k < len(mag) and due(mag[k, 0]) else None
            if m_next is not None and (r_next is None or m_next <= r_next):
                f.update_magnetometer(mag[k, 0], mag[k, 1:4])
                k += 1
            elif r_next is not None:
                reports.extend(f.add_range(ranges[j, 0], int(ranges[j, 1]), ranges[j, 2]))
                j += 1
            else:
                return

    for sample in imu:
        t = sample[0]
        feed(t, inclusive=False)
        reports.extend(f.predict(t, sample[1:4], sample[4:7]))
        feed(t, inclusive=True)
        s = f.state
        rows.append(np.concatenate([[t], s["position"], s["velocity"], s["orientation"]]))
    reports.extend(f.flush())
    return np.array(rows), reports


@pytest.mark.parametrize("method", list(CLASSES))
def test_streaming_equals_batch_for_every_class(staggered, method):
    run, imu, ranges, mag = staggered
    use_mag = mag if method == "ackf" else None
    f = CLASSES[method](run.anchors, initial=run.initial, config=run.config)
    rows, reports = stream(f, imu, ranges, use_mag)
    # smooth=False: `best` smooths by default; the streaming filter is its forward pass.
    df, upd = uwbimu_rs.run_filter(
        method, imu, ranges, run.anchors, initial=run.initial, config=run.config, updates=True, mag=use_mag, smooth=False
    )
    np.testing.assert_array_equal(rows, df.select(STATE).to_numpy())
    assert len(reports) == upd.height == ranges.shape[0]
    for column in ("t", "epoch_t", "anchor", "range", "innovation", "nis", "weight"):
        np.testing.assert_array_equal([getattr(r, column) for r in reports], upd[column].to_numpy())
    # The epochs of staggered ranges are applied together, at the time of their last range or
    # later (never before a range was taken).
    assert (upd["epoch_t"] >= upd["t"]).all() and (upd["epoch_t"] - upd["t"]).max() <= run.config["ranging"]["epoch_window_s"] + 0.01
    assert f.pending == 0
    # The final flush applied the last epoch after the last recorded row: the position is no less
    # certain than there.
    assert (np.sqrt(np.diag(f.covariance)[:3]) <= np.array(df.select("std_x", "std_y", "std_z").row(-1)) * (1 + 1e-9)).all()


@pytest.mark.parametrize("method", [m for m in CLASSES if m != "ackf"])
def test_streaming_smoother_equals_batch(staggered, method):
    run, imu, ranges, _ = staggered
    f = CLASSES[method](run.anchors, initial=run.initial, config=run.config, record=True)
    stream(f, imu, ranges)
    nodes = pl.DataFrame(f.smooth())
    batch = uwbimu_rs.run_filter(method, imu, ranges, run.anchors, initial=run.initial, config=run.config, smooth=True)
    # Every IMU time is a node of the streaming smoother; there the two agree.
    joined = batch.join(nodes, on="t", suffix="_s")
    assert joined.height == batch.height
    for c in ("x", "y", "z", "vx", "std_x"):
        np.testing.assert_allclose(joined[c], joined[f"{c}_s"], atol=1e-9)


def test_ackf_smoother_with_magnetometer_equals_batch(staggered):
    run, imu, ranges, mag = staggered
    f = uwbimu_rs.Ackf(run.anchors, initial=run.initial, config=run.config, record=True)
    stream(f, imu, ranges, mag)
    nodes = pl.DataFrame(f.smooth())
    batch = uwbimu_rs.run_filter("ackf", imu, ranges, run.anchors, initial=run.initial, config=run.config, smooth=True, mag=mag)
    joined = batch.join(nodes, on="t", suffix="_s")
    assert joined.height == batch.height
    np.testing.assert_allclose(joined["x"], joined["x_s"], atol=1e-9)


def test_add_range_groups_a_staggered_sweep_into_one_epoch():
    anchors = np.array([[0.0, 0.0, 2.0], [8.0, 0.0, 1.0], [8.0, 6.0, 2.0], [0.0, 6.0, 1.0]])
    f = uwbimu_rs.Ekf(anchors, initial={"position": [4.0, 3.0, 0.5], "velocity": [0, 0, 0], "orientation": [1, 0, 0, 0]})
    assert f.add_range(0.0, 0, 5.0) == []  # before the first IMU sample: skipped, as in batch
    f.predict(0.0, [0.0, 0.0, 9.80665], [0.0, 0.0, 0.0])
    p = np.array([4.0, 3.0, 0.5])
    out = [f.add_range(0.001 + 0.004 * i, i, float(np.linalg.norm(p - a))) for i, a in enumerate(anchors[:3])]
    assert out == [[], [], []] and f.pending == 3
    # An IMU sample inside the window keeps the epoch open; one past it applies it.
    assert f.predict(0.01, [0.0, 0.0, 9.80665], [0.0, 0.0, 0.0]) == []
    applied = f.predict(0.06, [0.0, 0.0, 9.80665], [0.0, 0.0, 0.0])
    assert [r.anchor for r in applied] == [0, 1, 2] and f.pending == 0
    assert all(r.epoch_t == pytest.approx(0.01) for r in applied)  # the filter time when applied
    # A full epoch (every anchor) is applied at once, at its last range's time.
    out = [f.add_range(0.07 + 0.002 * i, i, float(np.linalg.norm(p - a))) for i, a in enumerate(anchors)]
    assert out[:3] == [[], [], []] and [r.anchor for r in out[3]] == [0, 1, 2, 3]
    assert out[3][0].epoch_t == pytest.approx(0.076)
    with pytest.raises(ValueError, match="not after the previous time"):
        f.add_range(0.05, 0, 5.0)
    with pytest.raises(ValueError, match="anchor index 7"):
        f.add_range(0.2, 7, 5.0)
    with pytest.raises(ValueError, match="range must be finite"):
        f.add_range(0.2, 0, float("nan"))


@pytest.mark.parametrize("method", ["ekf", "ukf"])
def test_streaming_reports_the_reacquisition_after_an_outage(method):
    # The zoo's 10 s outage (40–50 s): the first epoch after it is applied as its UWB-only fix,
    # in streaming as in batch, and the reports say so.
    run = sim.zoo("outage", seed=1)
    imu = run.imu[run.imu[:, 0] <= 55.0]
    ranges = run.ranges[run.ranges[:, 0] <= imu[-1, 0]]
    f = CLASSES[method](run.anchors, initial=run.initial, config=run.config)
    _, reports = stream(f, imu, ranges)
    _, upd = uwbimu_rs.run_filter(method, imu, ranges, run.anchors, initial=run.initial, config=run.config, updates=True)
    np.testing.assert_array_equal([r.reacquired for r in reports], upd["reacquired"].to_numpy().astype(bool))
    reacquired = [r for r in reports if r.reacquired]
    assert reacquired, "no re-acquisition after the outage"
    assert 50.0 <= min(r.t for r in reacquired) < 50.5
    assert all(r.t > 50.0 for r in reacquired)
