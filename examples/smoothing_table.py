"""The smoothing table of docs/smoothing.md: `best` forward, smoothed as before the MAP smoother (the
RTS pass and its outlier passes, `smoothing.map_passes = 0`) and smoothed by the MAP passes (the
default), with the passes run and the time of each smoothed run; on isas-walk1 and simulated rigs
(horizontal RMSE after 10 s, raw / aligned, m; self-initialised; defaults with the rig's mounting).

    python examples/smoothing_table.py [--rigs handheld_walk agv_loop ...] [--seeds 25 26]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import polars as pl

import uwbimu_rs
import uwbimu_rs.metrics as metrics

sys.path.insert(0, str(Path(__file__).resolve().parent))
from model_selection_table import isas_walk1, rig_runs  # noqa: E402  (the same rigs)

#: Rigs of the table: the issue's peers' zoo logs, then rigs whose ranges go long.
RIGS = ("handheld_walk", "agv_loop", "drone_flight", "walk_nlos", "nlos_one", "hall_vehicle_nlos", "lab_robot_nlos", "garage_figure8")


def rmse(df: pl.DataFrame, truth: pl.DataFrame) -> str:
    """Horizontal RMSE after 10 s, raw / aligned."""
    df = df.filter(pl.col("t") >= df["t"][0] + 10.0)
    return f"{metrics.evaluate(df, truth).horizontal.rmse:.3f} / {metrics.evaluate(df, truth, align=True).horizontal.rmse:.3f}"


def row(name: str, imu, ranges, anchors, truth, config: dict) -> str:
    """One table row."""
    forward = uwbimu_rs.run_filter("best", imu, ranges, anchors, config=config, smooth=False)
    cells = [rmse(forward, truth)]
    passes = 0
    for extra in ({"map_passes": 0}, {}):
        smoothing = {**config.get("smoothing", {}), **extra}
        t0 = time.perf_counter()
        df, info = uwbimu_rs.run_filter("best", imu, ranges, anchors, config={**config, "smoothing": smoothing}, info=True)
        cells.append(f"{rmse(df, truth)} ({time.perf_counter() - t0:.2f} s)")
        passes = info["health"]["map_passes"]
    return f"| {name} | " + " | ".join(cells) + f" | {passes} |"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="*", default=[25, 26])
    parser.add_argument("--rigs", nargs="*", default=list(RIGS))
    args = parser.parse_args(argv)
    print("| log | forward | smoothed: RTS + outlier passes (time) | smoothed: MAP (time) | MAP passes |")
    print("|---|---|---|---|---|")
    walk = isas_walk1()
    if walk is not None:
        imu, ranges, anchors, truth = walk
        print(row("isas-walk1", imu, ranges, anchors, truth, {}), flush=True)
    for name, imu, ranges, anchors, truth, config in rig_runs(args.rigs, args.seeds):
        print(row(name, imu, ranges, anchors, truth, config), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
