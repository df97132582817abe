"""Accuracy metrics against ground truth (thin wrappers over the Rust core).

Positions are navigation-frame (ENU) metres, times seconds. All computation happens in
``uwbimu_rs._native``; this module only converts tables and wraps results.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Union

import numpy as np
import polars as pl

from uwbimu_rs import _native

__all__ = ["TRUTH_COLUMNS", "Alignment", "ErrorStats", "Evaluation", "cdf", "evaluate", "nees", "read_truth"]

Trajectory = Union[pl.DataFrame, np.ndarray]
"""A polars DataFrame with columns ``t, x, y, z`` (s, m; or ``t_s, x_m, y_m, z_m``, see
:data:`TRUTH_COLUMNS`), or an array whose first 4 columns are ``t, x, y, z``."""

TRUTH_COLUMNS: list[list[str]] = _native.TRUTH_COLUMNS
"""The accepted names of the time (s) and position (m) columns, one list of spellings per column
(``[["t", "t_s"], ["x", "x_m"], ["y", "y_m"], ["z", "z_m"]]``), declared once in Rust: ground-truth
CSV headers (CLI ``--ground-truth``, ``replay(ground_truth=...)``, :func:`read_truth`) and the
DataFrames :func:`evaluate` and :func:`nees` take."""

_COV_COLUMNS = ("cov_xx", "cov_xy", "cov_xz", "cov_yy", "cov_yz", "cov_zz")


@dataclass(frozen=True)
class ErrorStats:
    """Summary of error magnitudes.

    Attributes
    ----------
    n : int
        Number of errors.
    rmse, mean, median, p90, p95, max : float
        Root mean square, mean, median, 90th and 95th percentiles (linear interpolation, as
        ``numpy.percentile``) and maximum, m.
    """

    n: int
    rmse: float
    mean: float
    median: float
    p90: float
    p95: float
    max: float


@dataclass(frozen=True)
class Alignment:
    """Rigid transform ``x_truth = rotation @ x_est + translation`` (no scale).

    Attributes
    ----------
    rotation : numpy.ndarray, shape (3, 3)
        Rotation estimate frame -> truth frame (determinant +1).
    translation : numpy.ndarray, shape (3,)
        Translation, m.
    """

    rotation: np.ndarray
    translation: np.ndarray


@dataclass(frozen=True)
class Evaluation:
    """Result of :func:`evaluate`.

    Attributes
    ----------
    horizontal : ErrorStats
        Statistics of the horizontal (x-y) errors, m.
    three_d : ErrorStats
        Statistics of the 3-D errors, m.
    errors : polars.DataFrame
        One row per estimate inside the truth time span: ``t`` (s), ``e_h`` and ``e_3d`` (m).
    alignment : Alignment or None
        The estimate -> truth alignment applied before computing errors (``align=True``).
    """

    horizontal: ErrorStats
    three_d: ErrorStats
    errors: pl.DataFrame
    alignment: Alignment | None


def _txyz(data: Trajectory, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Split a trajectory into times ``(N,)`` and positions ``(N, 3)`` as float64."""
    if isinstance(data, pl.DataFrame):
        found = [next((c for c in names if c in data.columns), None) for names in TRUTH_COLUMNS]
        missing = [" or ".join(names) for names, c in zip(TRUTH_COLUMNS, found) if c is None]
        if missing:
            expected = ", ".join(" or ".join(names) for names in TRUTH_COLUMNS)
            raise ValueError(f"{name}: missing columns {missing}; expected {expected}")
        arr = data.select(found).to_numpy().astype(np.float64, copy=False)
    else:
        arr = np.asarray(data, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] < 4:
            raise ValueError(f"{name}: expected shape (N, >=4) with columns t, x, y, z, got {arr.shape}")
    return np.ascontiguousarray(arr[:, 0]), np.ascontiguousarray(arr[:, 1:4])


def _stats(d: dict) -> ErrorStats:
    return ErrorStats(**d)


def evaluate(estimate: Trajectory, truth: Trajectory, *, align: bool = False) -> Evaluation:
    """Compare an estimated trajectory with the truth.

    The truth is linearly interpolated at each estimate time; estimates outside the truth time
    span are skipped. Repeated truth times (a truth taken at the UWB times, one row per range)
    count as one sample at the mean of their positions.

    Parameters
    ----------
    estimate : polars.DataFrame or numpy.ndarray, shape (N, >=4)
        Columns ``t`` (s), ``x, y, z`` (m).
    truth : polars.DataFrame or numpy.ndarray, shape (M, >=4)
        Columns ``t`` (s, non-decreasing; repeated times are averaged), ``x, y, z`` (m).
    align : bool, default False
        First map the estimate through the least-squares rigid transform (rotation +
        translation, no scale) onto the truth.

    Returns
    -------
    Evaluation

    Raises
    ------
    ValueError
        Bad shapes or columns, non-finite values, a truth time that decreases (sort the truth
        by time), or no estimate inside the truth span (``uwbimu_rs.UwbImuError`` is a
        ``ValueError``).
    """
    est_t, est_xyz = _txyz(estimate, "estimate")
    truth_t, truth_xyz = _txyz(truth, "truth")
    out = _native.evaluate(est_t, est_xyz, truth_t, truth_xyz, align)
    alignment = None
    if out["rotation"] is not None:
        alignment = Alignment(rotation=out["rotation"], translation=out["translation"])
    return Evaluation(
        horizontal=_stats(out["horizontal"]),
        three_d=_stats(out["three_d"]),
        errors=pl.DataFrame(out["errors"]),
        alignment=alignment,
    )


def nees(estimate: pl.DataFrame, truth: Trajectory) -> pl.DataFrame:
    """Normalised estimation error squared of the position, ``e^T P^-1 e``.

    Parameters
    ----------
    estimate : polars.DataFrame
        Columns ``t`` (s), ``x, y, z`` (m) and the position covariance ``cov_xx, cov_xy,
        cov_xz, cov_yy, cov_yz, cov_zz`` (m^2).
    truth : polars.DataFrame or numpy.ndarray, shape (M, >=4)
        Columns ``t`` (s, non-decreasing; repeated times are averaged), ``x, y, z`` (m);
        interpolated linearly.

    Returns
    -------
    polars.DataFrame
        Columns ``t`` (s) and ``nees`` (dimensionless, chi-square with 3 degrees of freedom for
        a consistent filter), one row per estimate inside the truth time span.

    Raises
    ------
    ValueError
        Missing columns (named in the message), bad shapes, or non-finite values.
    uwbimu_rs.NumericalError
        A covariance that is not positive definite.
    """
    if not isinstance(estimate, pl.DataFrame):
        raise ValueError("estimate: expected a polars DataFrame with t, x, y, z and cov_* columns")
    missing = [c for c in ("t", "x", "y", "z", *_COV_COLUMNS) if c not in estimate.columns]
    if missing:
        raise ValueError(f"estimate: missing columns {missing}")
    est_t, est_xyz = _txyz(estimate, "estimate")
    truth_t, truth_xyz = _txyz(truth, "truth")
    truth_at = _native.interpolate_positions(truth_t, truth_xyz, est_t)
    inside = ~np.isnan(truth_at[:, 0])
    cov = estimate.select(*_COV_COLUMNS).to_numpy().astype(np.float64, copy=False)[inside]
    values = _native.nees(np.ascontiguousarray(est_xyz[inside] - truth_at[inside]), np.ascontiguousarray(cov))
    return pl.DataFrame({"t": est_t[inside], "nees": values})


def read_truth(path: str | os.PathLike[str]) -> pl.DataFrame:
    """Read a ground-truth CSV file (the reader of the CLI's ``--ground-truth``).

    Parameters
    ----------
    path : str or path
        CSV with a header row naming the columns as in :data:`TRUTH_COLUMNS` (``t,x,y,z`` or
        ``t_s,x_m,y_m,z_m``, any order, further columns ignored), or without a header and
        ``t, x, y, z`` first.

    Returns
    -------
    polars.DataFrame
        Columns ``t`` (s, sorted; repeated times kept, which :func:`evaluate` averages),
        ``x, y, z`` (m).

    Raises
    ------
    FileNotFoundError
        No such file.
    OSError
        Unreadable, or not a truth table (``uwbimu_rs.FormatError`` naming the file and line).
    """
    return pl.DataFrame(_native.read_truth(os.fspath(path)))


def cdf(errors: np.ndarray | pl.Series) -> tuple[np.ndarray, np.ndarray]:
    """Empirical CDF of error magnitudes.

    Parameters
    ----------
    errors : numpy.ndarray or polars.Series, shape (N,)
        Errors, m.

    Returns
    -------
    x : numpy.ndarray, shape (N,)
        The errors sorted ascending, m.
    p : numpy.ndarray, shape (N,)
        ``i / N`` for the i-th sorted error (1-based).
    """
    arr = errors.to_numpy() if isinstance(errors, pl.Series) else errors
    return _native.cdf(np.ascontiguousarray(arr, dtype=np.float64))
