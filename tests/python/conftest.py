"""Shared fixtures: small simulated runs from the seeded simulator."""

from __future__ import annotations

import pytest

from uwbimu_rs import sim


@pytest.fixture(scope="session")
def los_run():
    """seed-000 preset without NLOS (figure-8 ×4, 4 anchors, UWB 2 Hz, IMU 100 Hz)."""
    return sim.preset("seed000_los", seed=1)


@pytest.fixture(scope="session")
def filter_config():
    """Filter settings matching the seed-000 simulator (IMU 5 cm below the tag)."""
    return {"range_std": 0.1, "lever_arm": [0.0, 0.0, 0.05]}
