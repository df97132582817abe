"""Speed of a whole run, per IMU sample, as a user waits for it (docs/performance.md, "Whole run").

Two runs: a still drone with an IMU at 1 kHz and TDoA from 8 anchors (22.5 rounds/s, 11.4 s,
like a recorded quadrotor flight) and a moving walk with an IMU at 100 Hz and ranges (the zoo's
``handheld_walk``). Each goes through ``run_filter("ekf", ...)`` self-initialised, with the
initial state given, and given with the covariance propagated at 100 Hz
(``ins.covariance_interval_s = 0.01``), in rounds that alternate the variants so that the ratios
come from one run; the best of the rounds is reported. Then the streaming ``Ekf`` fed sample by
sample while it initialises itself: the latency of each call until it has started (p50, p99,
max) and of the call that starts it (it replays what it kept).

    python benches/whole_run.py [--repeat N]
    python benches/whole_run.py --profile still_flight self --repeat 300   # a loop to profile
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

import uwbimu_rs
from uwbimu_rs import sim

COVARIANCE_AT_100_HZ = {"ins": {"covariance_interval_s": 0.01}}


@dataclass
class Run:
    """One log: the arrays `run_filter` takes and the true initial state."""

    imu: np.ndarray
    ranges: np.ndarray
    tdoa: np.ndarray | None
    anchors: np.ndarray
    initial: dict[str, Any]


def still_flight(seconds: float = 11.4, seed: int = 0) -> Run:
    """A still drone 1.5 m up: IMU at 1 kHz, TDoA only (8 anchors of the zoo's `tdoa_drone`)."""
    anchors = sim.zoo("tdoa_drone", seed=seed).anchors
    # The figure-8 starts after its still period: cropped before it, the drone never moves.
    trajectory = sim.Trajectory.figure_eight([4.5, 3.0, 1.5], 2.0, 1.5, 16.0, 1, still_s=seconds + 1.0)
    s = sim.simulate(trajectory, anchors, seed=seed, imu_rate_hz=1000.0, tdoa=True, tdoa_rate_hz=22.5, tdoa_std_m=0.1)
    assert s.tdoa is not None
    return Run(s.imu[s.imu[:, 0] <= seconds], np.zeros((0, 3)), s.tdoa[s.tdoa[:, 0] <= seconds], anchors, s.initial)


def moving_walk(seed: int = 0) -> Run:
    """The zoo's `handheld_walk`: IMU at 100 Hz, ranges at 20 Hz from 5 anchors."""
    s = sim.zoo("handheld_walk", seed=seed)
    return Run(s.imu, s.ranges, None, s.anchors, s.initial)


def decimated(run: Run, every: int) -> Run:
    """`run` with every `every`-th IMU sample (the same UWB)."""
    return Run(run.imu[::every], run.ranges, run.tdoa, run.anchors, run.initial)


RUNS: dict[str, Callable[[], Run]] = {
    "still_flight": still_flight,
    "still_flight, IMU at 100 Hz": lambda: decimated(still_flight(), 10),
    "still_flight × 4 (45.6 s)": lambda: still_flight(seconds=45.6),
    "moving_walk": moving_walk,
}
VARIANTS: dict[str, dict[str, Any]] = {
    "self": {},
    "given": {"given": True},
    "given, covariance at 100 Hz": {"given": True, "config": COVARIANCE_AT_100_HZ},
}


def batch(run: Run, variant: dict[str, Any]) -> Callable[[], Any]:
    """The `run_filter` call of `variant` on `run`."""
    initial = run.initial if variant.get("given") else None
    config = variant.get("config")
    return lambda: uwbimu_rs.run_filter("ekf", run.imu, run.ranges, run.anchors, tdoa=run.tdoa, initial=initial, config=config)


def best_times(calls: dict[str, Callable[[], Any]], repeat: int) -> dict[str, float]:
    """The best time of each call over `repeat` rounds that call each in turn, s."""
    best = dict.fromkeys(calls, float("inf"))
    for _ in range(repeat):
        for label, call in calls.items():
            t0 = time.perf_counter()
            call()
            best[label] = min(best[label], time.perf_counter() - t0)
    return best


def batch_table(runs: dict[str, Run], repeat: int) -> None:
    print("| run | IMU samples | variant | time | per IMU sample | ÷ given |")
    print("|---|---|---|---|---|---|")
    for name, run in runs.items():
        best = best_times({label: batch(run, v) for label, v in VARIANTS.items()}, repeat)
        n = len(run.imu)
        for label, t in best.items():
            print(f"| {name} | {n} | {label} | {t * 1e3:.2f} ms | {t / n * 1e6:.3f} µs | {t / best['given']:.2f} |")


def split_table(run: Run, repeat: int) -> None:
    """The given run with the covariance at 100 Hz, with and without its TDoA: the cost of an
    IMU sample alone and of a TDoA update."""
    without = Run(run.imu, run.ranges, None, run.anchors, run.initial)
    variant = VARIANTS["given, covariance at 100 Hz"]
    best = best_times({"all": batch(run, variant), "imu": batch(without, variant)}, repeat)
    assert run.tdoa is not None
    per_tdoa = (best["all"] - best["imu"]) / len(run.tdoa)
    print("| still_flight, given, covariance at 100 Hz | per IMU sample without TDoA | per TDoA update |")
    print("|---|---|---|")
    print(f"| {best['all'] * 1e3:.2f} ms | {best['imu'] / len(run.imu) * 1e6:.3f} µs | {per_tdoa * 1e6:.2f} µs |")


def stream_start(run: Run) -> tuple[np.ndarray, float, float]:
    """Feeds `run` to a self-initialising streaming `Ekf` event by event; returns the latency of
    each IMU call before it started (s), the latency of the call that started it and its time."""
    f = uwbimu_rs.Ekf(run.anchors)
    events: list[tuple[float, int, Any]] = [(row[0], 1, row) for row in run.imu]
    events += [(row[0], 0, row) for row in run.ranges]
    if run.tdoa is not None:
        events += [(row[0], 0, row) for row in run.tdoa]
    events.sort(key=lambda e: (e[0], e[1]))
    waiting: list[float] = []
    for t, is_imu, row in events:
        if not is_imu:
            if run.tdoa is not None and len(row) == 4:
                f.add_tdoa(t, int(row[1]), int(row[2]), float(row[3]))
            else:
                f.add_range(t, int(row[1]), float(row[2]))
            continue
        t0 = time.perf_counter()
        f.add_imu(t, row[1:4], row[4:7])
        dt = time.perf_counter() - t0
        if f.initialized:
            return np.array(waiting), dt, t
        waiting.append(dt)
    return np.array(waiting), float("nan"), float("nan")


def stream_table(runs: dict[str, Run]) -> None:
    print("| run | samples before the start | p50 | p99 | max | the starting call | started at |")
    print("|---|---|---|---|---|---|---|")
    for name, run in runs.items():
        waiting, start, at = stream_start(run)
        p50, p99 = np.percentile(waiting, [50, 99]) * 1e6
        print(
            f"| {name} | {len(waiting)} | {p50:.1f} µs | {p99:.1f} µs | {waiting.max() * 1e6:.0f} µs "
            f"| {start * 1e3:.1f} ms | {at:.2f} s |"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=7, help="rounds (default 7); with --profile, calls")
    parser.add_argument("--profile", nargs=2, metavar=("RUN", "VARIANT"), help="only call one variant in a loop")
    args = parser.parse_args()
    if args.profile:
        name, variant = args.profile
        call = batch(RUNS[name](), VARIANTS[variant])
        for _ in range(args.repeat):
            call()
        return
    runs = {name: make() for name, make in RUNS.items()}
    print(f"uwbimu_rs {uwbimu_rs.__version__}; best of {args.repeat} rounds\n")
    batch_table(runs, args.repeat)
    print()
    split_table(runs["still_flight"], args.repeat)
    print()
    # A still start decides at the heading timeout (30 s): the stream waits that long.
    stream_table({"still_flight (40 s)": still_flight(seconds=40.0), "moving_walk": runs["moving_walk"]})


if __name__ == "__main__":
    main()
