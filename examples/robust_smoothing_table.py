"""The robust-smoothing table of docs/model-selection.md: `best` smoothed with its re-smoothing
passes (the default) against the plain RTS pass (`smoothing.outlier_passes = 0`), on simulated
rigs with and without NLOS and on isas-walk1 (horizontal RMSE after 10 s, m, self-initialised,
defaults with the rig's mounting; isas-walk1 raw / aligned), with the ranges it left out.

    python examples/robust_smoothing_table.py [--seeds 27 28] [--rigs walk_nlos nlos_one ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import polars as pl

import uwbimu_rs
import uwbimu_rs.metrics as metrics

sys.path.insert(0, str(Path(__file__).resolve().parent))
from model_selection_table import isas_walk1, rig_runs  # noqa: E402  (the same rigs)

#: `scenario+errors` as in model_selection_table.py (`rig_runs`): NLOS rigs first, then clean ones.
RIGS = (
    "walk_nlos",
    "nlos_one",
    "nlos_two",
    "forklift",
    "lab_robot_nlos",
    "hall_vehicle_nlos",
    "square_diagonal_outliers",
    "outliers",
    "handheld_walk+wandering",
    "drone_rates+steady",
    "corridor+steady",
    "survey_error",
    "outage",
    "far_start",
    "handheld_walk",
    "agv_loop",
    "drone_flight",
    "stop_and_go",
    "imu_20hz",
    "mixed_rates",
    "garage_figure8",
)

#: The plain RTS pass, and the outlier passes as such (`best`'s MAP passes, which replace them, off).
PLAIN = {"smoothing": {"outlier_passes": 0, "map_passes": 0}}
ROBUST = {"smoothing": {"map_passes": 0}}


def rmse(df: pl.DataFrame, truth: pl.DataFrame, align: bool) -> float:
    """Horizontal RMSE after 10 s."""
    df = df.filter(pl.col("t") >= df["t"][0] + 10.0)
    return metrics.evaluate(df, truth, align=align).horizontal.rmse


def row(name: str, imu, ranges, anchors, truth, config: dict, align: bool) -> str:
    """One table row: plain → robust smoothing, and the ranges left out."""
    plain = uwbimu_rs.run_filter("best", imu, ranges, anchors, config={**config, **PLAIN})
    robust, info = uwbimu_rs.run_filter("best", imu, ranges, anchors, config={**config, **ROBUST}, info=True)
    left_out = info["health"]["smoothing_left_out"]
    a, b = rmse(plain, truth, align), rmse(robust, truth, align)
    return f"| {name} | {a:.3f} → {b:.3f} ({100 * (b / a - 1):+.0f} %) | {left_out} of {ranges.shape[0]} |"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="*", default=[27, 28])
    parser.add_argument("--rigs", nargs="*", choices=RIGS, default=list(RIGS))
    args = parser.parse_args(argv)
    print("| rig | `best` smoothed, plain RTS → robust smoothing (m) | ranges left out |")
    print("|---|---|---|")
    for name, imu, ranges, anchors, truth, config in rig_runs(args.rigs, args.seeds):
        print(row(name, imu, ranges, anchors, truth, config, align=False), flush=True)
    walk = isas_walk1()
    if walk is not None:
        imu, ranges, anchors, truth = walk
        for align in (False, True):
            print(row(f"isas-walk1 ({'aligned' if align else 'raw'})", imu, ranges, anchors, truth, {}, align=align))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
