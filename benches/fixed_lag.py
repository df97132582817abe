"""Fixed-lag smoothing in streaming (docs/streaming.md, "Fixed-lag smoothing"): accuracy against
lag and cost per IMU sample, measured in one run.

For isas-walk1 (skipped with a message when ../shared/data/isas-walk1 is absent) and two zoo
scenarios, the streaming ``Best`` (self-initialised) is fed the log in time order, once causal
(``lag_s=None``), once per lag (0.5, 1, 2, 5 s) and once recording for the full RTS pass
(``record=True``, ``smooth()``). Each estimate is scored at the IMU times of the causal steps,
the first 10 s left out: horizontal RMSE raw and after rigid alignment (``metrics.evaluate``),
m. The cost is the wall time of the feeding loop (``add_imu``/``add_range`` calls, Python
included, plus the ``lagged_steps()`` calls and the final ``flush()``; for the full RTS pass the
recording and ``smooth()``) per IMU sample, µs, the best of ``--repeat`` runs.

    python benches/fixed_lag.py [--repeat 3] [--data ../shared/data/isas-walk1]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from datetime import date
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

import uwbimu_rs
import uwbimu_rs.metrics as metrics
from uwbimu_rs import sim
from uwbimu_rs.sim import ZooName

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "examples"))
from model_selection_table import isas_walk1  # noqa: E402  (the one loader of the walk)

LAGS = (0.5, 1.0, 2.0, 5.0)
ZOO: tuple[tuple[ZooName, int], ...] = (("handheld_walk", 101), ("walk_nlos", 101))
SKIP_S = 10.0


def isas(data: Path) -> dict[str, Any] | None:
    """isas-walk1 as the examples load it (None when absent)."""
    walk = isas_walk1(data)
    if walk is None:
        return None
    imu, ranges, anchors, truth = walk
    return {"name": "isas-walk1", "imu": imu, "ranges": ranges, "anchors": anchors, "truth": truth, "config": None}


def zoo(name: ZooName, seed: int) -> dict[str, Any]:
    run = sim.zoo(name, seed=seed)
    return {
        "name": f"{name} (sim, seed {seed})",
        "imu": run.imu,
        "ranges": run.ranges[:, :3],
        "anchors": run.anchors,
        "truth": run.truth,
        "config": run.config,
    }


def events(imu: np.ndarray, ranges: np.ndarray) -> list[tuple[float, int, np.ndarray]]:
    """The inputs in time order, IMU first at equal times."""
    out = [(float(r[0]), 0, r) for r in imu] + [(float(r[0]), 1, r) for r in ranges]
    out.sort(key=lambda e: (e[0], e[1]))
    return out


def feed(log: dict[str, Any], lag_s: float | None, record: bool) -> tuple[pl.DataFrame, pl.DataFrame | None, float]:
    """One streaming run: its causal steps, its lagged (or full smoothed) rows, and the loop's
    wall time, s."""
    f = uwbimu_rs.Best(log["anchors"], config=log["config"], reorder_window_s=0.0, lag_s=lag_s, record=record)
    evs = log["events"]
    steps, lagged = [], []
    t0 = time.perf_counter()
    for k, (_, kind, r) in enumerate(evs):
        if kind == 0:
            f.add_imu(r[0], r[1:4], r[4:7])
        else:
            f.add_range(r[0], int(r[1]), r[2])
        if k % 1000 == 999:
            steps.append(f.steps())
            if lag_s is not None:
                lagged.append(f.lagged_steps())
    f.flush()
    if lag_s is not None:
        lagged.append(f.lagged_steps())
    smoothed = pl.concat(lagged) if lag_s is not None else (f.smooth() if record else None)
    wall = time.perf_counter() - t0
    steps.append(f.steps())
    return pl.concat(steps), smoothed, wall


def score(df: pl.DataFrame, at: pl.DataFrame, truth: Any) -> str:
    """Horizontal RMSE raw / aligned of ``df`` at the times of ``at``, after the first 10 s."""
    df = df.join(at.select("t"), on="t", how="semi")
    df = df.filter(pl.col("t") >= at["t"][0] + SKIP_S)
    raw = metrics.evaluate(df, truth).horizontal.rmse
    aligned = metrics.evaluate(df, truth, align=True).horizontal.rmse
    return f"{raw:.3f} / {aligned:.3f}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "isas-walk1")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    logs = [log for log in [isas(args.data), *(zoo(n, s) for n, s in ZOO)] if log is not None]
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    runs = [("causal", None, False), *((f"lag {x:g} s", x, False) for x in LAGS), ("full RTS", None, True)]
    header = "| log | " + " | ".join(label for label, _, _ in runs) + " |"
    rule = "|---|" + "---|" * len(runs)
    accuracy, cost = [header, rule], [header, rule]
    for log in logs:
        log["events"] = events(log["imu"], log["ranges"])
        n = log["imu"].shape[0]
        cells, costs = [], []
        for label, lag, record in runs:
            best, out = float("inf"), None
            for _ in range(args.repeat):
                steps, smoothed, wall = feed(log, lag, record)
                best, out = min(best, wall), (steps, smoothed)
            assert out is not None
            steps, smoothed = out
            if lag is None and not record:
                causal = steps
                cells.append(score(steps, causal, log["truth"]))
            else:
                assert smoothed is not None
                cells.append(score(smoothed, causal, log["truth"]))
            costs.append(f"{1e6 * best / n:.1f}")
        accuracy.append(f"| {log['name']} | " + " | ".join(cells) + " |")
        cost.append(f"| {log['name']} | " + " | ".join(costs) + " |")
    print(f"Measured on {commit} ({date.today().isoformat()}), best of {args.repeat}.\n")
    print("Horizontal RMSE after the first 10 s, raw / aligned, m:\n")
    print("\n".join(accuracy))
    print("\nCost per IMU sample (the Python loop included), µs:\n")
    print("\n".join(cost))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
