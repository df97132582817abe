"""Every example and the Python benchmark script run to completion."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(
    "script",
    [
        ["examples/demo.py", "--no-plot"],
        ["examples/seed000_table1.py", "--seeds", "1"],
        ["examples/seed004_table1.py", "--seeds", "1"],
        ["examples/seed002_tables.py", "--seeds", "1"],
        ["examples/seed001_compare.py", "--seeds", "1"],
        ["benches/python_api.py", "--repeat", "1"],
    ],
    ids=lambda s: s[0],
)
def test_script_runs(script):
    out = subprocess.run([sys.executable, *script], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip()
