"""Speed of the Python API: batch `run_filter` against a numpy error-state EKF and the streaming `Ekf` class.

Reports per-sample costs and their ratio measured in one run (absolute times vary by machine).
The numpy filter below is the straightforward implementation of `ekf`'s model (same error
state, first-order Φ, one scalar Joseph update per range, the defaults' noise), written here so
that the ratio says what the library saves over writing the filter in numpy; its accuracy is
printed beside `ekf`'s to show it is the same filter.

    python benches/python_api.py [--repeat N]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import uwbimu_rs
from uwbimu_rs import sim
from rotations import quat_exp, quat_mul, quat_to_rot, skew


def best_of(fn, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def numpy_eskf(imu, ranges, anchors, initial, lever_arm, range_std=0.15, accel_noise=0.3, gyro_noise=0.01) -> np.ndarray:
    """A plain numpy error-state EKF (δp, δv, δθ, δb_a, δb_g): returns the (N, 3) positions."""
    gravity = np.array([0.0, 0.0, -9.80665])
    p, v = initial["position"].copy(), initial["velocity"].copy()
    q = initial["orientation"].copy()
    ba, bg = initial["accel_bias"].copy(), initial["gyro_bias"].copy()
    std = np.concatenate([initial["position_std"], initial["velocity_std"], initial["orientation_std"], [0.1] * 3, [0.01] * 3])
    P = np.diag(std**2)
    out = np.empty((imu.shape[0], 3))
    j, eye15 = 0, np.eye(15)
    for k in range(imu.shape[0]):
        t = imu[k, 0]
        if k > 0:
            dt = t - imu[k - 1, 0]
            f, w = imu[k - 1, 1:4] - ba, imu[k - 1, 4:7] - bg
            R = quat_to_rot(q)
            a = R @ f + gravity
            p = p + v * dt + 0.5 * a * dt * dt
            v = v + a * dt
            q = quat_mul(q, quat_exp(w * dt))
            F = np.eye(15)
            F[0:3, 3:6] = np.eye(3) * dt
            F[3:6, 6:9] = -R @ skew(f) * dt
            F[3:6, 9:12] = -R * dt
            F[6:9, 6:9] = np.eye(3) - skew(w) * dt
            F[6:9, 12:15] = -np.eye(3) * dt
            Q = np.diag([0.0] * 3 + [accel_noise**2 * dt] * 3 + [gyro_noise**2 * dt] * 3 + [1e-8 * dt] * 3 + [1e-10 * dt] * 3)
            P = F @ P @ F.T + Q
        while j < ranges.shape[0] and ranges[j, 0] <= t:
            R = quat_to_rot(q)
            anchor = anchors[int(ranges[j, 1])]
            d = p + R @ lever_arm - anchor
            dist = np.linalg.norm(d)
            u = d / dist
            h = np.zeros(15)
            h[0:3] = u
            h[6:9] = -u @ R @ skew(lever_arm)
            s = h @ P @ h + range_std**2
            K = P @ h / s
            dx = K * (ranges[j, 2] - dist)
            IKH = eye15 - np.outer(K, h)
            P = IKH @ P @ IKH.T + np.outer(K, K) * range_std**2
            p, v = p + dx[0:3], v + dx[3:6]
            q = quat_mul(q, quat_exp(dx[6:9]))
            q /= np.linalg.norm(q)
            ba, bg = ba + dx[9:12], bg + dx[12:15]
            j += 1
        out[k] = p + quat_to_rot(q) @ lever_arm
    return out


def _horizontal_rmse(xy: np.ndarray, t: np.ndarray, truth) -> float:
    keep = t >= t[0] + 10.0
    tx, ty = np.interp(t, truth["t"], truth["x"]), np.interp(t, truth["t"], truth["y"])
    return float(np.sqrt(np.mean((xy[keep, 0] - tx[keep]) ** 2 + (xy[keep, 1] - ty[keep]) ** 2)))


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
    # The comparison: 60 s at 100 Hz with 4 anchors, `run_filter("ekf")` against numpy.
    short_imu, short_ranges = run.imu[run.imu[:, 0] <= run.imu[0, 0] + 60.0], run.ranges[run.ranges[:, 0] <= run.imu[0, 0] + 60.0]
    lever = np.array(config["mounting.lever_arm"])
    lib = best_of(lambda: uwbimu_rs.run_filter("ekf", short_imu, short_ranges, run.anchors, initial=initial, config=config), args.repeat)
    t0 = time.perf_counter()
    theirs = numpy_eskf(short_imu, short_ranges, run.anchors, initial, lever)
    numpy_time = time.perf_counter() - t0
    ours = uwbimu_rs.run_filter("ekf", short_imu, short_ranges, run.anchors, initial=initial, config=config)
    t = short_imu[:, 0]
    print(
        f"ekf on 60 s, 100 Hz, {run.anchors.shape[0]} anchors: run_filter {lib * 1e3:.1f} ms, numpy ESKF {numpy_time * 1e3:.0f} ms, "
        f"ratio {numpy_time / lib:.0f}x (horizontal RMSE after 10 s: ours {_horizontal_rmse(ours.select(['x', 'y']).to_numpy(), t, run.truth):.3f} m, "
        f"numpy {_horizontal_rmse(theirs, t, run.truth):.3f} m)"
    )
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
