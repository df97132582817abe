"""Seed 000 Table 1 on the simulated seed-000 NLOS setup: UWB-only, EKF, REKF, RIEKF, CRIEKF.

Figure-8 ×4, 4 anchors, UWB 2 Hz, IMU 100 Hz, 1–2 anchors randomly shielded. Every filter
initialises itself and uses the same settings (range σ = the simulator's 0.1 m). Prints the
min / mean / max horizontal error per method, averaged over seeds, beside the paper's values.

    python examples/seed000_table1.py [--seeds 5] [--range-std 0.1]
"""

from __future__ import annotations

import argparse

import numpy as np

import uwbimu_rs
from uwbimu_rs import metrics, sim

PAPER = {  # seed 000 Table 1: min / mean / max error, m
    "uwb_ls": (0.02, 0.36, 3.98),
    "ekf": (0.01, 0.30, 3.18),
    "rekf": (0.01, 0.28, 3.19),
    "riekf": (0.00, 0.25, 1.18),
    "criekf": (0.00, 0.21, 0.92),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="number of simulator seeds")
    parser.add_argument("--range-std", type=float, default=0.1, help="filter range σ, m")
    args = parser.parse_args()
    config = {"range_std": args.range_std, "lever_arm": [0.0, 0.0, 0.05]}
    stats = {m: [] for m in PAPER}
    for seed in range(args.seeds):
        run = sim.preset("seed000", seed=seed)
        for method in PAPER:
            df = uwbimu_rs.run_filter(method, run.imu, run.ranges, run.anchors, config=config)
            e = metrics.evaluate(df, run.truth).errors["e_h"].to_numpy()
            stats[method].append((e.min(), e.mean(), e.max()))
    print(f"seed-000 NLOS preset, {args.seeds} seeds, range σ {args.range_std} m: horizontal error, m")
    print(f"{'method':<8} {'min':>6} {'mean':>6} {'max':>6}   paper: {'min':>5} {'mean':>5} {'max':>5}")
    for method, rows in stats.items():
        lo, mean, hi = np.mean(rows, axis=0)
        p = PAPER[method]
        print(f"{method:<8} {lo:6.2f} {mean:6.3f} {hi:6.2f}          {p[0]:5.2f} {p[1]:5.2f} {p[2]:5.2f}")


if __name__ == "__main__":
    main()
