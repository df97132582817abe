"""The crate's top-level modules form no import cycle (``scripts/module_cycles.py``)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "module_cycles.py"


def run(*args: str) -> subprocess.CompletedProcess[str]:
    """Runs the script with ``args``; returns its exit status and output."""
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True, check=False)


def test_the_crate_has_no_module_cycle():
    result = run()
    assert result.returncode == 0, result.stdout + result.stderr
    assert "no cycles among" in result.stdout


def test_a_cycle_is_reported_with_its_files(tmp_path):
    src = tmp_path / "src"
    (src / "b").mkdir(parents=True)
    (src / "lib.rs").write_text("pub mod a;\npub mod b;\npub mod c;\n")
    (src / "a.rs").write_text("use crate::b::Thing;\n/// [`crate::c`] in a comment is no edge.\npub fn f() {}\n")
    (src / "b.rs").write_text("mod inner;\npub struct Thing;\n")
    (src / "b" / "inner.rs").write_text("pub fn g() { crate::a::f() }\n")
    (src / "c.rs").write_text('pub fn h() { let _ = "crate::a"; }\n#[cfg(test)]\nmod tests {\n    use crate::a::f;\n}\n')
    # --strict: this tree has none of the crate's pending edges.
    result = run("--strict", "--graph", str(src))
    assert result.returncode == 1, result.stdout
    assert "cycle: a -> b -> a" in result.stdout
    assert "b -> a (b/inner.rs)" in result.stdout
    # Comments, strings and test blocks make no edge.
    graph = dict(line.split(":", 1) for line in result.stdout.splitlines()[:3])
    assert graph == {"a": " b", "b": " a", "c": " "}


def test_a_lower_layer_using_a_higher_one_is_reported(tmp_path):
    src = tmp_path / "src"
    for layer in ("vocabulary", "estimation", "app"):
        (src / layer).mkdir(parents=True)
    (src / "lib.rs").write_text("pub mod app;\npub mod estimation;\npub mod vocabulary;\n")
    (src / "vocabulary" / "math.rs").write_text("pub fn f() { crate::app::methods::g() }\n")
    (src / "estimation" / "filters.rs").write_text("use crate::math::f;\n")
    (src / "app" / "methods.rs").write_text("pub fn g() { crate::filters::h() }\n")
    result = run(str(src))
    assert result.returncode == 1, result.stdout
    assert "upward: math (vocabulary) -> methods (app): vocabulary/math.rs" in result.stdout
    assert "filters" not in result.stdout.split("upward:")[1]
