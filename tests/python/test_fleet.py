"""uwbimu_rs.fleet on a local Ray of 2 CPUs: a dozen generated logs with a corrupt and a truncated
one, outputs against serial replay, re-runs, a worker killed mid-task, sweeps, the real log."""

# Under xdist this file's tests share one worker (conftest.py, ONE_WORKER).
from __future__ import annotations

import dataclasses
import logging
import os
import shutil
import signal
import subprocess
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import polars as pl
import pytest

import uwbimu_rs
from uwbimu_rs import fleet, sim
from shared_data import ISAS, needs_isas

ray = pytest.importorskip("ray", reason="Ray is not installed (pip install 'uwbimu_rs[fleet]')")

ROOT = Path(__file__).resolve().parents[2]

SCENARIOS = ("hall_vehicle_nlos", "hall_vehicle", "garage_rectangle", "garage_figure8")

#: Length of each generated log, s: the presets' first 40 s (of 82–150 s). What is tested is the
#: fleet's bookkeeping against serial replay, which a shorter log holds as well at a third of the
#: cost; a log still outlasts `best`'s model-choice window, and a task runs long enough to be killed.
LOG_S = 40.0


@pytest.fixture(scope="module")
def local_ray():
    """One local Ray of 2 CPUs for the module (started here, in the main thread)."""
    ray.init(address="local", num_cpus=2, include_dashboard=False, logging_level=logging.ERROR)
    yield
    ray.shutdown()


def _write_truth(run: sim.SimResult, path: Path) -> None:
    """The run's truth as a ground-truth CSV (t, x, y, z)."""
    t = run.truth[:, 0:1]
    np.savetxt(path, np.hstack([t, run.truth[:, 1:4]]), delimiter=",", header="t,x,y,z", comments="")


def _first_seconds(run: sim.SimResult, seconds: float) -> sim.SimResult:
    """``run`` cut to its first ``seconds`` (IMU, ranges with their labels, truth)."""
    end = run.imu[0, 0] + seconds
    kept = run.ranges[:, 0] <= end
    return dataclasses.replace(
        run, imu=run.imu[run.imu[:, 0] <= end], ranges=run.ranges[kept], range_labels=run.range_labels[kept], truth=run.truth.filter(pl.col("t") <= end)
    )


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """Ten simulated logs in two directories (each with its truth CSV), a corrupt file and a copy of
    the first log cut at 60 % (no footer): (paths, truth dict, the corrupt and the truncated path)."""
    base = tmp_path_factory.mktemp("fleet_logs")
    paths: list[str] = []
    truth: dict[str, str] = {}
    for k in range(10):
        run = _first_seconds(sim.preset(SCENARIOS[k % len(SCENARIOS)], seed=k), LOG_S)
        folder = base / ("robot_a" if k % 2 == 0 else "robot_b")
        folder.mkdir(exist_ok=True)
        path = folder / f"run{k // 2}.mcap"
        sim.write_mcap(run, path)
        _write_truth(run, path.with_suffix(".csv"))
        paths.append(str(path))
        truth[str(path)] = str(path.with_suffix(".csv"))
    corrupt = base / "robot_b" / "corrupt.mcap"
    corrupt.write_bytes(b"\x89MCAP0\r\n" + bytes(range(256)) * 8)
    whole = Path(paths[0]).read_bytes()
    truncated = base / "robot_a" / "cut.mcap"
    # Cut at 60 %: past the first complete chunk of the 40 s log (at half, none is complete).
    truncated.write_bytes(whole[: len(whole) * 3 // 5])
    truth[str(truncated)] = truth[paths[0]]
    return paths + [str(corrupt), str(truncated)], truth, str(corrupt), str(truncated)


def _assert_same_trajectory(parquet: str, expected: pl.DataFrame) -> None:
    """The Parquet trajectory has the serial run's columns and values to 1e-9."""
    got = pl.read_parquet(parquet)
    assert got.columns == expected.columns
    assert got.height == expected.height
    for name in expected.columns:
        a, b = got[name].to_numpy().astype(float), expected[name].to_numpy().astype(float)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9, err_msg=f"{parquet}: column {name}")


def test_fleet_replay_matches_serial_and_reports_bad_logs(local_ray, logs, tmp_path):
    paths, truth, corrupt, truncated = logs
    summary = fleet.replay(paths, "best", out_dir=tmp_path, ground_truth=truth)
    assert summary.columns == list(fleet.SUMMARY_COLUMNS)
    assert summary["path"].to_list() == paths
    status = dict(zip(summary["path"], summary["status"]))
    assert status[corrupt] == "failed" and status[truncated] == "truncated"
    assert [s for p, s in status.items() if p not in (corrupt, truncated)] == ["ok"] * 10
    bad = summary.filter(pl.col("path") == corrupt).row(0, named=True)
    assert "FormatError" in bad["error"] and corrupt in bad["error"] and bad["output"] is None
    cut = summary.filter(pl.col("path") == truncated).row(0, named=True)
    assert cut["truncated_bytes"] > 0 and "footer" in cut["warnings"]
    for row in summary.filter(pl.col("status") != "failed").iter_rows(named=True):
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=".*ends before its footer", category=UserWarning)
            expected, info = uwbimu_rs.replay(row["path"], "best", ground_truth=truth[row["path"]])
        _assert_same_trajectory(row["output"], expected)
        assert row["n_imu"] == info["n_imu"] and row["n_ranges"] == info["n_ranges"]
        assert row["accepted"] == sum(a["accepted"] for a in info["anchors"])
        assert row["rejected"] == sum(a["rejected"] for a in info["anchors"])
        assert row["mean_nis"] == info["mean_nis"]
        assert row["rmse_horizontal_m"] == info["rmse_horizontal_m"] and 0 < row["rmse_horizontal_m"] < 1.0
        assert row["model"] == info["model"]["chosen"] and row["smoothed"] is True
    # Outputs mirror the logs' directories: robot_a/run0.mcap → out/robot_a/run0.parquet.
    first = summary.row(0, named=True)
    assert Path(first["output"]) == tmp_path / "robot_a" / "run0.parquet"


def test_rerun_reuses_finished_logs_unless_forced_or_changed(local_ray, logs, tmp_path):
    paths, _, corrupt, _ = logs
    good = [p for p in paths if p != corrupt][:3] + [corrupt]
    first = fleet.replay(good, "ekf", out_dir=tmp_path)
    stamps = {o: os.stat(o).st_mtime_ns for o in first["output"].drop_nulls()}
    again = fleet.replay(good, "ekf", out_dir=tmp_path)
    assert again["reused"].to_list() == [True, True, True, False]
    assert again.drop("reused", "wall_s").equals(first.drop("reused", "wall_s"))
    assert again["wall_s"].head(3).equals(first["wall_s"].head(3)), "a reused row keeps its run's figures"
    assert {o: os.stat(o).st_mtime_ns for o in again["output"].drop_nulls()} == stamps
    forced = fleet.replay(good, "ekf", out_dir=tmp_path, force=True)
    assert not any(forced["reused"])
    changed = fleet.replay(good, "ekf", out_dir=tmp_path, config={"ranging.range_std": 0.3})
    assert not any(changed["reused"])
    assert changed["mean_nis"][0] != first["mean_nis"][0]


def _kill_first_task_worker(run) -> tuple[object, int | None]:
    """Runs ``run()`` in a thread and SIGKILLs the first Ray worker seen executing a fleet task;
    returns the result and the killed pid (None if no task was caught running)."""
    result: dict[str, object] = {}
    thread = threading.Thread(target=lambda: result.setdefault("out", run()))
    thread.start()
    killed = None
    while thread.is_alive() and killed is None:
        found = subprocess.run(["pgrep", "-f", "ray::_replay_log"], capture_output=True, text=True).stdout.split()
        if found:
            killed = int(found[0])
            os.kill(killed, signal.SIGKILL)
        time.sleep(0.005)
    thread.join()
    return result["out"], killed


@pytest.mark.skipif(shutil.which("pgrep") is None, reason="pgrep (procps) is needed to find a Ray worker to kill")
@pytest.mark.parametrize("max_retries", [2, 0])
def test_task_lost_with_its_worker_is_retried(local_ray, logs, tmp_path, max_retries):
    paths = logs[0][:4]
    summary, killed = _kill_first_task_worker(lambda: fleet.replay(paths, "best", out_dir=tmp_path, max_retries=max_retries))
    assert killed is not None, "no fleet task was seen running"
    if max_retries:
        assert summary["status"].to_list() == ["ok"] * 4
        for row in summary.iter_rows(named=True):
            _assert_same_trajectory(row["output"], uwbimu_rs.replay(row["path"], "best")[0])
    else:
        lost = summary.filter(pl.col("status") == "failed")
        assert lost.height == 1 and "WorkerCrashedError" in lost["error"][0]
        assert (summary["status"] == "ok").sum() == 3


def test_sweep_grid_over_logs_equals_serial_runs(local_ray, logs):
    paths, truth, corrupt, _ = logs
    datasets = paths[:3] + [corrupt]
    configs = fleet.grid({"ranging.range_std": [0.1, 0.3], "robust.significance": [0.01]})
    table = fleet.sweep("riekf", configs, datasets, ground_truth=truth)
    assert table.height == 8
    assert table.columns[:3] == ["config", "ranging.range_std", "robust.significance"]
    assert table["config"].to_list() == [0] * 4 + [1] * 4
    assert table["ranging.range_std"].to_list() == [0.1] * 4 + [0.3] * 4
    assert table.filter(pl.col("path") == corrupt)["status"].to_list() == ["failed", "failed"]
    for row in table.filter(pl.col("status") == "ok").iter_rows(named=True):
        _, info = uwbimu_rs.replay(row["path"], "riekf", config=configs[row["config"]], ground_truth=truth[row["path"]])
        assert row["rmse_horizontal_m"] == info["rmse_horizontal_m"]
        assert row["mean_nis"] == info["mean_nis"]
    # A setting whose value is a mapping (a range calibration) is a setting, not a section.
    identity = fleet.sweep("ekf", [{"range_calibration": {0: [0.0, 1.0, 0.0, 0.0]}}], paths[:1])
    assert identity["status"].to_list() == ["ok"] and identity["range_calibration"][0] == '{"0": [0.0, 1.0, 0.0, 0.0]}'
    assert identity["mean_nis"][0] == uwbimu_rs.replay(paths[0], "ekf")[1]["mean_nis"]
    nis = table.filter(pl.col("status") == "ok").group_by("config").agg(pl.col("mean_nis").mean()).sort("config")
    assert nis["mean_nis"][0] > 2 * nis["mean_nis"][1], "a 3× larger range σ must shrink the NIS"


def test_progress_line_counts_logs_and_failures(local_ray, logs, tmp_path, capsys):
    paths, _, corrupt, _ = logs
    fleet.replay(paths[:3] + [corrupt], "ekf", out_dir=tmp_path, progress=True)
    err = capsys.readouterr().err
    assert "fleet: 1/4 logs" in err and err.rstrip().split("\r")[-1].startswith("fleet: 4/4 logs, 1 failed, ")


def test_bad_arguments_fail_before_any_task(logs, tmp_path):
    paths = logs[0][:2]
    with pytest.raises(uwbimu_rs.ConfigError, match="unknown method 'ekff'"):
        fleet.replay(paths, "ekff", out_dir=tmp_path)
    with pytest.raises(uwbimu_rs.ConfigError):
        fleet.replay(paths, "ekf", out_dir=tmp_path, config={"ranging.range_stdd": 0.1})
    with pytest.raises(uwbimu_rs.ConfigError, match=r"configs\[1\]"):
        fleet.sweep("ekf", [{}, {"no.such_key": 1.0}], paths)
    with pytest.raises(ValueError, match="given twice"):
        fleet.replay([paths[0], paths[1], paths[0]], "ekf", out_dir=tmp_path)
    with pytest.raises(ValueError, match="num_cpus"):
        fleet.replay(paths, "ekf", out_dir=tmp_path, address="auto", num_cpus=2, force=True)
    with pytest.raises(ValueError, match="no values"):
        fleet.grid({"ranging.range_std": []})

    assert not any(tmp_path.iterdir()), "nothing is written for rejected arguments"


@needs_isas
def test_real_log_copies_and_a_truncated_one(local_ray, tmp_path):
    """The bar of issue 25: copies of isas-walk1 plus a truncated one, outputs equal to serial replay."""
    source = (ISAS / "isas-walk1.mcap").read_bytes()
    paths = []
    for k in range(3):
        copy = tmp_path / "logs" / f"walk{k}.mcap"
        copy.parent.mkdir(exist_ok=True)
        copy.write_bytes(source)
        paths.append(str(copy))
    cut = tmp_path / "logs" / "walk_cut.mcap"
    cut.write_bytes(source[: int(len(source) * 0.6)])
    paths.append(str(cut))
    gt = str(ISAS / "gt_anchor_frame.csv")
    config = ROOT / "examples" / "isas-walk1.toml"
    summary = fleet.replay(paths, out_dir=tmp_path / "out", config_file=config, ground_truth=lambda _: gt)
    assert summary.height == 4
    assert summary["status"].to_list() == ["ok", "ok", "ok", "truncated"]
    expected, info = uwbimu_rs.replay(paths[0], "best", config_file=config, ground_truth=gt)
    for row in summary.head(3).iter_rows(named=True):
        _assert_same_trajectory(row["output"], expected)
        assert row["rmse_horizontal_aligned_m"] == info["rmse_horizontal_aligned_m"]
    with pytest.warns(UserWarning, match="ends before its footer"):
        cut_expected, _ = uwbimu_rs.replay(str(cut), "best", config_file=config, ground_truth=gt)
    _assert_same_trajectory(summary["output"][3], cut_expected)
    assert 0 < summary["n_imu"][3] < summary["n_imu"][0]


def test_docs_summary_table_is_the_declared_columns():
    names = {pl.String: "str", pl.Boolean: "bool", pl.Float64: "f64", pl.Int64: "i64"}
    expected = [f"| `{name}` | {names[dtype]} | {meaning} |" for name, (dtype, meaning) in fleet.SUMMARY_COLUMNS.items()]
    text = (ROOT / "docs" / "fleet.md").read_text(encoding="utf-8").splitlines()
    start = text.index("| column | type | meaning |") + 2
    assert text[start : start + len(expected) + 1] == [*expected, ""], "docs/fleet.md: regenerate the summary table from fleet.SUMMARY_COLUMNS"
