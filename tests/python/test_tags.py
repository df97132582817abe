"""Several UWB tags through the Python API: ranges (M, 4) in batch against the simulator's truth,
the tag column of the updates frame, lever arms as rows, ``add_range(..., tag=)``, and clear
errors for a tag without a lever arm or a method of one tag."""

from __future__ import annotations

import numpy as np
import pytest

import uwbimu_rs
from uwbimu_rs import sim


def _h_rmse(df, r) -> float:
    t = df["t"].to_numpy()
    x = np.interp(t, r.truth["t"].to_numpy(), r.truth["x"].to_numpy())
    y = np.interp(t, r.truth["t"].to_numpy(), r.truth["y"].to_numpy())
    return float(np.sqrt(np.mean(np.hypot(df["x"].to_numpy() - x, df["y"].to_numpy() - y) ** 2)))


def test_two_tags_run_in_batch_and_report_their_tag():
    r = sim.zoo("agv_loop", seed=0, tag_separation_m=0.6)
    assert r.ranges.shape[1] == 4 and set(np.unique(r.ranges[:, 3])) == {0.0, 1.0}
    arms = np.asarray(r.config["mounting"]["lever_arm"]).reshape(-1, 3)
    np.testing.assert_allclose(arms[1] - arms[0], [0.6, 0.0, 0.0])
    df, upd = uwbimu_rs.run_filter("riekf", r.imu, r.ranges, r.anchors, initial=r.initial, config=r.config, updates=True)
    assert _h_rmse(df, r) < 0.05  # truth as the oracle; σ 0.1 m ranges from eight anchors
    ranges = upd.filter(upd["sensor"] == "range")
    assert set(ranges["tag"].unique().to_list()) == {0, 1}
    assert ranges.height == r.ranges.shape[0]


def test_lever_arms_as_rows_equal_the_flat_form():
    r = sim.zoo("agv_loop", seed=1, tag_separation_m=0.5)
    arms = np.asarray(r.config["mounting"]["lever_arm"]).reshape(-1, 3)
    flat = uwbimu_rs.run_filter("ekf", r.imu, r.ranges, r.anchors, initial=r.initial, config=r.config)
    rows = {**r.config, "mounting": {**r.config["mounting"], "lever_arm": arms.tolist()}}
    as_rows = uwbimu_rs.run_filter("ekf", r.imu, r.ranges, r.anchors, initial=r.initial, config=rows)
    np.testing.assert_array_equal(flat["x"].to_numpy(), as_rows["x"].to_numpy())


def test_add_range_takes_a_tag_and_refuses_one_without_a_lever_arm():
    r = sim.zoo("agv_loop", seed=2, tag_separation_m=0.5)
    f = uwbimu_rs.Riekf(r.anchors, initial=r.initial, config=r.config)
    t0 = r.imu[0, 0]
    f.add_imu(t0, r.imu[0, 1:4], r.imu[0, 4:7])
    tagged = r.ranges[(r.ranges[:, 0] > t0) & (r.ranges[:, 3] == 1)][0]
    f.add_range(tagged[0], int(tagged[1]), tagged[2], tag=1)
    with pytest.raises(ValueError, match=r"tag=2.*mounting.lever_arm gives 2 tag"):
        f.add_range(tagged[0], int(tagged[1]), tagged[2], tag=2)


def test_a_tag_without_a_lever_arm_and_a_method_of_one_tag_are_clear_errors():
    r = sim.zoo("agv_loop", seed=0, tag_separation_m=0.5)
    one_arm = {**r.config, "mounting": {**r.config["mounting"], "lever_arm": [0.0, 0.0, 0.05]}}
    with pytest.raises(ValueError, match=r"from tag 1.*mounting.lever_arm gives 1 tag"):
        uwbimu_rs.run_filter("riekf", r.imu, r.ranges, r.anchors, config=one_arm)
    with pytest.raises(ValueError, match=r"eskf fuses one tag"):
        uwbimu_rs.run_filter("eskf", r.imu, r.ranges, r.anchors, config=r.config)
    bad = r.ranges.copy()
    bad[5, 3] = 1.5
    with pytest.raises(ValueError, match=r"ranges.*tag.*row 5"):
        uwbimu_rs.run_filter("riekf", r.imu, bad, r.anchors, config=r.config)
