"""Wang et al. 2018 on its simulated lab: mean / max x and y errors per method, LOS and NLOS (Table 1).

Six anchors around a 4 m × 3 m area, a small robot driving a figure-8, UWB at 40 Hz with
σ = 0.0514 m (the paper's range variance), a consumer MEMS IMU at 100 Hz; the NLOS preset shields
1–2 anchors at a time (furniture: +0.1–0.6 m bias). Every filter self-initialises with the same
settings, the simulated sensors' (``run.config``). Prints, per method, the mean over seeds of each
run's mean and max |x| and |y| error, beside the paper's Table 1 (its NLOS experiment).

    python examples/wang_2018_compare.py [--seeds 5]
"""

from __future__ import annotations

import argparse

import numpy as np

import uwbimu_rs
from uwbimu_rs import MethodName, sim

# Wang et al. 2018 Table 1 ("the error of NLOS relative to LOS"), m: x mean, x max, y mean, y max.
PAPER: dict[str, tuple[float, float, float, float]] = {"ekf2d": (0.911, 0.2124, 0.0791, 0.1137), "ukf2d": (0.0623, 0.1524, 0.0319, 0.1436), "cekf2d": (0.0744, 0.1711, 0.5174, 0.1091)}
METHODS: list[MethodName] = ["uwb_ls", "ekf2d", "ukf2d", "cekf2d", "ekf", "ukf"]


def axis_errors(df, truth) -> tuple[float, float, float, float]:
    """Mean and max |x| and |y| error of an estimate against the truth interpolated to its times."""
    t = df["t"].to_numpy()
    ex = np.abs(df["x"].to_numpy() - np.interp(t, truth["t"].to_numpy(), truth["x"].to_numpy()))
    ey = np.abs(df["y"].to_numpy() - np.interp(t, truth["t"].to_numpy(), truth["y"].to_numpy()))
    return ex.mean(), ex.max(), ey.mean(), ey.max()


def table(preset: sim.PresetName, seeds: int = 5) -> dict[str, tuple[float, float, float, float]]:
    """``{method: (x mean, x max, y mean, y max)}`` averaged over seeds 0..seeds, m."""
    rows: dict[str, list] = {m: [] for m in METHODS}
    for seed in range(seeds):
        run = sim.preset(preset, seed=seed)
        for method in METHODS:
            df = uwbimu_rs.run_filter(method, run.imu, run.ranges, run.anchors, config=run.config)
            rows[method].append(axis_errors(df, run.truth))
    return {m: _four(np.mean(r, axis=0)) for m, r in rows.items()}


def _four(v: np.ndarray) -> tuple[float, float, float, float]:
    """The four means as floats."""
    return float(v[0]), float(v[1]), float(v[2]), float(v[3])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    args = parser.parse_args()
    for preset in ("lab_robot", "lab_robot_nlos"):
        result = table(preset, args.seeds)
        print(f"{preset} ({'NLOS' if preset.endswith('nlos') else 'LOS'}), {args.seeds} seeds: |error| in m")
        print(f"{'method':<8} {'x mean':>7} {'x max':>7} {'y mean':>7} {'y max':>7}   paper x mean/max, y mean/max")
        for method, (xm, xx, ym, yx) in result.items():
            paper = PAPER.get(method) if preset.endswith("nlos") else None
            ref = "   " + " / ".join(f"{v:.4f}" for v in paper) if paper else ""
            print(f"{method:<8} {xm:7.4f} {xx:7.4f} {ym:7.4f} {yx:7.4f}{ref}")
        print()


if __name__ == "__main__":
    main()
