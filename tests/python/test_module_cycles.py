"""scripts/module_cycles.py, the lint that keeps import circles out: it finds a circle between
two files of a crate (direct, through a grouped use, through a re-export, inline), and passes
the uses that are not one (a module's own parts, tests, doc-only imports, other crates)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "module_cycles.py"


def _check(tmp_path: Path, files: dict[str, str]) -> subprocess.CompletedProcess[str]:
    for name, text in files.items():
        path = tmp_path / "crates" / "demo" / "src" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return subprocess.run([sys.executable, str(SCRIPT), str(tmp_path)], capture_output=True, text=True, check=False)


LIB = "pub mod a;\npub mod b;\npub mod c;\n"


def test_a_circle_between_two_files_fails_and_names_its_uses(tmp_path):
    out = _check(
        tmp_path,
        {
            "lib.rs": LIB,
            "a.rs": "use crate::{b::{Bee, other}, c};\npub struct Ay;\n",
            "b.rs": "pub struct Bee;\npub fn other() -> crate::a::Ay { todo!() }\n",
            "c.rs": "",
        },
    )
    assert out.returncode == 1, out.stdout
    assert "import circle in demo: src/a.rs <-> src/b.rs" in out.stdout
    assert "src/b.rs uses src/a.rs: crate::a::Ay" in out.stdout


def test_a_circle_through_a_re_export_is_found_at_the_defining_file(tmp_path):
    out = _check(
        tmp_path,
        {
            "lib.rs": LIB,
            "a.rs": "pub mod inner;\npub use self::inner::Deep;\n",
            "a/inner.rs": "use crate::b::Bee;\npub struct Deep;\n",
            "b.rs": "use crate::a::Deep;\npub struct Bee;\n",
            "c.rs": "",
        },
    )
    assert out.returncode == 1, out.stdout
    assert "src/a/inner.rs <-> src/b.rs" in out.stdout


def test_parts_tests_docs_and_other_crates_are_not_circles(tmp_path):
    out = _check(
        tmp_path,
        {
            "lib.rs": LIB,
            # a.rs uses its own part, which uses a.rs back: composition, not a circle.
            "a.rs": "mod part;\nuse part::helper;\npub struct Ay;\n#[cfg(doc)]\nuse crate::b::Bee;\n",
            "a/part.rs": "pub fn helper() -> super::Ay { todo!() }\n",
            # b.rs names a.rs only in a test, a comment, a string and through another crate.
            "b.rs": '// crate::a::Ay\npub struct Bee;\nconst S: &str = "crate::a::Ay";\nuse other_crate::a::Ay;\n'
            "#[cfg(test)]\nmod tests {\n    use crate::a::Ay;\n}\n",
            "c.rs": "use crate::a::Ay;\nuse crate::b::Bee;\n",
        },
    )
    assert out.returncode == 0, out.stdout
    assert "module cycles: none" in out.stdout
