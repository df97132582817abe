"""Errors that help: the exception class, the key path the user wrote, the value given and a
"did you mean"; reprs that read as Python."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

import uwbimu_rs
from uwbimu_rs import ConfigError, MappingError, sim

ANCHORS = np.array([[0.0, 0.0, 2.0], [8.0, 0.0, 1.0], [8.0, 6.0, 2.0], [0.0, 6.0, 1.0]])
AT_REST = {"position": [4.0, 3.0, 0.3], "velocity": [0, 0, 0], "orientation": [1, 0, 0, 0]}


@pytest.fixture
def still():
    t = np.arange(0.0, 1.0, 0.01)
    imu = np.zeros((t.size, 7))
    imu[:, 0] = t
    imu[:, 3] = 9.80665
    ranges = np.array([[0.5, a, 5.0] for a in range(4)] + [[0.6, 0, 5.0]])
    return imu, ranges


def run(still, **kwargs):
    imu, ranges = still
    return uwbimu_rs.run_filter("ekf", imu, kwargs.pop("ranges", ranges), ANCHORS, **{"initial": AT_REST, **kwargs})


@pytest.mark.parametrize(
    ("key", "suggestion"),
    [("range_sdt", "ranging.range_std"), ("ranging.range_sdt", "ranging.range_std"), ("range_std", "ranging.range_std")],
)
def test_unknown_config_key_suggests_the_closest(still, key, suggestion):
    with pytest.raises(ConfigError, match=rf"unknown config `{key}` \(did you mean `{suggestion}`\?\); allowed: "):
        run(still, config={key: 0.2})
    with pytest.raises(ConfigError, match=rf"did you mean `{suggestion}`"):
        uwbimu_rs.FilterConfig(**{key: 0.2})


def test_a_typo_in_the_key_is_reported_before_the_value_type(still):
    with pytest.raises(ConfigError, match=r"unknown config `range_std` \(did you mean `ranging.range_std`\?\)"):
        run(still, config={"range_std": "0.2"})


def test_nested_config_keys_suggest_too(still):
    with pytest.raises(ConfigError, match=r"unknown config `ranging.rnage_std` \(did you mean `ranging.range_std`\?\)"):
        run(still, config={"ranging": {"rnage_std": 0.2}})


def test_unknown_method_suggests_the_closest(still):
    imu, ranges = still
    with pytest.raises(ConfigError, match=r"unknown method `rekff` \(did you mean `rekf`"):
        uwbimu_rs.run_filter("rekff", imu, ranges, ANCHORS)
    with pytest.raises(ConfigError, match=r"did you mean `rekf`"):
        uwbimu_rs.run_filters("rekff", [(imu, ranges, ANCHORS)])


def test_simulator_names_suggest_the_closest():
    with pytest.raises(ConfigError, match=r"unknown preset `seed000_lso` \(did you mean `seed000_los`"):
        sim.preset("seed000_lso")
    with pytest.raises(ConfigError, match=r"unknown zoo scenario `forklfit` \(did you mean `forklift`"):
        sim.zoo("forklfit")


@pytest.mark.parametrize(
    ("config", "pattern"),
    [
        ({"ranging.range_std": "0.2"}, r"config `ranging.range_std`: expected a number, True/False or a sequence of numbers, got str '0.2'"),
        ({"ranging": {"range_std": "0.2"}}, r"config `ranging.range_std`: .* got str '0.2'"),
        ({"ranging.range_std": -0.1}, r"config `ranging.range_std`: must be finite and > 0, got -0.1"),
        ({"constraints.zupt": 1.0}, r"config `constraints.zupt`: expected True or False, got 1"),
        ({"mounting.lever_arm": [0.0, 0.1]}, r"config `mounting.lever_arm`: expected 3 numbers per tag \(\[x, y, z\], tag 0 first, up to 4 tags\), got 2: \[0.0, 0.1\]"),
        ({"range_calibration": {0: [0, 1, 0]}}, r"config `range_calibration\[0\]`: expected 4 coefficients"),
        ({"range_calibration": {9: [0, 1, 0, 0]}}, r"config `range_calibration\[9\]`: there is no anchor 9 \(there are 4 anchors: 0..3\)"),
        ({"range_calibration": {0: [0, float("nan"), 0, 0]}}, r"config `range_calibration\[0\]`: coefficients must be finite"),
        ({"range_calibration": [0, 1, 0, 0]}, r"config `range_calibration`: expected a dict"),
        ("ranging.range_std=0.2", r"config `config`: expected a dict, got str"),
    ],
)
def test_every_config_problem_is_a_config_error(still, config, pattern):
    with pytest.raises(ConfigError, match=pattern):
        run(still, config=config)


def test_filter_config_kwargs_raise_config_error():
    with pytest.raises(ConfigError, match=r"config `ranging.range_std`: .* got str '0.2'"):
        uwbimu_rs.FilterConfig(**{"ranging.range_std": "0.2"})
    with pytest.raises(ConfigError, match=r"config `ranging.range_std`: must be finite and > 0, got 0"):
        uwbimu_rs.FilterConfig(**{"ranging.range_std": 0.0})


@pytest.mark.parametrize(
    ("orientation", "pattern"),
    [
        ([0, 0, 0, 0], r"zero norm"),
        ([1, 0, 0], r"expected 4 numbers, got 3"),
        ([1, 0, 0, float("nan")], r"must be finite, got NaN"),
        ("up", r"got str 'up'"),
    ],
)
def test_initial_state_errors_name_initial_keys(still, orientation, pattern):
    with pytest.raises(ConfigError, match=rf"initial state `initial.orientation`: .*{pattern}"):
        run(still, initial={**AT_REST, "orientation": orientation})
    with pytest.raises(ConfigError, match=r"initial.orientation"):
        uwbimu_rs.Ekf(ANCHORS, initial={**AT_REST, "orientation": orientation})


def test_unknown_initial_key_suggests(still):
    with pytest.raises(ConfigError, match=r"unknown initial-state key `positon` \(did you mean `position`\?\)"):
        run(still, initial={**AT_REST, "positon": [0, 0, 0]})


def test_anchor_column_non_integer_and_out_of_range(still):
    _, ranges = still
    bad = ranges.copy()
    bad[3, 1] = 1.5
    with pytest.raises(uwbimu_rs.UwbImuError, match=r"ranges: the anchor column holds 1.5 at row 3, not an anchor index \(a whole number in 0..3"):
        run(still, ranges=bad)
    bad[3, 1] = 7
    with pytest.raises(uwbimu_rs.UwbImuError, match=r"ranges: anchor index 7 at row 3 is out of range \(there are 4 anchors: 0..3\)"):
        run(still, ranges=bad)


def test_streaming_anchor_non_integer_and_out_of_range():
    f = uwbimu_rs.Ekf(ANCHORS, initial=AT_REST)
    with pytest.raises(ValueError, match=r"add_range: anchor=1.5 is not a whole number \(an anchor index is one of 0..3"):
        f.add_range(0.1, 1.5, 5.0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"add_range: anchor=7 is not an anchor index \(there are 4 anchors: 0..3\)"):
        f.add_range(0.1, 7, 5.0)
    assert f.add_range(0.1, 2.0, 5.0) == []  # type: ignore[arg-type]  # a whole float is an index


def test_mapping_typo_names_the_key_path(tmp_path):
    missing = tmp_path / "never-read.mcap"  # the mapping is checked before the file is opened
    with pytest.raises(MappingError, match=r"`mapping.imu_topc`: unknown key \(did you mean `imu_topic`\?\); allowed here: ") as e:
        uwbimu_rs.read_mcap(missing, mapping={"imu_topc": "/imu"})
    assert "line 1 column" not in str(e.value)
    with pytest.raises(MappingError, match=r"`mapping.uwb.scael`: unknown key \(did you mean `scale`\?\)"):
        uwbimu_rs.read_mcap(missing, mapping={"uwb": {"scael": 0.001}})
    with pytest.raises(MappingError, match=r"`mapping.uwb.scale`: invalid type: string \"mm\", expected f64, got \"mm\"") as e:
        uwbimu_rs.read_mcap(missing, mapping={"uwb": {"scale": "mm"}})
    assert "line" not in str(e.value)


def test_replay_file_errors_name_the_file_and_key(tmp_path):
    toml = tmp_path / "replay.toml"
    toml.write_text('[mapping]\nimu_topc = "/imu"\n')
    with pytest.raises(MappingError, match=rf"{toml.name}: `mapping.imu_topc`: unknown key \(did you mean `imu_topic`"):
        uwbimu_rs.read_mcap(tmp_path / "never-read.mcap", config_file=toml)
    toml.write_text('[config]\nranging.range_std = "0.2"\n')
    with pytest.raises(ConfigError, match=rf"{toml.name}: config `ranging.range_std`: expected a number"):
        uwbimu_rs.read_mcap(tmp_path / "never-read.mcap", config_file=toml)


def test_reprs_read_as_python(still):
    imu, ranges = still
    c = uwbimu_rs.FilterConfig(**{"ranging.range_std": 0.2, "constraints.zupt": True, "mounting.lever_arm": [0, 0, 0.05]})
    assert repr(c) == "FilterConfig(ranging.range_std=0.2, mounting.lever_arm=[0.0, 0.0, 0.05], constraints.zupt=True)"
    assert repr(uwbimu_rs.FilterConfig()) == "FilterConfig()"
    f = uwbimu_rs.Ekf(ANCHORS, initial=AT_REST)
    assert repr(f) == "Ekf(anchors=4, initialized=True, t=None)"
    assert repr(uwbimu_rs.Best(ANCHORS)) == "Best(anchors=4, initialized=False, t=None)"
    reports = []
    for row in imu[:60]:
        f.add_imu(row[0], row[1:4], row[4:7])
    for t, a, r in ranges:
        reports += f.add_range(t, int(a), r)
    reports += f.flush()
    text = repr(reports[0])
    assert text.startswith("UpdateReport(t=0.5, epoch_t=0.5, sensor='range', anchor=0, value=5.0, ") and "accepted=True" in text, text
    for rust in ("true", "false", "NaN", "Some(", "bias="):
        assert rust not in text, text
    assert repr(f).startswith("Ekf(anchors=4, initialized=True, t=0.")


def test_sim_reprs_are_short():
    run = sim.preset("seed000_los", seed=1)
    text = repr(run)
    assert text.startswith("SimResult(duration_s=") and "imu_rate_hz=100" in text and "anchors=4" in text, text
    assert "nlos_fraction=0.000" in text and len(text) < 300, text
    assert repr(uwbimu_rs.sim.Trajectory.ellipse([0, 0, 0], 2.0, 1.0, 10.0, 1)).startswith("Trajectory(duration_s=12.0, start=[")


def test_smooth_returns_the_run_filter_frame(still):
    imu, ranges = still
    f = uwbimu_rs.Ekf(ANCHORS, initial=AT_REST, record=True)
    for row in imu:
        f.add_imu(row[0], row[1:4], row[4:7])
    for t, a, r in ranges:
        f.add_range(t, int(a), r)
    f.flush()
    nodes = f.smooth()
    batch = run(still, smooth=True)
    assert isinstance(nodes, pl.DataFrame) and nodes.schema == batch.schema
