"""The generality matrix: every filter on every scenario of the zoo against UWB-only least squares.

Each cell is the horizontal RMSE of the method divided by that of ``uwb_ls`` on the same run
(worst over the seeds), with the first column the mean ``uwb_ls`` RMSE in metres. The bound the
tests hold is 1.2 with the initial state given and 1.5 self-initialised (after the first 10 s);
time inside a range outage is left out (``uwb_ls`` has no output there). Prints a markdown table.

    python examples/zoo_matrix.py [--seeds 3] [--start given|self] [--settings matched|defaults]
                                  [--scenarios agv_loop ...] [--methods ekf riekf ...]
"""

from __future__ import annotations

import argparse

import polars as pl

import uwbimu_rs
from uwbimu_rs import sim


def matrix(seeds: int, start: str, settings: str, scenarios: list[str] | None, methods: list[str] | None) -> pl.DataFrame:
    """One row per scenario: ``uwb_ls`` (mean RMSE, m) and, per method, the worst ratio to it."""
    cells = sim.zoo_matrix(methods, scenarios, seeds=list(range(seeds)), start=start, settings=settings)
    worst = cells.group_by("scenario", "method").agg(pl.col("ratio").max(), pl.col("uwb_ls_rmse").mean())
    wide = worst.pivot(on="method", index="scenario", values="ratio")
    base = worst.group_by("scenario").agg(pl.col("uwb_ls_rmse").first().alias("uwb_ls"))
    order = pl.DataFrame({"scenario": scenarios or list(sim.ZOO_NAMES)}).with_row_index("k")
    return order.join(base, on="scenario").join(wide, on="scenario").sort("k").drop("k")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--start", choices=["given", "self"], default="given")
    parser.add_argument("--settings", choices=["matched", "defaults"], default="matched")
    parser.add_argument("--scenarios", nargs="*", default=None)
    parser.add_argument("--methods", nargs="*", default=None)
    args = parser.parse_args()
    table = matrix(args.seeds, args.start, args.settings, args.scenarios, args.methods)
    methods = [c for c in table.columns if c not in ("scenario", "uwb_ls")]
    print(f"Worst ratio to uwb_ls over {args.seeds} seeds ({args.start}, {args.settings}); uwb_ls = its mean RMSE, m\n")
    print("| scenario | uwb_ls | " + " | ".join(methods) + " |")
    print("|---|---|" + "---|" * len(methods))
    for row in table.iter_rows(named=True):
        cells = [f"{row[m]:.2f}" for m in methods]
        print(f"| {row['scenario']} | {row['uwb_ls']:.3f} | " + " | ".join(cells) + " |")
    bound = 1.2 if args.start == "given" else 1.5
    over = [(row["scenario"], m, row[m]) for row in table.iter_rows(named=True) for m in methods if row[m] > bound]
    print(f"\nabove {bound}: " + (", ".join(f"{m} on {s} ({r:.2f})" for s, m, r in over) if over else "none"))


if __name__ == "__main__":
    main()
