"""uwbimu_rs.plot: every function returns a Figure with the expected panels and lines and saves
to PNG under Agg; the errors for what a comparison cannot show."""

from __future__ import annotations

import sys

import matplotlib
import polars as pl
import pytest

matplotlib.use("Agg")

from matplotlib.figure import Figure  # noqa: E402  (after choosing the backend)

import uwbimu_rs  # noqa: E402
from uwbimu_rs import plot, sim  # noqa: E402

METHODS = ["uwb_ls", "ekf", "best"]


@pytest.fixture(scope="module")
def data():
    """The first 30 s of the NLOS preset: imu, ranges, anchors, truth, config."""
    run = sim.preset("hall_vehicle_nlos", seed=0)
    keep = 30.0
    return run.imu[run.imu[:, 0] < keep], run.ranges[run.ranges[:, 0] < keep], run.anchors, run.truth.filter(pl.col("t") < keep), run.config


@pytest.fixture(scope="module")
def cmp(data):
    imu, ranges, anchors, truth, config = data
    return uwbimu_rs.compare(METHODS, imu, ranges, anchors, truth=truth, config=config)


@pytest.fixture(autouse=True)
def close_figures():
    yield
    import matplotlib.pyplot as plt

    plt.close("all")


def saved(fig: Figure, tmp_path, name: str) -> Figure:
    path = tmp_path / f"{name}.png"
    fig.savefig(path, dpi=50)
    assert path.stat().st_size > 1000
    return fig


def test_trajectories(cmp, tmp_path):
    fig = saved(plot.trajectories(cmp), tmp_path, "tracks")
    (ax,) = fig.axes
    assert len(ax.lines) == len(METHODS) + 2  # methods, truth, anchors
    assert [t.get_text() for t in ax.texts] == ["A0", "A1", "A2", "A3"]
    assert ax.get_legend() is not None and ax.get_legend().get_bbox_to_anchor().x0 > ax.get_window_extent().x1 - 1
    assert ax.get_aspect() == 1.0 and "causal" in ax.get_title()


def test_error_over_time(cmp, tmp_path):
    fig = saved(plot.error_over_time(cmp), tmp_path, "errors")
    assert len(fig.axes) == len(METHODS)
    for ax, label in zip(fig.axes, METHODS):
        assert len(ax.lines) == 1 and ax.texts[0].get_text().startswith(label)
        assert len(ax.collections) == (0 if label == "uwb_ls" else 1)  # the 3σ band of inertial methods


def test_error_cdf(cmp, tmp_path):
    fig = saved(plot.error_cdf(cmp), tmp_path, "cdf")
    (ax,) = fig.axes
    assert len(ax.lines) == 2 * len(METHODS) + 2  # curve and median/p95 dots per method, two levels
    x, p = ax.lines[0].get_data()
    assert p[-1] == 1.0 and x[0] <= x[-1]


def test_nis(cmp, tmp_path):
    fig = saved(plot.nis(cmp, "best"), tmp_path, "nis")
    top, bottom = fig.axes
    assert [line.get_ydata()[0] for line in top.lines] == [plot.CHI2_1DOF_95, plot.CHI2_1DOF_99]
    assert len(top.collections) >= 4 + 1 and len(bottom.collections) == 4  # anchors, down-weighted
    assert "best" in top.get_title() and top.get_yscale() == "log"
    assert len(plot.nis(cmp.runs["ekf"].updates, "ekf").axes) == 2  # from a frame


def test_biases_innovation_and_states(data, cmp, tmp_path):
    fig = saved(plot.biases(cmp, "ekf"), tmp_path, "innovation")
    (ax,) = fig.axes
    assert len(ax.lines) == 2 * 4 + 1 and "innovation" in ax.get_ylabel()
    imu, ranges, anchors, truth, config = data
    with_states = uwbimu_rs.compare(["ekf"], imu, ranges, anchors, truth=truth, config={**config, "range_bias.states": True})
    (ax,) = saved(plot.biases(with_states, "ekf"), tmp_path, "bias").axes
    assert len(ax.lines) == 4 + 1 and len(ax.collections) == 4 and "bias estimate" in ax.get_ylabel()


def test_report(cmp, tmp_path):
    fig = saved(plot.report(cmp), tmp_path, "report")
    assert len(fig.axes) == 3 + len(METHODS)  # tracks, CDF, table, one error row per method
    assert len(fig.legends) == 1 and "causal" in fig.get_suptitle()


def test_smoothed_label_in_titles(data, tmp_path):
    imu, ranges, anchors, truth, config = data
    cmp = uwbimu_rs.compare(["uwb_ls", "best"], imu, ranges, anchors, truth=truth, config=config, smooth=True)
    fig = saved(plot.error_over_time(cmp), tmp_path, "smoothed")
    assert fig.axes[1].texts[0].get_text().startswith("best (smoothed)")
    assert "smoothed where labelled" in fig.axes[0].get_title()


def test_what_a_comparison_cannot_show(data, cmp):
    imu, ranges, anchors, _, config = data
    truthless = uwbimu_rs.compare(["ekf"], imu, ranges, anchors, config=config)
    for fn in (plot.error_over_time, plot.error_cdf, plot.report):
        with pytest.raises(ValueError, match="no truth"):
            fn(truthless)
    assert len(plot.trajectories(truthless).axes[0].lines) == 2  # ekf, anchors
    with pytest.raises(ValueError, match="no range updates"):
        plot.nis(cmp, "uwb_ls")
    with pytest.raises(ValueError, match="not in the comparison"):
        plot.biases(cmp, "riekf")
    with pytest.raises(ValueError, match="name the method"):
        plot.nis(cmp)


def test_missing_matplotlib_names_the_extra(monkeypatch, cmp):
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    with pytest.raises(ImportError, match=r"pip install uwbimu_rs\[plot\]"):
        plot.trajectories(cmp)


def test_the_chi2_lines_are_the_quantiles_of_the_robust_tests():
    # One degree of freedom: Φ⁻¹(1 − α/2)²; the native inverse normal measured within 2.3e-9
    # relative of these values.
    assert abs(plot.CHI2_1DOF_95 / 3.841458820694124 - 1.0) < 1e-8
    assert abs(plot.CHI2_1DOF_99 / 6.634896601021214 - 1.0) < 1e-8
