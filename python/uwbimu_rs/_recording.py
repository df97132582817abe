"""MCAP recordings: reading one into frames, replaying one through a method."""

from __future__ import annotations

import json
import os
from typing import Any, Mapping

import polars as pl

from uwbimu_rs import _native
from uwbimu_rs._convert import frame as _frame
from uwbimu_rs._convert import plain as _as_dict
from uwbimu_rs._native import FilterConfig, MappingError
from uwbimu_rs._typing import MethodName

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
    """Read an MCAP recording (IMU + UWB ranges and/or TDoA, heights, body velocities) into polars
    DataFrames.

    Parameters
    ----------
    path : str or path
        The MCAP file (chunked or not, indexed or not, zstd / lz4 / uncompressed).
    mapping : dict, optional
        The ``[mapping]`` table of a replay file as a dict (see the README, "MCAP replay"), e.g.
        ``{"imu_topic": "/imu", "uwb": {"topics": ["/uwb"], "range": "ranges[].range",
        "anchor_id": "ranges[].id", "valid": "ranges[].ra == 1"}}``, or for TDoA
        ``{"tdoa": {"topics": ["/tdoa"], "anchor_i": "idA", "anchor_j": "idB", "tdoa": "distanceDiff"}}``
        (those field names are the defaults); heights and wheel odometry need their topics,
        ``{"altitude": {"topics": ["/altitude"]}, "odometry": {"topics": ["/odom"]}}``, and
        ranges of several tags their tag, ``{"uwb": {"tag": "tag_id", "tag_ids": ["front", "rear"]}}``
        (docs/altitude.md, docs/odometry.md, docs/tags.md). Merged into the config file's ``[mapping]``: a
        key given overrides that key (``None`` clears it), nested tables (``uwb``, ``tdoa``,
        ``anchors``, ``ground_truth``) merge key by key, and every key not given keeps the
        file's value; e.g. ``{"ground_truth": {"file": "gt.csv"}}`` adds ground truth and keeps
        the file's IMU and UWB mapping.
    config_file : str or path, optional
        A replay TOML file whose ``[mapping]`` is used.

    Returns
    -------
    dict
        ``imu``: DataFrame t, ax, ay, az, gx, gy, gz (s, m/s², rad/s); ``ranges``: t, anchor
        (index into ``anchors``), range (m), variance (m², NaN when not in the message), tag
        (index into ``mounting.lever_arm``); ``altitude`` (t, z) and ``odometry`` (t, speed or
        t, vx, vy, vz) when the mapping reads them, the arrays :func:`run_filter` takes;
        ``tdoa``: t, i, j (indices into ``anchors``), d_ij = |p − a_j| − |p − a_i| (m) —
        ``frames["tdoa"].to_numpy()`` is the ``(M, 4)`` array :func:`run_filter` takes as
        ``tdoa``; ``anchors``: id, x, y, z (m); ``ground_truth``: t, x, y, z (empty when not mapped);
        ``stats``: dict (topics with schema, count and role; duration_s; reordered;
        late_dropped; invalid_per_anchor; anchor_source; tdoa_unknown_anchor and
        tdoa_unknown_ids (TDoA dropped for an anchor without a position); tdoa_bad_value;
        unknown_tag and unknown_tag_ids (ranges of a tag id not in ``uwb.tag_ids``); sensors
        (per sensor read: used, invalid);
        messages; complete (False for a file cut before its footer); ...).

    A file cut before its footer (a recorder that died) is read up to its last complete record
    with a ``UserWarning`` saying how many bytes were lost.

    Raises
    ------
    FileNotFoundError, OSError
        Missing, unreadable or corrupt file (``FormatError``, an OSError, for bad magic, a file
        that ends before its first message, CRC mismatch, unknown encoding).
    ValueError
        A mapping that does not fit the file (``MappingError``: missing topic, unknown field).
    """
    out = _native.read_mcap(
        os.fspath(path), mapping=_mapping_json(mapping), config_file=None if config_file is None else os.fspath(config_file)
    )
    ranges = pl.DataFrame(out["ranges"]).with_columns(pl.col("anchor", "tag").cast(pl.Int64))
    tdoa = pl.DataFrame(out["tdoa"]).with_columns(pl.col("i", "j").cast(pl.Int64))
    anchors = pl.DataFrame(out["anchors"]).insert_column(0, pl.Series("id", out["anchor_ids"], dtype=pl.String))
    sensors = {name: pl.DataFrame(out[name]) for name in _native.SENSORS if name in out and name != "tdoa"}
    return {
        "imu": pl.DataFrame(out["imu"]),
        "ranges": ranges,
        "tdoa": tdoa,
        "anchors": anchors,
        "ground_truth": pl.DataFrame(out["ground_truth"]),
        **sensors,
        "stats": out["stats"],
    }


def replay(
    path: str | os.PathLike[str],
    method: MethodName | None = None,
    *,
    mapping: Mapping[str, Any] | None = None,
    config_file: str | os.PathLike[str] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    overrides: Mapping[str, Any] | None = None,
    initial: Mapping[str, Any] | None = None,
    smooth: bool | None = None,
    ground_truth: str | os.PathLike[str] | None = None,
    progress: bool = False,
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
    overrides : dict, optional
        Settings set over that configuration (the config file's ``[config]``, or ``config``),
        every other key kept: ``{"ranging.range_std": 0.2}`` or ``{"ranging": {"range_std": 0.2}}``
        (what :func:`uwbimu_rs.fleet.sweep` varies).
    initial : dict, optional
        Initial state as for :func:`run_filter`; replaces the config file's ``[initial]``. None
        and no ``[initial]``: self-initialisation (from the ranges, or from the TDoA of a
        recording without ranges). TDoA are taken by the methods whose
        ``METHODS[name]["takes"]`` lists ``"tdoa"``; the others raise ValueError on a recording
        with TDoA.
    smooth : bool, optional
        Return RTS-smoothed estimates (inertial methods; None: only for ``"best"``).
    ground_truth : str or path, optional
        A ground-truth CSV, as the CLI's ``--ground-truth``: header ``t,x,y,z`` or
        ``t_s,x_m,y_m,z_m`` (s, m; ``uwbimu_rs.metrics.TRUTH_COLUMNS``), or no header and those
        four columns first. Overrides ``mapping["ground_truth"]["file"]``.
    progress : bool, default False
        Draw one-line bars on stderr while the file is read and the method runs.

    Returns
    -------
    (polars.DataFrame, dict)
        The trajectory with the :func:`run_filter` columns, and ``info`` with the keys of the
        CLI's ``--json`` summary: ``method``, ``smoothed`` (bool: the trajectory is
        RTS-smoothed), ``duration_s``, ``n_imu``, ``n_ranges``, ``n_tdoa``, ``n_ground_truth``,
        ``truncated_bytes`` (bytes lost at the end of a file cut before its footer), ``anchors`` (per anchor: id, accepted, down_weighted, rejected, for the ranges),
        ``tdoa`` (the same counts for the TDoA, when the recording has any), ``mean_nis``,
        ``smoothing_left_out`` (ranges the robust smoothing of a smoothed ``best`` left out;
        the anchor counts are those of its last pass), ``model`` (``best``'s choice) and,
        with ground truth, ``rmse_steps``, ``rmse_horizontal_m``,
        ``rmse_horizontal_aligned_m``, ``rmse_3d_m``, ``rmse_3d_aligned_m`` (m; rigid SE(3)
        alignment); plus ``stats`` (as :func:`read_mcap`), ``health`` and ``warnings``.

    Raises
    ------
    OSError, ValueError
        As :func:`read_mcap` (``FileNotFoundError`` for a missing ground-truth file,
        ``FormatError`` naming the line of a bad one); ``ConfigError`` for an unknown method or
        config key.
    KeyboardInterrupt
        Ctrl-C while the method runs (honoured within 0.1 s).
    """
    cols, info = _native.replay(
        os.fspath(path),
        method,
        mapping=_mapping_json(mapping),
        config_file=None if config_file is None else os.fspath(config_file),
        config=_as_dict(config),
        overrides=_as_dict(overrides),
        initial=_as_dict(initial),
        smooth=smooth,
        ground_truth=None if ground_truth is None else os.fspath(ground_truth),
        progress=progress,
    )
    return _frame(cols), info
