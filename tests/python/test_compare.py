"""uwbimu_rs.compare: its rows are run_filter + metrics.evaluate, its smoothing label, its
parallel run, its truth-less table and its input errors."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

import uwbimu_rs
from uwbimu_rs import metrics, sim

METHODS = ["uwb_ls", "ekf", "riekf", "best"]
STATS = ("rmse", "mean", "median", "p95", "max")


@pytest.fixture(scope="module")
def short_nlos():
    """The first 40 s of the NLOS preset (the presets have no duration override): imu, ranges,
    anchors, truth, config, initial."""
    run = sim.preset("hall_vehicle_nlos", seed=3)
    imu, ranges = run.imu[run.imu[:, 0] < 40.0], run.ranges[run.ranges[:, 0] < 40.0]
    return imu, ranges, run.anchors, run.truth.filter(pl.col("t") < 40.0), run.config, run.initial


@pytest.fixture(scope="module")
def causal(short_nlos):
    imu, ranges, anchors, truth, config, _ = short_nlos
    return uwbimu_rs.compare(METHODS, imu, ranges, anchors, truth=truth, config=config)


def test_rows_equal_run_filter_and_evaluate(short_nlos, causal):
    imu, ranges, anchors, truth, config, _ = short_nlos
    assert causal.skip_s == 10.0 and causal.table["method"].to_list() == METHODS
    for row in causal.table.iter_rows(named=True):
        m = row["method"]
        frame = uwbimu_rs.run_filter(m, imu, ranges, anchors, config=config, smooth=False)
        assert causal.runs[m].frame.equals(frame)
        scored = frame.filter(pl.col("t") >= imu[0, 0] + 10.0)
        for suffix, ev in (("", metrics.evaluate(scored, truth)), ("_aligned", metrics.evaluate(scored, truth, align=True))):
            assert row["n_errors"] == ev.horizontal.n
            for axis, stats in (("h", ev.horizontal), ("3d", ev.three_d)):
                for name in STATS:
                    assert row[f"{axis}_{name}{suffix}"] == pytest.approx(getattr(stats, name), abs=1e-12, rel=0)
        assert row["rows"] == frame.height and row["time_s"] > 0.0
        if m == "uwb_ls":
            assert causal.runs[m].updates is None and row["nis_mean"] is None
        else:
            _, updates = uwbimu_rs.run_filter(m, imu, ranges, anchors, config=config, smooth=False, updates=True)
            assert causal.runs[m].updates.equals(updates)
            assert row["nis_mean"] == pytest.approx(updates["nis"].mean(), abs=1e-12)
            assert row["accepted"] == pytest.approx(updates["accepted"].mean(), abs=1e-12)
            assert row["down_weighted"] == pytest.approx(updates["down_weighted"].mean(), abs=1e-12)


def test_column_layout(causal):
    errors = [f"{a}_{s}{x}" for x in ("", "_aligned") for a in ("h", "3d") for s in STATS]
    head = ["method", "smoothed", "time_s", "rows", "nis_mean", "accepted", "down_weighted", "n_errors"]
    assert causal.table.columns == head + errors
    text = str(causal)
    assert all(m in text for m in METHODS) and "h_rmse_aligned" in text and "–" in text  # uwb_ls has no NIS
    assert repr(causal).startswith("Comparison(skip_s=10, truth=yes)")


def test_smooth_false_keeps_every_row_causal(short_nlos, causal):
    imu, ranges, anchors, _, config, _ = short_nlos
    assert not any(causal.table["smoothed"])
    default_best = uwbimu_rs.run_filter("best", imu, ranges, anchors, config=config)  # smoothed by default
    assert not causal.runs["best"].frame.equals(default_best)
    assert [r.label for r in causal.runs.values()] == METHODS


def test_smooth_true_smooths_what_can(short_nlos):
    imu, ranges, anchors, truth, config, _ = short_nlos
    cmp = uwbimu_rs.compare(METHODS, imu, ranges, anchors, truth=truth, config=config, smooth=True)
    expected = [uwbimu_rs.METHODS[m]["smoothing"] != "never" for m in METHODS]
    assert cmp.table["smoothed"].to_list() == expected == [False, True, True, True]
    assert cmp.runs["best"].label == "best (smoothed)" and cmp.runs["uwb_ls"].label == "uwb_ls"
    for m in ("ekf", "best"):
        assert cmp.runs[m].frame.equals(uwbimu_rs.run_filter(m, imu, ranges, anchors, config=config, smooth=True))


def test_parallel_equals_serial(short_nlos, causal):
    imu, ranges, anchors, truth, config, _ = short_nlos
    serial = uwbimu_rs.compare(METHODS, imu, ranges, anchors, truth=truth, config=config, max_workers=1)
    assert serial.table.drop("time_s").equals(causal.table.drop("time_s"))
    assert all(serial.runs[m].frame.equals(causal.runs[m].frame) for m in METHODS)


def test_truth_as_array_and_given_initial(short_nlos):
    imu, ranges, anchors, truth, config, initial = short_nlos
    as_frame = uwbimu_rs.compare(["ekf"], imu, ranges, anchors, truth=truth, config=config, initial=initial)
    as_array = uwbimu_rs.compare(["ekf"], imu, ranges, anchors, truth=truth.to_numpy(), config=config, initial=initial)
    assert as_frame.skip_s == 0.0 and as_frame.table.drop("time_s").equals(as_array.table.drop("time_s"))
    assert as_frame.table["n_errors"].item() == imu.shape[0]
    skipped = uwbimu_rs.compare(["ekf"], imu, ranges, anchors, truth=truth, config=config, initial=initial, skip_s=5.0)
    assert skipped.table["n_errors"].item() == int(np.sum(imu[:, 0] >= 5.0))


def test_truthless_table(short_nlos):
    imu, ranges, anchors, _, config, _ = short_nlos
    cmp = uwbimu_rs.compare(["uwb_ls", "riekf"], imu, ranges, anchors, config=config)
    assert cmp.truth is None and cmp.runs["riekf"].errors is None
    assert cmp.table.columns == ["method", "smoothed", "time_s", "rows", "nis_mean", "accepted", "down_weighted"]
    row = cmp.table.row(1, named=True)
    assert row["nis_mean"] > 1.0 and 0.0 < row["down_weighted"] < 1.0 and row["accepted"] == 1.0


@pytest.mark.parametrize(
    ("methods", "kwargs", "error", "match"),
    [
        ([], {}, ValueError, "empty"),
        ("ekf", {}, ValueError, "list of names"),
        (["ekf", "kalman"], {}, uwbimu_rs.ConfigError, "kalman.*uwb_ls, ekf"),
        (["ekf", "ekf"], {}, ValueError, "more than once"),
        (["ekf"], {"truth": np.zeros((5, 3))}, ValueError, "truth: expected shape"),
        (["ekf"], {"truth": pl.DataFrame({"t": [0.0], "x": [0.0]})}, ValueError, "missing columns"),
        (["ekf"], {"skip_s": -1.0}, ValueError, "skip_s"),
    ],
)
def test_bad_input(short_nlos, methods, kwargs, error, match):
    imu, ranges, anchors, _, _, _ = short_nlos
    with pytest.raises(error, match=match):
        uwbimu_rs.compare(methods, imu, ranges, anchors, **kwargs)


def test_exported():
    assert {"compare", "Comparison", "MethodRun"} <= set(uwbimu_rs.__all__)


def test_truth_with_unit_suffixed_columns_scores_the_same(short_nlos):
    # The truth spellings of metrics.TRUTH_COLUMNS are accepted as by metrics.evaluate.
    imu, ranges, anchors, truth, config, initial = short_nlos
    plain = uwbimu_rs.compare(["ekf"], imu, ranges, anchors, truth=truth, config=config, initial=initial)
    renamed = truth.select("t", "x", "y", "z").rename({"t": "t_s", "x": "x_m", "y": "y_m", "z": "z_m"})
    suffixed = uwbimu_rs.compare(["ekf"], imu, ranges, anchors, truth=renamed, config=config, initial=initial)
    assert plain.table.drop("time_s").equals(suffixed.table.drop("time_s"))
