"""MCAP reading and replay: fixtures written by scripts/make_fixtures.py (PyPI mcap +
mcap-ros2-support) are read back through the mappings and compared with what was written."""

from __future__ import annotations

import importlib.util
import math
import tomllib
from pathlib import Path

import numpy as np
import polars as pl
import pytest

import uwbimu_rs
from shared_data import ISAS, needs_isas

ROOT = Path(__file__).resolve().parents[2]
VENDOR = {
    "uwb": {
        "topics": ["/uwb"],
        "range": "ranges[].range_mm",
        "anchor_id": "ranges[].id",
        "valid": "ranges[].valid == 1",
        "scale": 0.001,
    }
}

_spec = importlib.util.spec_from_file_location("make_fixtures", ROOT / "scripts" / "make_fixtures.py")
assert _spec is not None and _spec.loader is not None
fixtures = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fixtures)


@pytest.fixture(scope="module")
def fixture_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("mcap")
    assert fixtures.main([str(out)]) == 0
    return out


def check_against_written(data, *, n_ranges):
    imu, ranges, anchors = data["imu"], data["ranges"], data["anchors"]
    assert imu.columns == ["t", "ax", "ay", "az", "gx", "gy", "gz"]
    # The IMU the script wrote: level, yaw rate 2π·0.25 rad/s, centripetal 1.5·w² on body -x.
    w = 2 * math.pi * 0.25
    np.testing.assert_allclose(imu["gz"].to_numpy(), w)
    np.testing.assert_allclose(imu["ax"].to_numpy(), -1.5 * w * w)
    np.testing.assert_allclose(imu["az"].to_numpy(), 9.80665)
    assert np.all(np.diff(imu["t"].to_numpy()) > 0)
    assert anchors["id"].to_list() == list(fixtures.ANCHORS)
    np.testing.assert_allclose(anchors.select("x", "y", "z").to_numpy(), np.array(list(fixtures.ANCHORS.values())))
    assert ranges.height == n_ranges
    # Every range equals the distance from the written tag position (float32 mm ≈ 1e-4 m).
    t0 = fixtures.T0_NS * 1e-9
    ids = anchors["id"].to_list()
    for t, a, r in ranges.select("t", "anchor", "range").iter_rows():
        assert abs(r - fixtures.true_range(t - t0, ids[a])) < 1e-3


@pytest.mark.parametrize("kind", ["zstd", "lz4", "none", "unindexed"])
def test_vendor_messages_through_the_field_mapping(fixture_dir, kind):
    data = uwbimu_rs.read_mcap(fixture_dir / f"{kind}.mcap", mapping=VENDOR)
    # 40 messages × 4 anchors, every fifth range flagged invalid.
    check_against_written(data, n_ranges=128)
    assert data["imu"].height == 200
    assert sum(data["stats"]["invalid_per_anchor"].values()) == 32
    assert data["stats"]["anchor_source"] == "metadata uwbimu.anchors"


def test_json_ranges_and_sensor_msgs_range(fixture_dir):
    for kind in ["json", "range"]:
        data = uwbimu_rs.read_mcap(fixture_dir / f"{kind}.mcap")
        check_against_written(data, n_ranges=160)
        np.testing.assert_allclose(data["ranges"]["variance"].to_numpy(), 0.01, rtol=1e-6)


def test_out_of_order_messages_are_reordered_or_counted(fixture_dir):
    data = uwbimu_rs.read_mcap(fixture_dir / "out_of_order.mcap", mapping={**VENDOR, "time_source": "log"})
    stats = data["stats"]
    assert stats["late_dropped"] == 1
    assert stats["reordered"] >= 5
    assert data["imu"].height == 199
    assert np.all(np.diff(data["imu"]["t"].to_numpy()) > 0)
    # A window of 3 s takes the late message back in.
    wide = uwbimu_rs.read_mcap(fixture_dir / "out_of_order.mcap", mapping={**VENDOR, "reorder_window_s": 3.0})
    assert wide["stats"]["late_dropped"] == 0 and wide["imu"].height == 200


def test_replay_returns_the_run_filter_columns(fixture_dir):
    frame, info = uwbimu_rs.replay(fixture_dir / "zstd.mcap", "ekf", mapping=VENDOR)
    assert frame.columns[:4] == ["t", "x", "y", "z"] and frame.height == 200
    assert frame["still"].dtype == pl.Boolean
    assert [a["id"] for a in info["anchors"]] == list(fixtures.ANCHORS)
    assert sum(a["accepted"] + a["down_weighted"] + a["rejected"] for a in info["anchors"]) == 128
    fixes, _ = uwbimu_rs.replay(fixture_dir / "json.mcap", "uwb_ls")
    assert fixes.columns[-2:] == ["n_ranges", "residual_rms"]


def test_a_recording_cut_short_reads_up_to_its_last_complete_record(fixture_dir, tmp_path):
    whole = (fixture_dir / "zstd.mcap").read_bytes()
    full = uwbimu_rs.read_mcap(fixture_dir / "zstd.mcap", mapping=VENDOR)
    assert full["stats"]["complete"]
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(whole[: len(whole) * 3 // 4])
    with pytest.warns(UserWarning, match=r"ends before its footer .* bytes after it are lost"):
        part = uwbimu_rs.read_mcap(cut, mapping=VENDOR)
    assert not part["stats"]["complete"]
    n, total = len(part["imu"]["t"]), len(full["imu"]["t"])
    assert 0 < n < total
    assert part["stats"]["messages"] < full["stats"]["messages"]
    # What was read is the start of the complete file, sample for sample.
    assert part["imu"]["t"].to_list() == full["imu"]["t"][:n].to_list()
    with pytest.warns(UserWarning, match="ends before its footer"):
        _, info = uwbimu_rs.replay(cut, "ekf", mapping=VENDOR)
    assert info["truncated_bytes"] > 0 and info["n_imu"] == n


def test_errors(fixture_dir, tmp_path):
    with pytest.raises(FileNotFoundError):
        uwbimu_rs.read_mcap(tmp_path / "missing.mcap")
    truncated = tmp_path / "truncated.mcap"
    truncated.write_bytes((fixture_dir / "zstd.mcap").read_bytes()[:12])
    with pytest.raises(OSError, match="truncated|end of file"):
        uwbimu_rs.read_mcap(truncated, mapping=VENDOR)
    with pytest.raises(uwbimu_rs.FormatError, match="magic"):
        bad = tmp_path / "bad.mcap"
        bad.write_bytes(b"not an mcap file at all")
        uwbimu_rs.read_mcap(bad)
    with pytest.raises(ValueError, match="range_cm"):
        uwbimu_rs.read_mcap(fixture_dir / "zstd.mcap", mapping={"uwb": {"topics": ["/uwb"], "range": "ranges[].range_cm"}})
    with pytest.raises(uwbimu_rs.MappingError, match="/nope"):
        uwbimu_rs.read_mcap(fixture_dir / "zstd.mcap", mapping={**VENDOR, "imu_topic": "/nope"})
    with pytest.raises(uwbimu_rs.MappingError, match=r"`mapping.uwbb`: unknown key \(did you mean `uwb`\?\)"):
        uwbimu_rs.read_mcap(fixture_dir / "zstd.mcap", mapping={"uwbb": {}})


@needs_isas
def test_isas_walk1_replay_with_the_checked_in_config():
    config_file = ROOT / "examples" / "isas-walk1.toml"
    mapping = tomllib.loads(config_file.read_text())["mapping"]
    mapping["ground_truth"] = {"file": str(ISAS / "gt_anchor_frame.csv")}
    frame, info = uwbimu_rs.replay(ISAS / "isas-walk1.mcap", config_file=config_file, mapping=mapping)
    assert info["method"] == "best" and info["smoothed"] and frame.height == 4839
    # Same figure as the Rust test tests/integration/isas_walk1.rs (measured 0.121 m).
    assert info["rmse_horizontal_aligned_m"] < 0.25
    data = uwbimu_rs.read_mcap(ISAS / "isas-walk1.mcap", mapping=mapping)
    assert data["ranges"].height == 4266 and data["ground_truth"].height > 3000


def test_fixture_script_rejects_unknown_kinds(tmp_path):
    assert fixtures.main([str(tmp_path), "json"]) == 0 and (tmp_path / "json.mcap").stat().st_size > 1000
    assert fixtures.main([str(tmp_path), "nope"]) == 2


def test_simulator_recording_round_trip(tmp_path):
    run = uwbimu_rs.sim.preset("hall_vehicle", seed=2)
    path = tmp_path / "demo.mcap"
    uwbimu_rs.sim.write_mcap(run, path, range_std=0.1)
    data = uwbimu_rs.read_mcap(path)
    # IMU times are rounded to whole nanoseconds in the file; values are exact doubles.
    np.testing.assert_allclose(data["imu"].to_numpy(), run.imu, rtol=0, atol=1e-9)
    np.testing.assert_allclose(data["ranges"].select("t", "anchor", "range").to_numpy(), run.ranges, rtol=0, atol=1e-9)
    np.testing.assert_allclose(data["anchors"].select("x", "y", "z").to_numpy(), run.anchors)
    assert data["anchors"]["id"].to_list() == [f"A{i}" for i in range(len(run.anchors))]
    np.testing.assert_allclose(data["ranges"]["variance"].to_numpy(), 0.01)
    # The replay equals run_filter on the arrays the file holds (its times are whole nanoseconds:
    # a 1e-9 s shift may flip a still-detector decision of the self-initialised filter).
    recorded = (data["imu"].to_numpy(), data["ranges"].select("t", "anchor", "range").to_numpy())
    direct = uwbimu_rs.run_filter("ekf", *recorded, run.anchors, config={"mounting.lever_arm": [0, 0, 0.05]})
    replayed, _ = uwbimu_rs.replay(path, "ekf", config={"mounting.lever_arm": [0, 0, 0.05]})
    np.testing.assert_allclose(replayed.select("x", "y", "z").to_numpy(), direct.select("x", "y", "z").to_numpy(), atol=1e-6)


def test_simulator_tdoa_round_trip_and_replay(tmp_path):
    run = uwbimu_rs.sim.zoo("agv_loop", seed=7, tdoa=True)
    path = tmp_path / "tdoa.mcap"
    uwbimu_rs.sim.write_mcap(run, path)
    data = uwbimu_rs.read_mcap(path)
    tdoa = data["tdoa"]
    assert tdoa.columns == ["t", "i", "j", "d_ij"] and tdoa["i"].dtype == pl.Int64
    # Times rounded to whole nanoseconds in the file; anchor indices and d_ij exact.
    np.testing.assert_allclose(tdoa.to_numpy(), run.tdoa, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(tdoa.select("i", "j", "d_ij").to_numpy(), run.tdoa[:, 1:])
    direct = uwbimu_rs.run_filter("rekf", run.imu, run.ranges, run.anchors, config=run.config, tdoa=run.tdoa)
    replayed, info = uwbimu_rs.replay(path, "rekf", config=run.config)
    np.testing.assert_allclose(replayed.select("x", "y", "z").to_numpy(), direct.select("x", "y", "z").to_numpy(), atol=1e-6)
    counts = info["sensors"]["tdoa"]
    assert counts["id"] == "tdoa" and counts["accepted"] + counts["down_weighted"] + counts["rejected"] == len(run.tdoa)
    with pytest.raises(ValueError, match="eskf does not take TDoA"):
        uwbimu_rs.replay(path, "eskf", config=run.config)
    with pytest.raises(uwbimu_rs.MappingError, match="has no field `distDiff`"):
        uwbimu_rs.read_mcap(path, mapping={"tdoa": {"tdoa": "distDiff"}})
    with pytest.raises(uwbimu_rs.MappingError, match=r"`mapping.tdoa.anchor`: unknown key \(did you mean `anchor_i` or `anchor_j`\?\)"):
        uwbimu_rs.read_mcap(path, mapping={"tdoa": {"anchor": "idA"}})


def test_a_file_error_names_the_file_and_keeps_its_cause(tmp_path):
    run = uwbimu_rs.sim.preset("hall_vehicle_nlos", seed=0)
    target = tmp_path / "no_such_dir" / "out.mcap"
    with pytest.raises(FileNotFoundError, match="no_such_dir/out.mcap") as info:
        uwbimu_rs.sim.write_mcap(run, target)
    assert isinstance(info.value.__cause__, OSError) and "No such file" in str(info.value.__cause__)


def test_replay_overrides_set_keys_over_the_config_file(tmp_path):
    run = uwbimu_rs.sim.preset("hall_vehicle_nlos", seed=4)
    log = tmp_path / "run.mcap"
    uwbimu_rs.sim.write_mcap(run, log)
    site = tmp_path / "site.toml"
    site.write_text('method = "riekf"\n[config.ins]\naccel_noise_density = 0.5\n')
    over, over_info = uwbimu_rs.replay(log, config_file=site, overrides={"ranging": {"range_std": 0.3}})
    both, both_info = uwbimu_rs.replay(log, "riekf", config={"ins.accel_noise_density": 0.5, "ranging.range_std": 0.3})
    assert over.equals(both) and over_info["mean_nis"] == both_info["mean_nis"]
    replaced, _ = uwbimu_rs.replay(log, config_file=site, config={"ranging.range_std": 0.3})
    assert not replaced.equals(over), "config= replaces the file's [config]: its IMU noise is gone"
    with pytest.raises(uwbimu_rs.ConfigError, match="ranging.range_stdd"):
        uwbimu_rs.replay(log, config_file=site, overrides={"ranging.range_stdd": 0.3})


def test_heights_speeds_and_two_tags_round_trip_through_mcap_and_replay(tmp_path):
    run = uwbimu_rs.sim.zoo("agv_loop", seed=3, altimeter=True, odometer=True, odometer_lateral=True, tag_separation_m=0.6)
    path = tmp_path / "sensors.mcap"
    uwbimu_rs.sim.write_mcap(run, path)
    mapping = {
        "uwb": {"topics": ["/uwb"]},
        "altitude": {"topics": ["/altitude"]},
        "odometry": {"topics": ["/odom"], "axes": ["x", "y", "z"]},
    }
    data = uwbimu_rs.read_mcap(path, mapping=mapping)
    # The arrays run_filter takes come back: the tag column exact, heights to f32, speeds exact.
    np.testing.assert_allclose(data["ranges"].select("t", "anchor", "range", "tag").to_numpy(), run.ranges, atol=1e-9)
    assert data["altitude"].columns == ["t", "z"]
    np.testing.assert_allclose(data["altitude"].to_numpy(), run.altitude, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(data["odometry"].to_numpy(), run.odometry, atol=1e-9)
    assert data["stats"]["sensors"]["odometry"] == {"used": int(np.isfinite(run.odometry[:, 1:]).sum()), "invalid": 0}
    # The replay of the file follows the batch run on the arrays (truth as the common yardstick).
    sensors = {"altitude": run.altitude, "odometry": run.odometry}
    direct = uwbimu_rs.run_filter("riekf", run.imu, run.ranges, run.anchors, initial=run.initial, config=run.config, **sensors)
    replayed, info = uwbimu_rs.replay(path, "riekf", mapping=mapping, config=run.config, initial=run.initial)
    gap = np.abs(replayed.select("x", "y", "z").to_numpy() - direct.select("x", "y", "z").to_numpy())
    assert np.median(gap) < 1e-6 and replayed.height == direct.height
    readings = {"altitude": len(run.altitude), "odometry": int(np.isfinite(run.odometry[:, 1:]).sum())}
    for name, n in readings.items():
        counts = info["sensors"][name]
        assert counts["accepted"] + counts["down_weighted"] + counts["rejected"] == n, name
    # Two tags need a method that fuses them and a lever arm each.
    with pytest.raises(ValueError, match="eskf fuses one tag"):
        uwbimu_rs.replay(path, "eskf", mapping={"uwb": {"topics": ["/uwb"]}}, config=run.config)
    # A tag the mapping does not list is dropped and counted.
    one = uwbimu_rs.read_mcap(path, mapping={**mapping, "uwb": {"topics": ["/uwb"], "tag_ids": ["0"]}})
    assert one["stats"]["unknown_tag"] == int((run.ranges[:, 3] == 1).sum()) and one["stats"]["unknown_tag_ids"] == ["1"]
