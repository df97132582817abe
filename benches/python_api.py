"""Speed of the Python API: batch `run_filter` against the streaming `Ekf` class.

Reports per-sample costs and their ratio measured in one run (absolute times vary by machine).

    python benches/python_api.py [--repeat N]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import uwbimu_rs
from uwbimu_rs import sim


def best_of(fn, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def streaming(run, initial, config) -> None:
    ekf = uwbimu_rs.Ekf(run.anchors, initial=initial, config=config)
    ranges, j = run.ranges, 0
    for sample in run.imu:
        t = sample[0]
        while j < len(ranges) and ranges[j, 0] < t:
            ekf.add_range(ranges[j, 0], int(ranges[j, 1]), ranges[j, 2])
            j += 1
        ekf.add_imu(t, sample[1:4], sample[4:7])
        while j < len(ranges) and ranges[j, 0] == t:
            ekf.add_range(ranges[j, 0], int(ranges[j, 1]), ranges[j, 2])
            j += 1
    ekf.flush()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    run = sim.preset("hall_vehicle", seed=0)
    config = {"mounting.lever_arm": [0.0, 0.0, 0.05]}
    initial, _ = uwbimu_rs.initialize(run.imu, run.ranges, run.anchors, config=config)
    n = run.imu.shape[0]
    batch = best_of(lambda: uwbimu_rs.run_filter("ekf", run.imu, run.ranges, run.anchors, initial=initial, config=config), args.repeat)
    stream = best_of(lambda: streaming(run, initial, config), args.repeat)
    ls = best_of(lambda: uwbimu_rs.run_filter("uwb_ls", run.imu, run.ranges, run.anchors), args.repeat)
    epochs = np.unique(run.ranges[:, 0]).size
    print(f"data: {n} IMU samples, {run.ranges.shape[0]} ranges, {epochs} UWB epochs ({run.imu[-1, 0]:.0f} s)")
    print(f"ekf batch     : {batch / n * 1e9:8.0f} ns per IMU sample (incl. DataFrame), {run.imu[-1, 0] / batch:8.0f}x real time")
    print(f"ekf streaming : {stream / n * 1e9:8.0f} ns per IMU sample (Python loop)")
    print(f"uwb_ls batch  : {ls / epochs * 1e9:8.0f} ns per epoch")
    print(f"streaming / batch ratio: {stream / batch:.1f}")
    # `best` as a user calls it: self-initialised, smoothed.
    best = best_of(lambda: uwbimu_rs.run_filter("best", run.imu, run.ranges, run.anchors, config=config), args.repeat)
    print(f"best (self-init, smoothed) / ekf batch ratio: {best / batch:.1f}, {run.imu[-1, 0] / best:8.0f}x real time")
    runs = [sim.preset("hall_vehicle_nlos", seed=s) for s in range(4)]
    tuples = [(r.imu, r.ranges, r.anchors) for r in runs]
    one_by_one = best_of(lambda: [uwbimu_rs.run_filter("riekf", *t, config=config) for t in tuples], args.repeat)
    parallel = best_of(lambda: uwbimu_rs.run_filters("riekf", tuples, config=config), args.repeat)
    print(f"riekf over 4 runs: one by one / run_filters (all cores) = {one_by_one / parallel:.2f}")


if __name__ == "__main__":
    main()
