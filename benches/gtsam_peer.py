"""Peer benchmark: GTSAM's batch smoother (Levenberg–Marquardt) on the same logs as our filters.

What it measures, per log and robust kernel: the horizontal RMSE of the GTSAM smoothed trajectory
(one position per keyframe) against the truth, raw and after a rigid SE(3) alignment
(`uwbimu_rs.metrics.evaluate`, the first 10 s left out as `examples/isas_walk1_table.py` does),
the LM iterations, and the wall time of graph build (preintegration included) + optimisation; the
forward-EKF warm start is timed and scored separately.

The protocol (fixed by the issue):

- keyframes at every UWB epoch (the ranges sharing one timestamp), plus one at the first IMU
  sample that carries the prior of the initial state (the EKF's `initial`, same means and σ);
- `CombinedImuFactor` (`PreintegratedCombinedMeasurements`) between consecutive keyframes, biases
  as random walks; the IMU samples are held over their interval (zero-order hold, as our filters
  propagate), an interval cut where a keyframe falls; IMU noise densities and bias walks are
  uwbimu_rs's (the defaults: `FilterConfig().to_dict()["ins"]`), so GTSAM and the EKF share the
  IMU model; gravity [0, 0, -9.80665] (ENU, z up);
- one range factor per range (`RangeFactorWithTransform3D`: pose ∘ body→tag lever arm to the
  anchor; the anchors are Point3 variables pinned by a prior of σ 1e-6 m), isotropic σ 0.15 m;
- kernels: Gaussian, Cauchy (k = 1) and Huber (k = 1.345), k in units of σ
  (`noiseModel.Robust.Create(mEstimator.X.Create(k), Isotropic.Sigma(1, 0.15))`);
- LM (GTSAM's defaults: multifrontal Cholesky, COLAMD; at most 100 iterations; `--linear-solver qr`
  for multifrontal QR: on `handheld_walk`, whose staggered ranges put keyframes 2–3 ms apart,
  Cholesky LM creeps to the iteration cap with λ stuck at 10 though the accuracy is reached in
  about 4 iterations, while QR converges in 4–5) from a full-state warm
  start: the forward `ekf` (`run_filter(..., initial=..., smooth=False)`) started at the true position with the oracle
  heading; its pose and velocity interpolated at each keyframe time, its biases (which the batch
  frame has no column for) read from the streaming `Ekf` fed the same log, which equals the batch
  run bit for bit (checked here on the positions).

Logs: (a) the real recording isas-walk1 (skipped when ../shared/data/isas-walk1 is absent): the
truth is the tag's position only, so the oracle heading is found as the self-initialisation finds
its heading, with the truth in place of UWB: the IMU is dead-reckoned from the onset of motion
(roll, pitch and gyro bias of `uwbimu_rs.initialize`) and the yaw that turns its horizontal
displacement onto the truth's over the first metres is applied; (b) scenarios of the simulator's
zoo with the true initial state (`run.initial`), the library defaults plus the rig's lever arm.

isas-walk1 holds two gross ranges (23.94 m to anchor 4 at 17.08 s and 17.13 s) that the gate lets
through: the Gaussian kernel follows them (0.5 m error around 17 s); without them it is at
0.122 / 0.082 m, as our `rekf` / `riekf` smoothed (docs/accuracy.md).

Needs `pip install gtsam` (4.3); not run in CI.

    python benches/gtsam_peer.py [--data DIR] [--scenarios handheld_walk ...] [--seeds 25 26]
                                 [--kernels gaussian cauchy huber] [--linear-solver cholesky|qr]
                                 [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

import uwbimu_rs
from uwbimu_rs import metrics, sim
from rotations import quat_mul, quat_to_rot, skew

try:
    import gtsam  # type: ignore[import-untyped,import-not-found,unused-ignore]
except ImportError:  # pragma: no cover - reported by main()
    gtsam = None  # type: ignore[assignment]

ROOT = Path(__file__).resolve().parent.parent
RANGE_STD = 0.15
KERNELS: dict[str, float] = {"gaussian": 0.0, "cauchy": 1.0, "huber": 1.345}  # k in units of σ
ANCHOR_PIN_STD = 1e-6
SKIP_S = 10.0
MAX_ITERATIONS = 100
LINEAR_SOLVERS = {"cholesky": "MULTIFRONTAL_CHOLESKY", "qr": "MULTIFRONTAL_QR"}


@dataclass
class Log:
    """One log: inputs, truth (t, x, y, z of the body origin), the filter config and initial state."""

    name: str
    imu: np.ndarray
    ranges: np.ndarray
    anchors: np.ndarray
    truth: pl.DataFrame
    config: dict[str, Any]
    initial: dict[str, Any]
    note: str = ""


# ------------------------------------------------------------------------------------------------
# Rotations (Hamilton, w x y z, body -> nav)
# ------------------------------------------------------------------------------------------------


def unit(q: Any) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    return q / np.linalg.norm(q)


def exp_so3(phi: np.ndarray) -> np.ndarray:
    angle = float(np.linalg.norm(phi))
    k = skew(phi)
    if angle < 1e-12:
        return np.eye(3) + k
    return np.eye(3) + np.sin(angle) / angle * k + (1 - np.cos(angle)) / angle**2 * (k @ k)


def yaw_of(q: np.ndarray) -> float:
    r = quat_to_rot(unit(q))
    return float(np.arctan2(r[1, 0], r[0, 0]))


# ------------------------------------------------------------------------------------------------
# Logs
# ------------------------------------------------------------------------------------------------


def oracle_heading(imu: np.ndarray, truth: pl.DataFrame, init: dict[str, Any], distance_m: float = 1.0) -> float:
    """Yaw correction (rad) that turns the IMU's dead-reckoned horizontal displacement onto the
    truth's over the first ``distance_m``..2·``distance_m`` metres of motion.

    The IMU is dead-reckoned with the self-initialisation's attitude and gyro bias from the onset
    of motion (the truth has moved 5 cm), starting at the truth's velocity there, as the
    self-initialisation does with the UWB fixes (least squares over the samples in the window)."""
    t = imu[:, 0]
    tt = truth["t"].to_numpy()
    txyz = truth.select("x", "y", "z").to_numpy()
    p_true = np.column_stack([np.interp(t, tt, txyz[:, i]) for i in range(3)])
    moved = np.linalg.norm(p_true[:, :2] - p_true[0, :2], axis=1)
    onset = int(np.argmax(moved > 0.05))
    gravity = np.array([0.0, 0.0, -9.80665])
    bg = np.asarray(init.get("gyro_bias", np.zeros(3)))
    r = quat_to_rot(unit(init["orientation"]))
    for i in range(onset):  # attitude only up to the onset
        r = r @ exp_so3((imu[i, 4:7] - bg) * (t[i + 1] - t[i]))
    h = 0.2  # truth velocity at the onset: central difference over ±0.2 s
    v = np.array([(np.interp(t[onset] + h, tt, txyz[:, i]) - np.interp(t[onset] - h, tt, txyz[:, i])) / (2 * h) for i in range(3)])
    p = np.zeros(3)
    dr, tr = [], []
    for i in range(onset, len(t) - 1):
        dt = t[i + 1] - t[i]
        a = r @ imu[i, 1:4] + gravity
        p = p + v * dt + 0.5 * a * dt * dt
        v = v + a * dt
        r = r @ exp_so3((imu[i, 4:7] - bg) * dt)
        d_true = p_true[i + 1] - p_true[onset]
        dist = float(np.linalg.norm(d_true[:2]))
        if dist >= distance_m:
            dr.append(p[:2].copy())
            tr.append(d_true[:2])
        if dist >= 2 * distance_m:
            break
    a_dr, a_tr = np.array(dr), np.array(tr)
    cross = float(np.sum(a_dr[:, 0] * a_tr[:, 1] - a_dr[:, 1] * a_tr[:, 0]))
    dot = float(np.sum(a_dr[:, 0] * a_tr[:, 0] + a_dr[:, 1] * a_tr[:, 1]))
    return float(np.arctan2(cross, dot))


def isas_walk1(data: Path) -> Log | None:
    if not (data / "isas-walk1.mcap").exists():
        print(f"skipped isas-walk1: {data} is not present", file=sys.stderr)
        return None
    toml = tomllib.loads((ROOT / "examples" / "isas-walk1.toml").read_text())
    mapping = toml["mapping"]
    mapping["ground_truth"] = {"file": str(data / "gt_anchor_frame.csv")}
    d = uwbimu_rs.read_mcap(data / "isas-walk1.mcap", mapping=mapping)
    imu, anchors, truth = d["imu"].to_numpy(), d["anchors"].select("x", "y", "z").to_numpy(), d["ground_truth"]
    ranges = d["ranges"].select("t", "anchor", "range").to_numpy()
    lever = np.asarray(toml.get("config", {}).get("mounting", {}).get("lever_arm", [0.0, 0.0, 0.0]), dtype=float)
    if np.any(lever != 0.0):
        raise SystemExit("isas-walk1: a non-zero lever arm: the truth (tag) would need moving to the body")
    config: dict[str, Any] = {"ranging.range_std": RANGE_STD}  # the library defaults otherwise
    init, _ = uwbimu_rs.initialize(imu, ranges, anchors, config=config)
    dpsi = oracle_heading(imu, truth, init)
    half = np.array([np.cos(dpsi / 2), 0.0, 0.0, np.sin(dpsi / 2)])
    q = quat_mul(half, np.asarray(init["orientation"]))  # yaw about the nav z axis
    tt = truth["t"].to_numpy()
    position = np.array([np.interp(imu[0, 0], tt, truth[c].to_numpy()) for c in ("x", "y", "z")])
    initial = {
        "position": position,
        "velocity": np.zeros(3),
        "orientation": q,
        "gyro_bias": np.asarray(init["gyro_bias"]),
        "position_std": 0.3,
        "velocity_std": 0.1,
        "orientation_std": [0.05, 0.05, 0.2],
    }
    note = f"self-init yaw {np.degrees(yaw_of(np.asarray(init['orientation']))):.1f}°, oracle {np.degrees(yaw_of(q)):.1f}°"
    return Log("isas-walk1", imu, ranges, anchors, truth.select("t", "x", "y", "z"), config, initial, note)


def zoo_log(name: str, seed: int) -> Log:
    run = sim.zoo(name, seed=seed)  # type: ignore[arg-type]
    mounting = run.config["mounting"]
    if not np.allclose(mounting["imu_rotation"], [1.0, 0.0, 0.0, 0.0]):
        raise SystemExit(f"{name}: a mounting rotation is not supported here")
    if run.ranges.shape[1] != 3:
        raise SystemExit(f"{name}: a second tag is not supported here")
    config = {"ranging.range_std": RANGE_STD, "mounting.lever_arm": np.asarray(mounting["lever_arm"], dtype=float)}
    initial = dict(run.initial)
    return Log(f"{name}/{seed}", run.imu, run.ranges, run.anchors, run.truth.select("t", "x", "y", "z"), config, initial)


# ------------------------------------------------------------------------------------------------
# Warm start
# ------------------------------------------------------------------------------------------------


def ekf_biases(log: Log) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The streaming ``Ekf`` over the log (it equals ``run_filter(..., smooth=False)``): its
    position and accelerometer and gyroscope biases after each IMU sample."""
    f = uwbimu_rs.Ekf(log.anchors, initial=log.initial, config=log.config, reorder_window_s=0.0, keep_steps=0)
    imu, ranges = log.imu, log.ranges
    n = len(imu)
    pos, ba, bg = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    j = 0
    for i in range(n):
        t = imu[i, 0]
        f.add_imu(t, imu[i, 1:4], imu[i, 4:7])
        s = f.state  # the state of the batch frame's row i (ranges at or after t come next)
        pos[i], ba[i], bg[i] = s["position"], s["accel_bias"], s["gyro_bias"]
        while j < len(ranges) and (i + 1 == n or ranges[j, 0] < imu[i + 1, 0]):
            f.add_range(float(ranges[j, 0]), int(ranges[j, 1]), float(ranges[j, 2]))
            j += 1
    f.flush()
    return pos, ba, bg


def interpolate_states(df: pl.DataFrame, times: np.ndarray) -> dict[str, np.ndarray]:
    """Positions and velocities linearly interpolated at ``times``; orientations normalised-lerped."""
    t = df["t"].to_numpy()
    out = {}
    for name in ("x", "y", "z", "vx", "vy", "vz"):
        out[name] = np.interp(times, t, df[name].to_numpy())
    q = df.select("qw", "qx", "qy", "qz").to_numpy()
    i1 = np.clip(np.searchsorted(t, times), 1, len(t) - 1)
    i0 = i1 - 1
    w = np.clip((times - t[i0]) / (t[i1] - t[i0]), 0.0, 1.0)[:, None]
    q1 = q[i1] * np.sign(np.sum(q[i0] * q[i1], axis=1))[:, None]
    qi = (1 - w) * q[i0] + w * q1
    out["q"] = qi / np.linalg.norm(qi, axis=1)[:, None]
    return out


# ------------------------------------------------------------------------------------------------
# GTSAM
# ------------------------------------------------------------------------------------------------


def range_noise(kernel: str) -> Any:
    base = gtsam.noiseModel.Isotropic.Sigma(1, RANGE_STD)
    k = KERNELS[kernel]
    if kernel == "cauchy":
        return gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Cauchy.Create(k), base)
    if kernel == "huber":
        return gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Huber.Create(k), base)
    return base


def preintegration_params(config: dict[str, Any]) -> Any:
    ins = uwbimu_rs.FilterConfig(**{k: v for k, v in config.items() if not k.startswith("mounting")}).to_dict()["ins"]
    params = gtsam.PreintegrationCombinedParams(np.asarray(ins["gravity"], dtype=float))
    params.setAccelerometerCovariance(ins["accel_noise_density"] ** 2 * np.eye(3))
    params.setGyroscopeCovariance(ins["gyro_noise_density"] ** 2 * np.eye(3))
    params.setIntegrationCovariance(1e-8 * np.eye(3))
    params.setBiasAccCovariance(ins["accel_bias_walk"] ** 2 * np.eye(3))
    params.setBiasOmegaCovariance(ins["gyro_bias_walk"] ** 2 * np.eye(3))
    return params


def keyframe_times(log: Log) -> tuple[np.ndarray, np.ndarray]:
    """Keyframe times (the first IMU time, then each UWB epoch within the IMU span) and the
    keyframe of each range (-1: outside the IMU span, dropped as the filters drop it)."""
    t_imu = log.imu[:, 0]
    r_t = log.ranges[:, 0]
    inside = (r_t >= t_imu[0]) & (r_t <= t_imu[-1])
    epochs = np.unique(r_t[inside])
    times = np.concatenate([[t_imu[0]], epochs[epochs > t_imu[0]]])
    which = np.full(len(r_t), -1)
    which[inside] = np.searchsorted(times, r_t[inside])
    return times, which


def build_graph(log: Log, kernel: str, times: np.ndarray, which: np.ndarray, warm: dict[str, np.ndarray]) -> tuple[Any, Any]:
    """The factor graph and its initial values (the warm start)."""
    X, V, B, L = gtsam.symbol_shorthand.X, gtsam.symbol_shorthand.V, gtsam.symbol_shorthand.B, gtsam.symbol_shorthand.L
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    n = len(times)
    ba, bg = warm["ba"], warm["bg"]
    for k in range(n):
        values.insert(X(k), gtsam.Pose3(gtsam.Rot3.Quaternion(*warm["q"][k]), warm["p"][k]))
        values.insert(V(k), warm["v"][k])
        values.insert(B(k), gtsam.imuBias.ConstantBias(ba[k], bg[k]))

    # Prior: the EKF's initial state and σ, at the first IMU sample (keyframe 0).
    init = log.initial
    cfg = uwbimu_rs.FilterConfig(**{k: v for k, v in log.config.items() if not k.startswith("mounting")}).to_dict()
    r0 = quat_to_rot(unit(init["orientation"]))
    att_nav = np.diag(np.broadcast_to(np.asarray(init.get("orientation_std", [0.05, 0.05, 0.2]), dtype=float), 3) ** 2)
    pos_std = np.broadcast_to(np.asarray(init.get("position_std", 0.3), dtype=float), 3)
    cov = np.zeros((6, 6))
    cov[:3, :3] = r0.T @ att_nav @ r0  # GTSAM's Pose3 tangent: body-frame rotation, then translation
    cov[3:, 3:] = r0.T @ np.diag(pos_std**2) @ r0
    pose0 = gtsam.Pose3(gtsam.Rot3(r0), np.asarray(init["position"], dtype=float))
    graph.add(gtsam.PriorFactorPose3(X(0), pose0, gtsam.noiseModel.Gaussian.Covariance(cov)))
    vel_std = np.broadcast_to(np.asarray(init.get("velocity_std", 0.1), dtype=float), 3)
    graph.add(gtsam.PriorFactorVector(V(0), np.asarray(init["velocity"], dtype=float), gtsam.noiseModel.Diagonal.Sigmas(vel_std)))
    ba_std = float(init.get("accel_bias_std", cfg["init"]["accel_bias_std"]))
    bg_std = float(init.get("gyro_bias_std", cfg["init"]["gyro_bias_std"]))
    bias0 = gtsam.imuBias.ConstantBias(np.asarray(init.get("accel_bias", np.zeros(3)), dtype=float),
                                       np.asarray(init.get("gyro_bias", np.zeros(3)), dtype=float))
    graph.add(gtsam.PriorFactorConstantBias(B(0), bias0, gtsam.noiseModel.Diagonal.Sigmas(np.array([ba_std] * 3 + [bg_std] * 3))))

    # IMU: each sample held until the next, the intervals cut at the keyframes.
    params = preintegration_params(log.config)
    t_imu = log.imu[:, 0]
    cuts = np.union1d(t_imu, times)
    cuts = cuts[cuts <= t_imu[-1]]
    seg_start, seg_dt = cuts[:-1], np.diff(cuts)
    seg_sample = np.searchsorted(t_imu, seg_start, side="right") - 1
    seg_kf = np.searchsorted(times, seg_start, side="right") - 1  # keyframe interval of each piece
    acc, gyr = log.imu[seg_sample, 1:4], log.imu[seg_sample, 4:7]
    bounds = np.searchsorted(seg_kf, np.arange(n + 1))
    for k in range(n - 1):
        pim = gtsam.PreintegratedCombinedMeasurements(params, gtsam.imuBias.ConstantBias(ba[k], bg[k]))
        for s in range(bounds[k], bounds[k + 1]):
            pim.integrateMeasurement(acc[s], gyr[s], seg_dt[s])
        graph.add(gtsam.CombinedImuFactor(X(k), V(k), X(k + 1), V(k + 1), B(k), B(k + 1), pim))

    # Ranges: pose ∘ body→tag to the pinned anchor.
    lever = np.asarray(log.config.get("mounting.lever_arm", np.zeros(3)), dtype=float)
    body_t_tag = gtsam.Pose3(gtsam.Rot3(), lever)
    pin = gtsam.noiseModel.Isotropic.Sigma(3, ANCHOR_PIN_STD)
    for j, a in enumerate(log.anchors):
        values.insert(L(j), np.asarray(a, dtype=float))
        graph.add(gtsam.PriorFactorPoint3(L(j), np.asarray(a, dtype=float), pin))
    noise = range_noise(kernel)
    for (_, anchor, rng), k in zip(log.ranges, which):
        if k >= 0:
            graph.add(gtsam.RangeFactorWithTransform3D(X(int(k)), L(int(anchor)), float(rng), noise, body_t_tag))
    return graph, values


def score(df: pl.DataFrame, truth: pl.DataFrame) -> tuple[float, float]:
    df = df.filter(pl.col("t") >= df["t"][0] + SKIP_S)
    return metrics.evaluate(df, truth).horizontal.rmse, metrics.evaluate(df, truth, align=True).horizontal.rmse


def run_log(log: Log, kernels: list[str], linear_solver: str = "cholesky") -> list[dict[str, Any]]:
    t0 = time.perf_counter()
    df = uwbimu_rs.run_filter("ekf", log.imu, log.ranges, log.anchors, initial=log.initial, config=log.config, smooth=False)
    ekf_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    pos, ba, bg = ekf_biases(log)
    stream_s = time.perf_counter() - t0
    same = float(np.max(np.abs(pos - df.select("x", "y", "z").to_numpy())))
    if same > 1e-9:
        print(f"{log.name}: the streaming Ekf differs from run_filter by {same:.3g} m", file=sys.stderr)
    ekf_raw, ekf_aligned = score(df.select("t", "x", "y", "z"), log.truth)

    times, which = keyframe_times(log)
    s = interpolate_states(df, times)
    t_imu = log.imu[:, 0]
    after = np.clip(np.searchsorted(t_imu, times), 0, len(t_imu) - 1)  # first IMU sample at/after
    warm = {
        "p": np.column_stack([s["x"], s["y"], s["z"]]),
        "v": np.column_stack([s["vx"], s["vy"], s["vz"]]),
        "q": s["q"],
        "ba": ba[after],
        "bg": bg[after],
    }
    rows = []
    for kernel in kernels:
        t0 = time.perf_counter()
        graph, values = build_graph(log, kernel, times, which, warm)
        t1 = time.perf_counter()
        params = gtsam.LevenbergMarquardtParams()
        params.setMaxIterations(MAX_ITERATIONS)
        params.setLinearSolverType(LINEAR_SOLVERS[linear_solver])
        optimizer = gtsam.LevenbergMarquardtOptimizer(graph, values, params)
        result = optimizer.optimize()
        t2 = time.perf_counter()
        X = gtsam.symbol_shorthand.X
        xyz = np.array([result.atPose3(X(k)).translation() for k in range(len(times))])
        smoothed = pl.DataFrame({"t": times, "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2]})
        raw, aligned = score(smoothed, log.truth)
        rows.append({
            "log": log.name,
            "kernel": kernel,
            "linear_solver": linear_solver,
            "raw": raw,
            "aligned": aligned,
            "iterations": int(optimizer.iterations()),
            "build_s": t1 - t0,
            "optimise_s": t2 - t1,
            "time_s": t2 - t0,
            "error_initial": float(graph.error(values)),
            "error_final": float(graph.error(result)),
            "keyframes": len(times),
            "range_factors": int(np.sum(which >= 0)),
            "ekf_raw": ekf_raw,
            "ekf_aligned": ekf_aligned,
            "ekf_s": ekf_s,
            "ekf_stream_s": stream_s,
            "note": log.note,
        })
    return rows


def markdown(rows: list[dict[str, Any]]) -> str:
    lines = [
        "| log | kernel | GTSAM raw / aligned (m) | LM iters | build + LM (s) | build (s) | keyframes | EKF warm start raw / aligned (m) | EKF (s) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['log']} | {r['kernel']} | {r['raw']:.3f} / {r['aligned']:.3f} | {r['iterations']} | {r['time_s']:.2f} "
            f"| {r['build_s']:.2f} | {r['keyframes']} | {r['ekf_raw']:.3f} / {r['ekf_aligned']:.3f} | {r['ekf_s']:.3f} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "isas-walk1")
    parser.add_argument("--scenarios", nargs="*", default=["handheld_walk", "drone_flight", "agv_loop"], choices=sim.ZOO_NAMES)
    parser.add_argument("--seeds", nargs="*", type=int, default=[25, 26])
    parser.add_argument("--kernels", nargs="*", default=list(KERNELS), choices=list(KERNELS))
    parser.add_argument("--linear-solver", choices=list(LINEAR_SOLVERS), default="cholesky",
                        help="LM's linear solver (cholesky: GTSAM's default)")
    parser.add_argument("--json", type=Path, default=None, help="write the rows as JSON here")
    args = parser.parse_args(argv)
    if gtsam is None:
        print("gtsam is not installed: pip install gtsam (4.3)", file=sys.stderr)
        return 1
    logs: list[Log] = []
    real = isas_walk1(args.data)
    if real is not None:
        logs.append(real)
    logs += [zoo_log(name, seed) for name in args.scenarios for seed in args.seeds]
    rows: list[dict[str, Any]] = []
    for log in logs:
        if log.note:
            print(f"{log.name}: {log.note}", file=sys.stderr)
        rows += run_log(log, args.kernels, args.linear_solver)
        for r in rows[-len(args.kernels):]:
            print(f"{r['log']} {r['kernel']}: {r['raw']:.3f} / {r['aligned']:.3f} m, {r['iterations']} iterations, {r['time_s']:.2f} s", file=sys.stderr)
    print(
        f"Horizontal RMSE after the first {SKIP_S:.0f} s; range σ {RANGE_STD} m; Cauchy k = 1, Huber k = 1.345 (units of σ); "
        f"LM at most {MAX_ITERATIONS} iterations, {args.linear_solver}\n"
    )
    print(markdown(rows))
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
