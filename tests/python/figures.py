"""Measured figures stored beside the tests (``tests/figures/<name>.csv``), the Python side of
``tests/common/figures.rs``: :func:`hold` fails a figure more than 10 % (plus 2 mm) above its
stored value; with ``UPDATE_BOUNDS=1`` it records the figure instead and prints what moved."""

from __future__ import annotations

import os
from pathlib import Path

REGRESSION_MARGIN = 1.10
ABSOLUTE_MARGIN_M = 0.002
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
        if old is None:
            print(f"new: {name}: {key}: {value:.4f}")
        elif abs(value / old - 1.0) > 0.01:
            print(f"moved: {name}: {key}: {old:.4f} -> {value:.4f} ({100.0 * (value / old - 1.0):+.1f} %)")
        figures[key] = value
        path.write_text("".join(f"{k},{v:.6f}\n" for k, v in sorted(figures.items())))
        return
    assert key in figures, f"{key}: no stored figure in {path} (run `bash scripts/update_test_bounds.sh`)"
    bound = figures[key] * REGRESSION_MARGIN + ABSOLUTE_MARGIN_M
    assert value <= bound, f"{key}: {value:.4f}, above its measured figure {figures[key]:.4f} (+10 %)"
