"""Tests of uwbimu_rs.metrics (shapes, exceptions, hand-checkable statistics, alignment)."""

import math

import numpy as np
import polars as pl
import pytest

from uwbimu_rs import NumericalError, UwbImuError
from uwbimu_rs import _native, metrics


def _traj(t, xyz):
    return pl.DataFrame({"t": t, "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2]})


def test_bad_shapes_raise_value_error():
    good = np.zeros((3, 4))
    good[:, 0] = [0.0, 1.0, 2.0]
    with pytest.raises(ValueError):
        metrics.evaluate(np.zeros((3, 3)), good)
    with pytest.raises(ValueError):
        metrics.evaluate(good, np.zeros(4))
    with pytest.raises(ValueError, match="missing columns"):
        metrics.evaluate(pl.DataFrame({"t": [0.0], "x": [0.0]}), good)
    with pytest.raises(UwbImuError):
        metrics.cdf(np.zeros((2, 2)))
    # Native shape checks map to ValueError as well.
    from uwbimu_rs import _native

    with pytest.raises(ValueError):
        _native.nees(np.zeros((2, 3)), np.zeros((2, 5)))


def test_stats_on_tiny_hand_made_case():
    truth = np.array([[0.0, 0.0, 0.0, 0.0], [10.0, 10.0, 0.0, 0.0]])
    # Truth at t is (t, 0, 0); errors: (0, 3, 4) -> e_h 3, e_3d 5; (0, 0, 1) -> e_h 0, e_3d 1.
    est = np.array([[-1.0, 0.0, 0.0, 0.0], [2.0, 2.0, 3.0, 4.0], [5.0, 5.0, 0.0, 1.0], [11.0, 0.0, 0.0, 0.0]])
    ev = metrics.evaluate(est, truth)
    assert ev.errors["t"].to_list() == [2.0, 5.0]
    assert ev.errors["e_h"].to_list() == pytest.approx([3.0, 0.0])
    assert ev.errors["e_3d"].to_list() == pytest.approx([5.0, 1.0])
    assert ev.three_d.n == 2
    assert ev.three_d.mean == pytest.approx(3.0)
    assert ev.three_d.rmse == pytest.approx(math.sqrt(13.0))
    assert ev.three_d.median == pytest.approx(3.0)
    assert ev.three_d.p90 == pytest.approx(4.6)
    assert ev.three_d.max == pytest.approx(5.0)
    assert ev.horizontal.max == pytest.approx(3.0)
    assert ev.alignment is None
    x, p = metrics.cdf(ev.errors["e_3d"])
    np.testing.assert_allclose(x, [1.0, 5.0])
    np.testing.assert_allclose(p, [0.5, 1.0])


def test_a_truth_taken_at_each_range_counts_each_time_once():
    # Truth at t is (t, 0, 0), given twice at t = 10 (one row per range of an epoch), the two
    # rows 0.2 m apart across the track: their mean is the truth there.
    truth = np.array([[0.0, 0.0, 0.0, 0.0], [10.0, 10.0, -0.1, 0.0], [10.0, 10.0, 0.1, 0.0], [20.0, 20.0, 0.0, 0.0]])
    est = np.array([[5.0, 5.0, 0.3, 0.0], [10.0, 10.0, 0.4, 0.0], [15.0, 15.0, 0.0, 0.0]])
    ev = metrics.evaluate(est, truth)
    assert ev.errors["e_h"].to_list() == pytest.approx([0.3, 0.4, 0.0])
    # A truth that goes back in time is refused, and the message says where.
    with pytest.raises(ValueError, match=r"truth_t: time 5 s at row 2 is not after the previous time 10 s"):
        metrics.evaluate(est, truth[[0, 1, 0]] + [[0, 0, 0, 0], [0, 0, 0, 0], [5.0, 0, 0, 0]])


def test_alignment_recovers_rotated_copy():
    t = np.linspace(0.0, 10.0, 101)
    truth_xyz = np.column_stack([3 * np.cos(t), 2 * np.sin(0.7 * t), 0.1 * t])
    a = 0.6
    rot = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])
    trans = np.array([1.0, -2.0, 0.5])
    est_xyz = (truth_xyz - trans) @ rot  # rot.T @ (g - trans) row-wise
    ev = metrics.evaluate(_traj(t, est_xyz), _traj(t, truth_xyz), align=True)
    assert ev.alignment is not None
    np.testing.assert_allclose(ev.alignment.rotation, rot, atol=1e-9)
    np.testing.assert_allclose(ev.alignment.translation, trans, atol=1e-9)
    assert ev.three_d.max < 1e-9
    assert metrics.evaluate(_traj(t, est_xyz), _traj(t, truth_xyz)).three_d.max > 1.0


def test_nees_uses_covariance_columns():
    t = np.array([0.0, 1.0, 2.0])
    truth = _traj(t, np.zeros((3, 3)))
    est = _traj(t, np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 0.0]])).with_columns(
        cov_xx=pl.lit(4.0), cov_xy=pl.lit(0.0), cov_xz=pl.lit(0.0), cov_yy=pl.lit(1.0), cov_yz=pl.lit(0.0), cov_zz=pl.lit(1.0)
    )
    out = metrics.nees(est, truth)
    assert out["nees"].to_list() == pytest.approx([0.25, 4.0, 0.0])
    with pytest.raises(ValueError, match="cov_yz"):
        metrics.nees(est.drop("cov_yz"), truth)
    with pytest.raises(NumericalError):
        metrics.nees(est.with_columns(cov_zz=pl.lit(-1.0)), truth)


def test_tables_are_read_by_rows_in_any_memory_layout():
    # The native side reads a C-ordered table as one slice of rows and any other layout row by
    # row: Fortran order, a strided view and C order must give the NEES numpy computes.
    rng = np.random.default_rng(0)
    errors = rng.normal(size=(40, 3))
    sigma = rng.uniform(0.5, 2.0, size=(40, 3))
    cov = np.column_stack([sigma[:, 0] ** 2, np.zeros(40), np.zeros(40), sigma[:, 1] ** 2, np.zeros(40), sigma[:, 2] ** 2])
    expected = np.sum((errors / sigma) ** 2, axis=1)
    wide = np.zeros((40, 6))
    wide[:, ::2] = errors
    for e, c in [
        (np.ascontiguousarray(errors), np.ascontiguousarray(cov)),
        (np.asfortranarray(errors), np.asfortranarray(cov)),
        (wide[:, ::2], cov[:, :]),
    ]:
        np.testing.assert_allclose(_native.nees(e, c), expected, rtol=1e-12)
