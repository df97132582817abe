"""Shared fixtures: small simulated runs from the seeded simulator."""

from __future__ import annotations

from pathlib import Path

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


#: Test files whose tests run on one xdist worker, in turn, when pytest runs them on several
#: (scripts/test.sh: `-n auto --dist loadgroup`); every other test goes to whichever worker is
#: free. "ray": test_fleet.py's worker kill finds its victim with `pgrep -f ray::_replay_log`,
#: which would also see the two-node cluster's tasks, and two Ray clusters at once would each
#: start workers for the same 2 cores. "live": the node runs over DDS and a pseudo-terminal paced
#: by wall-clock waits (a player at 4× speed, 1.5 s for the node to open its port), so no two
#: nodes share the machine. A file, not pytest-xdist's `xdist_group` mark: since pytest 9.2 the
#: mark no longer groups anything (pytest-xdist issue 1386) and says nothing.
ONE_WORKER = {"test_fleet.py": "ray", "test_fleet_cluster.py": "ray", "test_live.py": "live"}


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """With ``--dist loadgroup``: each file of :data:`ONE_WORKER` a unit of its group's worker,
    every other test a unit of its own."""
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class OneWorkerGroups(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return ONE_WORKER.get(Path(nodeid.split("::", 1)[0]).name, nodeid)

    assert "_split_scope" in vars(LoadScopeScheduling), "pytest-xdist no longer splits scopes by _split_scope"
    return OneWorkerGroups(config, log)


def pytest_collection_modifyitems(config, items):
    """Skips the ``needs_isas`` tests, with the reason, when the recording is not there."""
    reason = skip_reason()
    if reason is not None:
        for item in items:
            if item.get_closest_marker("needs_isas") is not None:
                item.add_marker(pytest.mark.skip(reason=reason))
