"""Altitude and wheel odometry through the Python API: batch runs against the simulator's truth,
the updates frame, the streaming calls, the fleet call, and clear errors."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

import uwbimu_rs
from uwbimu_rs import sim


def _z_rmse(df: pl.DataFrame, r: sim.SimResult) -> float:
    t = df["t"].to_numpy()
    z = np.interp(t, r.truth["t"].to_numpy(), r.truth["z"].to_numpy())
    return float(np.sqrt(np.mean((df["z"].to_numpy() - z) ** 2)))


def _h_rmse(df: pl.DataFrame, r: sim.SimResult, window: tuple[float, float]) -> float:
    t = df["t"].to_numpy()
    keep = (t >= window[0]) & (t < window[1])
    x = np.interp(t, r.truth["t"].to_numpy(), r.truth["x"].to_numpy())
    y = np.interp(t, r.truth["t"].to_numpy(), r.truth["y"].to_numpy())
    return float(np.sqrt(np.mean(np.hypot(df["x"].to_numpy() - x, df["y"].to_numpy() - y)[keep] ** 2)))


def test_an_altitude_fixes_the_height_and_each_reading_is_reported():
    # Four anchors coplanar 2.6 m above the floor; a 25 Hz height, σ 0.05 m (truth as the oracle).
    r = sim.zoo("stop_and_go", seed=1, altimeter=True)
    assert r.altitude is not None and r.altitude.shape[1] == 2 and r.config["altitude"]["std"] == pytest.approx(0.05)
    without = uwbimu_rs.run_filter("riekf", r.imu, r.ranges, r.anchors, initial=r.initial, config=r.config)
    with_alt, upd = uwbimu_rs.run_filter(
        "riekf", r.imu, r.ranges, r.anchors, initial=r.initial, config=r.config, altitude=r.altitude, updates=True
    )
    assert _z_rmse(with_alt, r) < 0.025 and _z_rmse(with_alt, r) < 0.5 * _z_rmse(without, r)
    assert upd["sensor"].dtype == pl.Enum(["range", *uwbimu_rs.SENSORS])
    heights = upd.filter(pl.col("sensor") == "altitude")
    assert heights.height == r.altitude.shape[0]
    np.testing.assert_array_equal(heights["value"].to_numpy(), r.altitude[:, 1])
    assert (heights["anchor"] == -1).all() and (heights["axis"] == -1).all()


def test_odometry_carries_an_outage_in_batch_and_in_the_fleet_call():
    r = sim.zoo("agv_loop", seed=0, odometer=True)
    t0 = r.imu[0, 0]
    window = (t0 + 10.0, t0 + 30.0)  # a 20 s outage
    ranges = r.ranges[(r.ranges[:, 0] < window[0]) | (r.ranges[:, 0] >= window[1])]
    args = ("ekf", r.imu, ranges, r.anchors)
    without = uwbimu_rs.run_filter(*args, initial=r.initial, config=r.config)
    with_odo = uwbimu_rs.run_filter(*args, initial=r.initial, config=r.config, odometry=r.odometry)
    e_without, e_with = _h_rmse(without, r, window), _h_rmse(with_odo, r, window)
    # Measured: 0.19 m with odometry, 0.88 m without after 15 s of outage.
    assert e_with < 0.5 and e_with < 0.4 * e_without, (e_with, e_without)
    fleet = uwbimu_rs.run_filters(
        "ekf", [(r.imu, ranges, r.anchors), (r.imu, ranges, r.anchors, {"odometry": r.odometry})], initial=[r.initial] * 2, config=r.config
    )
    np.testing.assert_array_equal(fleet[0]["x"].to_numpy(), without["x"].to_numpy())
    np.testing.assert_array_equal(fleet[1]["x"].to_numpy(), with_odo["x"].to_numpy())


def test_a_velocity_row_reads_each_axis_it_measures():
    r = sim.zoo("agv_loop", seed=2, odometer=True, odometer_lateral=True)
    assert r.odometry.shape[1] == 4
    rows = r.odometry.copy()
    rows[::2, 3] = np.nan  # vz not measured on every other row
    _, upd = uwbimu_rs.run_filter(
        "ekf", r.imu, r.ranges, r.anchors, initial=r.initial, config=r.config, odometry=rows, updates=True
    )
    odo = upd.filter(pl.col("sensor") == "odometry")
    assert odo.height == int(np.isfinite(rows[:, 1:]).sum())
    assert odo["axis"].value_counts().sort("axis")["count"].to_list() == [len(rows), len(rows), len(rows) // 2]


def test_the_streaming_calls_take_heights_and_velocities():
    r = sim.zoo("agv_loop", seed=0, altimeter=True, odometer=True)
    f = uwbimu_rs.Riekf(r.anchors, initial=r.initial, config=r.config, reorder_window_s=0.0)
    t = r.imu[5, 0]
    for row in r.imu[:6]:
        f.add_imu(row[0], row[1:4], row[4:7])
    (height,) = f.add_altitude(t, 0.31)
    assert (height.sensor, height.anchor, height.axis, height.value) == ("altitude", None, None, 0.31)
    reports = f.add_odometry(t, [0.5, np.nan, 0.0])
    assert [(x.sensor, x.axis) for x in reports] == [("odometry", 0), ("odometry", 2)]
    assert [x.axis for x in f.add_odometry(t + 0.001, 0.5)] == [0]
    assert "sensor='odometry'" in repr(reports[0]) and "axis=0" in repr(reports[0])
    with pytest.raises(ValueError, match="no axis"):
        f.add_odometry(t + 0.002, [np.nan, np.nan, np.nan])
    with pytest.raises(ValueError, match="z"):
        f.add_altitude(t + 0.003, float("nan"))
    assert f.add_altitude(t + 0.004, 900.0) == [] and f.health["rejected"]["altitude_beyond_hall"] == 1
    assert f.add_odometry(t + 0.005, 80.0) == [] and f.health["rejected"]["speed_beyond_range"] == 1
    eskf = uwbimu_rs.Eskf(r.anchors, initial=r.initial)
    with pytest.raises(ValueError, match="altitude"):
        eskf.add_altitude(t, 0.3)


def test_wrong_odometry_and_altitude_tables_say_what_they_should_be():
    r = sim.zoo("agv_loop", seed=0)
    args = ("ekf", r.imu, r.ranges, r.anchors)
    with pytest.raises(ValueError, match=r"\(M, 2\) = t, speed or \(M, 4\) = t, vx, vy, vz"):
        uwbimu_rs.run_filter(*args, initial=r.initial, odometry=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="altitude given, but eskf does not take altitude"):
        uwbimu_rs.run_filter("eskf", r.imu, r.ranges, r.anchors, altitude=np.array([[1.0, 0.3]]))
    with pytest.raises(ValueError, match="altitude"):
        uwbimu_rs.run_filter(*args, initial=r.initial, altitude=np.array([[1.0, np.inf]]))


def test_pose_fixes_stream_through_add_sensor_as_the_batch_takes_them():
    # shelf_aisles: 1 Hz fixes of σ 3 cm with yaw; the streamed filter fed every record in time
    # order gives the batch run's track (the batch run as the oracle).
    r = sim.zoo("shelf_aisles", seed=0)
    assert r.pose_fix is not None and r.pose_fix.shape[1] == 9 and "pose_fix" in uwbimu_rs.METHODS["ekf"]["takes"]
    cut = r.imu[:, 0] <= 20.0
    imu, ranges, fixes = r.imu[cut], r.ranges[r.ranges[:, 0] <= 20.0], r.pose_fix[r.pose_fix[:, 0] <= 20.0]
    batch = uwbimu_rs.run_filter("ekf", imu, ranges, r.anchors, initial=r.initial, config=r.config, pose_fix=fixes)
    f = uwbimu_rs.Ekf(r.anchors, initial=r.initial, config=r.config, reorder_window_s=0.0)
    events = [(s[0], 0, s) for s in imu] + [(x[0], 1, x) for x in ranges] + [(p[0], 2, p) for p in fixes]
    fix_reports = []
    for t, kind, row in sorted(events, key=lambda e: (e[0], e[1])):
        if kind == 0:
            f.add_imu(t, row[1:4], row[4:7])
        elif kind == 1:
            f.add_range(t, row[1], row[2])
        else:
            fix_reports += f.add_sensor("pose_fix", row)
    f.flush()
    assert len(fix_reports) == len(fixes) and {x.sensor for x in fix_reports} == {"pose_fix"}
    both = f.steps().join(batch, on="t", suffix="_batch")
    assert both.height >= batch.height - 1
    np.testing.assert_allclose(both.select("x", "y", "z").to_numpy(), both.select("x_batch", "y_batch", "z_batch").to_numpy(), atol=1e-9)


def test_add_sensor_refuses_an_unknown_sensor_a_wrong_row_and_a_method_that_does_not_take_it():
    r = sim.zoo("agv_loop", seed=0)
    f = uwbimu_rs.Ekf(r.anchors, initial=r.initial, reorder_window_s=0.0)
    with pytest.raises(ValueError, match="unknown sensor `pose_fixes`"):
        f.add_sensor("pose_fixes", [0.0, 1.0, 2.0, 0.3, 0.1, 0.1, 0.1])
    with pytest.raises(ValueError, match=r"pose_fix.*\(7\) = t, x, y, z, sx, sy, sz"):
        f.add_sensor("pose_fix", [0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match="σ must be > 0"):
        f.add_sensor("pose_fix", [0.0, 1.0, 2.0, 0.3, 0.1, 0.0, 0.1])
    assert f.add_sensor("pose_fix", [0.0, 500.0, 2.0, 0.3, 0.1, 0.1, 0.1]) == []
    assert f.health["rejected"]["pose_fix_beyond_hall"] == 1
    with pytest.raises(ValueError, match="pose_fix"):
        uwbimu_rs.Eskf(r.anchors, initial=r.initial).add_sensor("pose_fix", [0.0, 1.0, 2.0, 0.3, 0.1, 0.1, 0.1])
