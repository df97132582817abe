"""Every relative link of the README and the docs pages points at a file that exists, and every
``#anchor`` at a heading of that file (GitHub's anchor rule), so moving a section cannot leave a
dead link behind."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
LINK = re.compile(r"\]\(([^)\s]+)\)")


def anchors(page: Path) -> set[str]:
    """The anchors of ``page``: explicit ``<a id="...">`` tags, and the ones GitHub gives its
    headings (tags removed, lower case, punctuation dropped, spaces to hyphens)."""
    text = page.read_text(encoding="utf-8")
    out = set(re.findall(r'<a id="([^"]+)"', text))
    for line in text.splitlines():
        if line.startswith("#"):
            title = re.sub(r"<[^>]+>", "", line.lstrip("#")).strip().lower()
            out.add(re.sub(r"[^\w\- ]", "", title).replace(" ", "-"))
    return out


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_relative_links_resolve(page: Path) -> None:
    text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.S)
    for target in LINK.findall(text):
        if re.match(r"[a-z]+:", target):
            continue  # https:, mailto:
        path, _, anchor = target.partition("#")
        file = (page.parent / path).resolve() if path else page
        assert file.exists(), f"{page.name}: link to missing {target}"
        if anchor and file.suffix == ".md":
            assert anchor in anchors(file), f"{page.name}: no heading for #{anchor} in {file.name}"
