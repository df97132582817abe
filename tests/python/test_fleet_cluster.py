"""The multi-node recipe of docs/fleet.md as run: a head and a second Ray node on this machine
(scripts/fleet_two_nodes.sh), ``fleet.replay`` across both, outputs equal to serial replay."""

# Under xdist this file's tests share one worker (conftest.py, ONE_WORKER).
from __future__ import annotations

import re
import shutil
import socket
import subprocess
from pathlib import Path

import pytest

pytest.importorskip("ray", reason="Ray is not installed (pip install 'uwbimu_rs[fleet]')")

ROOT = Path(__file__).resolve().parents[2]


def _free_port() -> int:
    """A TCP port nothing listens on now (for the head node)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.mark.skipif(shutil.which("bash") is None, reason="bash is needed to run the recipe script")
def test_two_local_nodes_share_a_fleet():
    proc = subprocess.run(
        ["bash", "scripts/fleet_two_nodes.sh", str(_free_port()), "--logs", "6", "--method", "ekf"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, f"recipe failed:\n{proc.stdout}\n{proc.stderr[-3000:]}"
    assert re.search(r"Ray: 2 node\(s\) .*, 2 CPUs", proc.stdout), proc.stdout
    assert "max |Δposition| = 0.00e+00 m" in proc.stdout, proc.stdout
