"""Replay from Python like the CLI: the ``uwbimu-replay`` console script (``--help``, ``--json``),
``replay(ground_truth=...)``, the merge of ``mapping=`` into the config file's mapping, the two
spellings of ground-truth columns, and the progress bars on stderr."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import polars as pl
import pytest

import uwbimu_rs
from uwbimu_rs import metrics
from shared_data import ISAS, needs_isas

SCRIPT = Path(sys.executable).with_name("uwbimu-replay")
ROOT = Path(__file__).resolve().parents[2]
CONFIG = {"mounting.lever_arm": [0, 0, 0.05]}


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A simulated recording as MCAP, its truth as CSV in both column spellings, and a replay
    TOML whose mapping names the recording's topics."""
    out = tmp_path_factory.mktemp("replay_cli")
    run = uwbimu_rs.sim.preset("seed000_los", seed=4)
    mcap = out / "sim.mcap"
    uwbimu_rs.sim.write_mcap(run, mcap, range_std=0.1)
    truth = run.truth.select("t", "x", "y", "z")
    short, units = out / "truth.csv", out / "truth_units.csv"
    truth.write_csv(short)
    truth.rename({"t": "t_s", "x": "x_m", "y": "y_m", "z": "z_m"}).write_csv(units)
    toml = out / "replay.toml"
    toml.write_text('method = "ekf"\n[config]\nmounting.lever_arm = [0, 0, 0.05]\n[mapping]\nimu_topic = "/imu"\n[mapping.uwb]\ntopics = ["/uwb"]\n')
    return {"dir": out, "mcap": mcap, "truth": short, "truth_units": units, "toml": toml}


def cli(*args: object) -> subprocess.CompletedProcess[str]:
    if not SCRIPT.exists():
        pytest.skip(f"console script {SCRIPT} not installed (run scripts/setup.sh)")
    return subprocess.run([str(SCRIPT), *map(str, args)], capture_output=True, text=True, timeout=300)


def test_console_script_help_lists_every_method():
    proc = cli("--help")
    assert proc.returncode == 0, proc.stderr
    assert "Usage: uwbimu-replay" in proc.stdout
    for name in uwbimu_rs.FILTERS:
        assert f"- {name}:" in proc.stdout, name
    assert "--json" in proc.stdout and "--no-progress" in proc.stdout
    bad = cli("x.mcap", "--method", "kalman")
    assert bad.returncode == 2 and "possible values" in bad.stderr and bad.stdout == ""


def test_json_summary_equals_replay_info(recording):
    csv = recording["dir"] / "out.csv"
    proc = cli(recording["mcap"], "--config", recording["toml"], "--ground-truth", recording["truth"], "--json", "--csv", csv)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    frame, info = uwbimu_rs.replay(recording["mcap"], config_file=recording["toml"], ground_truth=recording["truth"])
    assert summary["outputs"] == [str(csv)] and csv.exists()
    assert summary["method"] == info["method"] == "ekf" and summary["smoothed"] is info["smoothed"] is False
    # The command line streams the file and adds the errors up as they go: the same figures to
    # rounding (tests/integration/streamed_replay.rs holds the steps to 1e-9).
    figures = ("rmse_horizontal_m", "rmse_horizontal_aligned_m", "rmse_3d_m", "rmse_3d_aligned_m", "mean_nis")
    for key in figures:
        assert abs(summary[key] - info[key]) <= 1e-9, key
    assert summary["interrupted"] is None and summary["peak_rss_bytes"] > 0
    # Every other key of the summary but the command line's own is in the info dict, with the same value.
    for key, value in summary.items():
        if key not in ("outputs", "interrupted", "peak_rss_bytes") + figures:
            assert info[key] == value, key
    assert summary["n_imu"] == frame.height and summary["n_ground_truth"] > 0
    assert sum(a["accepted"] + a["down_weighted"] + a["rejected"] for a in summary["anchors"]) == summary["n_ranges"]
    assert 0 < info["rmse_horizontal_m"] < 0.3


def test_text_summary_says_whether_smoothed(recording):
    proc = cli(recording["mcap"], "--config", recording["toml"], "--method", "best", "--no-progress")
    assert proc.returncode == 0, proc.stderr
    assert "method: best (RTS-smoothed; --forward for the causal filter)" in proc.stdout
    forward = cli(recording["mcap"], "--config", recording["toml"], "--method", "best", "--forward")
    assert "method: best (causal filter" in forward.stdout
    _, info = uwbimu_rs.replay(recording["mcap"], "best", config=CONFIG)
    assert info["smoothed"] is True


def test_mapping_merges_into_the_config_files_mapping(recording, tmp_path):
    gt = {"ground_truth": {"file": str(recording["truth"])}}
    _, info = uwbimu_rs.replay(recording["mcap"], config_file=recording["toml"], mapping=gt)
    assert info["rmse_horizontal_m"] > 0 and info["n_ground_truth"] > 0
    # The file's UWB topic is kept when the dict names only ground truth ...
    misfit = tmp_path / "misfit.toml"
    misfit.write_text('[mapping.uwb]\ntopics = ["/uwb_elsewhere"]\n')
    with pytest.raises(uwbimu_rs.MappingError, match="/uwb_elsewhere"):
        uwbimu_rs.replay(recording["mcap"], "ekf", config_file=misfit, mapping=gt)
    # ... and a key given overrides the file's.
    _, fixed = uwbimu_rs.replay(recording["mcap"], "ekf", config_file=misfit, config=CONFIG, mapping={**gt, "uwb": {"topics": ["/uwb"]}})
    assert fixed["rmse_horizontal_m"] == info["rmse_horizontal_m"]
    with pytest.raises(uwbimu_rs.MappingError, match="/nope"):
        uwbimu_rs.replay(recording["mcap"], config_file=recording["toml"], mapping={"imu_topic": "/nope"})


def test_both_truth_spellings_give_equal_results(recording):
    short = metrics.read_truth(recording["truth"])
    units = metrics.read_truth(recording["truth_units"])
    assert short.columns == ["t", "x", "y", "z"] and short.equals(units)
    _, a = uwbimu_rs.replay(recording["mcap"], config_file=recording["toml"], ground_truth=recording["truth"])
    _, b = uwbimu_rs.replay(recording["mcap"], config_file=recording["toml"], ground_truth=recording["truth_units"])
    assert a["rmse_horizontal_m"] == b["rmse_horizontal_m"] and a["rmse_3d_aligned_m"] == b["rmse_3d_aligned_m"]
    frame, _ = uwbimu_rs.replay(recording["mcap"], config_file=recording["toml"])
    renamed = short.rename({"t": "t_s", "x": "x_m", "y": "y_m", "z": "z_m"})
    e1, e2 = metrics.evaluate(frame, short), metrics.evaluate(frame, renamed)
    assert e1.horizontal == e2.horizontal and abs(e1.horizontal.rmse - a["rmse_horizontal_m"]) < 1e-12
    assert metrics.TRUTH_COLUMNS == [["t", "t_s"], ["x", "x_m"], ["y", "y_m"], ["z", "z_m"]]
    with pytest.raises(ValueError, match="t or t_s"):
        metrics.evaluate(frame, short.rename({"t": "time"}))


def test_bad_truth_files_raise_os_errors_naming_them(recording, tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.csv"):
        uwbimu_rs.replay(recording["mcap"], config_file=recording["toml"], ground_truth=tmp_path / "missing.csv")
    bad = tmp_path / "vive.csv"
    bad.write_text("t_header_s,t_bag_s,x_m,y_m,z_m\n1,1,0,0,0\n")
    with pytest.raises(uwbimu_rs.FormatError, match=r"vive.csv.*line 1.*t or t_s"):
        metrics.read_truth(bad)
    broken = tmp_path / "broken.csv"
    broken.write_text("t,x,y,z\n0,1,2,3\n0.1,nan,2,3\n")
    with pytest.raises(OSError, match="line 3"):
        uwbimu_rs.replay(recording["mcap"], config_file=recording["toml"], ground_truth=broken)


def test_progress_goes_to_stderr_only_when_asked(recording, capfd):
    run = uwbimu_rs.sim.preset("seed000_los", seed=4)
    quiet = uwbimu_rs.run_filter("ekf", run.imu, run.ranges, run.anchors, config=CONFIG)
    assert capfd.readouterr().err == ""
    loud = uwbimu_rs.run_filter("ekf", run.imu, run.ranges, run.anchors, config=CONFIG, progress=True)
    out = capfd.readouterr()
    assert "filtering" in out.err and "100%" in out.err and out.out == ""
    assert quiet.equals(loud)
    uwbimu_rs.run_filters("ekf", [(run.imu, run.ranges, run.anchors)] * 2, config=CONFIG, smooth=True, progress=True)
    err = capfd.readouterr().err
    assert "filtering" in err and "smoothing" in err
    uwbimu_rs.replay(recording["mcap"], config_file=recording["toml"], progress=True)
    assert "filtering" in capfd.readouterr().err


@needs_isas
def test_isas_walk1_json_and_replay_agree_on_the_real_log():
    config = ROOT / "examples" / "isas-walk1.toml"
    truth = ISAS / "gt_anchor_frame.csv"
    proc = cli(ISAS / "isas-walk1.mcap", "--config", config, "--ground-truth", truth, "--json")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    _, info = uwbimu_rs.replay(ISAS / "isas-walk1.mcap", config_file=config, ground_truth=truth)
    assert abs(summary["rmse_horizontal_aligned_m"] - info["rmse_horizontal_aligned_m"]) <= 1e-9
    assert summary["rmse_horizontal_aligned_m"] < 0.25
    np.testing.assert_equal(summary["n_imu"], 4839)
    assert pl.DataFrame(metrics.read_truth(truth)).height > 3000
