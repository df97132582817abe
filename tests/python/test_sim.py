"""Tests of the Python simulator API: shapes, dtypes, reproducibility, errors."""

from typing import get_args

import numpy as np
import polars as pl
import pytest

import uwbimu_rs
from uwbimu_rs import sim

TRUTH_COLUMNS = ["t", "x", "y", "z", "vx", "vy", "vz", "qw", "qx", "qy", "qz"]


@pytest.mark.parametrize("name", sim.PRESET_NAMES)
def test_preset_shapes_and_dtypes(name):
    r = sim.preset(name, seed=1)
    n = r.imu.shape[0]
    assert r.imu.shape == (n, 7) and r.imu.dtype == np.float64
    assert r.ranges.ndim == 2 and r.ranges.shape[1] == 3 and r.ranges.dtype == np.float64
    assert r.range_labels.shape == (r.ranges.shape[0],) and r.range_labels.dtype == np.uint8
    k = 6 if name.startswith("lab_robot") else 4
    assert r.anchors.shape == (k, 3)
    assert isinstance(r.truth, pl.DataFrame)
    assert r.truth.columns == TRUTH_COLUMNS and r.truth.height == n
    assert r.accel_bias.shape == (n, 3) and r.gyro_bias.shape == (n, 3)
    assert r.nlos_windows.ndim == 2 and r.nlos_windows.shape[1] == 4
    assert np.all(np.diff(r.imu[:, 0]) > 0)
    assert np.all(r.ranges[:, 2] >= 0)
    assert set(np.unique(r.ranges[:, 1])) <= set(range(k))
    if name.startswith("square_diagonal"):
        assert r.mag is not None and r.mag.shape == (n, 4)
    else:
        assert r.mag is None


def test_still_start_senses_gravity():
    r = sim.preset("hall_vehicle", seed=0, imu_noise=False)
    still = r.imu[r.imu[:, 0] < 1.9]
    np.testing.assert_allclose(still[:, 1:4], np.tile([0.0, 0.0, 9.80665], (len(still), 1)), atol=1e-12)


def test_reproducible_by_seed():
    a = sim.preset("hall_vehicle_nlos", seed=7)
    b = sim.preset("hall_vehicle_nlos", seed=7)
    c = sim.preset("hall_vehicle_nlos", seed=8)
    np.testing.assert_array_equal(a.imu, b.imu)
    np.testing.assert_array_equal(a.ranges, b.ranges)
    np.testing.assert_array_equal(a.range_labels, b.range_labels)
    assert a.truth.equals(b.truth)
    assert not np.array_equal(a.imu, c.imu)
    assert a.truth.equals(c.truth)


def test_overrides_switch_nlos_off():
    r = sim.preset("hall_vehicle_nlos", seed=2, nlos=False, outlier_prob=0.0, dropout_prob=0.0, uwb_rate_hz=4.0)
    assert np.all(r.range_labels == 0)
    assert r.nlos_windows.shape == (0, 4)
    duration = r.imu[-1, 0]
    assert r.ranges.shape[0] == 4 * int(np.floor(duration * 4.0 + 1e-9))


def test_stagger_jitter_and_late_start_overrides():
    plain = sim.preset("hall_vehicle", seed=1)
    r = sim.preset("hall_vehicle", seed=1, stagger_s=0.004, jitter_s=0.001, start_s=10.0)
    # The log starts 10 s into the trajectory, already moving.
    assert r.imu[0, 0] >= 10.0 and plain.imu[0, 0] < 1.0
    first = r.truth.row(0, named=True)
    assert np.hypot(first["vx"], first["vy"]) > 0.1
    # Within a sweep anchor k comes k·4 ms (plus up to 1 ms) after anchor 0.
    t, a = r.ranges[:, 0], r.ranges[:, 1].astype(int)
    sweep = np.round((t - 10.0) * 2.0) / 2.0  # 2 Hz sweeps
    delay = t - sweep - 10.0
    for k in range(4):
        d = delay[a == k] - 0.004 * k
        assert d.min() >= -1e-9 and d.max() <= 0.001 + 1e-9, (k, d.min(), d.max())
    with pytest.raises(ValueError, match="stagger_s"):
        sim.preset("hall_vehicle", stagger_s=-0.001)


def test_name_literals_match_the_native_lists():
    # The type hints spell the names out; the native module is the source.
    assert get_args(sim.PresetName) == sim.PRESET_NAMES + sim.PRESET_ALIASES
    assert get_args(sim.ZooName) == sim.ZOO_NAMES


def test_unknown_preset_raises_value_error():
    with pytest.raises(ValueError, match="hall_vehicle"):
        sim.preset("seed003", seed=0)
    with pytest.raises(uwbimu_rs.ConfigError):
        sim.preset("nope")


def test_unknown_override_raises_value_error_listing_keys():
    with pytest.raises(ValueError, match="range_std_m"):
        sim.preset("hall_vehicle_nlos", seed=0, range_sigma=0.2)
    with pytest.raises(ValueError, match="outlier_prob"):
        sim.simulate(sim.Trajectory.diagonal([0, 0, 0], [1, 1, 0]), np.eye(3), bogus=1.0)


def test_invalid_value_raises_value_error():
    with pytest.raises(ValueError, match="uwb.rate_hz"):
        sim.preset("square_diagonal", uwb_rate_hz=-1.0)


def test_custom_trajectory_simulation():
    traj = sim.Trajectory.figure_eight([5.0, 4.0, 0.4], 3.5, 4.5, 37.0, 1)
    assert traj.duration_s == pytest.approx(39.0)
    k = traj.sample(10.0)
    assert k["position"].shape == (3,) and k["orientation"].shape == (4,)
    cols = traj.sample_many(np.array([0.0, 10.0]))
    assert list(cols) == TRUTH_COLUMNS
    anchors = np.array([[0.0, 0.0, 0.8], [10.0, 0.0, 2.2], [10.0, 8.0, 1.2]])
    r = sim.simulate(traj, anchors, seed=3, imu_noise=False, range_std_m=0.0, magnetometer=True, lever_arm_m=(0.0, 0.0, 0.0))
    assert r.anchors.shape == (3, 3) and r.mag.shape == (r.imu.shape[0], 4)
    # Noise-free ranges equal the distance from the truth position (zero lever arm).
    t = r.truth
    for t_s, anchor, rng in r.ranges[:5]:
        i = int(round(t_s * 100))
        p = np.array([t["x"][i], t["y"][i], t["z"][i]])
        assert rng == pytest.approx(np.linalg.norm(p - anchors[int(anchor)]), abs=1e-9)
    # Upside-down mounting flips the still specific force.
    r2 = sim.simulate(traj, anchors, imu_noise=False, imu_rotation=(0.0, 1.0, 0.0, 0.0))
    np.testing.assert_allclose(r2.imu[0, 1:4], [0.0, 0.0, -9.80665], atol=1e-12)
    with pytest.raises(ValueError):
        sim.simulate(traj, np.zeros((2, 2)))


@pytest.mark.parametrize("name, alias", list(zip(sim.PRESET_NAMES, sim.PRESET_ALIASES)))
def test_a_former_preset_name_simulates_the_same_run(name, alias):
    new, old = sim.preset(name, seed=2), sim.preset(alias, seed=2)
    np.testing.assert_array_equal(new.imu, old.imu)
    np.testing.assert_array_equal(new.ranges, old.ranges)
