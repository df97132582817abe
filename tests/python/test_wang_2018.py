"""Wang et al. 2018 from Python: planar filters and the 15-state UKF through run_filter, SDS-TWR and the
range calibration of uwbimu_rs.ranging, and their input errors."""

from __future__ import annotations

import numpy as np
import pytest

import uwbimu_rs
from uwbimu_rs import metrics, ranging, sim

C = ranging.SPEED_OF_LIGHT_MPS


@pytest.fixture(scope="module")
def lab():
    """The lab of Wang et al. 2018, line of sight (6 anchors, UWB 40 Hz σ 0.0514 m)."""
    return sim.preset("lab_robot", seed=2)


@pytest.fixture(scope="module")
def config(lab):
    """The lab's sensors: range σ 0.0514 m, consumer MEMS IMU, tag 5 cm above the IMU."""
    return dict(lab.config)


@pytest.mark.parametrize("method", ["ekf2d", "ukf2d", "cekf2d", "ukf"])
def test_wang_2018_methods_through_run_filter(lab, config, method):
    df = uwbimu_rs.run_filter(method, lab.imu, lab.ranges, lab.anchors, config={**config, "constraints.plane_height": 0.2})
    assert df.columns[:15] == ["t", "x", "y", "z", "vx", "vy", "vz", "qw", "qx", "qy", "qz", "std_x", "std_y", "std_z", "still"]
    assert df.height == lab.imu.shape[0]
    h = metrics.evaluate(df, lab.truth).horizontal
    ls = uwbimu_rs.run_filter("uwb_ls", lab.imu, lab.ranges, lab.anchors, config=config)
    ls_mean = metrics.evaluate(ls, lab.truth).horizontal.mean
    # Against UWB-only on the same run (measured 0.043 m): planar ≈ 0.45×, the 15-state ukf ≈ 0.26×.
    assert h.mean < (0.55 if method != "ukf" else 0.32) * ls_mean, (h, ls_mean)
    if method != "ukf":
        assert np.all(df["z"].to_numpy() == 0.2) and np.all(df["std_z"].to_numpy() == 0.0)
        assert np.all(df["vz"].to_numpy() == 0.0)


def test_planar_settings_are_validated(lab):
    for bad in ({"unscented.lambda": -4.0}, {"planar.cekf_window": 0}, {"planar.cekf_window": 2.5}, {"planar.accel_density": -1.0}):
        with pytest.raises(uwbimu_rs.ConfigError):
            uwbimu_rs.run_filter("ukf2d", lab.imu, lab.ranges, lab.anchors, config=bad)
    with pytest.raises(uwbimu_rs.ConfigError, match="smoothing"):
        uwbimu_rs.run_filter("ekf2d", lab.imu, lab.ranges, lab.anchors, smooth=True)


def test_sds_twr_vectorised_under_clock_drift():
    rng = np.random.default_rng(3)
    d = rng.uniform(0.5, 30.0, 500)
    tof = d / C
    ea, eb = rng.choice([-20e-6, 20e-6], (2, 500))
    reply_a, reply_b = rng.uniform(200e-6, 600e-6, (2, 500))
    round1, reply1 = (2 * tof + reply_b) * (1 + ea), reply_b * (1 + eb)
    round2, reply2 = (2 * tof + reply_a) * (1 + eb), reply_a * (1 + ea)
    sds = ranging.sds_twr(round1, reply1, round2, reply2)
    ss = ranging.ss_twr(round1, reply1)
    assert sds.shape == d.shape and sds.dtype == np.float64
    assert np.max(np.abs(sds - d)) < 0.01
    drifting = ea != eb
    assert np.min(np.abs(ss - d)[drifting]) > 0.5  # ≥ 40 ppm × 200 µs / 2 · c ≈ 1.2 m
    # 2-D input keeps its shape; antenna delay is removed.
    delay = 515e-9
    out = ranging.sds_twr(
        (round1 + 2 * delay * (1 + ea)).reshape(20, 25),
        reply1.reshape(20, 25),
        (round2 + 2 * delay * (1 + eb)).reshape(20, 25),
        reply2.reshape(20, 25),
        antenna_delay_s=delay,
    )
    assert out.shape == (20, 25) and np.max(np.abs(out.ravel() - d)) < 0.01


def test_dw1000_wraparound():
    start = np.array([2**40 - 10, 5, 0], dtype=np.uint64)
    end = np.array([20, 105, 2**40 - 1], dtype=np.uint64)
    dt = ranging.dw1000_elapsed(start, end)
    np.testing.assert_allclose(dt / ranging.DW1000_TICK_S, [30, 100, 2**40 - 1])
    with pytest.raises(ValueError, match="40 bits"):
        ranging.dw1000_elapsed([0], [2**40])
    with pytest.raises(ValueError, match="whole number"):
        ranging.dw1000_elapsed([0.5], [1])


def test_calibration_fit_apply_and_preprocessing(lab, config):
    c_true = [0.08, 0.95, 0.012, -0.002]
    m = np.linspace(0.3, 5.0, 30)
    t = np.polyval(c_true[::-1], m)
    c = ranging.fit_calibration(m, t)
    np.testing.assert_allclose(c, c_true, atol=1e-9)
    assert np.max(np.abs(ranging.apply_calibration(c, m) - t)) < 1e-3
    per_anchor = ranging.fit_range_calibration(np.repeat([0, 4], 30), np.tile(m, 2), np.tile(t, 2))
    assert sorted(per_anchor) == [0, 4] and np.allclose(per_anchor[4], c_true)

    # Identity calibration leaves run_filter's output unchanged; a real one changes it.
    base = uwbimu_rs.run_filter("ekf2d", lab.imu, lab.ranges, lab.anchors, config=config)
    same = uwbimu_rs.run_filter(
        "ekf2d", lab.imu, lab.ranges, lab.anchors, config={**config, "range_calibration": {0: [0, 1, 0, 0]}}
    )
    assert base.equals(same)
    cal = {1: c_true, 3: c_true}
    cfg = {**config, "range_calibration": cal}
    moved = uwbimu_rs.run_filter("ekf2d", lab.imu, lab.ranges, lab.anchors, config=cfg)
    pre = ranging.calibrate_ranges(lab.ranges, cal, len(lab.anchors))
    by_hand = uwbimu_rs.run_filter("ekf2d", lab.imu, pre, lab.anchors, config=config)
    assert not base.equals(moved) and moved.equals(by_hand)
    assert uwbimu_rs.FilterConfig(**cfg).to_dict()["range_calibration"] == {1: c_true, 3: c_true}


@pytest.mark.parametrize(
    ("calibration", "pattern"),
    [
        ({9: [0, 1, 0, 0]}, r"range_calibration\[9\]`: there is no anchor 9"),
        ({0: [0, 1, 0]}, "4 coefficients"),
        ({0: [float("nan"), 1, 0, 0]}, "coefficients must be finite"),
        ({"a": [0, 1, 0, 0]}, "not an anchor index"),
        ([0, 1, 0, 0], "expected a dict"),
        ({0: [-50.0, 1, 0, 0]}, "negative"),
    ],
)
def test_bad_calibration_is_a_clear_error(lab, calibration, pattern):
    with pytest.raises(ValueError, match=pattern):
        uwbimu_rs.run_filter("ekf2d", lab.imu, lab.ranges, lab.anchors, config={"range_calibration": calibration})


def test_ranging_input_errors():
    with pytest.raises(ValueError, match="t_reply1"):
        ranging.sds_twr([1e-3, 1e-3], [1e-3], [1e-3], [1e-3])
    with pytest.raises(ValueError, match="t_round2"):
        ranging.sds_twr([1e-3], [9e-4], [np.nan], [9e-4])
    with pytest.raises(ValueError, match="negative time of flight"):
        ranging.sds_twr([1e-6], [2e-6], [1e-6], [2e-6])
    with pytest.raises(ValueError, match="at least 4 distinct"):
        ranging.fit_calibration([1.0, 2.0, 3.0], [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="non-finite"):
        ranging.fit_calibration([1.0, np.inf, 2.0, 3.0, 4.0], [1.0] * 5)
