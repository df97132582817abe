"""Shared fixtures: small simulated runs from the seeded simulator."""

from __future__ import annotations

import pytest
from shared_data import skip_reason

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


def pytest_configure(config):
    config.addinivalue_line("markers", "needs_isas: reads ../shared/data/isas-walk1 (skipped without it)")


def pytest_collection_modifyitems(config, items):
    """Skips the ``needs_isas`` tests, with the reason, when the recording is not there."""
    reason = skip_reason()
    if reason is not None:
        for item in items:
            if item.get_closest_marker("needs_isas") is not None:
                item.add_marker(pytest.mark.skip(reason=reason))
