#!/usr/bin/env python3
"""Reports import cycles between the crate's modules, and uses of a higher layer.

The graph has one node per module: a top-level module of ``src/`` (``src/NAME.rs`` together with
everything under ``src/NAME/``), or, inside the layer folders ``src/vocabulary``,
``src/estimation`` and ``src/app`` (lowest first; their modules are re-exported at the crate
root), a module of the layer (``src/LAYER/NAME.rs`` and ``src/LAYER/NAME/``). There is an edge
A → B when a file of A names ``crate::B`` (or ``crate::LAYER::B``) — in a
``use crate::B::...`` line, a grouped ``use crate::{B, ...}`` or an inline path such as
``crate::B::f()``. Comments (so doc links) do not count, nor do ``#[cfg(test)]`` blocks and
files (tests may use anything). ``src/bindings`` and ``src/bin`` sit on top of the library and
are left out, as is ``src/lib.rs``.

An edge of ``PENDING`` (a known cycle whose fix needs an edit that has to wait) is left out of
the search and reported as pending; ``--strict`` keeps it in. A pending edge that no longer exists
is an error too, so the list cannot go stale.

A use of a higher layer's module by a lower layer's (``UPWARD_ALLOWED`` lists the accepted ones,
with the reason) is reported and fails the check, as does a stale accepted entry.

Usage: ``python scripts/module_cycles.py [--graph] [--strict] [SRC_DIR]`` (default: the ``src``
beside this script's folder). ``--graph`` also prints every module's dependencies. Prints each
cycle as ``a -> b -> a`` with the files behind each edge, and exits with status 1 when there is
one (or a stale pending edge), 0 otherwise.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

#: Folders of ``src/`` that sit on top of the library and so are not part of the graph.
EXCLUDED = {"bindings", "bin"}

#: Edges ``(from, to)`` of known cycles whose fix has to wait, with the reason.
PENDING: dict[tuple[str, str], str] = {}

_CRATE_PATH = re.compile(r"\bcrate::(\{[^}]*\}|[A-Za-z_][A-Za-z0-9_]*)")
_CFG_TEST = re.compile(r"#\[cfg\(test\)\]\s*")
_TEST_MOD_FILE = re.compile(r"#\[cfg\(test\)\]\s*(?:pub(?:\([a-z]+\))?\s+)?mod\s+([A-Za-z_][A-Za-z0-9_]*)\s*;")


def strip_comments_and_strings(text: str) -> str:
    """Returns ``text`` with comments and string/char literals blanked out (line breaks kept)."""
    out: list[str] = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            i = j
        elif text.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if text.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif text.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            out.append("\n" * text.count("\n", i, j))
            i = j
        elif c == "r" and re.match(r'r#*"', text[i:]) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            m = re.match(r'r(#*)"', text[i:])
            assert m is not None
            end = text.find('"' + m.group(1), i + len(m.group(0)))
            j = n if end < 0 else end + 1 + len(m.group(1))
            out.append('""' + "\n" * text.count("\n", i, j))
            i = j
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            out.append('""' + "\n" * text.count("\n", i, j))
            i = j + 1
        elif c == "'":
            # A char literal ('a', '\n', '\u{..}') or a lifetime ('a): only the former is skipped.
            m = re.match(r"'(\\u\{[0-9a-fA-F]+\}|\\.|[^\\'])'", text[i:])
            if m:
                out.append("' '")
                i += len(m.group(0))
            else:
                out.append(c)
                i += 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def strip_test_blocks(code: str) -> str:
    """Returns ``code`` (already without comments and strings) without its ``#[cfg(test)]`` items."""
    while True:
        m = _CFG_TEST.search(code)
        if not m:
            return code
        j = m.end()
        # The item ends at the first ';' before any '{', or at the '}' closing its first '{'.
        depth = 0
        while j < len(code):
            ch = code[j]
            if ch == ";" and depth == 0:
                break
            if ch == "{":
                depth += 1
            elif ch == "}":
                depth -= 1
                if depth == 0:
                    break
            j += 1
        code = code[: m.start()] + "\n" * code.count("\n", m.start(), j + 1) + code[j + 1 :]


def test_module_files(path: Path, text: str) -> set[Path]:
    """Files of the ``#[cfg(test)] mod NAME;`` declarations in the file at ``path``."""
    folder = path.parent if path.name == "mod.rs" else path.with_suffix("")
    files: set[Path] = set()
    for name in _TEST_MOD_FILE.findall(strip_comments_and_strings(text)):
        files.add(folder / f"{name}.rs")
        files.update((folder / name).rglob("*.rs"))
    return files


#: The layer folders, lowest first.
LAYERS = ("vocabulary", "estimation", "app")

#: Uses of a higher layer that are accepted, with the reason.
UPWARD_ALLOWED: dict[tuple[str, str], str] = {
    ("config", "robust"): "the configuration embeds the Sage–Husa settings type",
    ("config", "ranging"): "the configuration embeds the range calibration table",
    ("config", "epoch"): "the epoch window's default and check live with the epoch rule",
    ("init", "metrics"): "the self-initialisation's median is metrics::percentile",
}


def top_module(src: Path, path: Path) -> str | None:
    """The module that the file at ``path`` belongs to (``None`` for ``lib.rs`` and the layer
    files themselves)."""
    parts = path.relative_to(src).parts
    if parts[0] in LAYERS:
        parts = parts[1:]
        if not parts:
            return None
    elif len(parts) == 1 and parts[0][: -len(".rs")] in LAYERS:
        return None
    if len(parts) == 1:
        return None if parts[0] in ("lib.rs", "main.rs") else parts[0][: -len(".rs")]
    return parts[0]


def layer_of(src: Path) -> dict[str, int]:
    """The layer index of every module inside a layer folder."""
    out: dict[str, int] = {}
    for k, layer in enumerate(LAYERS):
        for p in (src / layer).glob("*.rs") if (src / layer).is_dir() else []:
            out[p.stem] = k
    return out


def module_graph(src: Path) -> dict[str, dict[str, set[str]]]:
    """Edges between top-level modules: ``graph[a][b]`` holds the files of ``a`` that name ``b``."""
    files = sorted(p for p in src.rglob("*.rs") if p.relative_to(src).parts[0] not in EXCLUDED)
    texts = {p: p.read_text(encoding="utf-8") for p in files}
    test_files: set[Path] = set()
    for p, text in texts.items():
        test_files |= test_module_files(p, text)
    graph: dict[str, dict[str, set[str]]] = {}
    for p in files:
        module = top_module(src, p)
        if module is None or p in test_files:
            continue
        graph.setdefault(module, {})
        code = strip_test_blocks(strip_comments_and_strings(texts[p]))
        code = re.sub(r"crate::(?:" + "|".join(LAYERS) + r")::", "crate::", code)
        for m in _CRATE_PATH.finditer(code):
            target = m.group(1)
            # In a grouped `crate::{a::x, b}` each path's first segment is a module.
            names = [seg.split("::")[0].strip() for seg in target[1:-1].split(",")] if target.startswith("{") else [target]
            for name in names:
                if name and name != module and name not in ("self", "super"):
                    graph[module].setdefault(name, set()).add(str(p.relative_to(src)))
    return graph


def find_cycles(graph: dict[str, dict[str, set[str]]]) -> list[list[str]]:
    """One cycle for each strongly connected component of more than one module (Tarjan's)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, {})):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                components.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)

    cycles = []
    for component in components:
        members = set(component)
        # Every module of the component lies on a cycle: report every shortest cycle through the
        # component's modules (breadth-first), each once.
        seen: set[tuple[str, ...]] = set()
        for start in component:
            cycle = _shortest_cycle(graph, start, members)
            key = tuple(sorted(cycle[:-1]))
            if key not in seen:
                seen.add(key)
                cycles.append(cycle)
    return cycles


def _shortest_cycle(graph: dict[str, dict[str, set[str]]], start: str, members: set[str]) -> list[str]:
    """The shortest path ``start → … → start`` within ``members``."""
    parents: dict[str, str] = {}
    frontier = [start]
    while frontier:
        nxt = []
        for v in frontier:
            for w in sorted(graph.get(v, {})):
                if w not in members:
                    continue
                if w == start:
                    path = [v]
                    while path[-1] != start:
                        path.append(parents[path[-1]])
                    return [start, *reversed(path[:-1]), start]
                if w not in parents:
                    parents[w] = v
                    nxt.append(w)
        frontier = nxt
    raise AssertionError("a module of a strongly connected component lies on a cycle")


def main(argv: list[str]) -> int:
    """Prints the cycles (and with ``--graph`` the graph); returns 1 when there is a cycle."""
    flags = {a for a in argv if a.startswith("--")}
    args = [a for a in argv if not a.startswith("--")]
    src = Path(args[0]) if args else Path(__file__).resolve().parent.parent / "src"
    graph = module_graph(src)
    if "--graph" in flags:
        for module in sorted(graph):
            print(f"{module}: {', '.join(sorted(graph[module]))}")
    stale = False
    if "--strict" not in flags:
        for (a, b), reason in PENDING.items():
            if b in graph.get(a, {}):
                print(f"pending: {a} -> {b} ({', '.join(sorted(graph[a].pop(b)))}): {reason}")
            else:
                print(f"stale: {a} -> {b} is listed in PENDING but no longer in the code; remove it")
                stale = True
    cycles = find_cycles(graph)
    for cycle in cycles:
        edges = []
        for a, b in zip(cycle, cycle[1:]):
            edges.append(f"{a} -> {b} ({', '.join(sorted(graph[a][b]))})")
        print("cycle: " + " -> ".join(cycle))
        for edge in edges:
            print("    " + edge)
    if not cycles:
        print(f"no cycles among {len(graph)} modules")
    layers = layer_of(src)
    upward = False
    for a in sorted(graph):
        for b in sorted(graph[a]):
            if a in layers and b in layers and layers[b] > layers[a] and (a, b) not in UPWARD_ALLOWED:
                print(f"upward: {a} ({LAYERS[layers[a]]}) -> {b} ({LAYERS[layers[b]]}): {', '.join(sorted(graph[a][b]))}")
                upward = True
    for (a, b) in UPWARD_ALLOWED:
        if layers and b not in graph.get(a, {}):
            print(f"stale: {a} -> {b} is listed in UPWARD_ALLOWED but no longer in the code; remove it")
            stale = True
    if layers and not upward:
        print(f"no upward use between the layers {' < '.join(LAYERS)}")
    return 1 if cycles or stale or upward else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
