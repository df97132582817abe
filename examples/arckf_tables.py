"""The ARCKF paper on its simulated garage: Table 4 (acceleration outliers) and Table 6 (range outliers).

Site: 10 m × 5 m, four beacons at 1.5 / 2.0 m, UWB 2 Hz, IMU 100 Hz with the x-IMU densities of
Table 1. Table 4: the 8 m × 3 m rectangle route with 1–4 abnormal accelerometer samples (white
noise of 50 dBW, std 316 m/s² per axis). Table 6: the figure-8 route with 3 / 5 / 7 / 10 % gross
range errors U(1, 8) m on beacons 2 and 4. Every filter self-initialises from the first still
seconds, with the simulated sensors' settings (``run.config``). Prints the horizontal RMSE of CKF,
ARCKF and the RTS-smoothed ARCKF, averaged over seeds, beside the paper's values.

    python examples/arckf_tables.py [--seeds 5]
"""

from __future__ import annotations

import argparse

import numpy as np

import uwbimu_rs
from uwbimu_rs import MethodName, metrics, sim

TABLE4 = {"ckf": [0.87, 1.26, 1.56, 2.27], "arckf": [0.49, 0.58, 0.79, 1.02]}  # m, 1–4 outliers
TABLE6 = {"ckf": [0.67, 1.06, 1.36, 1.67], "arckf": [0.39, 0.45, 0.52, 0.59]}  # m, 3/5/7/10 %
LABELS = ("ckf", "arckf", "arckf+rts")


def mean_rmse(preset: sim.PresetName, seeds: int, **overrides: float) -> dict[str, float]:
    """Mean horizontal RMSE over seeds of ckf, arckf and the smoothed arckf."""
    runs = [sim.preset(preset, seed=s, **overrides) for s in range(seeds)]
    arrays = [(r.imu, r.ranges, r.anchors) for r in runs]
    out = {}
    rows: tuple[tuple[str, MethodName, bool], ...] = (("ckf", "ckf", False), ("arckf", "arckf", False), ("arckf+rts", "arckf", True))
    for label, method, smooth in rows:
        frames = uwbimu_rs.run_filters(method, arrays, config=runs[0].config, smooth=smooth)
        out[label] = float(np.mean([metrics.evaluate(df, r.truth).horizontal.rmse for df, r in zip(frames, runs)]))
    return out


def table4(seeds: int = 5) -> list[dict[str, float]]:
    """Table 4 rows for 1–4 acceleration outliers."""
    return [mean_rmse("garage_rectangle", seeds, accel_outlier_count=n) for n in (1, 2, 3, 4)]


def table6(seeds: int = 5) -> list[dict[str, float]]:
    """Table 6 rows for 3 / 5 / 7 / 10 % range outliers."""
    return [mean_rmse("garage_figure8", seeds, outlier_prob=p) for p in (0.03, 0.05, 0.07, 0.10)]


def show(title: str, columns: list[str], rows: list[dict[str, float]], paper: dict[str, list[float]]) -> None:
    print(title)
    print(f"{'':<16}" + "".join(f"{c:>8}" for c in columns))
    for label in LABELS:
        print(f"{label + ' (ours)':<16}" + "".join(f"{r[label]:8.2f}" for r in rows))
        if label in paper:
            print(f"{label + ' (paper)':<16}" + "".join(f"{v:8.2f}" for v in paper[label]))
    print()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    args = parser.parse_args()
    show(f"Table 4: horizontal RMSE (m), rectangle, {args.seeds} seeds; acceleration outliers", ["1", "2", "3", "4"], table4(args.seeds), TABLE4)
    show(f"Table 6: horizontal RMSE (m), figure-8, {args.seeds} seeds; range outliers on beacons 2, 4", ["3 %", "5 %", "7 %", "10 %"], table6(args.seeds), TABLE6)


if __name__ == "__main__":
    main()
