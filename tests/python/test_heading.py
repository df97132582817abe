"""The self-initialised heading through the Python API (docs/heading.md): no magnetometer, any
start heading, the heading bank's yaw and its honest σ; against the simulator's truth."""

from __future__ import annotations

import numpy as np
import pytest

import uwbimu_rs
from uwbimu_rs import sim


def yaw(q: np.ndarray) -> float:
    """The z–y–x Euler yaw of a quaternion (w, x, y, z), rad."""
    w, x, y, z = q
    return float(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))


def wrapped(a: float) -> float:
    """`a` wrapped into [−π, π), rad."""
    return float((a + np.pi) % (2.0 * np.pi) - np.pi)


@pytest.mark.parametrize(("scenario", "seed"), [("corridor", 3), ("stop_and_go", 5), ("tilted_walk", 1)])
def test_the_self_initialised_heading_is_within_three_sigma_of_the_truth(scenario, seed):
    run = sim.zoo(scenario, seed=seed)
    initial, info = uwbimu_rs.initialize(run.imu, run.ranges, run.anchors, config=run.config)
    assert info["heading_from"] == "motion", info
    truth = run.truth.row(0, named=True)
    error = wrapped(yaw(np.asarray(initial["orientation"])) - yaw(np.array([truth[k] for k in ("qw", "qx", "qy", "qz")])))
    sigma = float(initial["orientation_std"][2])
    assert abs(error) <= 3.0 * sigma, f"{scenario}: heading {np.degrees(error):.1f}° off, σ {np.degrees(sigma):.1f}°"
    assert sigma >= 0.2 - 1e-12, "the start's heading σ is at least 0.2 rad"
