"""Side-by-side runs of several methods on one recording: :func:`compare` and its :class:`Comparison`."""

from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np
import polars as pl

from uwbimu_rs import metrics
from uwbimu_rs._batch import run_frames
from uwbimu_rs._native import METHODS, ConfigError, FilterConfig
from uwbimu_rs._typing import MethodName

__all__ = ["Comparison", "MethodRun", "compare"]

SELF_INIT_SKIP_S = 10.0
"""Default ``skip_s`` of a self-initialised comparison, s: the time after which every method's
error has settled on the simulated presets (``docs/compare-and-plot.md`` gives the measurement)."""

_STATS = ("rmse", "mean", "median", "p95", "max")
"""The :class:`~uwbimu_rs.metrics.ErrorStats` fields the table reports."""


@dataclass(frozen=True)
class MethodRun:
    """One method's run inside a :class:`Comparison`.

    Attributes
    ----------
    method : str
        The method name (a key of ``uwbimu_rs.METHODS``).
    smoothed : bool
        Whether ``frame`` holds RTS-smoothed estimates (not causal).
    label : str
        ``method``, or ``"<method> (smoothed)"``: the name plots and tables show.
    frame : polars.DataFrame
        The :func:`~uwbimu_rs.run_filter` trajectory frame (all rows, ``skip_s`` included).
    updates : polars.DataFrame or None
        Its per-update frame (``run_filter(..., updates=True)``, always the forward pass); None for
        a method without filter updates (``uwb_ls``).
    time_s : float
        Wall-clock time of the ``run_filter`` call, s.
    errors : metrics.Evaluation or None
        Errors against the truth from ``skip_s`` on; None without truth.
    errors_aligned : metrics.Evaluation or None
        The same after the least-squares rigid alignment onto the truth (``align=True``).
    """

    method: str
    smoothed: bool
    label: str
    frame: pl.DataFrame
    updates: pl.DataFrame | None
    time_s: float
    errors: metrics.Evaluation | None
    errors_aligned: metrics.Evaluation | None


@dataclass(frozen=True)
class Comparison:
    """Result of :func:`compare`.

    Attributes
    ----------
    table : polars.DataFrame
        One row per method, in the order given; columns in ``docs/compare-and-plot.md``:
        ``method, smoothed, time_s, rows, nis_mean, accepted, down_weighted`` and, with truth,
        ``n_errors`` and ``{h,3d}_{rmse,mean,median,p95,max}[_aligned]`` (m).
    runs : dict of str to MethodRun
        Per method (same keys and order as the table), the frames kept for plotting.
    truth : polars.DataFrame or None
        ``t, x, y, z`` (s, m) of the truth, or None.
    anchors : numpy.ndarray, shape (K, 3)
        Anchor positions, m.
    skip_s : float
        Seconds after the first IMU sample left out of the errors.
    """

    table: pl.DataFrame
    runs: dict[str, MethodRun]
    truth: pl.DataFrame | None
    anchors: np.ndarray
    skip_s: float

    def __str__(self) -> str:
        """The table transposed to fit a terminal: one line per column, one column per method
        (headed by its label, e.g. ``best (smoothed)``); numbers to 3 decimals, missing as ``–``."""
        labels = [run.label for run in self.runs.values()]
        names = [c for c in self.table.columns if c not in ("method", "smoothed")]
        lines = [[name, *(_cell(v) for v in self.table[name])] for name in names]
        widths = [max(len(x) for x in col) for col in zip(["", *labels], *lines)]
        rows = [["", *labels], *lines]
        return "\n".join("  ".join(x.rjust(w) if i else x.ljust(w) for i, (x, w) in enumerate(zip(r, widths))) for r in rows)

    def __repr__(self) -> str:
        return f"Comparison(skip_s={self.skip_s:g}, truth={'yes' if self.truth is not None else 'no'})\n{self}"


def _cell(value: Any) -> str:
    """A table value as printed by :meth:`Comparison.__str__`."""
    if value is None:
        return "–"
    return f"{value:.3f}" if isinstance(value, float) else str(value)


def _truth_frame(truth: pl.DataFrame | np.ndarray) -> pl.DataFrame:
    """``truth`` as a frame of ``t, x, y, z`` (float64), read and checked as
    :func:`~uwbimu_rs.metrics.evaluate` reads it (either spelling of :data:`~uwbimu_rs.metrics.TRUTH_COLUMNS`)."""
    t, xyz = metrics._txyz(truth, "truth")
    return pl.DataFrame({"t": t, "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2]})


def _check_methods(methods: Sequence[str]) -> list[MethodName]:
    """The method list, checked: not empty, no repeats, every name in the registry."""
    if isinstance(methods, str):
        raise ValueError(f"methods: expected a list of names, got the string {methods!r}")
    chosen = list(methods)
    if not chosen:
        raise ValueError("methods: empty; give at least one of " + ", ".join(METHODS))
    unknown = [m for m in chosen if m not in METHODS]
    if unknown:
        raise ConfigError(f"unknown method(s) {unknown}; expected one of " + ", ".join(METHODS))
    repeated = sorted({m for m in chosen if chosen.count(m) > 1})
    if repeated:
        raise ValueError(f"methods: {repeated} given more than once")
    return chosen  # type: ignore[return-value]  # checked against the registry above


def _one_run(
    method: MethodName,
    smooth: bool,
    imu: np.ndarray,
    ranges: np.ndarray,
    anchors: np.ndarray,
    truth: pl.DataFrame | None,
    initial: Mapping[str, Any] | None,
    config: FilterConfig | Mapping[str, Any] | None,
    skip_s: float,
) -> MethodRun:
    """Runs and scores one method (called in a worker thread; ``run_filter`` releases the GIL)."""
    smoothed = smooth and METHODS[method]["smoothing"] != "never"
    start = time.perf_counter()
    frame, updates, _info = run_frames(method, imu, ranges, anchors, initial=initial, config=config, updates=True, smooth=smoothed)
    elapsed = time.perf_counter() - start
    errors = aligned = None
    if truth is not None:
        scored = frame.filter(pl.col("t") >= float(imu[0, 0]) + skip_s)
        errors = metrics.evaluate(scored, truth)
        aligned = metrics.evaluate(scored, truth, align=True)
    label = f"{method} (smoothed)" if smoothed else method
    return MethodRun(method, smoothed, label, frame, updates, elapsed, errors, aligned)


def _row(run: MethodRun) -> dict[str, Any]:
    """The table row of one run."""
    row: dict[str, Any] = {"method": run.method, "smoothed": run.smoothed, "time_s": run.time_s, "rows": run.frame.height}
    ranges = pl.DataFrame() if run.updates is None else run.updates.filter(pl.col("sensor") == "range")
    for name, column in (("nis_mean", "nis"), ("accepted", "accepted"), ("down_weighted", "down_weighted")):
        row[name] = ranges[column].mean() if ranges.height else None
    for prefix, errors in (("", run.errors), ("_aligned", run.errors_aligned)):
        if errors is None:
            continue
        row["n_errors"] = errors.horizontal.n
        for axis, stats in (("h", errors.horizontal), ("3d", errors.three_d)):
            for name in _STATS:
                row[f"{axis}_{name}{prefix}"] = getattr(stats, name)
    return row


def _table(runs: Sequence[MethodRun]) -> pl.DataFrame:
    """One row per run; error columns grouped raw then aligned, horizontal then 3-D."""
    table = pl.DataFrame([_row(r) for r in runs], infer_schema_length=None).with_columns(
        pl.col("nis_mean", "accepted", "down_weighted").cast(pl.Float64)
    )
    if "n_errors" not in table.columns:
        return table
    errors = [f"{axis}_{name}{suffix}" for suffix in ("", "_aligned") for axis in ("h", "3d") for name in _STATS]
    head = ["method", "smoothed", "time_s", "rows", "nis_mean", "accepted", "down_weighted", "n_errors"]
    return table.select(*head, *errors)


def compare(
    methods: Sequence[MethodName],
    imu: np.ndarray,
    ranges: np.ndarray,
    anchors: np.ndarray,
    *,
    truth: pl.DataFrame | np.ndarray | None = None,
    initial: Mapping[str, Any] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    smooth: bool = False,
    skip_s: float | None = None,
    max_workers: int | None = None,
) -> Comparison:
    """Run several methods on one recording, in parallel, and tabulate their accuracy.

    Each method runs through :func:`~uwbimu_rs.run_filter` in a worker thread (the GIL is released
    while Rust runs, so the threads use all cores) and, given the truth, is scored with
    :func:`~uwbimu_rs.metrics.evaluate`, raw and with ``align=True``.

    Parameters
    ----------
    methods : sequence of str
        Names of ``uwbimu_rs.METHODS``, each at most once; the table keeps this order.
    imu : numpy.ndarray, shape (N, 7)
        ``t`` (s), specific force (m/s²), angular rate (rad/s), as for :func:`~uwbimu_rs.run_filter`.
    ranges : numpy.ndarray, shape (M, 3)
        ``t`` (s), anchor index, range (m).
    anchors : numpy.ndarray, shape (K, 3)
        Anchor positions, navigation frame, m.
    truth : polars.DataFrame or numpy.ndarray of shape (T, >=4), optional
        Columns ``t`` (s, strictly increasing), ``x, y, z`` (m) (``sim.SimResult.truth``). Without it
        the table has no error columns.
    initial : dict, optional
        Initial state shared by every method (as for :func:`~uwbimu_rs.run_filter`); None: each
        method initialises itself.
    config : FilterConfig or dict, optional
        Configuration shared by every method.
    smooth : bool, default False
        False: every row is the causal (forward) filter, ``best`` included (``run_filter`` would
        smooth it by default). True: every method whose ``METHODS[name]["smoothing"]`` is not
        ``"never"`` is RTS-smoothed; the ``smoothed`` column says which rows are.
    skip_s : float, optional
        Errors are computed from ``imu[0, 0] + skip_s`` on, s. Default: 0 with ``initial``, else
        :data:`SELF_INIT_SKIP_S` (10 s), to leave out the self-initialisation transient.
    max_workers : int, optional
        Worker threads; default ``os.cpu_count()``; 1 runs the methods one after the other.

    Returns
    -------
    Comparison
        ``table`` (one row per method) with columns:

        - ``method`` (str), ``smoothed`` (bool), ``time_s`` (wall-clock of ``run_filter``, s),
          ``rows`` (rows of the trajectory frame);
        - ``nis_mean``: mean NIS (γ) of the range updates; ``accepted``, ``down_weighted``: fraction
          of range updates accepted and down-weighted (null for ``uwb_ls``);
        - with truth: ``n_errors`` (estimates scored) and ``h_<stat>``, ``3d_<stat>``,
          ``h_<stat>_aligned``, ``3d_<stat>_aligned`` for ``<stat>`` in ``rmse, mean, median,
          p95, max`` (m): horizontal and 3-D error, raw and after the rigid alignment.

    Raises
    ------
    ValueError
        Empty ``methods``, a name given twice, a bad ``truth``, a negative ``skip_s``, or any error
        of :func:`~uwbimu_rs.run_filter` / :func:`~uwbimu_rs.metrics.evaluate`.
    ConfigError
        An unknown method (the message lists the names; a ``ValueError``).
    """
    chosen = _check_methods(methods)
    skip = (0.0 if initial is not None else SELF_INIT_SKIP_S) if skip_s is None else float(skip_s)
    if not skip >= 0.0:
        raise ValueError(f"skip_s: expected a non-negative number of seconds, got {skip_s}")
    truth_frame = None if truth is None else _truth_frame(truth)
    workers = (os.cpu_count() or 1) if max_workers is None else max_workers
    with ThreadPoolExecutor(max_workers=workers) as pool:
        futures = [
            pool.submit(_one_run, m, smooth, imu, ranges, anchors, truth_frame, initial, config, skip) for m in chosen
        ]
        runs = [f.result() for f in futures]
    return Comparison(
        table=_table(runs),
        runs={r.method: r for r in runs},
        truth=truth_frame,
        anchors=np.asarray(anchors, dtype=np.float64),
        skip_s=skip,
    )
