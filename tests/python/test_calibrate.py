"""Range-bias calibration through Python: known biases come back with truth, the result feeds a
filter's configuration, and bad input raises."""

from __future__ import annotations

import numpy as np
import pytest

import uwbimu_rs
from uwbimu_rs import sim


def _biased_run():
    run = sim.zoo("handheld_walk", seed=1)
    biases = np.array([0.15, -0.10, 0.05, -0.20, 0.0])
    ranges = run.ranges.copy()
    ranges[:, 2] += biases[ranges[:, 1].astype(int)]
    return run, ranges, biases


def _tag_truth(run):
    """``t, x, y, z`` of the tag: body position + R(q)·lever arm."""
    q = run.truth.select("qw", "qx", "qy", "qz").to_numpy()
    lever = np.asarray(run.config["mounting"]["lever_arm"])
    w, x, y, z = q.T
    rot = np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        1,
    )
    tag = run.truth.select("x", "y", "z").to_numpy() + rot @ lever
    return np.column_stack([run.truth["t"].to_numpy(), tag])


def test_known_biases_with_truth_and_the_calibration_helps():
    run, ranges, biases = _biased_run()
    truth = _tag_truth(run)
    cal = uwbimu_rs.calibrate(run.imu, ranges, run.anchors, truth=truth, initial=run.initial, config=run.config)
    np.testing.assert_allclose(cal["biases"]["bias"].to_numpy(), biases, atol=0.015)
    assert cal["biases"]["anchor"].to_list() == [0, 1, 2, 3, 4]
    config = {**run.config, "range_calibration": cal["range_calibration"]}

    def rmse(cfg):
        df = uwbimu_rs.run_filter("riekf", run.imu, ranges, run.anchors, initial=run.initial, config=cfg)
        t = df["t"].to_numpy()
        e = np.hypot(
            df["x"].to_numpy() - np.interp(t, run.truth["t"].to_numpy(), run.truth["x"].to_numpy()),
            df["y"].to_numpy() - np.interp(t, run.truth["t"].to_numpy(), run.truth["y"].to_numpy()),
        )
        return float(np.sqrt(np.mean(e**2)))

    assert rmse(config) < 0.8 * rmse(run.config)
    # Without truth: the same ordering of the biases.
    own = uwbimu_rs.calibrate(run.imu, ranges, run.anchors, initial=run.initial, config=run.config)
    assert own["iterations"] == 8
    est = own["biases"]["bias"].to_numpy()
    assert np.argsort(est).tolist() == np.argsort(biases).tolist()


def test_calibrate_errors():
    run, ranges, _ = _biased_run()
    with pytest.raises(ValueError, match="truth"):
        uwbimu_rs.calibrate(run.imu, ranges, run.anchors, truth=np.zeros((5, 3)))
    with pytest.raises(ValueError, match="uwb_ls"):
        uwbimu_rs.calibrate(run.imu, ranges, run.anchors, method="uwb_ls")


def test_time_offset_and_lever_arm_feed_the_config():
    run = sim.zoo("handheld_walk", seed=13)
    lag = 0.05
    ranges = run.ranges.copy()
    ranges[:, 0] += lag
    ranges = ranges[ranges[:, 0] <= run.imu[-1, 0]]
    config = {"mounting": run.config["mounting"]}
    tag = _tag_truth(run)
    with_truth = uwbimu_rs.calibrate(run.imu, ranges, run.anchors, truth=tag, config=config, offsets=True)
    assert abs(with_truth["time_offset"] + lag) < 0.01 and with_truth["lever_arm"] is None
    own = uwbimu_rs.calibrate(run.imu, ranges, run.anchors, config=config, offsets=True)
    assert own["iterations"] == 16 and len(own["lever_arm"]) == 3
    assert abs(own["time_offset"] + lag) < 0.03, own["time_offset"]
    assert own["config"]["ranging"]["time_offset_s"] == own["time_offset"]
    df = uwbimu_rs.run_filter("riekf", run.imu, ranges, run.anchors, config=own["config"])
    assert df.height == run.imu.shape[0]
