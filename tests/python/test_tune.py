"""Noise tuning, range bias states and `best` through Python."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

import uwbimu_rs
from uwbimu_rs import metrics, sim


def _rmse(df: pl.DataFrame, run) -> float:
    df = df.filter(pl.col("t") >= df["t"][0] + 10.0)
    return metrics.evaluate(df, run.truth).horizontal.rmse


def test_tune_by_likelihood_returns_a_config_that_helps():
    run = sim.zoo("handheld_walk", seed=8)
    base = {"mounting": run.config["mounting"]}
    out = uwbimu_rs.tune("riekf", run.imu, run.ranges, run.anchors, config=base)
    assert out["objective"] == "innovation_likelihood" and out["score"] < out["initial_score"]
    assert out["trials"].columns == [*out["keys"], "score"] and out["trials"].height == 25
    before = _rmse(uwbimu_rs.run_filter("riekf", run.imu, run.ranges, run.anchors, config=base), run)
    after = _rmse(uwbimu_rs.run_filter("riekf", run.imu, run.ranges, run.anchors, config=out["config"]), run)
    # Measured on other seeds while building: handheld_walk seed 5 0.049 → 0.042 m.
    assert after < 0.95 * before, (before, after)
    with pytest.raises(ValueError, match="uwb_ls"):
        uwbimu_rs.tune("uwb_ls", run.imu, run.ranges, run.anchors)


def test_best_is_the_smoothed_riekf_composition_and_bias_states_report():
    run = sim.zoo("agv_loop", seed=4)
    cfg = {"mounting": run.config["mounting"]}
    best = uwbimu_rs.run_filter("best", run.imu, run.ranges, run.anchors, config=cfg)
    # best = riekf + the zero-velocity constraint + the NLOS skew of 4, smoothed by default.
    composed = {**cfg, "constraints": {"zupt": True}, "robust": {"nlos_skew": 4.0}}
    smoothed = uwbimu_rs.run_filter("riekf", run.imu, run.ranges, run.anchors, config=composed, smooth=True)
    forward = uwbimu_rs.run_filter("best", run.imu, run.ranges, run.anchors, config=cfg, smooth=False)
    np.testing.assert_array_equal(best["x"].to_numpy(), smoothed["x"].to_numpy())
    assert _rmse(best, run) < 0.8 * _rmse(forward, run)
    assert "best" in uwbimu_rs.FILTERS
    ranges = run.ranges.copy()
    ranges[:, 2] += np.where(ranges[:, 1] == 0, 0.2, 0.0)
    _, upd = uwbimu_rs.run_filter(
        "riekf", run.imu, ranges, run.anchors, config={**cfg, "range_bias": {"states": True}}, updates=True
    )
    last = upd.group_by("anchor").agg(pl.col("bias").last(), pl.col("bias_std").last()).sort("anchor")
    assert abs(last["bias"][0] - 0.2) < 0.05 and (last["bias_std"] > 0).all()
    _, plain = uwbimu_rs.run_filter("riekf", run.imu, run.ranges, run.anchors, config=cfg, updates=True)
    assert plain["bias"].is_nan().all()


def test_the_innovation_likelihood_tells_whether_bias_states_pay():
    # rounds=0 scores the given configuration only. Constant per-anchor biases like a rig whose
    # ranges are all short (−0.13 m + U(−0.18, 0.16) m): bias states lower the mean negative
    # log-likelihood by 0.24–0.43 (measured on seeds 3–4 of drone_flight and handheld_walk);
    # without biases they cost 0.001–0.004.
    run = sim.zoo("drone_flight", seed=5)
    biases = -0.13 + np.random.default_rng(105).uniform(-0.18, 0.16, len(run.anchors))
    biased = run.ranges.copy()
    biased[:, 2] += biases[biased[:, 1].astype(int)]
    cfg = {"mounting": run.config["mounting"]}
    on = {**cfg, "range_bias": {"states": True}}

    def nll(ranges, config):
        out = uwbimu_rs.tune("best", run.imu, ranges, run.anchors, config=config, rounds=0)
        assert out["score"] == out["initial_score"] and out["trials"].height == 1
        return out["score"]

    assert nll(biased, cfg) - nll(biased, on) > 0.15
    assert abs(nll(run.ranges, cfg) - nll(run.ranges, on)) < 0.01
