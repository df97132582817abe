"""Anchors refined from an ordinary log (issue 47, deliverable 2), against the simulated site the
log was drawn from: the wrong survey comes back, the track's accuracy with it, the gauge stays the
given anchors', and bad settings are clear errors."""

from __future__ import annotations

import numpy as np
import pytest

import uwbimu_rs
import uwbimu_rs.metrics as metrics
import uwbimu_rs.sim as sim

SITE = np.array([[0.5, 0.3, 2.4], [9.8, 0.1, 2.6], [10.2, 7.9, 0.4], [0.2, 8.1, 2.5], [5.1, -0.2, 0.5], [4.9, 8.3, 2.2]])


def _aligned(anchors, truth):
    """`anchors` after the translation and yaw that best align them on `truth` (the gauge)."""
    c, c0 = anchors.mean(axis=0), truth.mean(axis=0)
    d, d0 = anchors - c, truth - c0
    yaw = np.arctan2(np.sum(d[:, 0] * d0[:, 1] - d[:, 1] * d0[:, 0]), np.sum(d[:, 0] * d0[:, 0] + d[:, 1] * d0[:, 1]))
    rot = np.array([[np.cos(yaw), -np.sin(yaw), 0.0], [np.sin(yaw), np.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
    return d @ rot.T + c0


def _rmse(run, anchors):
    # The RTS pass (MAP passes off): their kernel leaves out ranges a wrong survey lengthens, which
    # hides part of its cost (seed 1, true / wrong / refined anchors, m: RTS 0.0090 / 0.0149 /
    # 0.0128, MAP 0.0089 / 0.0119 / 0.0124), and the survey's effect on the track is what is tested.
    config = {**run.config, "smoothing": {"map_passes": 0}}
    df = uwbimu_rs.run_filter("best", run.imu, run.ranges, anchors, config=config, smooth=True)
    return metrics.evaluate(df.filter(df["t"] >= 10.0), run.truth, align=True).horizontal.rmse


@pytest.mark.parametrize("seed", [0, 1])
def test_a_wrong_survey_is_refined_back_and_the_track_with_it(seed):
    run = sim.simulate(sim.Trajectory.figure_eight([5.0, 4.0, 1.0], 3.5, 2.5, 20.0, 3), SITE, seed=seed, uwb_rate_hz=10.0, range_std_m=0.05)
    rng = np.random.default_rng(50 + seed)
    d = rng.normal(size=SITE.shape)
    given = SITE + 0.25 * d / np.linalg.norm(d, axis=1, keepdims=True)
    r = uwbimu_rs.calibrate(run.imu, run.ranges, given, refine_anchors=True, anchor_std=0.25, config=run.config)
    horizontal = lambda a: np.hypot(*(_aligned(a, SITE) - SITE)[:, :2].T).max()  # noqa: E731
    assert horizontal(given) > 0.15
    assert horizontal(r["anchors"]) < 0.08, (horizontal(given), horizontal(r["anchors"]), r["moves"])
    true, wrong, refined = _rmse(run, SITE), _rmse(run, given), _rmse(run, r["anchors"])
    assert refined < wrong and refined < 1.5 * true + 0.005, (true, wrong, refined)
    # The gauge is the prior's: no translation of the whole layout, to rounding.
    assert np.allclose(r["anchors"].mean(axis=0), given.mean(axis=0), atol=1e-6)
    assert [x["kind"] for x in r["directions"]][:4] == ["gauge"] * 4
    assert r["anchor_std"].shape == (6, 3) and r["anchor_covariances"].shape == (6, 3, 3)
    assert np.all(r["anchor_std"] > 0) and np.all(r["anchor_std"] < 0.25)
    assert not r["biases_estimated"] and r["config"]["range_calibration"] == run.config.get("range_calibration", {})
    # The walk stays 1 m up: the anchors' heights are open to a mirror image, and it says so.
    assert any("of one height" in w for w in r["warnings"]), r["warnings"]


def test_bad_settings_say_what_is_wrong():
    run = sim.simulate(sim.Trajectory.figure_eight([5.0, 4.0, 1.0], 3.5, 2.5, 20.0, 1), SITE, seed=0, uwb_rate_hz=5.0)
    call = lambda **kw: uwbimu_rs.calibrate(run.imu, run.ranges, SITE, refine_anchors=True, **kw)  # noqa: E731
    with pytest.raises(ValueError, match="needs anchor_std"):
        call()
    with pytest.raises(ValueError, match="anchor_std"):
        call(anchor_std=np.full(7, 0.3))
    with pytest.raises(ValueError, match="anchor_std"):
        call(anchor_std=-0.1)
    with pytest.raises(ValueError, match="range_bias_std"):
        call(anchor_std=0.3, range_bias_std=0.0)
    with pytest.raises(ValueError, match="offsets"):
        call(anchor_std=0.3, offsets=True)
