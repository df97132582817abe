"""Whole-recording runs: one method over arrays, many runs on all cores, self-initialisation and
the posterior Cramér–Rao bound."""

from __future__ import annotations

from typing import Any, Literal, Mapping, Sequence, overload

import numpy as np
import polars as pl

from uwbimu_rs import _native
from uwbimu_rs._convert import frame as _frame
from uwbimu_rs._convert import model_choice as _model_choice
from uwbimu_rs._convert import plain as _as_dict
from uwbimu_rs._native import FilterConfig
from uwbimu_rs._typing import MethodName


Run = tuple[np.ndarray, np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, np.ndarray, Mapping[str, np.ndarray | None]]
"""One recording for :func:`run_filters`: ``(imu, ranges, anchors)``, or with a dict of the other
sensors' arrays by keyword, ``(imu, ranges, anchors, {"tdoa": ..., "mag": ...})``."""

@overload
def run_filter(
    method: MethodName,
    imu: np.ndarray,
    ranges: np.ndarray,
    anchors: np.ndarray,
    *,
    initial: Mapping[str, Any] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    covariance: bool = False,
    updates: Literal[False] = False,
    smooth: bool | None = None,
    progress: bool = False,
    info: Literal[False] = False,
    **sensors: np.ndarray | None,
) -> pl.DataFrame: ...


@overload
def run_filter(
    method: MethodName,
    imu: np.ndarray,
    ranges: np.ndarray,
    anchors: np.ndarray,
    *,
    initial: Mapping[str, Any] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    covariance: bool = False,
    updates: Literal[True],
    smooth: bool | None = None,
    progress: bool = False,
    info: Literal[False] = False,
    **sensors: np.ndarray | None,
) -> tuple[pl.DataFrame, pl.DataFrame]: ...


@overload
def run_filter(
    method: MethodName,
    imu: np.ndarray,
    ranges: np.ndarray,
    anchors: np.ndarray,
    *,
    initial: Mapping[str, Any] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    covariance: bool = False,
    updates: Literal[False] = False,
    smooth: bool | None = None,
    progress: bool = False,
    info: Literal[True],
    **sensors: np.ndarray | None,
) -> tuple[pl.DataFrame, dict[str, Any]]: ...


@overload
def run_filter(
    method: MethodName,
    imu: np.ndarray,
    ranges: np.ndarray,
    anchors: np.ndarray,
    *,
    initial: Mapping[str, Any] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    covariance: bool = False,
    updates: Literal[True],
    smooth: bool | None = None,
    progress: bool = False,
    info: Literal[True],
    **sensors: np.ndarray | None,
) -> tuple[pl.DataFrame, pl.DataFrame, dict[str, Any]]: ...


def run_filter(
    method: MethodName,
    imu: np.ndarray,
    ranges: np.ndarray,
    anchors: np.ndarray,
    *,
    initial: Mapping[str, Any] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    covariance: bool = False,
    updates: bool = False,
    smooth: bool | None = None,
    progress: bool = False,
    info: bool = False,
    **sensors: np.ndarray | None,
) -> (
    pl.DataFrame
    | tuple[pl.DataFrame, pl.DataFrame]
    | tuple[pl.DataFrame, dict[str, Any]]
    | tuple[pl.DataFrame, pl.DataFrame, dict[str, Any]]
):
    """Run one method over whole recordings (the GIL is released while Rust runs).

    Parameters
    ----------
    method : MethodName
        One of ``uwbimu_rs.FILTERS``; ``uwbimu_rs.METHODS[name]["summary"]`` says what each is.
        ``"best"`` is the recommended method for real logs.
    imu : array (N, 7)
        t [s], ax, ay, az [m/s², body specific force], gx, gy, gz [rad/s]; t strictly increasing.
    ranges : array (M, 3) or (M, 4)
        t [s] (non-decreasing), anchor index (row of ``anchors``, or its id when ``anchors`` is
        a dict), range [m], and with several tags the tag (its lever arm the row ``tag`` of
        ``mounting.lever_arm``; docs/tags.md).
    anchors : array (K, 3) or dict
        Anchor positions in the navigation frame [m]; or a dict ``{id: [x, y, z]}`` of anchors
        by hardware id (a log numbering them 11, 12, 4, 9), whose ids the anchor columns of
        ``ranges`` and ``tdoa`` then hold (rows in the dict's order; frames report rows).
    initial : dict, optional
        ``position`` (3,), ``velocity`` (3,), ``orientation`` (w, x, y, z) and optional
        ``position_std``, ``velocity_std``, ``orientation_std`` (rad), ``accel_bias``,
        ``gyro_bias``, ``accel_bias_std``, ``gyro_bias_std``; valid at the first IMU time.
        None: the filter initialises itself (see :func:`initialize`).
    config : FilterConfig or dict, optional
        Keys as in ``FilterConfig.keys()``; unknown keys raise :class:`ConfigError`.
        ``range_calibration={anchor: [c0, c1, c2, c3]}`` calibrates the ranges first (Wang et al. 2018).
    covariance : bool
        Add position covariance columns ``cov_xx, cov_xy, cov_xz, cov_yy, cov_yz, cov_zz`` [m²].
    smooth : bool, optional
        Return the Rauch–Tung–Striebel smoothed estimates (same columns) instead of the filtered
        ones (None: only for ``"best"``) (inertial methods only; the updates frame stays the forward
        pass's — with ``smoothing.outlier_passes``, on by default in ``"best"``, that of the last
        pass, without the ranges the robust smoothing left out).
    **sensors : numpy.ndarray, optional
        The other sensors' arrays by keyword, one per sensor of :data:`SENSORS` (its
        ``keyword``, one row per reading in one of its ``columns`` layouts, time first), each
        taken by the methods whose ``METHODS[name]["takes"]`` lists the sensor; the others raise
        ValueError. TDoA alone (``ranges`` an empty ``(0, 3)`` array) starts the filter from TDoA
        fixes. The keywords:

{sensor_keywords}
    progress : bool, default False
        Draw a one-line bar on stderr of the IMU samples processed (then "smoothing" during
        the smoothing pass) while the run goes on.
    updates : bool
        Also return a DataFrame with one row per update, of a range or of another sensor
        (t, epoch_t, sensor, anchor, anchor_j, tag, axis, value, innovation, nis, accepted, weight,
        inflation, down_weighted, iterations, prior_fading, reacquired, bias, bias_std):
        ``sensor`` is ``"range"`` or a name of :data:`SENSORS` (a polars Enum); ``value`` the
        range, TDoA d_ij, altitude [m] or speed [m/s] (a magnetometer sample's field norm, a pose
        fix's distance from the origin);
        ``anchor`` a range's anchor or a TDoA's i, ``anchor_j`` a TDoA's j, ``tag`` a range's
        tag, ``axis`` an odometry reading's body axis, each −1 where it does not apply;
        ``bias``, ``bias_std``: the estimated additive bias after the update (a range's anchor
        total with ``range_bias.states``, an altitude's offset with ``altitude.offset_std``; NaN
        without).
        Ranges within the epoch window (``epoch_window_s``) form one epoch, updated jointly.
    info : bool
        Also return what the run counted and chose, as a dict (last in the tuple):
        ``health`` (``rejected`` {gate kind: count}, ``numerical_repairs``,
        ``ranges_before_start``, ``reordered``, ``late_dropped``, ``smoothing_left_out``: the
        ranges the robust smoothing left out, ``map_passes``: the MAP passes the smoothing kept,
        ``map_objective``: the MAP objective at its first pass and after each kept one (a list),
        ``smoothing_repairs``: predicted covariances the smoother repaired, ``smoothing_failed``:
        the smoother failed numerically and the smoothed columns hold the forward estimate, with
        a warning),
        ``ranges_before_start``, after
        self-initialisation ``still_start`` and ``heading_from``, and for ``"best"`` ``model``:
        the range-error model it chose on the log and why, the dict of :func:`choose_model`
        (``chosen``, ``reason``, ``overrides``, ``candidates``, ``config``). Empty for ``uwb_ls``.

    Returns
    -------
    polars.DataFrame
        Inertial filters: one row per IMU sample with ``t, x, y, z, vx, vy, vz, qw, qx, qy, qz,
        std_x, std_y, std_z, still, status`` (``still``: the still detector's decision, in every
        inertial method; ``status``: bits since the previous row — 1 a measurement the
        plausibility gate rejected, 2 a numerical failure repaired and its measurement skipped,
        4 late streamed data dropped). Planar
        methods fill the same columns: ``z`` = the plane height, ``vz`` = 0, a yaw-only
        quaternion, ``std_z`` = 0. ``uwb_ls``: one row per solvable UWB epoch with
        ``t, x, y, z, std_x, std_y, std_z, n_ranges, residual_rms``.
        ``(frame, updates_frame)`` when ``updates=True``, ``(frame, info)`` when ``info=True``,
        ``(frame, updates_frame, info)`` with both.

    Raises
    ------
    ValueError
        Wrong shape, NaN/inf, decreasing time, anchor index out of range, unknown method or
        config key (the message names the array, row and column or the allowed values), IMU
        times that cannot be seconds, an accelerometer that looks like g or a gyroscope that
        looks like deg/s (the message names the fix; ``gate.refuse_unit_slips=False`` takes
        them as they are). A negative or impossible measurement inside good data is not an
        error: the plausibility gate drops it (``gate.*`` config keys).
    KeyboardInterrupt
        Ctrl-C while the method runs (honoured within 0.1 s; the run is cancelled).

    Warns
    -----
    UserWarning
        An accelerometer far from gravity in any unit; with ``gate.refuse_unit_slips=False``, an
        accelerometer that looks like g or a gyroscope that looks like deg/s.
    """
    frame, upd, run_info = run_frames(
        method,
        imu,
        ranges,
        anchors,
        initial=initial,
        config=config,
        covariance=covariance,
        updates=updates,
        smooth=smooth,
        **sensors,
        progress=progress,
    )
    if updates:
        if upd is None:
            raise ValueError(f"method {method!r} has no filter updates to report")
        return (frame, upd, run_info) if info else (frame, upd)
    return (frame, run_info) if info else frame


def _sensor_keywords() -> str:
    """The ``**sensors`` keywords of :func:`run_filter`'s docstring, one per row of :data:`SENSORS`."""
    lines = []
    for row in _native.SENSORS.values():
        layouts = " or ".join(f"``({len(c)})`` ``{', '.join(c)}``" for c in row["columns"])
        lines.append(f"        ``{row['keyword']}`` : {layouts}\n            {row['doc']}")
    return "\n".join(lines)


run_filter.__doc__ = (run_filter.__doc__ or "").replace("{sensor_keywords}", _sensor_keywords())


def run_frames(
    method: MethodName,
    imu: np.ndarray,
    ranges: np.ndarray,
    anchors: np.ndarray,
    *,
    initial: Mapping[str, Any] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    covariance: bool = False,
    updates: bool = False,
    smooth: bool | None = None,
    progress: bool = False,
    **sensors: np.ndarray | None,
) -> tuple[pl.DataFrame, pl.DataFrame | None, dict[str, Any]]:
    """:func:`run_filter` for callers that take any method (private to the package): the updates
    frame is None when not asked for or when the method has none (``uwb_ls``) instead of an error;
    the run's ``info`` comes last."""
    cols, upd, info = _native.run_filter(
        method,
        imu,
        ranges,
        anchors,
        initial=_as_dict(initial),
        config=_as_dict(config),
        covariance=covariance,
        updates=updates,
        smooth=smooth,
        **sensors,
        progress=progress,
    )
    info = _run_info(info)
    if upd is None:
        return _frame(cols), None, info
    return _frame(cols), _updates_frame(upd), info


_SENSOR_NAMES = ["range", *_native.SENSORS]
"""The ``sensor`` column's values: code 0 is a range, code 1 + i the i-th sensor of the registry."""


def _updates_frame(columns: Mapping[str, np.ndarray]) -> pl.DataFrame:
    """The updates frame of the native columns: integer indices, booleans, the sensor as an Enum."""
    sensor = pl.Enum(_SENSOR_NAMES)
    return pl.DataFrame(columns).with_columns(
        pl.col("sensor").cast(pl.UInt32).replace_strict(dict(enumerate(_SENSOR_NAMES)), return_dtype=sensor),
        pl.col("anchor", "anchor_j", "tag", "axis", "iterations").cast(pl.Int64),
        pl.col("accepted", "down_weighted").cast(pl.Boolean),
    )


@overload
def run_filters(
    method: MethodName,
    runs: Sequence[Run],
    *,
    initial: Sequence[Mapping[str, Any] | None] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    covariance: bool = False,
    smooth: bool | None = None,
    progress: bool = False,
    info: Literal[False] = False,
) -> list[pl.DataFrame]: ...


@overload
def run_filters(
    method: MethodName,
    runs: Sequence[Run],
    *,
    initial: Sequence[Mapping[str, Any] | None] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    covariance: bool = False,
    smooth: bool | None = None,
    progress: bool = False,
    info: Literal[True],
) -> list[tuple[pl.DataFrame, dict[str, Any]]]: ...


def run_filters(
    method: MethodName,
    runs: Sequence[Run],
    *,
    initial: Sequence[Mapping[str, Any] | None] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    covariance: bool = False,
    smooth: bool | None = None,
    progress: bool = False,
    info: bool = False,
) -> list[pl.DataFrame] | list[tuple[pl.DataFrame, dict[str, Any]]]:
    """Run one method over many recordings in parallel on all cores (GIL released).

    Parameters
    ----------
    method : str
        As for :func:`run_filter`.
    runs : sequence of (imu, ranges, anchors) or (imu, ranges, anchors, sensors)
        One tuple of arrays per recording, shapes as for :func:`run_filter`
        (e.g. ``[(r.imu, r.ranges, r.anchors) for r in sims]``); ``sensors`` is a dict of the
        other sensors' arrays by the keywords of :func:`run_filter` (e.g. ``{"tdoa": r.tdoa}``).
    initial : sequence of dict or None, optional
        One initial state per run (None entries self-initialise); None: all self-initialise.
    config, covariance, smooth
        As for :func:`run_filter`, shared by all runs (``"best"`` chooses its model on each run).
    progress : bool, default False
        Draw a one-line bar on stderr of the IMU samples processed over all runs.
    info : bool, default False
        Return ``(frame, info)`` per run, ``info`` as :func:`run_filter`'s (the health counts and,
        for ``"best"``, the model it chose on that run).

    Returns
    -------
    list of polars.DataFrame, or of (polars.DataFrame, dict) with ``info=True``
        One entry per run, in order, identical to what :func:`run_filter` returns for it.
    """
    inits = None if initial is None else [_as_dict(i) for i in initial]
    outputs = _native.run_filters(
        method,
        list(runs),
        initial=inits,
        config=_as_dict(config),
        covariance=covariance,
        smooth=smooth,
        progress=progress,
    )
    if not info:
        return [_frame(cols) for cols, _upd, _info in outputs]
    return [(_frame(cols), _run_info(run_info)) for cols, _upd, run_info in outputs]


def _run_info(info: dict[str, Any]) -> dict[str, Any]:
    """A native run's ``info`` with the model choice (``"best"``) in its Python form."""
    if "model" in info:
        info["model"] = _model_choice(info["model"])
    return info


def initialize(
    imu: np.ndarray,
    ranges: np.ndarray,
    anchors: np.ndarray,
    *,
    config: FilterConfig | Mapping[str, Any] | None = None,
) -> tuple[dict[str, Any], dict[str, Any]]:
    """Initialise a filter from the start of a recording.

    Roll and pitch (and gyro bias) from the first ``init.still_s`` seconds, position from
    UWB multilateration (at rest or driving steadily), heading from a Gaussian-sum bank of
    inertial filters fed the UWB (and the tags' baseline with two tags), taken when its σ is at
    most ``init.heading_std`` (fallback after ``init.heading_timeout_s``: the bank's heading
    with its σ). See docs/heading.md.

    Returns
    -------
    (initial, info)
        ``initial``: dict usable as ``initial=`` of :func:`run_filter` or a filter class;
        ``info``: ``still_start`` (bool) and ``heading_from`` ("motion", "tags" or "fallback").
    """
    return _native.initialize_state(imu, ranges, anchors, config=_as_dict(config))


_TRUTH_COLUMNS = ["t", "x", "y", "z", "vx", "vy", "vz", "qw", "qx", "qy", "qz"]


def crlb(
    imu: np.ndarray,
    ranges: np.ndarray,
    anchors: np.ndarray,
    truth: pl.DataFrame | np.ndarray,
    *,
    biases: np.ndarray | None = None,
    initial: Mapping[str, Any] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
) -> pl.DataFrame:
    """Posterior Cramér–Rao lower bound along the true trajectory (the ARCKF paper's eqs. (43)–(44)).

    Parameters
    ----------
    imu, ranges, anchors : arrays
        As for :func:`run_filter`.
    truth : polars.DataFrame or array (N, 11)
        The true state at every IMU time: ``t, x, y, z, vx, vy, vz, qw, qx, qy, qz`` (as
        ``sim.SimResult.truth``).
    biases : array (N, 6), optional
        True accelerometer (m/s²) and gyroscope (rad/s) biases per IMU sample
        (``np.hstack([run.accel_bias, run.gyro_bias])``); zero when omitted.
    initial : dict, optional
        Only its standard deviations are used: the bound starts from that covariance.
    config : FilterConfig or dict, optional
        Noise model (as given to the filter being compared).

    Returns
    -------
    polars.DataFrame
        ``t, crlb_x, crlb_y, crlb_z``: the bound as standard deviations, m, one row per IMU sample.
    """
    if isinstance(truth, pl.DataFrame):
        truth = truth.select(_TRUTH_COLUMNS).to_numpy()
    cols = _native.posterior_crlb(
        imu, ranges, anchors, truth, biases=biases, initial=_as_dict(initial), config=_as_dict(config)
    )
    return pl.DataFrame(cols)
