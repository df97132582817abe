"""Anchors known by hardware id (a third party's log numbers them 11, 12, 4, 9): ``anchors`` as a
dict ``{id: [x, y, z]}`` makes the anchor columns of ranges and TDoA, and the streaming calls,
take ids. Oracle: the same run with the ids written as rows, bit for bit; an id that is no
anchor's, or an id given where rows are expected, says to map ids to rows."""

from __future__ import annotations

import numpy as np
import pytest

import uwbimu_rs
from uwbimu_rs import sim


def _by_id(run, ids):
    """The run's anchors as a dict by id, and its ranges with ids in the anchor column."""
    anchors = {int(i): row.tolist() for i, row in zip(ids, run.anchors)}
    ranges = run.ranges.copy()
    ranges[:, 1] = np.asarray(ids, dtype=float)[run.ranges[:, 1].astype(int)]
    return anchors, ranges


def test_anchors_by_id_run_as_the_rows_they_name():
    run = sim.zoo("agv_loop", seed=1)
    ids = [11, 12, 4, 9, 30, 31, 7, 2][: len(run.anchors)]
    anchors, ranges = _by_id(run, ids)
    by_rows, upd_rows = uwbimu_rs.run_filter("riekf", run.imu, run.ranges, run.anchors, initial=run.initial, config=run.config, updates=True)
    by_id, upd_id = uwbimu_rs.run_filter("riekf", run.imu, ranges, anchors, initial=run.initial, config=run.config, updates=True)
    np.testing.assert_array_equal(by_id.select("x", "y", "z").to_numpy(), by_rows.select("x", "y", "z").to_numpy())
    np.testing.assert_array_equal(upd_id["anchor"].to_numpy(), upd_rows["anchor"].to_numpy())  # frames report rows
    # String keys of whole numbers are ids too (a JSON or TOML table).
    as_text = {str(k): v for k, v in anchors.items()}
    again = uwbimu_rs.run_filter("riekf", run.imu, ranges, as_text, initial=run.initial, config=run.config)
    np.testing.assert_array_equal(again.select("x", "y", "z").to_numpy(), by_rows.select("x", "y", "z").to_numpy())


def test_a_streaming_filter_takes_ids_in_add_range_and_add_tdoa():
    run = sim.zoo("agv_loop", seed=2, tdoa=True, tdoa_rate_hz=5.0)
    ids = [40 + 3 * k for k in range(len(run.anchors))]
    anchors, _ = _by_id(run, ids)
    f_id = uwbimu_rs.Ekf(anchors, initial=run.initial, config=run.config)
    f_row = uwbimu_rs.Ekf(run.anchors, initial=run.initial, config=run.config)
    for f, name in ((f_id, "id"), (f_row, "row")):
        for s in run.imu[:400]:
            f.add_imu(s[0], s[1:4], s[4:7])
        for t, i, j, d in run.tdoa[run.tdoa[:, 0] < run.imu[399, 0]]:
            a, b = (ids[int(i)], ids[int(j)]) if name == "id" else (i, j)
            f.add_tdoa(t, a, b, d)
        for t, a, r in run.ranges[run.ranges[:, 0] < run.imu[399, 0]][:, :3]:
            f.add_range(t, ids[int(a)] if name == "id" else a, r)
        f.flush()
    np.testing.assert_array_equal(f_id.state["position"], f_row.state["position"])
    with pytest.raises(ValueError, match=r"anchor=5 is not the id of an anchor.*map ids to rows"):
        f_id.add_range(run.imu[399, 0] + 0.01, 5, 3.0)


def test_an_id_that_is_no_anchors_says_to_map_ids_to_rows():
    run = sim.zoo("agv_loop", seed=3)
    ids = list(range(100, 100 + len(run.anchors)))
    anchors, ranges = _by_id(run, ids)
    ranges[7, 1] = 7.0
    with pytest.raises(ValueError, match=r"ranges: anchor id 7 at row 7 .*100, 101.*map ids to rows"):
        uwbimu_rs.run_filter("ekf", run.imu, ranges, anchors, initial=run.initial, config=run.config)
    # Ids given where rows are expected: the message says how to give them.
    _, ranges = _by_id(run, ids)
    with pytest.raises(ValueError, match=r"anchor index 10\d at row 0 is out of range .*map ids to rows: anchors=\{id: \[x, y, z\]\}"):
        uwbimu_rs.run_filter("ekf", run.imu, ranges, run.anchors, initial=run.initial, config=run.config)
    with pytest.raises(ValueError, match="each anchor id is given once"):
        uwbimu_rs.run_filter("ekf", run.imu, ranges, {1: [0, 0, 0], "1": [1, 0, 0]}, config=run.config)
    with pytest.raises(ValueError, match="an anchor id is a whole number"):
        uwbimu_rs.run_filter("ekf", run.imu, ranges, {"north": [0, 0, 0]}, config=run.config)
