"""The types users see must match what runs.

The hand-written stub ``uwbimu_rs/_native.pyi`` must match the compiled module, the typed
public package (``py.typed``; its modules carry their own annotations) must match its runtime, and
the examples — code written as a user writes it — must type-check against it.

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
ROOT = Path(__file__).resolve().parents[2]
ALLOWLIST = Path(__file__).with_name("stubtest_allowlist.txt")


def run_module(*args: str) -> subprocess.CompletedProcess[str]:
    """``python -m <args>`` from the repository root, output captured."""
    return subprocess.run([sys.executable, "-m", *args], capture_output=True, text=True, timeout=600, cwd=ROOT)


def test_stub_matches_runtime():
    proc = run_module("mypy.stubtest", "uwbimu_rs._native")
    assert proc.returncode == 0, f"stubtest failed:\n{proc.stdout}\n{proc.stderr}"


def test_public_package_types_match_runtime():
    # Every public module of the package, its signatures and __all__ against what imports.
    proc = run_module("mypy.stubtest", "uwbimu_rs", "--allowlist", str(ALLOWLIST))
    assert proc.returncode == 0, f"stubtest failed:\n{proc.stdout}\n{proc.stderr}"


def test_examples_type_check_against_the_public_api():
    scripts = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "examples").glob("*.py"))
    proc = run_module("mypy", *scripts, "benches/python_api.py", "benches/fleet.py", "benches/fixed_lag.py", "benches/whole_run.py")
    assert proc.returncode == 0, f"mypy failed:\n{proc.stdout}\n{proc.stderr}"


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
