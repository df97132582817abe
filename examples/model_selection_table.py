"""The rig table of docs/model-selection.md: what `best` chooses on each rig without ground truth,
and the horizontal RMSE (m, after 10 s, self-initialised, defaults with the rig's mounting) with
the choice off → on, forward and smoothed.

Rigs of three kinds: steady range errors (per-anchor biases like the drone rig's, −0.13 m +
U(−0.18, 0.16) m, added to the zoo's ranges; anchors surveyed off), range errors that wander
(Gauss–Markov per anchor, τ 1 s, σ 0.1 m, added to the ranges; sustained NLOS; one NLOS anchor),
and clean zoo runs; then isas-walk1 when ../shared/data is present.

    python examples/model_selection_table.py [--seeds 25 26] [--rigs drone_flight+steady ...]
"""

from __future__ import annotations

import argparse
import sys
import tomllib
from pathlib import Path
from typing import cast

import numpy as np
import polars as pl

import uwbimu_rs
import uwbimu_rs.metrics as metrics
from uwbimu_rs import sim

ROOT = Path(__file__).resolve().parent.parent
ISAS = ROOT.parent / "shared" / "data" / "isas-walk1"

#: Zoo scenarios run at other rates: the drone rig's (IMU 19 Hz, UWB 50 Hz jittered 5 ms).
RATES = {"drone_rates": ("drone_flight", {"imu_rate_hz": 19.0, "uwb_rate_hz": 50.0, "jitter_s": 0.005})}

#: `scenario+errors`: the zoo scenario (or preset, or one of RATES) and the range errors added to
#: its ranges.
RIGS = (
    "drone_flight+steady",
    "drone_rates+steady",
    "handheld_walk+steady",
    "corridor+steady",
    "agv_loop+long",
    "drone_flight+long",
    "handheld_walk+long",
    "mixed_rates+long",
    "outliers+long",
    "survey_error",
    "handheld_walk+wandering",
    "agv_loop+wandering",
    "walk_nlos",
    "nlos_one",
    "drone_flight",
    "drone_rates",
    "agv_loop",
    "handheld_walk",
    "mixed_rates",
    "outliers",
    "corridor",
    "tilted_walk",
    "lab_robot",
    "lab_robot_nlos",
)


def added_errors(ranges: np.ndarray, n_anchors: int, kind: str, seed: int) -> np.ndarray:
    """The ranges with `kind` errors added: `steady` per-anchor biases, `wandering` Gauss–Markov."""
    out = ranges.copy()
    rng = np.random.default_rng(100 + seed)
    if kind == "steady":
        bias = -0.13 + rng.uniform(-0.18, 0.16, n_anchors)
        out[:, 2] += bias[out[:, 1].astype(int)]
    elif kind == "long":
        bias = rng.uniform(0.10, 0.36, n_anchors)
        out[:, 2] += bias[out[:, 1].astype(int)]
    elif kind == "wandering":
        tau, sigma = 1.0, 0.1
        for k in range(n_anchors):
            rows = np.flatnonzero(out[:, 1] == k)
            x, t_prev = rng.normal() * sigma, out[rows[0], 0]
            for i in rows:
                phi = np.exp(-(out[i, 0] - t_prev) / tau)
                x = phi * x + sigma * np.sqrt(1.0 - phi * phi) * rng.normal()
                t_prev = out[i, 0]
                out[i, 2] += x
    return out


def rmse(df: pl.DataFrame, truth: pl.DataFrame) -> tuple[float, float]:
    """Horizontal RMSE after 10 s, raw and after rigid alignment."""
    df = df.filter(pl.col("t") >= df["t"][0] + 10.0)
    return metrics.evaluate(df, truth).horizontal.rmse, metrics.evaluate(df, truth, align=True).horizontal.rmse


def row(name: str, imu, ranges, anchors, truth, config: dict, aligned: bool) -> str:
    """One table row: the choice, its score against the plain filter's, RMSE off → on."""
    choice = uwbimu_rs.choose_model("best", imu, ranges, anchors, config=config)
    candidates = choice["candidates"]
    plain = {**config, "model_selection": {"enabled": False}}
    cells = []
    for smooth in (False, True):
        before = rmse(uwbimu_rs.run_filter("best", imu, ranges, anchors, config=plain, smooth=smooth), truth)
        after = rmse(uwbimu_rs.run_filter("best", imu, ranges, anchors, config=choice["config"], smooth=smooth), truth)
        k = 1 if aligned else 0
        cells.append(f"{before[k]:.3f} → {after[k]:.3f}")
    chosen = choice["chosen"] or "(no selection)"
    if candidates.is_empty():
        score = "–"
    else:
        picked = candidates.filter(pl.col("label") == choice["chosen"])["score"][0]
        score = f"{candidates['score'][0]:.3f} → {picked:.3f}"
    return f"| {name} | {chosen} | {score} | " + " | ".join(cells) + " |"


def rig_runs(rigs: list[str], seeds: list[int]):
    """`(label, imu, ranges, anchors, truth, config)` of each rig and seed: the zoo scenario (or
    preset, or one of RATES) with the rig's errors added to its ranges, and the rig's mounting (a
    preset's whole configuration)."""
    for rig in rigs:
        scenario, _, kind = rig.partition("+")
        scenario, overrides = RATES.get(scenario, (scenario, {}))
        for seed in seeds:
            zoo = scenario in sim.ZOO_NAMES
            run = (
                sim.zoo(cast(sim.ZooName, scenario), seed=seed, **overrides)
                if zoo
                else sim.preset(cast(sim.PresetName, scenario), seed=seed)
            )
            config = {"mounting": run.config["mounting"]} if zoo else dict(run.config)
            ranges = added_errors(run.ranges, len(run.anchors), kind, seed)
            yield f"{rig} s{seed}", run.imu, ranges, run.anchors, run.truth, config


def isas_walk1(data: Path = ISAS):
    """`(imu, ranges, anchors, truth)` of isas-walk1 in the folder `data` with the checked-in
    mapping, or None (said on stderr) when it is absent (a clone without ../shared)."""
    if not (data / "isas-walk1.mcap").exists():
        print(f"skipped isas-walk1: {data} is not present", file=sys.stderr)
        return None
    mapping = tomllib.loads((ROOT / "examples" / "isas-walk1.toml").read_text())["mapping"]
    mapping["ground_truth"] = {"file": str(data / "gt_anchor_frame.csv")}
    d = uwbimu_rs.read_mcap(data / "isas-walk1.mcap", mapping=mapping)
    imu, anchors = d["imu"].to_numpy(), d["anchors"].select("x", "y", "z").to_numpy()
    return imu, d["ranges"].select("t", "anchor", "range").to_numpy(), anchors, d["ground_truth"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="*", default=[25, 26])
    parser.add_argument("--rigs", nargs="*", choices=RIGS, default=list(RIGS))
    args = parser.parse_args(argv)
    print("| rig | `best` chose | held-out score plain → chosen (m) | forward off → on | smoothed off → on |")
    print("|---|---|---|---|---|")
    for name, imu, ranges, anchors, truth, config in rig_runs(args.rigs, args.seeds):
        print(row(name, imu, ranges, anchors, truth, config, aligned=False), flush=True)
    walk = isas_walk1()
    if walk is not None:
        imu, ranges, anchors, truth = walk
        print(row("isas-walk1 (aligned)", imu, ranges, anchors, truth, {}, aligned=True))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
