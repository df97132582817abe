"""What the MAP passes buy, log by log (docs/smoothing.md, issue 60): smoothed `best` with its
MAP default against the same run with ``smoothing.map_passes = 0`` (RTS and the outlier passes),
on every zoo scenario and seed, self-initialised, with the scenario's noise configured; the
horizontal RMSE against the truth after the first 10 s, and the ratio (default / none). With
``../shared`` beside the clone, isas-walk1 too (its replay file, aligned RMSE).

    python examples/map_passes_table.py [--seeds 0 1 2] [--scenarios agv_loop outage]
"""

from __future__ import annotations

import argparse
import copy
from pathlib import Path

import polars as pl

import uwbimu_rs
from uwbimu_rs import sim
from uwbimu_rs.metrics import evaluate

ROOT = Path(__file__).resolve().parent.parent
SETTLE_S = 10.0


def zoo_rmse(run: sim.SimResult, map_passes: int | None) -> tuple[float, int]:
    """Horizontal RMSE after the first 10 s and the MAP passes run, for one setting."""
    config = copy.deepcopy(dict(run.config))
    if map_passes is not None:
        config.setdefault("smoothing", {})["map_passes"] = map_passes
    tdoa = run.tdoa if run.tdoa is not None and len(run.tdoa) else None
    df, info = uwbimu_rs.run_filter("best", run.imu, run.ranges, run.anchors, config=config, smooth=True, info=True, tdoa=tdoa)
    settled = df.filter(pl.col("t") >= df["t"][0] + SETTLE_S)
    return evaluate(settled, run.truth).horizontal.rmse, info["health"]["map_passes"]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    p.add_argument("--scenarios", nargs="+", default=list(sim.ZOO_NAMES), choices=sim.ZOO_NAMES)
    p.add_argument("--isas", type=Path, default=ROOT.parent / "shared" / "data" / "isas-walk1")
    args = p.parse_args()
    print("| log | seed | RMSE, no MAP, m | RMSE, MAP default, m | ratio | passes kept |")
    print("|---|---|---|---|---|---|")
    worse = 0
    for name in args.scenarios:
        for seed in args.seeds:
            run = sim.zoo(name, seed=seed)
            (none, _), (default, passes) = zoo_rmse(run, 0), zoo_rmse(run, None)
            worse += default > 1.02 * none
            print(f"| {name} | {seed} | {none:.4f} | {default:.4f} | {default / none:.3f} | {passes} |")
    if (args.isas / "isas-walk1.mcap").exists():
        cells = []
        for overrides in ({"smoothing.map_passes": 0}, None):
            _, info = uwbimu_rs.replay(
                args.isas / "isas-walk1.mcap",
                config_file=ROOT / "examples" / "isas-walk1.toml",
                overrides=overrides,
                ground_truth=args.isas / "gt_anchor_frame.csv",
            )
            cells.append((info["rmse_horizontal_aligned_m"], info["map_passes"]))
        (none, _), (default, passes) = cells
        worse += default > 1.02 * none
        print(f"| isas-walk1 (aligned) | – | {none:.4f} | {default:.4f} | {default / none:.3f} | {passes} |")
    print(f"\nruns more than 2 % worse with the MAP default: {worse}")


if __name__ == "__main__":
    main()
