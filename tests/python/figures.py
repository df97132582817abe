"""Measured figures stored beside the tests (``tests/figures/<name>.csv``), the Python side of
``tests/integration/common/figures.rs``: :func:`hold` fails a figure more than 10 % (plus 2 mm) above its
stored value; with ``UPDATE_BOUNDS=1`` it records the figure instead and prints what moved. A
figure more than 1 % worse (higher) is not stored unless ``UPDATE_BOUNDS_ALLOW_WORSE=1`` is set
too: it is printed as ``worse:`` and ``scripts/update_test_bounds.sh`` fails. Snapshots, not
oracles (docs/testing.md)."""

from __future__ import annotations

import os
from pathlib import Path

REGRESSION_MARGIN = 1.10
ABSOLUTE_MARGIN_M = 0.002
MOVED = 0.01
FIGURES = Path(__file__).resolve().parents[1] / "figures"


def _read(path: Path) -> dict[str, float]:
    if not path.exists():
        return {}
    out = {}
    for line in path.read_text().splitlines():
        key, _, value = line.rpartition(",")
        out[key] = float(value)
    return out


def hold(name: str, key: str, value: float) -> None:
    """Asserts `value` is within the margin of the stored figure `key` of `name` (or records it)."""
    path = FIGURES / f"{name}.csv"
    figures = _read(path)
    if os.environ.get("UPDATE_BOUNDS"):
        old = figures.get(key)
        change = "" if old is None else f"{old:.4f} -> {value:.4f} ({100.0 * (value / old - 1.0):+.1f} %)"
        if old is None:
            print(f"new: {name}: {key}: {value:.4f}")
        elif value > old * (1.0 + MOVED) and not os.environ.get("UPDATE_BOUNDS_ALLOW_WORSE"):
            print(f"worse: {name}: {key}: {change}, not stored")
            return
        elif abs(value / old - 1.0) > MOVED:
            print(f"{'worse' if value > old else 'moved'}: {name}: {key}: {change}")
        figures[key] = value
        path.write_text("".join(f"{k},{v:.6f}\n" for k, v in sorted(figures.items())))
        return
    assert key in figures, f"{key}: no stored figure in {path} (run `bash scripts/update_test_bounds.sh`)"
    bound = figures[key] * REGRESSION_MARGIN + ABSOLUTE_MARGIN_M
    assert value <= bound, f"{key}: {value:.4f}, above its measured figure {figures[key]:.4f} (+10 %)"
