"""The hand-written stub ``uwbimu_rs/_native.pyi`` must match the compiled module.

``mypy.stubtest`` imports ``uwbimu_rs._native`` and compares every name, signature, parameter
default, property and ``@final`` marker with the stub; a renamed parameter, a changed default or a
new function without a stub entry fails here. It does not compare class bases, so the second test
checks those (e.g. that ``UwbImuError`` stays a ``ValueError``).
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import uwbimu_rs
from uwbimu_rs import _native

STUB = Path(uwbimu_rs.__file__).with_name("_native.pyi")


def test_stub_matches_runtime():
    proc = subprocess.run(
        [sys.executable, "-m", "mypy.stubtest", "uwbimu_rs._native"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, f"stubtest failed:\n{proc.stdout}\n{proc.stderr}"


def test_stub_class_bases_match_runtime():
    tree = ast.parse(STUB.read_text(encoding="utf-8"))
    # A private stub class (``_StreamingFilter``) documents an API shared by several classes once;
    # it is a base in the stub only, with no runtime counterpart.
    classes = {node.name: node for node in tree.body if isinstance(node, ast.ClassDef) and not node.name.startswith("_")}
    assert classes, f"no classes found in {STUB}"
    for name, node in classes.items():
        stub_bases = tuple(b for b in (ast.unparse(b) for b in node.bases) if not b.startswith("_")) or ("object",)
        runtime_bases = tuple(b.__name__ for b in getattr(_native, name).__bases__)
        assert stub_bases == runtime_bases, f"{name}: stub bases {stub_bases}, runtime {runtime_bases}"
