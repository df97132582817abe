"""Figures of a :class:`~uwbimu_rs.Comparison`: tracks, error over time, error CDF, NIS, range
biases and a one-page report.

Every function returns a ``matplotlib.figure.Figure`` (save it with ``fig.savefig("x.png")``).
matplotlib is the ``plot`` extra (``pip install uwbimu_rs[plot]``) and is imported on first use;
on a headless Linux machine with no backend chosen the non-interactive ``Agg`` backend is
selected, otherwise the user's backend is left alone. Each method keeps one colour in every panel
(matplotlib's ``C0``, ``C1``, … in the comparison's order); the truth is black.
"""

from __future__ import annotations

import os
import sys
from types import ModuleType
from typing import TYPE_CHECKING, Sequence

import numpy as np
import polars as pl

from uwbimu_rs import _native, metrics
from uwbimu_rs._compare import Comparison, MethodRun

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["biases", "error_cdf", "error_over_time", "nis", "report", "trajectories"]

CHI2_1DOF_95: float = _native.chi2_quantile(1, 0.05)
"""χ²₁ 95 % quantile, 3.841 (the NIS of one range exceeds it 5 % of the time in a consistent filter),
from the quantile function the robust tests use."""
CHI2_1DOF_99: float = _native.chi2_quantile(1, 0.01)
"""χ²₁ 99 % quantile, 6.635."""

INNOVATION_WINDOW = 20
"""Range updates per anchor in the running mean of :func:`biases` without bias states
(10 s at the presets' 2 Hz)."""


def _pyplot() -> ModuleType:
    """``matplotlib.pyplot``, imported now; ``Agg`` only when headless and no backend was chosen."""
    try:
        import matplotlib
    except ImportError as err:
        raise ImportError("uwbimu_rs.plot needs matplotlib: pip install uwbimu_rs[plot]") from err
    headless = sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    if headless and "matplotlib.pyplot" not in sys.modules:
        # The public `get_backend(auto_select=False)` needs matplotlib 3.10; this private call
        # answers the same question (None: nothing chosen by rc file, MPLBACKEND or use()) from 3.5 on.
        if matplotlib.rcParams._get_backend_or_none() is None:  # type: ignore[attr-defined]
            matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _colours(cmp: Comparison) -> dict[str, str]:
    """One matplotlib colour per method, by its position in the comparison."""
    return {method: f"C{i % 10}" for i, method in enumerate(cmp.runs)}


def _inertial(run: MethodRun) -> bool:
    """Whether the run has an attitude, i.e. is an IMU filter (``uwb_ls`` is not)."""
    return "qw" in run.frame.columns


def _scored(cmp: Comparison, what: str) -> dict[str, metrics.Evaluation]:
    """Each run's raw errors; ValueError when the comparison has no truth."""
    scored = {m: r.errors for m, r in cmp.runs.items() if r.errors is not None}
    if cmp.truth is None or not scored:
        raise ValueError(f"plot.{what}: the comparison has no truth; call compare(..., truth=...)")
    return scored


def _run(cmp: Comparison, method: str, what: str) -> MethodRun:
    """The run of ``method``; ValueError naming the methods compared."""
    if method not in cmp.runs:
        raise ValueError(f"plot.{what}: {method!r} is not in the comparison ({', '.join(cmp.runs)})")
    return cmp.runs[method]


def _legend_outside(ax: Axes) -> None:
    """The legend right of the axes, never on the data."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=9)


def _draw_tracks(ax: Axes, cmp: Comparison) -> None:
    colours = _colours(cmp)
    if cmp.truth is not None:
        ax.plot(cmp.truth["x"], cmp.truth["y"], color="black", lw=1.0, ls="--", label="truth", zorder=4)
    for method, run in cmp.runs.items():
        if _inertial(run):
            ax.plot(run.frame["x"], run.frame["y"], color=colours[method], lw=0.9, label=run.label, zorder=2)
        else:
            ax.plot(run.frame["x"], run.frame["y"], ".", ms=3, color=colours[method], label=run.label, zorder=2)
    ax.plot(cmp.anchors[:, 0], cmp.anchors[:, 1], "^", ms=9, color="crimson", mec="black", label="anchors", zorder=5)
    for k, (x, y) in enumerate(cmp.anchors[:, :2]):
        ax.annotate(f"A{k}", (x, y), xytext=(6, 6), textcoords="offset points", fontsize=9, weight="bold")
    ax.set_xlabel("east x [m]")
    ax.set_ylabel("north y [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)


def _sigma_h(run: MethodRun, t: pl.Series) -> np.ndarray:
    """Horizontal standard deviation ``sqrt(std_x² + std_y²)`` (m) of the run at the times ``t``."""
    joined = pl.DataFrame({"t": t}).join(run.frame.select("t", "std_x", "std_y"), on="t", how="left")
    return joined.select((pl.col("std_x") ** 2 + pl.col("std_y") ** 2).sqrt()).to_series().to_numpy()


def _draw_errors(axes: Sequence[Axes], cmp: Comparison) -> None:
    """One row per method (shared axes): its error and, for an inertial method, its 3σ band."""
    colours = _colours(cmp)
    scored = _scored(cmp, "error_over_time")
    for ax, (method, ev) in zip(axes, scored.items()):
        run, e = cmp.runs[method], ev.errors
        if _inertial(run):
            ax.fill_between(e["t"], 0.0, 3.0 * _sigma_h(run, e["t"]), color=colours[method], alpha=0.25, lw=0, label="3σ")
            ax.plot(e["t"], e["e_h"], color=colours[method], lw=0.9)
        else:
            ax.plot(e["t"], e["e_h"], ".", ms=3, color=colours[method])
        ax.set_ylim(bottom=0.0)
        ax.grid(alpha=0.3)
        ax.text(0.005, 0.93, f"{run.label}: RMSE {ev.horizontal.rmse:.2f} m", transform=ax.transAxes, va="top", fontsize=9, color=colours[method], weight="bold", bbox={"facecolor": "white", "alpha": 0.8, "lw": 0, "pad": 1.5})
        ax.label_outer()
    axes[-1].set_xlabel("time [s]")
    axes[len(axes) // 2].set_ylabel("horizontal error [m]")


def _draw_cdf(ax: Axes, cmp: Comparison) -> None:
    colours = _colours(cmp)
    for method, ev in _scored(cmp, "error_cdf").items():
        x, p = metrics.cdf(ev.errors["e_h"])
        ax.plot(x, p, color=colours[method], lw=1.5, label=cmp.runs[method].label)
        ax.plot([ev.horizontal.median, ev.horizontal.p95], [0.5, 0.95], "o", color=colours[method], mec="black", ms=6)
    for level, text in ((0.5, "median"), (0.95, "p95")):
        ax.axhline(level, color="grey", lw=0.8, ls=":")
        ax.annotate(text, (1.0, level), xycoords=("axes fraction", "data"), xytext=(-4, -12), textcoords="offset points", ha="right", fontsize=8, color="grey")
    ax.set_xscale("log")
    ax.set_xlabel("horizontal error [m] (log scale)")
    ax.set_ylabel("fraction of estimates ≤ error")
    ax.set_ylim(0.0, 1.0)
    ax.grid(alpha=0.3, which="both")


_TABLE_COLUMNS = (("h_rmse", "RMSE h"), ("h_p95", "p95 h"), ("h_max", "max h"), ("h_rmse_aligned", "RMSE h\naligned"), ("3d_rmse", "RMSE 3-D"), ("time_s", "time [s]"))
"""Table columns of :func:`report` and their headers (errors in m)."""


def _draw_table(ax: Axes, cmp: Comparison) -> None:
    colours = _colours(cmp)
    labels = [run.label for run in cmp.runs.values()]
    cells = [[f"{v:.3f}" for v in cmp.table[name]] for name, _ in _TABLE_COLUMNS]
    table = ax.table(
        cellText=[list(r) for r in zip(*cells)],
        rowLabels=labels,
        colLabels=[h for _, h in _TABLE_COLUMNS],
        rowColours=[colours[m] for m in cmp.runs],
        loc="upper center",
        cellLoc="right",
    )
    table.auto_set_font_size(False)
    table.set_fontsize(9)
    table.scale(1.0, 1.8)
    for (row, col), cell in table.get_celld().items():
        if col == -1 and row > 0:
            cell.get_text().set_color("white")
            cell.get_text().set_fontweight("bold")
    ax.set_axis_off()
    ax.set_title(f"Horizontal (h) and 3-D errors [m], from t₀ + {cmp.skip_s:g} s", fontsize=10)
    ax.text(
        0.0,
        0.47,
        "aligned: after the least-squares rigid rotation + translation of the track onto the truth\n"
        "(what remains is shape error, not a frame offset); time: wall-clock of the run",
        transform=ax.transAxes,
        fontsize=8.5,
        color="dimgrey",
        va="top",
    )


def _kind(cmp: Comparison) -> str:
    """``causal``, ``smoothed`` or ``mixed``: what the compared rows are, for titles."""
    flags = {run.smoothed for run in cmp.runs.values()}
    return "mixed: smoothed where labelled" if len(flags) > 1 else ("RTS-smoothed" if flags == {True} else "causal")


def trajectories(cmp: Comparison) -> Figure:
    """Horizontal tracks of every method over the anchors and the truth.

    Parameters
    ----------
    cmp : Comparison
        From :func:`uwbimu_rs.compare` (the truth is drawn if it has one).

    Returns
    -------
    matplotlib.figure.Figure
        One axes: x-y (m, equal aspect) of each method (inertial methods as lines, ``uwb_ls`` fixes
        as dots), the truth (thick grey-black), the anchors (triangles labelled ``A0``, ``A1``, …);
        the legend is right of the axes.
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8.5, 6.0))
    _draw_tracks(ax, cmp)
    ax.set_title(f"Horizontal tracks ({_kind(cmp)})")
    _legend_outside(ax)
    fig.tight_layout()
    return fig


def error_over_time(cmp: Comparison) -> Figure:
    """Horizontal error of each method against time, with each inertial method's 3σ band.

    Parameters
    ----------
    cmp : Comparison
        With truth.

    Returns
    -------
    matplotlib.figure.Figure
        One axes per method (shared time and error axes, labelled with the method and its RMSE):
        ``e_h`` (m) against t (s) from ``skip_s`` on, and shaded from 0 up to
        ``3·sqrt(std_x² + std_y²)`` (the filter's own 3σ horizontal bound, m) for each method with
        an attitude; a consistent filter keeps its error inside its band nearly always.

    Raises
    ------
    ValueError
        The comparison has no truth.
    """
    plt = _pyplot()
    n = len(_scored(cmp, "error_over_time"))
    fig, axes = plt.subplots(n, 1, figsize=(10.0, 1.2 + 1.6 * n), sharex=True, sharey=True, squeeze=False)
    _draw_errors(list(axes[:, 0]), cmp)
    axes[0, 0].set_title(f"Horizontal error over time ({_kind(cmp)}); shaded: the filter's own 3σ")
    fig.tight_layout()
    return fig


def error_cdf(cmp: Comparison) -> Figure:
    """Empirical CDF of the horizontal error of each method, median and p95 marked.

    Parameters
    ----------
    cmp : Comparison
        With truth.

    Returns
    -------
    matplotlib.figure.Figure
        One axes: :func:`uwbimu_rs.metrics.cdf` of ``e_h`` (m, log x axis), with dots at each
        method's median (0.5) and 95th percentile (0.95); further left and steeper is better.

    Raises
    ------
    ValueError
        The comparison has no truth.
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8.0, 4.5))
    _draw_cdf(ax, cmp)
    ax.set_title(f"CDF of the horizontal error ({_kind(cmp)})")
    _legend_outside(ax)
    fig.tight_layout()
    return fig


def _updates(source: Comparison | pl.DataFrame, method: str | None, what: str) -> tuple[pl.DataFrame, str]:
    """The range rows of an updates frame and a label for titles."""
    if isinstance(source, pl.DataFrame):
        frame, label = source, method or "updates"
    else:
        if method is None:
            raise ValueError(f"plot.{what}: name the method to plot ({', '.join(source.runs)})")
        run = _run(source, method, what)
        if run.updates is None:
            raise ValueError(f"plot.{what}: {method!r} has no range updates (a UWB-only solver)")
        frame, label = run.updates, method
    ranges = frame.filter(pl.col("sensor") == "range")
    if ranges.height == 0:
        raise ValueError(f"plot.{what}: no range updates in the frame")
    return ranges, label


def nis(source: Comparison | pl.DataFrame, method: str | None = None) -> Figure:
    """NIS of each range update against time, per anchor, with the χ²₁ 95 % and 99 % lines.

    Parameters
    ----------
    source : Comparison or polars.DataFrame
        A comparison (then name ``method``) or an updates frame of ``run_filter(..., updates=True)``.
    method : str, optional
        The method of the comparison to plot (with a frame: only its title label).

    Returns
    -------
    matplotlib.figure.Figure
        Two axes sharing time (s). Top: the ``nis`` column (γ, the squared Mahalanobis distance of
        the innovation, dimensionless, log scale) per anchor, down-weighted updates ringed black,
        rejected ones as ×, and the χ²₁ 95 % / 99 % quantiles (3.841, 6.635) dashed: a consistent
        filter with Gaussian ranges has mean NIS ≈ 1 and 5 % of points above the 95 % line.
        Bottom: each update's weight ``R / R_used`` (1 = full, down-weighting by the robust policy
        below 1). The updates are always the forward pass's, also for a smoothed run.
    """
    plt = _pyplot()
    ranges, label = _updates(source, method, "nis")
    fig, (ax, axw) = plt.subplots(2, 1, figsize=(10.0, 6.0), sharex=True, height_ratios=(2.2, 1.0))
    for k in sorted(ranges["anchor"].unique()):
        a = ranges.filter(pl.col("anchor") == k)
        ax.scatter(a["t"], a["nis"].clip(lower_bound=1e-6), s=6, color=f"C{k % 10}", label=f"A{k}", zorder=2)
        axw.scatter(a["t"], a["weight"], s=6, color=f"C{k % 10}", zorder=2)
    down = ranges.filter(pl.col("down_weighted"))
    ax.scatter(down["t"], down["nis"], s=28, facecolors="none", edgecolors="black", lw=0.6, label="down-weighted", zorder=3)
    rejected = ranges.filter(~pl.col("accepted"))
    if rejected.height:
        ax.scatter(rejected["t"], rejected["nis"].clip(lower_bound=1e-6), s=30, marker="x", color="black", label="rejected", zorder=3)
    ax.axhline(CHI2_1DOF_95, color="dimgrey", ls="--", lw=1.0, label=f"χ²₁ 95 % ({CHI2_1DOF_95:.2f})")
    ax.axhline(CHI2_1DOF_99, color="black", ls="--", lw=1.0, label=f"χ²₁ 99 % ({CHI2_1DOF_99:.2f})")
    ax.set_yscale("log")
    ax.set_ylabel("NIS γ (dimensionless)")
    nis_values = ranges["nis"].to_numpy()
    above = 100.0 * float(np.mean(nis_values > CHI2_1DOF_95))
    ax.set_title(f"Range NIS per anchor, {label} (forward pass): mean {np.mean(nis_values):.2f}, {above:.0f} % above the χ²₁ 95 % line")
    ax.grid(alpha=0.3)
    _legend_outside(ax)
    axw.set_ylabel("weight R / R_used")
    axw.set_xlabel("time [s]")
    axw.set_ylim(-0.05, 1.05)
    axw.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def biases(source: Comparison | pl.DataFrame, method: str | None = None) -> Figure:
    """Per-anchor range bias: the filter's estimate if it has bias states, else the innovations.

    ``run_filter`` frames carry no IMU bias columns, so this shows the UWB side: with
    ``range_bias.states`` the updates frame's ``bias`` ± ``bias_std`` per anchor (m); without, each
    anchor's range innovation ``z − h(x)`` (m, dots) and its running mean over
    :data:`INNOVATION_WINDOW` updates (line): a mean that leaves zero and stays there marks an
    anchor whose ranges are biased (NLOS makes them longer, so positive).

    Parameters
    ----------
    source : Comparison or polars.DataFrame
        A comparison (then name ``method``) or an updates frame of ``run_filter(..., updates=True)``.
    method : str, optional
        The method of the comparison to plot (with a frame: only its title label).

    Returns
    -------
    matplotlib.figure.Figure
        One axes: bias or innovation (m) against time (s), one colour per anchor.
    """
    plt = _pyplot()
    ranges, label = _updates(source, method, "biases")
    fig, ax = plt.subplots(figsize=(10.0, 4.5))
    estimated = ranges["bias"].is_not_nan().any()
    for k in sorted(ranges["anchor"].unique()):
        a = ranges.filter(pl.col("anchor") == k)
        colour = f"C{k % 10}"
        if estimated:
            ax.fill_between(a["t"], a["bias"] - a["bias_std"], a["bias"] + a["bias_std"], color=colour, alpha=0.2, lw=0)
            ax.plot(a["t"], a["bias"], color=colour, lw=1.2, label=f"A{k}")
        else:
            ax.plot(a["t"], a["innovation"], ".", ms=2, color=colour, alpha=0.35)
            ax.plot(a["t"], a["innovation"].rolling_mean(INNOVATION_WINDOW, min_samples=1), color=colour, lw=1.4, label=f"A{k}")
    ax.axhline(0.0, color="black", lw=0.8)
    if estimated:
        ax.set_ylabel("range bias estimate ± 1σ [m]")
        ax.set_title(f"Per-anchor range bias estimate, {label} (range_bias.states, forward pass)")
    else:
        ax.set_ylabel("range innovation z − h(x) [m]")
        ax.set_title(f"Per-anchor range innovation, {label}: dots each update, line mean of {INNOVATION_WINDOW}")
    ax.set_xlabel("time [s]")
    ax.grid(alpha=0.3)
    _legend_outside(ax)
    fig.tight_layout()
    return fig


def report(cmp: Comparison) -> Figure:
    """A one-page look at a comparison: tracks, error over time, error CDF and a metrics table.

    Parameters
    ----------
    cmp : Comparison
        With truth.

    Returns
    -------
    matplotlib.figure.Figure
        Four axes (the panels of :func:`trajectories`, :func:`error_over_time`, :func:`error_cdf`
        and a table of horizontal RMSE / p95 / max, aligned RMSE, 3-D RMSE in m and run time in s),
        one legend for all at the top.

    Raises
    ------
    ValueError
        The comparison has no truth.
    """
    _scored(cmp, "report")
    plt = _pyplot()
    n = len(cmp.runs)
    fig = plt.figure(figsize=(14.0, 9.5), layout="constrained")
    grid = fig.add_gridspec(2, 2, width_ratios=(1.0, 1.25))
    tracks, cdf, table = fig.add_subplot(grid[0, 0]), fig.add_subplot(grid[1, 0]), fig.add_subplot(grid[1, 1])
    rows = grid[0, 1].subgridspec(n, 1, hspace=0.0)
    first = fig.add_subplot(rows[0])
    errors = [first, *(fig.add_subplot(rows[i], sharex=first, sharey=first) for i in range(1, n))]
    _draw_tracks(tracks, cmp)
    tracks.set_title("Horizontal tracks")
    _draw_errors(errors, cmp)
    first.set_title("Horizontal error over time (shaded: the filter's own 3σ)")
    _draw_cdf(cdf, cmp)
    cdf.set_title("CDF of the horizontal error (dots: median, p95)")
    _draw_table(table, cmp)
    handles, labels = tracks.get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=len(labels), fontsize=10)
    fig.suptitle(f"{n} methods compared ({_kind(cmp)})", fontsize=13)
    return fig
