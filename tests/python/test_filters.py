"""Batch and streaming filter API: shapes, accuracy, streaming == batch, bad input."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from figures import hold

import uwbimu_rs
from uwbimu_rs import metrics

COLUMNS = ["t", "x", "y", "z", "vx", "vy", "vz", "qw", "qx", "qy", "qz", "std_x", "std_y", "std_z", "still", "status"]


def test_ekf_batch_frame_and_accuracy(los_run, filter_config):
    df = uwbimu_rs.run_filter("ekf", los_run.imu, los_run.ranges, los_run.anchors, config=filter_config)
    assert isinstance(df, pl.DataFrame)
    assert df.columns == COLUMNS
    assert df.height == los_run.imu.shape[0]
    assert (df["t"].to_numpy() == los_run.imu[:, 0]).all()
    q = df.select("qw", "qx", "qy", "qz").to_numpy()
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0)
    ev = metrics.evaluate(df, los_run.truth)
    ls = uwbimu_rs.run_filter("uwb_ls", los_run.imu, los_run.ranges, los_run.anchors, config=filter_config)
    ev_ls = metrics.evaluate(ls, los_run.truth)
    assert ev.horizontal.rmse < 0.10
    assert ev.horizontal.rmse < ev_ls.horizontal.rmse


def test_uwb_ls_one_row_per_epoch(los_run):
    df = uwbimu_rs.run_filter("uwb_ls", los_run.imu, los_run.ranges, los_run.anchors)
    epochs = np.unique(los_run.ranges[:, 0])
    assert df.height == epochs.size
    assert {"t", "x", "y", "z", "std_x", "n_ranges", "residual_rms"} <= set(df.columns)


def test_covariance_and_update_reports(los_run, filter_config):
    df, upd = uwbimu_rs.run_filter(
        "ekf", los_run.imu, los_run.ranges, los_run.anchors, config=filter_config, covariance=True, updates=True
    )
    assert {"cov_xx", "cov_xy", "cov_zz"} <= set(df.columns)
    assert np.allclose(df["cov_xx"].to_numpy(), df["std_x"].to_numpy() ** 2)
    assert upd.height == los_run.ranges.shape[0]
    assert upd["accepted"].all()
    # With matched noise the mean NIS of a consistent filter is near 1 (1 dof per range).
    assert 0.5 < upd["nis"].mean() < 2.0
    # A consistent filter: the mean NEES of the 3-D position is near its 3 degrees of freedom
    # (measured 2.4 with the matched configuration).
    nees = metrics.nees(df, los_run.truth)
    assert nees.height == df.height
    assert 1.5 < nees["nees"].mean() < 4.5, nees["nees"].mean()


def test_streaming_state_and_report_types(los_run):
    ekf = uwbimu_rs.Ekf(
        los_run.anchors,
        initial={"position": [5.0, 4.0, 0.4], "velocity": [0, 0, 0], "orientation": [1, 0, 0, 0]},
        reorder_window_s=0.0,
    )
    assert ekf.time is None
    assert ekf.add_range(0.0, 0, 3.0) == [] and ekf.health["ranges_before_start"] == 1
    ekf.add_imu(0.0, [0.0, 0.0, 9.80665], [0.0, 0.0, 0.0])
    p0 = ekf.covariance
    (rep,) = ekf.apply_ranges_now(0.005, [1], [6.0])
    assert isinstance(rep, uwbimu_rs.UpdateReport)
    # γ = ε² / (h·P·hᵀ + R) at the prior (Li & Wang 2020 eq. (37)): the tag at [5, 4, 0.4] (no lever arm
    # by default) is 5.036 m from anchor 1; P barely moves in 5 ms at rest.
    d = np.array([5.0, 4.0, 0.4]) - los_run.anchors[1]
    u = d / np.linalg.norm(d)
    assert rep.innovation == pytest.approx(6.0 - np.linalg.norm(d), abs=1e-6)
    expected_nis = rep.innovation**2 / (u @ p0[:3, :3] @ u + 0.15**2)
    assert rep.accepted and rep.weight == 1.0 and rep.nis == pytest.approx(expected_nis, rel=1e-3)
    assert (rep.t, rep.sensor, rep.anchor, rep.value, rep.epoch_t) == (0.005, "range", 1, 6.0, pytest.approx(0.005))
    assert ekf.time == pytest.approx(0.005)
    # Without a window a late sample is dropped and counted.
    assert ekf.add_imu(0.001, [0.0, 0.0, 9.8], [0.0, 0.0, 0.0]) == [] and ekf.health["late_dropped"] == 1
    with pytest.raises(ValueError, match="add_range: anchor=9"):
        ekf.add_range(0.01, 9, 3.0)
    with pytest.raises(ValueError, match="add_imu: accel=.* must be finite"):
        ekf.add_imu(0.02, [0.0, np.nan, 9.8], [0.0, 0.0, 0.0])


# ---------------------------------------------------------------------------- bad input


@pytest.fixture()
def small():
    t = np.arange(0.0, 1.0, 0.01)
    imu = np.zeros((t.size, 7))
    imu[:, 0] = t
    imu[:, 3] = 9.80665
    anchors = np.array([[0.0, 0.0, 2.0], [8.0, 0.0, 1.0], [8.0, 6.0, 2.0], [0.0, 6.0, 1.0]])
    ranges = np.array([[0.5, 0, 5.0], [0.5, 1, 5.0], [0.5, 2, 5.0], [0.5, 3, 5.0]])
    initial = {"position": [4.0, 3.0, 0.3], "velocity": [0, 0, 0], "orientation": [1, 0, 0, 0]}
    return imu, ranges, anchors, initial


@pytest.mark.parametrize(
    ("mutate", "pattern"),
    [
        (lambda i, r, a: (i[:, :6], r, a), r"imu: expected shape \(N, 7\)"),
        (lambda i, r, a: (i, r[:, :2], a), r"ranges: expected shape \(M, 3\)"),
        (lambda i, r, a: (i, r, a[:, :2]), r"anchors: expected shape \(K, 3\)"),
        (lambda i, r, a: (i[:, 0], r, a), r"imu: expected shape"),
        (lambda i, r, a: (_set(i, (5, 2), np.nan), r, a), r"imu: non-finite value NaN at row 5, column 2"),
        (lambda i, r, a: (_set(i, (3, 4), np.inf), r, a), r"imu: non-finite value inf at row 3, column 4"),
        (lambda i, r, a: (i, _set(r, (2, 2), np.nan), a), r"ranges: non-finite value NaN at row 2"),
        (lambda i, r, a: (_set(i, (10, 0), 0.05), r, a), r"imu: time 0.05 s at row 10 is not after"),
        (lambda i, r, a: (i, _set(r, (3, 0), 0.1), a), r"ranges: time 0.1 s at row 3"),
        (lambda i, r, a: (i, _set(r, (1, 1), 4.0), a), r"anchor index 4 at row 1 is out of range \(there are 4 anchors: 0..3\)"),
        (lambda i, r, a: (i, _set(r, (1, 1), -1.0), a), r"anchor index -1 at row 1"),
        (lambda i, r, a: ([["a"] * 7], r, a), r"imu: cannot convert to a float64 array"),
    ],
)
def test_bad_arrays_raise_value_error(small, mutate, pattern):
    imu, ranges, anchors, initial = small
    imu, ranges, anchors = mutate(imu.copy(), ranges.copy(), anchors.copy())
    with pytest.raises(ValueError, match=pattern):
        uwbimu_rs.run_filter("ekf", imu, ranges, anchors, initial=initial)


def _set(a, idx, value):
    a[idx] = value
    return a


def test_a_negative_range_is_dropped_and_flagged_not_raised(small):
    imu, ranges, anchors, initial = small
    bad = _set(ranges.copy(), (2, 2), -2.0)
    df, info = uwbimu_rs.run_filter("ekf", imu, bad, anchors, initial=initial, info=True)
    clean = uwbimu_rs.run_filter("ekf", imu, np.delete(ranges, 2, axis=0), anchors, initial=initial)
    # The row after the range's time carries the gate's bit and the run counts it; the estimate
    # is the run without it.
    assert df["status"].dtype == pl.UInt8 and (df["status"] & 1).sum() == 1
    assert {k: n for k, n in info["health"]["rejected"].items() if n} == {"negative_range": 1}
    np.testing.assert_array_equal(df["x"].to_numpy(), clean["x"].to_numpy())
    fixes = uwbimu_rs.run_filter("uwb_ls", imu, bad, anchors)
    assert fixes.height == uwbimu_rs.run_filter("uwb_ls", imu, np.delete(ranges, 2, axis=0), anchors).height


def test_unknown_method_lists_allowed(small):
    imu, ranges, anchors, _ = small
    with pytest.raises(ValueError, match=r"unknown method `kalman`; allowed: uwb_ls, ekf, iekf, rekf, riekf, criekf, ckf, arckf, ackf, eskf, shaf, shfaf"):
        uwbimu_rs.run_filter("kalman", imu, ranges, anchors)


def test_unknown_config_key_lists_allowed(small):
    imu, ranges, anchors, initial = small
    with pytest.raises(uwbimu_rs.ConfigError, match=r"unknown config `range_sigma`; allowed: ranging.range_std, "):
        uwbimu_rs.run_filter("ekf", imu, ranges, anchors, initial=initial, config={"range_sigma": 0.1})
    with pytest.raises(ValueError, match=r"unknown config `foo`"):
        uwbimu_rs.FilterConfig(foo=1.0)


@pytest.mark.parametrize(
    ("config", "pattern"),
    [
        ({"ranging.range_std": -0.1}, r"config `ranging.range_std`: must be finite and > 0"),
        ({"mounting.lever_arm": [0.0, 0.1]}, r"config `mounting.lever_arm`: expected 3 numbers per tag"),
        ({"mounting.imu_rotation": [0, 0, 0, 0]}, r"config `mounting.imu_rotation`: quaternion"),
        ({"ranging.range_std": "big"}, r"`ranging.range_std`: expected a number"),
        ({"ins.gravity": float("nan")}, r"config `ins.gravity`: must be finite"),
    ],
)
def test_bad_config_values(small, config, pattern):
    imu, ranges, anchors, initial = small
    with pytest.raises(ValueError, match=pattern):
        uwbimu_rs.run_filter("ekf", imu, ranges, anchors, initial=initial, config=config)


def test_bad_initial_key(small):
    imu, ranges, anchors, initial = small
    with pytest.raises(ValueError, match=r"unknown initial-state key `pos` \(did you mean `position` or `position_std`\?\); allowed: position"):
        uwbimu_rs.run_filter("ekf", imu, ranges, anchors, initial={"pos": [0, 0, 0]})


def test_config_object_and_dict_agree(small):
    imu, ranges, anchors, initial = small
    # Flat keys of earlier versions, section keys and section dicts all say the same.
    cfg = uwbimu_rs.FilterConfig(ranging={"range_std": 0.2}, mounting={"lever_arm": [0, 0, 0.05]})
    d = cfg.to_dict()
    # The given keys are kept, the others are the defaults, and the keys are the allowed ones.
    assert d["ranging"]["range_std"] == 0.2 and list(d["mounting"]["lever_arm"]) == [0, 0, 0.05]
    assert d["ins"]["accel_noise_density"] == uwbimu_rs.FilterConfig().to_dict()["ins"]["accel_noise_density"] == 0.3
    keys = set(uwbimu_rs.FilterConfig.keys())
    assert {f"{s}.{k}" for s, fields in d.items() if s != "range_calibration" for k in fields} <= keys
    a = uwbimu_rs.run_filter("ekf", imu, ranges, anchors, initial=initial, config=cfg)
    b = uwbimu_rs.run_filter("ekf", imu, ranges, anchors, initial=initial, config={"ranging": {"range_std": 0.2}, "mounting.lever_arm": [0, 0, 0.05]})
    c = uwbimu_rs.run_filter("ekf", imu, ranges, anchors, initial=initial, config=d)
    e = uwbimu_rs.run_filter("ekf", imu, ranges, anchors, initial=initial, config={"ranging.range_std": 0.2, "mounting": {"lever_arm": [0, 0, 0.05]}})
    defaults = uwbimu_rs.run_filter("ekf", imu, ranges, anchors, initial=initial)
    assert a.equals(b) and a.equals(c) and a.equals(e)
    assert not a.equals(defaults)
    assert keys >= {"ranging.range_std", "ranging.tdoa_std", "ins.accel_noise_density", "ins.gravity", "mounting.lever_arm", "mounting.imu_rotation", "robust.significance", "unscented.alpha", "sage_husa.alpha"}
    with pytest.raises(ValueError, match="robust.significance"):
        uwbimu_rs.FilterConfig(robust={"alpha": 0.05})
    # The NLOS skew is unset (the method's own) until given, and at least 1.
    assert "nlos_skew" not in d["robust"] and uwbimu_rs.FilterConfig(robust={"nlos_skew": 2}).to_dict()["robust"]["nlos_skew"] == 2
    with pytest.raises(ValueError, match=r"robust.nlos_skew.*>= 1"):
        uwbimu_rs.FilterConfig(robust={"nlos_skew": 0.5})


def test_self_init_without_uwb_fails_clearly(small):
    imu, _ranges, anchors, _ = small
    with pytest.raises(ValueError, match="no solvable UWB epoch"):
        uwbimu_rs.run_filter("ekf", imu, np.zeros((0, 3)), anchors)


def test_robust_reports_on_nlos_data(filter_config):
    from uwbimu_rs import sim

    run = sim.preset("hall_vehicle_nlos", seed=2)
    df, upd = uwbimu_rs.run_filter("riekf", run.imu, run.ranges, run.anchors, config=filter_config, updates=True)
    assert {"inflation", "down_weighted", "iterations"} <= set(upd.columns)
    assert upd["down_weighted"].dtype == pl.Boolean and upd["iterations"].dtype == pl.Int64
    assert upd["down_weighted"].any() and (upd["iterations"] >= 1).all()
    down = upd.filter(pl.col("down_weighted"))
    np.testing.assert_allclose(down["weight"] * down["inflation"], 1.0)
    assert (down["inflation"] > 1.0).all()
    # The χ² threshold at the default α = 0.01 is 6.63: a down-weighted range has γ above it
    # for its last iterate.
    assert (down["nis"] >= 6.63).all()


def test_constraint_switches_and_still_column(filter_config):
    from uwbimu_rs import sim

    run = sim.preset("hall_vehicle", seed=0)
    cfg = uwbimu_rs.FilterConfig(**{**filter_config, "constraints.zupt": True})
    assert cfg.to_dict()["constraints"]["zupt"] is True
    df = uwbimu_rs.run_filter("ekf", run.imu, run.ranges, run.anchors, config=cfg)
    assert df["still"].dtype == pl.Boolean
    # The preset starts with 2 s still: the detector fires there and not while driving.
    early = df.filter(pl.col("t") < 2.0)["still"].mean()
    late = df.filter(pl.col("t") > 10.0)["still"].mean()
    assert early > 0.5 and late < 0.02
    with pytest.raises(ValueError, match=r"config `constraints.zupt`: expected True or False"):
        uwbimu_rs.FilterConfig(constraints={"zupt": 1.0})


def test_smoothing_batch(los_run, filter_config):
    df = uwbimu_rs.run_filter("ekf", los_run.imu, los_run.ranges, los_run.anchors, config=filter_config)
    sm = uwbimu_rs.run_filter("ekf", los_run.imu, los_run.ranges, los_run.anchors, config=filter_config, smooth=True)
    assert sm.columns == df.columns and sm.height == df.height
    # Measured 0.073 → 0.031 m.
    assert metrics.evaluate(sm, los_run.truth).horizontal.rmse < 0.6 * metrics.evaluate(df, los_run.truth).horizontal.rmse
    assert (sm["std_x"] <= df["std_x"] * (1 + 1e-9)).all()
    with pytest.raises(ValueError, match="smoothing method `uwb_ls`"):
        uwbimu_rs.run_filter("uwb_ls", los_run.imu, los_run.ranges, los_run.anchors, smooth=True)
    plain = uwbimu_rs.Ekf(los_run.anchors, initial=los_run.initial, config=filter_config)
    with pytest.raises(ValueError, match="record=True"):
        plain.smooth()


def test_crlb_beside_the_filter_error(los_run, filter_config):
    initial = {
        "position": los_run.truth.select("x", "y", "z").row(0),
        "velocity": [0.0, 0.0, 0.0],
        "orientation": los_run.truth.select("qw", "qx", "qy", "qz").row(0),
    }
    df = uwbimu_rs.run_filter("ekf", los_run.imu, los_run.ranges, los_run.anchors, initial=initial, config=filter_config)
    biases = np.hstack([los_run.accel_bias, los_run.gyro_bias])
    bound = uwbimu_rs.crlb(los_run.imu, los_run.ranges, los_run.anchors, los_run.truth, biases=biases, initial=initial, config=filter_config)
    assert bound.columns == ["t", "crlb_x", "crlb_y", "crlb_z"] and bound.height == df.height
    late = pl.col("t") > 30.0
    e = metrics.evaluate(df.filter(late), los_run.truth).errors
    b = bound.filter(late)
    mse = (e["e_h"] ** 2).mean()
    crlb_h = (b["crlb_x"] ** 2 + b["crlb_y"] ** 2).mean()
    assert mse > 0.5 * crlb_h  # one run: loose Monte-Carlo tolerance (6 runs in tests/integration/crlb.rs)
    with pytest.raises(ValueError, match=r"truth: expected shape \(N, 11\)"):
        uwbimu_rs.crlb(los_run.imu, los_run.ranges, los_run.anchors, np.zeros((3, 4)))


def test_run_filters_in_parallel_equals_one_by_one(filter_config):
    from uwbimu_rs import sim

    runs = [sim.preset("hall_vehicle_nlos", seed=s) for s in range(3)]
    many = uwbimu_rs.run_filters("riekf", [(r.imu, r.ranges, r.anchors) for r in runs], config=filter_config)
    assert len(many) == 3
    for r, df in zip(runs, many):
        one = uwbimu_rs.run_filter("riekf", r.imu, r.ranges, r.anchors, config=filter_config)
        assert df.equals(one)
    # With info, each run's counts are its own: one negative range in the second run only.
    inputs = [(r.imu, r.ranges.copy(), r.anchors) for r in runs]
    inputs[1][1][5, 2] = -1.0
    counted = uwbimu_rs.run_filters("riekf", inputs, config=filter_config, info=True)
    for (imu, ranges, anchors), (df, info) in zip(inputs, counted):
        one, one_info = uwbimu_rs.run_filter("riekf", imu, ranges, anchors, config=filter_config, info=True)
        assert df.equals(one) and info == one_info
    assert [info["health"]["rejected"]["negative_range"] for _, info in counted] == [0, 1, 0]
    with pytest.raises(ValueError, match=r"runs\[1\]: expected a tuple"):
        uwbimu_rs.run_filters("ekf", [(runs[0].imu, runs[0].ranges, runs[0].anchors), "nope"])
    with pytest.raises(ValueError, match=r"initial: expected shape 1 items \(one per run\), got 2"):
        uwbimu_rs.run_filters("ekf", [(runs[0].imu, runs[0].ranges, runs[0].anchors)], initial=[None, None])


def test_ackf_uses_the_magnetometer_and_others_refuse_it():
    run = uwbimu_rs.sim.preset("square_diagonal", seed=1)
    assert run.mag is not None
    df = uwbimu_rs.run_filter("ackf", run.imu, run.ranges, run.anchors, mag=run.mag, config={"aiding.reference_s": 1.5})
    err = uwbimu_rs.metrics.evaluate(df, run.truth).horizontal.rmse
    ls = uwbimu_rs.run_filter("uwb_ls", run.imu, run.ranges, run.anchors)
    ls_err = uwbimu_rs.metrics.evaluate(ls, run.truth).horizontal.rmse
    assert err < ls_err, (err, ls_err)
    hold("python", "ackf,square_diagonal,1,rmse", err)
    with pytest.raises(ValueError, match=r"ckf does not take magnetometer samples \(these do: ackf\)"):
        uwbimu_rs.run_filter("ckf", run.imu, run.ranges, run.anchors, mag=run.mag)
    bad = run.mag.copy()
    bad[5, 0] = bad[4, 0]
    with pytest.raises(ValueError, match="mag"):
        uwbimu_rs.run_filter("ackf", run.imu, run.ranges, run.anchors, mag=bad)
    with pytest.raises(ValueError, match="mag"):
        uwbimu_rs.run_filter("ackf", run.imu, run.ranges, run.anchors, mag=run.mag[:, :3])
