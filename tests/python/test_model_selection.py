"""`best`'s model choice with four anchors (held-out time blocks, docs/model-selection.md), checked
against the truth on seeds and errors the rule was not chosen on (it was chosen on seeds 21–24)."""

from __future__ import annotations

import numpy as np
import polars as pl

import uwbimu_rs
from uwbimu_rs import metrics, sim


def _forward_rmse(run, ranges: np.ndarray, config: dict) -> float:
    df = uwbimu_rs.run_filter("best", run.imu, ranges, run.anchors, config=config, smooth=False)
    df = df.filter(pl.col("t") >= df["t"][0] + 10.0)
    return metrics.evaluate(df, run.truth).horizontal.rmse


def _choice_against_plain(run, ranges: np.ndarray) -> tuple[dict, float, float]:
    config = {"mounting": run.config["mounting"]}
    choice = uwbimu_rs.choose_model("best", run.imu, ranges, run.anchors, config=config)
    plain = {**config, "model_selection": {"enabled": False}}
    return choice, _forward_rmse(run, ranges, plain), _forward_rmse(run, ranges, choice["config"])


def test_four_anchors_with_steady_biases_choose_no_worse_than_plain():
    # Coplanar anchors 2.6 m above a robot, ranges with steady per-anchor biases like the drone
    # rig's; seed 41 was not looked at before this test was written.
    run = sim.zoo("stop_and_go", seed=41)
    assert len(run.anchors) == 4
    ranges = run.ranges.copy()
    ranges[:, 2] += np.array([-0.31, -0.05, -0.18, 0.03])[ranges[:, 1].astype(int)]
    choice, before, after = _choice_against_plain(run, ranges)
    assert choice["chosen"] is not None and choice["candidates"].height == 8, choice["reason"]
    assert after <= 1.05 * before, (choice["reason"], before, after)


def test_four_anchors_every_range_long_choose_no_worse_than_plain():
    run = sim.zoo("forklift", seed=41)
    ranges = run.ranges.copy()
    ranges[:, 2] += np.array([0.12, 0.31, 0.18, 0.36])[ranges[:, 1].astype(int)]
    choice, before, after = _choice_against_plain(run, ranges)
    assert after <= 1.05 * before, (choice["reason"], before, after)


def test_four_anchors_clean_choose_no_worse_than_plain():
    run = sim.zoo("imu_20hz", seed=41)
    choice, before, after = _choice_against_plain(run, run.ranges)
    assert after <= 1.05 * before, (choice["reason"], before, after)


def test_three_anchors_select_nothing():
    run = sim.zoo("forklift", seed=41)
    ranges = run.ranges[run.ranges[:, 1] < 3]
    choice = uwbimu_rs.choose_model("best", run.imu, ranges, run.anchors[:3])
    assert choice["chosen"] is None and "3 anchors" in choice["reason"]
