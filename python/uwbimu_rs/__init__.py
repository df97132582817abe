"""uwbimu_rs: UWB + IMU fusion filters for indoor positioning, implemented in Rust.

Conventions: navigation frame ENU (z up); accelerometer = specific force in the body frame
(≈ [0, 0, +9.81] m/s² level and still); gyroscope rad/s; quaternions Hamilton [w, x, y, z]
rotating body → navigation; error-state order δp, δv, δθ, δb_a, δb_g; times in seconds.
"""

from __future__ import annotations

import json
import os
from typing import Any, Mapping, Sequence

import numpy as np
import polars as pl

from uwbimu_rs._native import (
    FILTERS,
    METHODS,
    Ackf,
    Arckf,
    Best,
    Ckf,
    ConfigError,
    Criekf,
    Ekf,
    Eskf,
    FilterConfig,
    FormatError,
    Iekf,
    MappingError,
    NumericalError,
    Rekf,
    Riekf,
    Rukf,
    Shaf,
    Shfaf,
    Ukf,
    UpdateReport,
    UwbImuError,
)
from uwbimu_rs import _native, ranging

__all__ = [
    "FILTERS",
    "METHODS",
    "Ackf",
    "Arckf",
    "Best",
    "Ckf",
    "ConfigError",
    "Criekf",
    "Ekf",
    "Eskf",
    "FilterConfig",
    "FormatError",
    "Iekf",
    "MappingError",
    "NumericalError",
    "Rekf",
    "Riekf",
    "Rukf",
    "Shaf",
    "Shfaf",
    "Ukf",
    "UpdateReport",
    "UwbImuError",
    "calibrate",
    "crlb",
    "initialize",
    "ranging",
    "read_mcap",
    "replay",
    "run_filter",
    "run_filters",
    "tune",
]


def calibrate(
    imu: np.ndarray,
    ranges: np.ndarray,
    anchors: np.ndarray,
    *,
    truth: np.ndarray | None = None,
    method: str = "riekf",
    initial: Mapping[str, Any] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    iterations: int | None = None,
    offsets: bool = False,
) -> dict[str, Any]:
    """Estimate a constant range bias per anchor (measured − true) from a log, and with
    ``offsets=True`` also the UWB–IMU time offset and the lever arm.

    With ``truth`` the residuals are taken against the true tag track; without it against the
    Rauch–Tung–Striebel smoothed track of ``method``, refined by expectation–maximisation over
    ``iterations`` passes (the ranges corrected by the current biases, filtered and smoothed
    again). Each anchor's bias is the mean of its residuals within 3 robust σ of their median.

    Parameters
    ----------
    imu, ranges, anchors, initial, config
        As for :func:`run_filter`.
    truth : numpy.ndarray, shape (N, 4), optional
        ``t, x, y, z`` of the tag (UWB antenna) in the navigation frame [s, m], time increasing.
    method : str
        A smoothable inertial method for the no-truth estimate.
    iterations : int, optional
        EM passes without truth (default 8, with ``offsets`` 16).
    offsets : bool
        Also estimate, jointly with the biases (Gauss–Newton on
        ``r = ‖p(t + τ) + R(t + τ)·l − a‖ + b_a``), the time offset ``τ`` (a range stamped ``t``
        was measured at ``t + τ``) and, without truth, the lever arm ``l``; the result then also
        has ``time_offset``, ``time_offset_std`` [s], ``lever_arm``, ``lever_arm_std`` [m] (None with
        truth: the truth is already the tag), ``residual_rms`` [m] and ``config`` (the input
        configuration with ``ranging.time_offset_s``, ``mounting.lever_arm`` and
        ``range_calibration`` set: pass it as ``config=``).

    Returns
    -------
    dict
        ``biases``: polars DataFrame ``anchor, bias, std, used, ranges`` (m; ``std`` is the
        statistical σ/√n: without truth the part the smoothed track absorbs is larger — on
        isas-walk1 each bias lands within 0.052 m of the truth-based one); ``common_offset``,
        ``common_std`` (m); ``iterations``; ``range_calibration`` ``{anchor: [−b, 1, 0, 0]}`` to
        pass as ``config["range_calibration"]``.
    """
    out = _native.calibrate_log(
        imu,
        ranges,
        anchors,
        truth=truth,
        method=method,
        initial=_as_dict(initial),
        config=_as_dict(config),
        iterations=iterations if iterations is not None else (16 if offsets else 8),
        offsets=offsets,
    )
    out["biases"] = pl.DataFrame(out["biases"]).with_columns(pl.col("anchor", "used", "ranges").cast(pl.Int64))
    return out


def tune(
    method: str,
    imu: np.ndarray,
    ranges: np.ndarray,
    anchors: np.ndarray,
    *,
    truth: np.ndarray | None = None,
    initial: Mapping[str, Any] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    smooth: bool | None = None,
    rounds: int = 2,
) -> dict[str, Any]:
    """Pick the noise settings of ``method`` for a log.

    Coordinate search on a log scale over ``ins.accel_noise_density``,
    ``ins.gyro_noise_density`` and ``ranging.range_std`` (``rounds`` passes: factors 1/4 … 4,
    then 0.6 … 1.6), each candidate a whole run, the candidates of a step in parallel on all
    cores. Without ``truth`` it maximises the likelihood of the innovations at the prior under a
    Student-t law (ν = 4: an NLOS spike costs only its logarithm, so it does not inflate
    ``range_std``); with ``truth`` it minimises the
    horizontal RMSE of the tag track (smoothed when ``smooth``; the first 10 s left out when
    self-initialised).

    Parameters
    ----------
    method, imu, ranges, anchors, initial, config, smooth
        As for :func:`run_filter` (``config`` is the starting point; its other settings are kept).
    truth : numpy.ndarray, shape (N, 4), optional
        ``t, x, y, z`` of the tag in the navigation frame [s, m].
    rounds : int
        Passes over the three settings; 0 only scores ``config`` (e.g. to compare two model
        choices, such as ``range_bias.states``, by their innovation likelihood).

    Returns
    -------
    dict
        ``config`` (the tuned configuration, nested dict, to pass as ``config=``), ``objective``
        (``"innovation_likelihood"`` or ``"truth_rmse"``), ``initial_score`` and ``score`` (lower
        is better: mean negative log-likelihood per range, or RMSE m), ``trials`` (polars
        DataFrame: the three settings and ``score`` of every candidate).
    """
    out = _native.tune_noise(
        method,
        imu,
        ranges,
        anchors,
        truth=truth,
        initial=_as_dict(initial),
        config=_as_dict(config),
        smooth=smooth,
        rounds=rounds,
    )
    out["trials"] = pl.DataFrame(out["trials"])
    return out


def run_filter(
    method: str,
    imu: np.ndarray,
    ranges: np.ndarray,
    anchors: np.ndarray,
    *,
    initial: Mapping[str, Any] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    covariance: bool = False,
    updates: bool = False,
    smooth: bool | None = None,
    mag: np.ndarray | None = None,
    tdoa: np.ndarray | None = None,
) -> pl.DataFrame | tuple[pl.DataFrame, pl.DataFrame]:
    """Run one method over whole recordings (the GIL is released while Rust runs).

    Parameters
    ----------
    method : str
        One of ``uwbimu_rs.FILTERS``; ``uwbimu_rs.METHODS[name]["summary"]`` says what each is.
        ``"best"`` is the recommended method for real logs.
    imu : array (N, 7)
        t [s], ax, ay, az [m/s², body specific force], gx, gy, gz [rad/s]; t strictly increasing.
    ranges : array (M, 3)
        t [s] (non-decreasing), anchor index (row of ``anchors``), range [m].
    anchors : array (K, 3)
        Anchor positions in the navigation frame [m].
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
        ones (None: only for ``"best"``) (inertial methods only; the updates frame stays the forward pass's).
    mag : numpy.ndarray, shape (N, 4), optional
        Magnetometer samples ``t, mx, my, mz`` (IMU frame, any unit, time strictly increasing);
        only ``ackf`` uses them (geomagnetic aiding of the ACKF paper), other methods raise ValueError.
    tdoa : numpy.ndarray, shape (M, 4), optional
        Time differences of arrival ``t, i, j, d_ij`` with ``d_ij = |p − a_j| − |p − a_i|`` [m]
        (Loco Positioning TDoA2/TDoA3), time non-decreasing, each applied at its own time,
        noise σ = ``tdoa_std``. Alone (``ranges`` an empty ``(0, 3)`` array; without ``initial`` the
        filter initialises itself from TDoA fixes) or with ranges. Taken by the methods whose
        ``METHODS[name]["takes"]`` lists ``"tdoa"`` (the tightly coupled ones) through their own noise policy (the robust ones down-weight TDoA
        outliers by χ² inflation); the others raise ValueError.
    updates : bool
        Also return a DataFrame with one row per range or TDoA update
        (t, epoch_t, anchor, anchor_j, range, innovation, nis, accepted, weight, inflation,
        down_weighted, iterations, prior_fading, reacquired, bias, bias_std); ``bias``, ``bias_std``:
        the anchor's range bias estimate after the update with ``range_bias.states`` (NaN without); a TDoA row has ``anchor`` = i,
        ``anchor_j`` = j and ``range`` = d_ij, a range row ``anchor_j`` = −1. Ranges within the
        epoch window (``epoch_window_s``) form one epoch, updated jointly.

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
        ``(frame, updates_frame)`` when ``updates=True``.

    Raises
    ------
    ValueError
        Wrong shape, NaN/inf, decreasing time, anchor index out of range, unknown method or
        config key (the message names the array, row and column or the allowed values), IMU
        times that cannot be seconds. A negative or impossible measurement inside good data is
        not an error: the plausibility gate drops it (``gate.*`` config keys).

    Warns
    -----
    UserWarning
        An accelerometer that looks like g or a gyroscope that looks like deg/s.
    """
    cols, upd, _info = _native.run_filter(
        method,
        imu,
        ranges,
        anchors,
        initial=_as_dict(initial),
        config=_as_dict(config),
        covariance=covariance,
        updates=updates,
        smooth=smooth,
        mag=mag,
        tdoa=tdoa,
    )
    frame = _frame(cols)
    if updates:
        if upd is None:
            raise ValueError(f"method {method!r} has no range updates to report")
        u = pl.DataFrame(upd).with_columns(
            pl.col("anchor", "anchor_j", "iterations").cast(pl.Int64), pl.col("accepted", "down_weighted").cast(pl.Boolean)
        )
        return frame, u
    return frame


def run_filters(
    method: str,
    runs: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]],
    *,
    initial: Sequence[Mapping[str, Any] | None] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    covariance: bool = False,
    smooth: bool | None = None,
) -> list[pl.DataFrame]:
    """Run one method over many recordings in parallel on all cores (GIL released).

    Parameters
    ----------
    method : str
        As for :func:`run_filter`.
    runs : sequence of (imu, ranges, anchors)
        One tuple of arrays per recording, shapes as for :func:`run_filter`
        (e.g. ``[(r.imu, r.ranges, r.anchors) for r in sims]``).
    initial : sequence of dict or None, optional
        One initial state per run (None entries self-initialise); None: all self-initialise.
    config, covariance, smooth
        As for :func:`run_filter`, shared by all runs.

    Returns
    -------
    list of polars.DataFrame
        One frame per run, in order, identical to what :func:`run_filter` returns for it.
    """
    inits = None if initial is None else [_as_dict(i) for i in initial]
    outputs = _native.run_filters(
        method, list(runs), initial=inits, config=_as_dict(config), covariance=covariance, smooth=smooth
    )
    return [_frame(cols) for cols, _upd, _info in outputs]


def initialize(
    imu: np.ndarray,
    ranges: np.ndarray,
    anchors: np.ndarray,
    *,
    config: FilterConfig | Mapping[str, Any] | None = None,
) -> tuple[dict[str, Any], dict[str, Any]]:
    """Initialise a filter from the start of a recording.

    Roll and pitch (and gyro bias) from the first ``init.still_s`` seconds, position from
    UWB multilateration, heading from the first ``init.heading_distance_m`` metres of motion
    against UWB (fallback: yaw 0 with σ = π).

    Returns
    -------
    (initial, info)
        ``initial``: dict usable as ``initial=`` of :func:`run_filter` or a filter class;
        ``info``: ``still_start`` (bool) and ``heading_from`` ("motion" or "fallback").
    """
    return _native.initialize_state(imu, ranges, anchors, config=_as_dict(config))


def _mapping_json(mapping: Mapping[str, Any] | None) -> str | None:
    """The mapping as JSON text for the native layer (it parses and checks it)."""
    if mapping is None:
        return None
    try:
        return json.dumps(dict(mapping), default=os.fspath)
    except TypeError as e:
        raise MappingError(f"mapping: cannot convert to JSON: {e}") from e


def read_mcap(
    path: str | os.PathLike[str],
    *,
    mapping: Mapping[str, Any] | None = None,
    config_file: str | os.PathLike[str] | None = None,
) -> dict[str, Any]:
    """Read an MCAP recording (IMU + UWB ranges and/or TDoA) into polars DataFrames.

    Parameters
    ----------
    path : str or path
        The MCAP file (chunked or not, indexed or not, zstd / lz4 / uncompressed).
    mapping : dict, optional
        The ``[mapping]`` table of a replay file as a dict (see the README, "MCAP replay"), e.g.
        ``{"imu_topic": "/imu", "uwb": {"topics": ["/uwb"], "range": "ranges[].range",
        "anchor_id": "ranges[].id", "valid": "ranges[].ra == 1"}}``, or for TDoA
        ``{"tdoa": {"topics": ["/tdoa"], "anchor_i": "idA", "anchor_j": "idB", "tdoa": "distanceDiff"}}``
        (those field names are the defaults); replaces the file's mapping.
    config_file : str or path, optional
        A replay TOML file whose ``[mapping]`` is used.

    Returns
    -------
    dict
        ``imu``: DataFrame t, ax, ay, az, gx, gy, gz (s, m/s², rad/s); ``ranges``: t, anchor
        (index into ``anchors``), range (m), variance (m², NaN when not in the message);
        ``tdoa``: t, i, j (indices into ``anchors``), d_ij = |p − a_j| − |p − a_i| (m) —
        ``frames["tdoa"].to_numpy()`` is the ``(M, 4)`` array :func:`run_filter` takes as
        ``tdoa``; ``anchors``: id, x, y, z (m); ``ground_truth``: t, x, y, z (empty when not mapped);
        ``stats``: dict (topics with schema, count and role; duration_s; reordered;
        late_dropped; invalid_per_anchor; anchor_source; tdoa_unknown_anchor and
        tdoa_unknown_ids (TDoA dropped for an anchor without a position); tdoa_bad_value; ...).

    Raises
    ------
    FileNotFoundError, OSError
        Missing, unreadable or corrupt file (``FormatError``, an OSError, for bad magic,
        truncation, CRC mismatch, unknown encoding).
    ValueError
        A mapping that does not fit the file (``MappingError``: missing topic, unknown field).
    """
    out = _native.read_mcap(
        os.fspath(path), mapping=_mapping_json(mapping), config_file=None if config_file is None else os.fspath(config_file)
    )
    ranges = pl.DataFrame(out["ranges"]).with_columns(pl.col("anchor").cast(pl.Int64))
    tdoa = pl.DataFrame(out["tdoa"]).with_columns(pl.col("i", "j").cast(pl.Int64))
    anchors = pl.DataFrame(out["anchors"]).insert_column(0, pl.Series("id", out["anchor_ids"], dtype=pl.String))
    return {
        "imu": pl.DataFrame(out["imu"]),
        "ranges": ranges,
        "tdoa": tdoa,
        "anchors": anchors,
        "ground_truth": pl.DataFrame(out["ground_truth"]),
        "stats": out["stats"],
    }


def replay(
    path: str | os.PathLike[str],
    method: str | None = None,
    *,
    mapping: Mapping[str, Any] | None = None,
    config_file: str | os.PathLike[str] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    initial: Mapping[str, Any] | None = None,
    smooth: bool | None = None,
) -> tuple[pl.DataFrame, dict[str, Any]]:
    """Replay an MCAP recording through one method (the core of the ``uwbimu-replay`` binary).

    Parameters
    ----------
    path : str or path
        The MCAP file.
    method : str, optional
        One of ``FILTERS``; None: the config file's ``method``, else ``"best"``.
    mapping, config_file
        As for :func:`read_mcap`; the config file also supplies ``method``, ``[config]`` and
        ``[initial]``.
    config : FilterConfig or dict, optional
        Filter settings; replaces the config file's ``[config]``.
    initial : dict, optional
        Initial state as for :func:`run_filter`; replaces the config file's ``[initial]``. None
        and no ``[initial]``: self-initialisation (from the ranges, or from the TDoA of a
        recording without ranges). TDoA are taken by the methods whose
        ``METHODS[name]["takes"]`` lists ``"tdoa"``; the others raise ValueError on a recording
        with TDoA.
    smooth : bool, optional
        Return RTS-smoothed estimates (inertial methods; None: only for ``"best"``).

    Returns
    -------
    (polars.DataFrame, dict)
        The trajectory with the :func:`run_filter` columns, and ``info``: ``method``,
        ``anchors`` (per anchor: id, accepted, down_weighted, rejected, for the ranges),
        ``tdoa`` (the same counts for the TDoA, when the recording has any), ``mean_nis``,
        ``stats`` (as :func:`read_mcap`) and, when ground truth is mapped,
        ``rmse_horizontal_m``, ``rmse_horizontal_aligned_m``, ``rmse_3d_m``,
        ``rmse_3d_aligned_m`` (rigid SE(3) alignment).

    Raises
    ------
    OSError, ValueError
        As :func:`read_mcap`; ``ConfigError`` for an unknown method or config key.
    """
    cols, info = _native.replay(
        os.fspath(path),
        method,
        mapping=_mapping_json(mapping),
        config_file=None if config_file is None else os.fspath(config_file),
        config=_as_dict(config),
        initial=_as_dict(initial),
        smooth=smooth,
    )
    return _frame(cols), info


def _frame(cols: dict[str, np.ndarray]) -> pl.DataFrame:
    """A result frame from native columns (``still`` as a boolean, ``status`` as UInt8 bits)."""
    frame = pl.DataFrame(cols)
    if "still" in frame.columns:
        frame = frame.with_columns(pl.col("still").cast(pl.Boolean))
    if "status" in frame.columns:
        frame = frame.with_columns(pl.col("status").cast(pl.UInt8))
    return frame


def _as_dict(value: Any) -> Any:
    """A plain dict for any mapping (the native layer reads dicts); other values unchanged."""
    return dict(value) if isinstance(value, Mapping) else value


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
