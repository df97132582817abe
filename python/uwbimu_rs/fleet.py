"""Fleets of recordings on Ray: replay many MCAP logs, sweep configurations over them.

:func:`replay` runs :func:`uwbimu_rs.replay` on every log as a Ray task, writes each trajectory
to Parquet and returns one summary row per log; :func:`sweep` runs a grid of configurations
(:func:`grid`) over many logs and returns one row per (configuration, log). Ray runs the tasks:
a local instance on this machine by default, a cluster when given its address. One bad log
never stops a fleet: it fails alone and its row says why.

Needs the optional extra ``uwbimu_rs[fleet]`` (``pip install "uwbimu_rs[fleet]"``, which
installs ``ray``); Ray is imported when a fleet runs, not with ``uwbimu_rs``. On a cluster
every node needs ``uwbimu_rs`` installed, the logs at the same paths and ``out_dir`` on a shared
file system. See docs/fleet.md.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import logging
import os
import sys
import time
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence, Union

import numpy as np
import polars as pl

from uwbimu_rs import _native
from uwbimu_rs._native import ConfigError, FilterConfig
from uwbimu_rs._recording import replay as _replay

if TYPE_CHECKING:  # pragma: no cover - typing only
    from types import ModuleType

__all__ = ["SUMMARY_COLUMNS", "grid", "replay", "sweep"]

_PathLike = Union[str, "os.PathLike[str]"]
_GroundTruth = Union[Mapping[_PathLike, _PathLike], Callable[[str], Union[_PathLike, None]], None]

SUMMARY_COLUMNS: dict[str, tuple[Any, str]] = {
    "path": (pl.String, "the log, as given"),
    "output": (pl.String, "its trajectory (Parquet, the `run_filter` columns); null for a failed log and in a sweep"),
    "status": (pl.String, "`ok`; `truncated`: a file cut before its footer, read up to its last intact record; `failed`"),
    "reused": (pl.Boolean, "the output of an earlier run with the same inputs, not recomputed"),
    "error": (pl.String, "why a failed log failed (exception type and message); null otherwise"),
    "method": (pl.String, "the method that ran"),
    "smoothed": (pl.Boolean, "the trajectory is RTS-smoothed"),
    "duration_s": (pl.Float64, "time span of the recording (s)"),
    "n_imu": (pl.Int64, "IMU samples"),
    "n_ranges": (pl.Int64, "UWB ranges"),
    "n_tdoa": (pl.Int64, "TDoA measurements"),
    "truncated_bytes": (pl.Int64, "bytes lost at the end of a file cut before its footer"),
    "accepted": (pl.Int64, "ranges and TDoA the filter used at full weight"),
    "down_weighted": (pl.Int64, "ranges and TDoA used with a robust weight below one"),
    "rejected": (pl.Int64, "ranges and TDoA the filter's gate rejected"),
    "mean_nis": (pl.Float64, "mean normalised innovation squared of the updates"),
    "impossible": (pl.Int64, "measurements rejected before the filter as physically impossible (health)"),
    "numerical_repairs": (pl.Int64, "covariance repairs (health)"),
    "late_dropped": (pl.Int64, "measurements too late to be used (health)"),
    "reordered": (pl.Int64, "messages put back in time order (health)"),
    "smoothing_left_out": (pl.Int64, "ranges the robust smoothing of a smoothed `best` left out (health)"),
    "model": (pl.String, "the range-error model `best` chose (null for other methods)"),
    "model_reason": (pl.String, "the scores behind that choice"),
    "model_overrides": (pl.String, "the settings the choice changed, as JSON"),
    "rmse_horizontal_m": (pl.Float64, "horizontal RMSE against the ground truth (m; null without)"),
    "rmse_horizontal_aligned_m": (pl.Float64, "the same after a rigid SE(3) alignment (m)"),
    "rmse_3d_m": (pl.Float64, "3-D RMSE (m)"),
    "rmse_3d_aligned_m": (pl.Float64, "3-D RMSE after alignment (m)"),
    "warnings": (pl.String, "the run's warnings, joined by `; `"),
    "wall_s": (pl.Float64, "seconds the task took on its worker"),
}
"""The columns of a fleet summary, in order: name → (polars dtype, meaning)."""

_SWEEP_OMITS = ("output", "reused")
_REPLAY_KEYWORDS = ("mapping", "config_file", "config", "overrides", "smooth", "ground_truth")
_COUNTS = ("accepted", "down_weighted", "rejected")
_HEALTH = ("numerical_repairs", "late_dropped", "reordered", "smoothing_left_out")
_RMSE = ("rmse_horizontal_m", "rmse_horizontal_aligned_m", "rmse_3d_m", "rmse_3d_aligned_m")


def replay(
    paths: Sequence[_PathLike],
    method: str | None = "best",
    *,
    out_dir: _PathLike,
    config_file: _PathLike | None = None,
    mapping: Mapping[str, Any] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    smooth: bool | None = None,
    ground_truth: _GroundTruth = None,
    address: str | None = None,
    num_cpus: int | None = None,
    force: bool = False,
    max_retries: int = 3,
    progress: bool = False,
) -> pl.DataFrame:
    """Replay every log through ``method`` as Ray tasks; trajectories to Parquet, one summary row each.

    Each log runs :func:`uwbimu_rs.replay` (the core of ``uwbimu-replay``) in a Ray task of one
    CPU, so its trajectory equals a serial ``replay`` of the same file. The trajectory goes to
    ``out_dir`` as Parquet: the log's path relative to the deepest directory holding all the
    logs, with ``.parquet`` for its suffix (``a/x.mcap``, ``b/x.mcap`` → ``out_dir/a/x.parquet``,
    ``out_dir/b/x.parquet``), written to a temporary name and renamed, with a
    ``.summary.json`` beside it. A re-run reuses a log whose output exists from the same inputs
    (the log's size and modification time, method, settings, config file contents, ground truth
    and package version) unless ``force``; a failed log always runs again.

    Parameters
    ----------
    paths : sequence of str or path
        The MCAP logs (each once).
    method : str or None, default "best"
        One of ``uwbimu_rs.FILTERS``; None: each config file's ``method``, else ``"best"``.
    out_dir : str or path
        Where the trajectories and their summaries go (created; shared by all nodes on a cluster).
    config_file, mapping, config, smooth
        As for :func:`uwbimu_rs.replay`, the same for every log.
    ground_truth : dict or callable, optional
        Each log's ground-truth CSV: a dict from log path (as given) to CSV, or a function of the
        log path returning the CSV or None. Logs with ground truth get the RMSE columns.
    address : str, optional
        A Ray cluster to join (``"auto"``: the one ``ray start`` started on this machine;
        ``"host:6379"``; ``"ray://host:10001"``); None starts a local Ray for this process. A
        process that already joined a Ray (``ray.init``) keeps it and ignores ``address``.
    num_cpus : int, optional
        CPUs of the local Ray (None: all of this machine's); not with ``address``.
    force : bool, default False
        Recompute logs whose output already exists.
    max_retries : int, default 3
        Times a task lost with its worker (a crashed or killed process, a lost node) is retried.
    progress : bool, default False
        Draw a line on stderr as logs finish (done / all, failed, logs per second).

    Returns
    -------
    polars.DataFrame
        One row per log in the order of ``paths``, the columns of :data:`SUMMARY_COLUMNS`.

    Raises
    ------
    ImportError
        Ray is not installed (``pip install "uwbimu_rs[fleet]"``).
    ConfigError
        Unknown method or configuration key (checked before any task runs).
    ValueError
        A log given twice, ``num_cpus`` with ``address``, a ``max_retries`` below 0.
    KeyboardInterrupt
        Ctrl-C: the tasks still running are cancelled; finished outputs stay.
    """
    logs = _distinct_paths(paths)
    out_root = Path(out_dir)
    outputs = _output_paths(logs, out_root)
    settings = _Settings.checked(method, config_file, mapping, config, smooth)
    jobs = [settings.job(log, out, _truth_for(ground_truth, log), None) for log, out in zip(logs, outputs)]
    rows: list[dict[str, Any] | None] = [None if force else _reusable(job) for job in jobs]
    pending = [k for k, row in enumerate(rows) if row is None]
    if pending:
        out_root.mkdir(parents=True, exist_ok=True)
        for k, row in zip(pending, _run_tasks([jobs[k] for k in pending], address, num_cpus, max_retries, progress)):
            rows[k] = row
    return _frame([row for row in rows if row is not None], SUMMARY_COLUMNS)


def sweep(
    method: str | None,
    configs: Sequence[Mapping[str, Any]],
    datasets: Sequence[_PathLike],
    *,
    config_file: _PathLike | None = None,
    mapping: Mapping[str, Any] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    smooth: bool | None = None,
    ground_truth: _GroundTruth = None,
    address: str | None = None,
    num_cpus: int | None = None,
    max_retries: int = 3,
    progress: bool = False,
) -> pl.DataFrame:
    """Run every configuration of ``configs`` on every log of ``datasets`` as Ray tasks, one table.

    Each configuration is a dict of settings set over the base configuration (``config``, else
    the config file's ``[config]``, else the defaults) — the ``overrides`` of
    :func:`uwbimu_rs.replay` — e.g. from :func:`grid`. With ``method="best"`` each run also
    makes ``best``'s model selection on its log, reported in ``model`` / ``model_reason`` /
    ``model_overrides``. Nothing is written to disk; give ``ground_truth`` to compare by RMSE.

    Parameters
    ----------
    method : str or None
        As for :func:`replay`.
    configs : sequence of dict
        The settings of each configuration, ``{"ranging.range_std": 0.2}`` or nested
        ``{"ranging": {"range_std": 0.2}}``; ``{}`` is the base configuration.
    datasets : sequence of str or path
        The MCAP logs (each once).
    config_file, mapping, config, smooth, ground_truth, address, num_cpus, max_retries, progress
        As for :func:`replay`.

    Returns
    -------
    polars.DataFrame
        One row per (configuration, log), configurations first: ``config`` (index into
        ``configs``), one column per setting any configuration sets (its dotted key; null where
        a configuration leaves it), then the columns of :data:`SUMMARY_COLUMNS` except
        ``output`` and ``reused``.

    Raises
    ------
    ImportError, ConfigError, ValueError, KeyboardInterrupt
        As :func:`replay`; ``ConfigError`` also for an unknown key in a configuration.
    """
    logs = _distinct_paths(datasets)
    settings = _Settings.checked(method, config_file, mapping, config, smooth)
    points = [_checked_overrides(c, k) for k, c in enumerate(configs)]
    keys = list(dict.fromkeys(key for point in points for key in point))
    pairs = list(itertools.product(range(len(points)), logs))
    jobs = [settings.job(log, None, _truth_for(ground_truth, log), points[k]) for k, log in pairs]
    rows = _run_tasks(jobs, address, num_cpus, max_retries, progress) if jobs else []
    settings_columns = {key: _setting_column([p.get(key) for p in points]) for key in keys}
    columns: dict[str, tuple[Any, str]] = {"config": (pl.Int64, "index into configs")}
    columns.update({key: (dtype, "setting") for key, (dtype, _) in settings_columns.items()})
    columns.update({name: spec for name, spec in SUMMARY_COLUMNS.items() if name not in _SWEEP_OMITS})
    table = [{"config": k, **{key: values[k] for key, (_, values) in settings_columns.items()}, **row} for (k, _), row in zip(pairs, rows)]
    return _frame(table, columns)


def grid(axes: Mapping[str, Sequence[Any]]) -> list[dict[str, Any]]:
    """Every combination of the values of ``axes`` (dotted config keys → values), for :func:`sweep`.

    ``grid({"ranging.range_std": [0.1, 0.2], "ins.accel_noise_density": [0.1, 0.4]})`` gives four
    configurations, the last key varying fastest.

    Raises
    ------
    ValueError
        An axis with no values.
    """
    for key, values in axes.items():
        if len(values) == 0:
            raise ValueError(f"grid: axis {key!r} has no values")
    names = list(axes)
    return [dict(zip(names, combo)) for combo in itertools.product(*(axes[n] for n in names))]


class _Settings:
    """The inputs every task of a fleet shares, checked once before any task runs, with the digest
    of them that each log's input key starts from."""

    def __init__(self, method: str | None, config_file: str | None, mapping: dict[str, Any] | None, config: Any, smooth: bool | None):
        self.method, self.config_file, self.mapping, self.config, self.smooth = method, config_file, mapping, config, smooth
        from uwbimu_rs import __version__

        shared = {
            "config_file": None if config_file is None else hashlib.sha256(Path(config_file).read_bytes()).hexdigest(),
            "version": __version__,
            "method": method,
            "mapping": mapping,
            "config": config,
            "smooth": smooth,
        }
        self.digest = _digest(shared)

    @classmethod
    def checked(cls, method: str | None, config_file: _PathLike | None, mapping: Mapping[str, Any] | None, config: Any, smooth: bool | None) -> _Settings:
        """The settings, or ConfigError for an unknown method or key / OSError for a missing config file."""
        if method is not None and method not in _native.FILTERS:
            raise ConfigError(f"fleet: unknown method {method!r}; expected one of {', '.join(_native.FILTERS)}")
        if isinstance(config, Mapping):
            FilterConfig(**dict(config))
        file = None if config_file is None else os.fspath(config_file)
        if file is not None and not os.path.isfile(file):
            raise FileNotFoundError(f"fleet: config file {file} does not exist")
        plain_config = config.to_dict() if isinstance(config, FilterConfig) else (None if config is None else dict(config))
        return cls(method, file, None if mapping is None else dict(mapping), plain_config, smooth)

    def job(self, log: str, output: Path | None, truth: str | None, overrides: dict[str, Any] | None) -> dict[str, Any]:
        """One task's inputs, with the key that says whether an earlier output is still valid: the
        shared digest, the log's and the ground truth's size and modification time, the
        overrides."""
        job = {
            "path": log,
            "output": None if output is None else os.fspath(output),
            "method": self.method,
            "config_file": self.config_file,
            "mapping": self.mapping,
            "config": self.config,
            "overrides": overrides,
            "smooth": self.smooth,
            "ground_truth": truth,
        }
        own = {"shared": self.digest, "log": _file_stamp(log), "truth": _file_stamp(truth), "overrides": overrides}
        job["key"] = _digest(own) if output is not None else None
        return job


def _distinct_paths(paths: Sequence[_PathLike]) -> list[str]:
    """The paths as strings; ValueError for one given twice (two tasks would write one output)."""
    logs = [os.fspath(p) for p in paths]
    seen: dict[str, str] = {}
    for log in logs:
        real = os.path.realpath(log)
        if real in seen:
            raise ValueError(f"fleet: {log!r} is given twice (as {seen[real]!r})")
        seen[real] = log
    return logs


def _output_paths(logs: list[str], out_dir: Path) -> list[Path]:
    """Each log's Parquet path: its path under the deepest directory holding all logs."""
    if not logs:
        return []
    absolute = [os.path.abspath(log) for log in logs]
    root = os.path.commonpath([os.path.dirname(a) for a in absolute])
    return [(out_dir / os.path.relpath(a, root)).with_suffix(".parquet") for a in absolute]


def _truth_for(ground_truth: _GroundTruth, log: str) -> str | None:
    """The ground-truth CSV of ``log`` from a dict or function, or None."""
    if ground_truth is None:
        return None
    if callable(ground_truth):
        found = ground_truth(log)
    else:
        found = {os.fspath(k): v for k, v in ground_truth.items()}.get(log)
    return None if found is None else os.fspath(found)


def _checked_overrides(point: Mapping[str, Any], index: int) -> dict[str, Any]:
    """A configuration of a sweep as flat dotted keys; ConfigError (naming it) for an unknown key."""
    flat: dict[str, Any] = {}
    for key, value in point.items():
        if isinstance(value, Mapping) and key != "range_calibration":  # a section of fields
            flat.update({f"{key}.{field}": v for field, v in value.items()})
        else:
            flat[key] = value
    try:
        FilterConfig(**flat)
    except ValueError as e:
        raise type(e)(f"sweep: configs[{index}]: {e}") from e
    return flat


def _setting_column(values: list[Any]) -> tuple[Any, list[Any]]:
    """A swept setting's column: dtype and values (numbers as Float64, bools as Boolean, anything
    else as JSON text)."""
    present = [v for v in values if v is not None]
    if all(isinstance(v, bool) for v in present):
        return pl.Boolean, values
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in present):
        return pl.Float64, [None if v is None else float(v) for v in values]
    return pl.String, [None if v is None else json.dumps(v, default=_jsonable) for v in values]


def _jsonable(value: Any) -> Any:
    """Plain JSON for numpy values inside configurations (for the input key)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return str(value)


def _file_stamp(path: str | None) -> list[Any] | None:
    """Size and modification time of a file (what says it changed), None when absent."""
    if path is None:
        return None
    try:
        st = os.stat(path)
    except OSError:
        return None
    return [os.path.abspath(path), st.st_size, st.st_mtime_ns]


def _digest(parts: dict[str, Any]) -> str:
    """SHA-256 of the parts as sorted JSON (numpy values as lists)."""
    return hashlib.sha256(json.dumps(parts, sort_keys=True, default=_jsonable).encode()).hexdigest()


def _summary_path(output: str) -> Path:
    """The JSON summary written beside an output."""
    return Path(output).with_suffix(".summary.json")


def _reusable(job: dict[str, Any]) -> dict[str, Any] | None:
    """The summary row of an earlier run of ``job`` whose output is still valid, else None."""
    summary = _summary_path(job["output"])
    if not (summary.is_file() and Path(job["output"]).is_file()):
        return None
    try:
        saved = json.loads(summary.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(saved, dict) or saved.get("key") != job["key"]:
        return None
    row = saved.get("row")
    return {**row, "reused": True} if isinstance(row, dict) else None


def _replace_atomically(write: Callable[[Path], object], target: Path) -> None:
    """Writes through ``write`` to a hidden temporary beside ``target``, then renames it over."""
    target.parent.mkdir(parents=True, exist_ok=True)
    partial = target.with_name(f".{target.name}.{os.getpid()}.partial")
    try:
        write(partial)
        os.replace(partial, target)
    finally:
        partial.unlink(missing_ok=True)


def _summary_row(info: dict[str, Any]) -> dict[str, Any]:
    """The summary columns of a replay's ``info``."""
    counted = list(info.get("anchors", [])) + list((info.get("sensors") or {}).values())
    health = info.get("health") or {}
    model = info.get("model") or {}
    row: dict[str, Any] = {name: sum(int(c.get(name, 0)) for c in counted) for name in _COUNTS}
    row.update({name: health.get(name) for name in _HEALTH})
    row.update({name: info.get(name) for name in ("method", "smoothed", "duration_s", "n_imu", "n_ranges", "n_tdoa", "truncated_bytes", "mean_nis", *_RMSE)})
    rejected = health.get("rejected")
    row["impossible"] = sum(rejected.values()) if isinstance(rejected, dict) else None
    row["model"] = model.get("chosen")
    row["model_reason"] = model.get("reason")
    row["model_overrides"] = None if not model else json.dumps(model.get("overrides"), default=_jsonable)
    row["status"] = "truncated" if (info.get("truncated_bytes") or 0) > 0 else "ok"
    return row


def _replay_log(job: dict[str, Any]) -> dict[str, Any]:
    """One task: replays ``job["path"]``, writes its outputs, returns its summary row (never raises
    for a bad log: the row says ``failed`` and why)."""
    # A task holds one CPU: one Rust worker thread, unless the worker's environment says otherwise
    # (read when the thread pool starts, at the first parallel call of this worker process).
    os.environ.setdefault("RAYON_NUM_THREADS", "1")
    start = time.perf_counter()
    row: dict[str, Any] = {"path": job["path"], "output": job["output"], "reused": False, "error": None}
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            trajectory, info = _replay(job["path"], job["method"], **{k: job[k] for k in _REPLAY_KEYWORDS})
        row.update(_summary_row(info))
        messages = [str(w.message) for w in caught] + list(info.get("warnings") or [])
        row["warnings"] = "; ".join(dict.fromkeys(messages)) or None
        if job["output"] is not None:
            _replace_atomically(trajectory.write_parquet, Path(job["output"]))
    except (OSError, ValueError) as e:
        row.update(status="failed", output=None, error=f"{type(e).__name__}: {e}")
    row["wall_s"] = time.perf_counter() - start
    if job["output"] is not None and row["status"] != "failed":
        text = json.dumps({"key": job["key"], "row": row}, default=_jsonable)
        _replace_atomically(lambda p: p.write_text(text), _summary_path(job["output"]))
    return row


def _import_ray() -> ModuleType:
    """The ray module, or ImportError saying how to install it."""
    try:
        import ray
    except ImportError as e:
        raise ImportError('uwbimu_rs.fleet needs Ray: pip install "uwbimu_rs[fleet]" (or pip install ray)') from e
    return ray


def _connect(address: str | None, num_cpus: int | None) -> ModuleType:
    """Ray, joined to the cluster at ``address`` or to a local instance (started when needed)."""
    if address is not None and num_cpus is not None:
        raise ValueError("fleet: num_cpus sizes a local Ray; a cluster at an address has its own CPUs")
    ray = _import_ray()
    if not ray.is_initialized():
        if address is None:
            ray.init(address="local", num_cpus=num_cpus, include_dashboard=False, logging_level=logging.WARNING)
        else:
            ray.init(address=address, logging_level=logging.WARNING)
    return ray


def _run_tasks(
    jobs: list[dict[str, Any]], address: str | None, num_cpus: int | None, max_retries: int, progress: bool
) -> list[dict[str, Any]]:
    """Runs the jobs as Ray tasks of one CPU (one Rust thread each) and collects the rows as the
    tasks finish; rows in job order. A task Ray gives up on (its worker lost ``max_retries`` + 1
    times) becomes a failed row. ``progress`` draws a line on stderr as rows come in."""
    if max_retries < 0:
        raise ValueError(f"fleet: max_retries must be ≥ 0, got {max_retries}")
    ray = _connect(address, num_cpus)
    task = ray.remote(num_cpus=1, max_retries=max_retries)(_replay_log)
    refs = [task.remote(job) for job in jobs]
    index = {ref: k for k, ref in enumerate(refs)}
    rows: list[dict[str, Any]] = [{} for _ in jobs]
    pending, failed, start = list(refs), 0, time.perf_counter()
    try:
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                k = index[ref]
                rows[k] = _task_row(ray, ref, jobs[k])
                failed += rows[k]["status"] == "failed"
            if progress:
                finished = len(jobs) - len(pending)
                rate = finished / max(time.perf_counter() - start, 1e-9)
                end = "\n" if not pending else ""
                print(f"\rfleet: {finished}/{len(jobs)} logs, {failed} failed, {rate:.1f} logs/s", end=end, file=sys.stderr, flush=True)
    except KeyboardInterrupt:
        for ref in pending:
            ray.cancel(ref, force=True)
        raise
    return rows


def _task_row(ray: ModuleType, ref: Any, job: dict[str, Any]) -> dict[str, Any]:
    """The row a finished task returned, or a failed row with Ray's error (a task lost for good)."""
    try:
        row: dict[str, Any] = ray.get(ref)
    except ray.exceptions.RayError as e:
        reason = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        return {"path": job["path"], "output": None, "reused": False, "status": "failed", "error": f"{type(e).__name__}: {reason}"}
    return row


def _frame(rows: list[dict[str, Any]], columns: Mapping[str, tuple[Any, str]]) -> pl.DataFrame:
    """The table of ``rows`` with exactly ``columns`` (absent values null)."""
    data = {name: [row.get(name) for row in rows] for name in columns}
    return pl.DataFrame(data, schema={name: dtype for name, (dtype, _) in columns.items()})
