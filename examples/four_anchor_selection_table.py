"""The four-anchor table of docs/model-selection.md: what `best` chooses by held-out time blocks on
the zoo's and the presets' four-anchor rigs (clean, and with the steady / long / wandering range
errors of model_selection_table.py), the forward horizontal RMSE (m, after 10 s, raw) with the
choice off → on, and the smoothed `best`'s median and p95 against `uwb_ls`'s.

    python examples/four_anchor_selection_table.py [--seeds 25 26] [--scenarios hall_vehicle ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import polars as pl

import uwbimu_rs
import uwbimu_rs.metrics as metrics

sys.path.insert(0, str(Path(__file__).resolve().parent))
from model_selection_table import rig_runs  # noqa: E402

SCENARIOS = (
    "hall_vehicle",
    "hall_vehicle_nlos",
    "garage_rectangle",
    "stop_and_go",
    "outage",
    "imu_20hz",
    "forklift",
    "far_start",
    "nlos_two",
)
ERRORS = ("+steady", "+long", "", "+wandering")


def stats(df: pl.DataFrame, truth: pl.DataFrame) -> tuple[float, float, float]:
    """Horizontal RMSE, median and p95 after 10 s, m."""
    h = metrics.evaluate(df.filter(pl.col("t") >= df["t"][0] + 10.0), truth).horizontal
    return h.rmse, h.median, h.p95


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="*", default=[25, 26])
    parser.add_argument("--scenarios", nargs="*", choices=SCENARIOS, default=list(SCENARIOS))
    args = parser.parse_args(argv)
    print("| rig | `best` chose | forward off → on | smoothed median, p95 | `uwb_ls` median, p95 |")
    print("|---|---|---|---|---|")
    rigs = [s + e for s in args.scenarios for e in ERRORS]
    for name, imu, ranges, anchors, truth, config in rig_runs(rigs, args.seeds):
        choice = uwbimu_rs.choose_model("best", imu, ranges, anchors, config=config)
        plain = {**config, "model_selection": {"enabled": False}}
        before = stats(uwbimu_rs.run_filter("best", imu, ranges, anchors, config=plain, smooth=False), truth)[0]
        after = stats(uwbimu_rs.run_filter("best", imu, ranges, anchors, config=choice["config"], smooth=False), truth)[0]
        smoothed = stats(uwbimu_rs.run_filter("best", imu, ranges, anchors, config=choice["config"]), truth)
        ls = stats(uwbimu_rs.run_filter("uwb_ls", imu, ranges, anchors, config=config), truth)
        chosen = choice["chosen"] if choice["chosen"] not in (None, "as configured") else "kept"
        print(
            f"| {name} | {chosen} | {before:.3f} → {after:.3f} | {smoothed[1]:.3f}, {smoothed[2]:.3f} "
            f"| {ls[1]:.3f}, {ls[2]:.3f} |",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
