"""Fails when `maturin develop` would compile the workspace's crates a second time after
`cargo test --workspace`: a crate in both builds with different features gets another hash, and
so does every crate that depends on it (Cargo.toml, the comment at `either`). Compares the
features `cargo tree` resolves for the two builds, crate by crate, this package left out."""

import subprocess
import sys

TREE = ["cargo", "tree", "-e", "features", "--prefix", "none", "-f", "{p} [{f}]"]
TESTS = ["--workspace", "-e", "normal,build,dev"]
EXTENSION = ["-p", "uwbimu_rs", "--features", "python", "-e", "normal,build"]


def features(args: list[str]) -> dict[str, set[str]]:
    """`{crate and version: its feature lists}` of the build `args` describes."""
    out = subprocess.run(TREE + args, capture_output=True, text=True, check=True).stdout
    found: dict[str, set[str]] = {}
    for line in out.splitlines():
        if " feature \"" in line or "[" not in line:
            continue
        crate, _, rest = line.partition(" [")
        name = " ".join(crate.split()[:2])
        if name.split()[0] != "uwbimu_rs":
            found.setdefault(name, set()).add(rest.split("]")[0])
    return found


def main() -> int:
    tests, extension = features(TESTS), features(EXTENSION)
    differ = sorted(c for c in tests.keys() & extension.keys() if tests[c] != extension[c])
    for c in differ:
        print(f"{c}: tests {sorted(tests[c])}, extension {sorted(extension[c])}", file=sys.stderr)
    if differ:
        print("one build: the extension would compile the workspace again (Cargo.toml, at `either`)", file=sys.stderr)
        return 1
    print("one build: the extension reuses the tests' crates")
    return 0


if __name__ == "__main__":
    sys.exit(main())
