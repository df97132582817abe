"""The anchor-refinement tables of docs/anchors.md: anchors surveyed wrong by 0.05–0.5 m, refined
from the log with `uwbimu_rs.calibrate(..., refine_anchors=True)`, and the track's accuracy with
the true, the wrong and the refined anchors.

* Simulated sites: 4, 6 or 8 anchors on walls at 0.4–2.9 m or all at 2.5 m, a figure-8 walk at
  1 m for 2 minutes, UWB at 10 Hz with σ 5 cm and random NLOS shielding; each anchor moved by the
  survey error in a random direction.
* isas-walk1 (../shared/data): its 5 anchors moved by 0.3 m in a random direction each.

Anchor errors are after the translation and yaw that best align the anchors on the truth (the
gauge, which no log fixes). Track errors are the horizontal RMSE of `best` after rigid alignment,
forward / smoothed, the first 10 s left out.

    python examples/anchor_refine_table.py [--part sims|isas|both] [--seeds 3]
"""

from __future__ import annotations

import argparse
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

import uwbimu_rs
import uwbimu_rs.metrics as metrics
import uwbimu_rs.sim as sim

ROOT = Path(__file__).resolve().parent.parent
WALLS = np.array(
    [[0.5, 0.3, 2.4], [9.8, 0.1, 2.6], [10.2, 7.9, 0.4], [0.2, 8.1, 2.5], [5.1, -0.2, 0.5], [4.9, 8.3, 2.2], [7.5, 4.0, 2.9], [2.5, 4.2, 0.9]]
)


def aligned(anchors: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """`anchors` moved by the translation and yaw that best align them on `truth`."""
    c, c0 = anchors.mean(axis=0), truth.mean(axis=0)
    d, d0 = anchors - c, truth - c0
    yaw = np.arctan2(np.sum(d[:, 0] * d0[:, 1] - d[:, 1] * d0[:, 0]), np.sum(d[:, 0] * d0[:, 0] + d[:, 1] * d0[:, 1]))
    rot = np.array([[np.cos(yaw), -np.sin(yaw), 0.0], [np.sin(yaw), np.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
    return d @ rot.T + c0


def anchor_errors(anchors: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Largest horizontal and vertical error after alignment, m."""
    e = aligned(anchors, truth) - truth
    return float(np.hypot(e[:, 0], e[:, 1]).max()), float(np.abs(e[:, 2]).max())


def moved(anchors: np.ndarray, error_m: float, rng: np.random.Generator) -> np.ndarray:
    """Each anchor moved by `error_m` in a random direction."""
    d = rng.normal(size=anchors.shape)
    return anchors + error_m * d / np.linalg.norm(d, axis=1, keepdims=True)


def track_rmse(imu, ranges, anchors, truth, config=None) -> tuple[float, float]:
    """Horizontal RMSE of `best` after rigid alignment, forward and smoothed, after 10 s."""
    out = []
    for smooth in (False, True):
        df = uwbimu_rs.run_filter("best", imu, ranges, anchors, config=config, smooth=smooth)
        df = df.filter(df["t"] >= df["t"][0] + 10.0)
        out.append(metrics.evaluate(df, truth, align=True).horizontal.rmse)
    return out[0], out[1]


def fmt(pair: tuple[float, float]) -> str:
    return f"{pair[0]:.3f} / {pair[1]:.3f}"


def sims(seeds: int) -> None:
    print("| site | anchors | survey error (m) | anchor error, horizontal / vertical (m): given → refined | track, true anchors | given | refined | s |")
    print("|---|---|---|---|---|---|---|---|")
    for name, flat in (("walls", False), ("one height", True)):
        for k in (4, 6, 8):
            site = WALLS[:k].copy()
            if flat:
                site[:, 2] = 2.5
            for error in (0.05, 0.2, 0.5):
                rows = []
                for seed in range(seeds):
                    run = sim.simulate(
                        sim.Trajectory.figure_eight([5.0, 4.0, 1.0], 3.5, 2.5, 20.0, 6), site, seed=seed, uwb_rate_hz=10.0, range_std_m=0.05, nlos=True
                    )
                    given = moved(site, error, np.random.default_rng(1000 + seed))
                    start = time.perf_counter()
                    r = uwbimu_rs.calibrate(run.imu, run.ranges, given, refine_anchors=True, anchor_std=max(error, 0.05), config=run.config)
                    took = time.perf_counter() - start
                    rows.append(
                        [*anchor_errors(given, site), *anchor_errors(r["anchors"], site)]
                        + [*track_rmse(run.imu, run.ranges, site, run.truth, run.config)]
                        + [*track_rmse(run.imu, run.ranges, given, run.truth, run.config)]
                        + [*track_rmse(run.imu, run.ranges, r["anchors"], run.truth, run.config), took]
                    )
                m = np.mean(rows, axis=0)
                print(
                    f"| {name} | {k} | {error} | {m[0]:.3f} / {m[1]:.3f} → {m[2]:.3f} / {m[3]:.3f} | {fmt(m[4:6])} | {fmt(m[6:8])} | {fmt(m[8:10])} | {m[10]:.1f} |",
                    flush=True,
                )


def isas(seeds: int, data: Path) -> None:
    if not (data / "isas-walk1.mcap").exists():
        print(f"skipped: {data} is not present", file=sys.stderr)
        return
    mapping = tomllib.loads((ROOT / "examples" / "isas-walk1.toml").read_text())["mapping"]
    mapping["ground_truth"] = {"file": str(data / "gt_anchor_frame.csv")}
    d = uwbimu_rs.read_mcap(data / "isas-walk1.mcap", mapping=mapping)
    imu, surveyed, truth = d["imu"].to_numpy(), d["anchors"].select("x", "y", "z").to_numpy(), d["ground_truth"]
    ranges = d["ranges"].select("t", "anchor", "range").to_numpy()
    print(f"surveyed anchors: track {fmt(track_rmse(imu, ranges, surveyed, truth))}")
    print()
    print("| seed | anchor error, horizontal / vertical (m): given → refined | track, given | refined | refined with range biases (σ 0.1 m) | s |")
    print("|---|---|---|---|---|---|")
    for seed in range(seeds):
        given = moved(surveyed, 0.3, np.random.default_rng(seed))
        start = time.perf_counter()
        r = uwbimu_rs.calibrate(imu, ranges, given, refine_anchors=True, anchor_std=0.3)
        took = time.perf_counter() - start
        rb = uwbimu_rs.calibrate(imu, ranges, given, refine_anchors=True, anchor_std=0.3, range_bias_std=0.1)
        before, after = anchor_errors(given, surveyed), anchor_errors(r["anchors"], surveyed)
        print(
            f"| {seed} | {fmt(before)} → {fmt(after)} | {fmt(track_rmse(imu, ranges, given, truth))} | "
            f"{fmt(track_rmse(imu, ranges, r['anchors'], truth))} | "
            f"{fmt(track_rmse(imu, ranges, rb['anchors'], truth, rb['config']))} | {took:.1f} |",
            flush=True,
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=("sims", "isas", "both"), default="both")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "isas-walk1")
    args = parser.parse_args()
    if args.part in ("isas", "both"):
        isas(max(args.seeds, 5), args.data)
        print()
    if args.part in ("sims", "both"):
        sims(args.seeds)


if __name__ == "__main__":
    main()
