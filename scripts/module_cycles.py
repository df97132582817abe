#!/usr/bin/env python3
"""Fails on an import circle between the source files of any crate of the workspace.

One node per source file (its module: ``src/a/b.rs`` and ``src/a/b/mod.rs`` are ``a::b``,
``lib.rs`` the crate root). A file uses another when it names a path into it — in a ``use``
(grouped ``{...}`` expanded), or inline (``crate::a::f()``, ``super::X``, ``self::b::Y``, or a
child module's name as the first segment): the path's file is its longest prefix that is a module
of the crate. Comments, strings and ``#[cfg(test)]`` items do not count (tests may use anything).

A path counts for the file that defines what it names: through a re-export (``pub use``, also
``pub use self::x::*``) to the file the item is declared in; a re-export itself is not a use, and
neither is a module's use of its own parts (``a.rs`` naming ``a::b``: the parts compose it). A circle is a strongly connected set of files; each is
printed with the uses that close it, and the exit status is 1.

Usage: ``python3 scripts/module_cycles.py [ROOT]`` (default: the repository of this script).
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

_IDENT = r"[A-Za-z_][A-Za-z0-9_]*"
_USE = re.compile(r"\buse\s+([^;]+);")
_INLINE = re.compile(rf"(?<![A-Za-z0-9_:])({_IDENT}(?:\s*::\s*{_IDENT})+)")
_CFG_TEST = re.compile(r"#\[cfg\((?:test|doc)\)\]")
_PUB_USE = re.compile(r"\bpub(?:\([a-z]+\))?\s+use\s+([^;]+);")
_DEF = re.compile(rf"\b(?:fn|struct|enum|trait|type|const|static|union|mod|macro_rules!)\s+({_IDENT})")

Module = tuple[str, ...]


def blank_comments_and_strings(text: str) -> str:
    """``text`` with comments and string / char literals replaced by spaces (lines kept)."""
    out, i, n = [], 0, len(text)
    while i < n:
        if text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                depth += text.startswith("/*", j) - text.startswith("*/", j)
                j += 2 if text.startswith(("/*", "*/"), j) else 1
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif (m := re.match(r'r(#*)"', text[i:])) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            end = text.find('"' + m.group(1), i + len(m.group(0)))
            j = n if end < 0 else end + 1 + len(m.group(1))
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif text[i] == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            out.append(re.sub(r"[^\n]", " ", text[i : j + 1]))
            i = j + 1
        elif text[i] == "'" and (m := re.match(r"'(\\.[^']*|[^\\'])'", text[i:])):
            out.append(" " * len(m.group(0)))
            i += len(m.group(0))
        else:
            out.append(text[i])
            i += 1
    return "".join(out)


def blank_test_items(code: str) -> tuple[str, set[str]]:
    """``code`` without its ``#[cfg(test)]`` items, and the names of test modules in own files."""
    test_mods: set[str] = set()
    while m := _CFG_TEST.search(code):
        j = m.end()
        brace, semi = code.find("{", j), code.find(";", j)
        if semi >= 0 and (brace < 0 or semi < brace):
            if mod := re.search(rf"\bmod\s+({_IDENT})\s*$", code[j:semi]):
                test_mods.add(mod.group(1))
            end = semi + 1
        else:
            depth, end = 0, brace
            while end < len(code):
                depth += (code[end] == "{") - (code[end] == "}")
                end += 1
                if depth == 0:
                    break
        code = code[: m.start()] + re.sub(r"[^\n]", " ", code[m.start() : end]) + code[end:]
    return code, test_mods


def expand_use(tree: str) -> list[str]:
    """The paths of one ``use`` tree: ``a::{b, c::{d, e as f}}`` gives ``a::b``, ``a::c::d``,
    ``a::c::e as f``."""
    tree = re.sub(r"\s+", " ", tree).strip()
    tree = re.sub(r"\s*(::|[{},])\s*", r"\1", tree)
    if "{" not in tree:
        return [tree]
    head, rest = tree.split("{", 1)
    body = rest[: rest.rfind("}")]
    parts, depth, start = [], 0, 0
    for k, c in enumerate(body):
        depth += (c == "{") - (c == "}")
        if c == "," and depth == 0:
            parts.append(body[start:k])
            start = k + 1
    parts.append(body[start:])
    return [p for part in parts if part for p in expand_use(head + part)]


class Crate:
    """The files of one crate (``src`` holding ``lib.rs``), what each defines and re-exports."""

    def __init__(self, src: Path) -> None:
        self.src = src
        self.files: dict[Module, Path] = {}
        for path in sorted(src.rglob("*.rs")):
            parts = path.relative_to(src).with_suffix("").parts
            if parts[:1] == ("bin",):
                continue
            self.files[parts[:-1] if parts[-1] in ("mod", "lib") else parts] = path
        self.code: dict[Module, str] = {}
        test_files: set[Module] = set()
        for module, path in self.files.items():
            code, test_mods = blank_test_items(blank_comments_and_strings(path.read_text()))
            self.code[module] = code
            test_files |= {module + (name,) for name in test_mods}
        # A test module's own children are tests too.
        self.test_files = {m for m in self.files if any(m[: len(t)] == t for t in test_files)}
        self.defs = {m: set(_DEF.findall(code)) for m, code in self.code.items()}
        self.reexports: dict[Module, dict[str, list[str]]] = {}
        self.globs: dict[Module, list[list[str]]] = {}
        for module, code in self.code.items():
            for tree in _PUB_USE.findall(code):
                for path in expand_use(tree):
                    segments = split_path(path)
                    if segments[-1] == "*":
                        self.globs.setdefault(module, []).append(segments[:-1])
                    else:
                        alias = re.search(rf"\bas\s+({_IDENT})$", path)
                        name = alias.group(1) if alias else segments[-1]
                        self.reexports.setdefault(module, {})[name] = segments

    def module_of(self, base: Module, segments: list[str]) -> tuple[Module, list[str]] | None:
        """The deepest module ``segments`` (named in ``base``) reach, and the segments after it;
        None for a path into another crate."""
        head, *rest = segments
        if head == "crate":
            target: Module = ()
        elif head in ("self", "super"):
            target, rest = base, list(segments)
            while rest and rest[0] in ("self", "super"):
                target = target[:-1] if rest.pop(0) == "super" else target
        elif base + (head,) in self.files:
            target = base + (head,)
        else:
            return None
        while rest and target + (rest[0],) in self.files:
            target += (rest.pop(0),)
        return target, rest

    def defining_file(self, base: Module, segments: list[str], depth: int = 0) -> Module | None:
        """The file that defines what ``segments`` names from ``base``, through re-exports."""
        reached = self.module_of(base, segments)
        if reached is None:
            return None
        module, rest = reached
        if not rest or rest[0] in self.defs[module] or depth > 8:
            return module
        if (path := self.reexports.get(module, {}).get(rest[0])) is not None:
            found = self.defining_file(module, path + rest[1:], depth + 1)
            return module if found is None else found
        for glob in self.globs.get(module, []):
            inner = self.module_of(module, glob)
            if inner is not None and not inner[1] and rest[0] in self.defs[inner[0]] | set(self.reexports.get(inner[0], {})):
                return self.defining_file(module, glob + rest, depth + 1)
        return module

    def uses(self) -> dict[Module, dict[Module, str]]:
        """For each file, the files it uses, each with one path that shows it."""
        edges: dict[Module, dict[Module, str]] = {}
        for module, code in self.code.items():
            if module in self.test_files:
                continue
            private = _PUB_USE.sub(" ", code)
            paths = [p for tree in _USE.findall(private) for p in expand_use(tree)]
            paths += [m.group(1) for m in _INLINE.finditer(_USE.sub(" ", private))]
            out = edges.setdefault(module, {})
            for text in paths:
                segments = [s for s in split_path(text) if s != "*"]
                target = self.defining_file(module, segments) if segments else None
                if target is not None and target[: len(module)] != module and target not in self.test_files:
                    out.setdefault(target, text)
        return edges

    def name(self, module: Module) -> str:
        return str(self.files[module].relative_to(self.src.parent))


def split_path(text: str) -> list[str]:
    """``a :: b::c as d`` → ``[a, b, c]``."""
    return [s for s in re.split(r"\s*::\s*", re.sub(rf"\s+as\s+{_IDENT}$", "", text.strip())) if s]


def circles(edges: dict[Module, dict[Module, str]]) -> list[list[Module]]:
    """The strongly connected sets of more than one file (Tarjan's algorithm)."""
    index: dict[Module, int] = {}
    low: dict[Module, int] = {}
    stack: list[Module] = []
    found: list[list[Module]] = []

    def visit(v: Module) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in edges.get(v, {}):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while (w := stack.pop()) != v:
                group.append(w)
            if group:
                found.append(sorted([v, *group]))

    sys.setrecursionlimit(10_000)
    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def main() -> int:
    root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent
    roots = [root / "src", *sorted(p for p in (root / "crates").glob("*/src"))]
    status = 0
    for src in roots:
        if not (src / "lib.rs").exists():
            continue
        crate = Crate(src)
        edges = crate.uses()
        for group in circles(edges):
            status = 1
            print(f"import circle in {src.parent.name}: " + " <-> ".join(crate.name(m) for m in group))
            for a in group:
                for b, text in edges[a].items():
                    if b in group:
                        print(f"  {crate.name(a)} uses {crate.name(b)}: {text}")
    if status == 0:
        print("module cycles: none")
    return status


if __name__ == "__main__":
    sys.exit(main())
