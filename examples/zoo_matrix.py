"""The generality matrix: every filter on every scenario of the zoo against UWB-only least squares.

The first table's cells are the horizontal RMSE of the method divided by that of ``uwb_ls`` on the
same run (worst over the seeds), with the first column the mean ``uwb_ls`` RMSE in metres; the
second gives each method's mean RMSE in metres. The bound the tests hold is 1.2 with the initial
state given and 1.5 self-initialised (after the first 10 s); time inside a range outage is left
out (``uwb_ls`` has no output there). Prints markdown tables.

    python examples/zoo_matrix.py [--seeds 3] [--start given|self] [--settings matched|defaults]
                                  [--scenarios agv_loop ...] [--methods ekf riekf ...]
"""

from __future__ import annotations

import argparse
from typing import Literal

import polars as pl

import uwbimu_rs
from uwbimu_rs import sim


def matrix(
    seeds: int,
    start: Literal["given", "self"],
    settings: Literal["matched", "defaults"],
    scenarios: list[str] | None,
    methods: list[str] | None,
) -> tuple[pl.DataFrame, pl.DataFrame]:
    """Two tables with one row per scenario and ``uwb_ls`` (mean RMSE, m) first: per method, the
    worst ratio to ``uwb_ls`` over the seeds, and the mean horizontal RMSE (m)."""
    cells = sim.zoo_matrix(methods, scenarios, seeds=list(range(seeds)), start=start, settings=settings)
    per_method = cells.group_by("scenario", "method").agg(
        pl.col("ratio").max(), pl.col("rmse").mean(), pl.col("uwb_ls_rmse").mean()
    )
    base = per_method.group_by("scenario").agg(pl.col("uwb_ls_rmse").first().alias("uwb_ls"))
    order = pl.DataFrame({"scenario": scenarios or list(sim.ZOO_NAMES)}).with_row_index("k")

    def wide(values: str) -> pl.DataFrame:
        table = per_method.pivot(on="method", index="scenario", values=values)
        columns = [m for m in uwbimu_rs.FILTERS if m in table.columns]  # the order of FILTERS
        return order.join(base, on="scenario").join(table.select("scenario", *columns), on="scenario").sort("k").drop("k")

    return wide("ratio"), wide("rmse")


def markdown(table: pl.DataFrame, decimals: int) -> str:
    """``table`` as a markdown table, the method columns to ``decimals`` decimals, ``uwb_ls`` to 3."""
    methods = [c for c in table.columns if c not in ("scenario", "uwb_ls")]
    lines = ["| scenario | uwb_ls | " + " | ".join(methods) + " |", "|---|---|" + "---|" * len(methods)]
    for row in table.iter_rows(named=True):
        cells = [f"{row[m]:.{decimals}f}" for m in methods]
        lines.append(f"| {row['scenario']} | {row['uwb_ls']:.3f} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--start", choices=["given", "self"], default="given")
    parser.add_argument("--settings", choices=["matched", "defaults"], default="matched")
    parser.add_argument("--scenarios", nargs="*", default=None)
    parser.add_argument("--methods", nargs="*", default=None)
    args = parser.parse_args()
    ratios, rmse = matrix(args.seeds, args.start, args.settings, args.scenarios, args.methods)
    print(f"Worst ratio to uwb_ls over {args.seeds} seeds ({args.start}, {args.settings}); uwb_ls = its mean RMSE, m\n")
    print(markdown(ratios, 2))
    print(f"\nMean horizontal RMSE over {args.seeds} seeds, m ({args.start}, {args.settings})\n")
    print(markdown(rmse, 3))
    bound = 1.2 if args.start == "given" else 1.5
    methods = [c for c in ratios.columns if c not in ("scenario", "uwb_ls")]
    over = [(row["scenario"], m, row[m]) for row in ratios.iter_rows(named=True) for m in methods if row[m] > bound]
    print(f"\nabove {bound}: " + (", ".join(f"{m} on {s} ({r:.2f})" for s, m, r in over) if over else "none"))

if __name__ == "__main__":
    main()
