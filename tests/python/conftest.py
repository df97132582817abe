"""Shared fixtures: small simulated runs from the seeded simulator."""

from __future__ import annotations

import pytest

from uwbimu_rs import sim


@pytest.fixture(scope="session")
def los_run():
    """The Li & Wang 2020 preset without NLOS (figure-8 ×4, 4 anchors, UWB 2 Hz, IMU 100 Hz)."""
    return sim.preset("hall_vehicle", seed=1)


@pytest.fixture(scope="session")
def filter_config(los_run):
    """Filter settings matching the sensors of the Li & Wang 2020 preset (σ 0.1 m, consumer-MEMS IMU, IMU
    5 cm below the tag): the library defaults are chosen for real logs, not this simulator."""
    return dict(los_run.config)
