"""The isas-walk1 accuracy table of docs/accuracy.md: every method, self-initialised, first 10 s left out,
horizontal RMSE raw and after rigid alignment, forward and smoothed, with the defaults
(`config=None`) and with the noise `uwbimu_rs.tune` picks from the log alone (no ground truth).

    python examples/isas_walk1_table.py [--data ../shared/data/isas-walk1] [--methods riekf best]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import polars as pl

import uwbimu_rs
import uwbimu_rs.metrics as metrics

sys.path.insert(0, str(Path(__file__).resolve().parent))
from model_selection_table import isas_walk1  # noqa: E402  (the one loader of the walk)

ROOT = Path(__file__).resolve().parent.parent
SMOOTHABLE = {name for name, row in uwbimu_rs.METHODS.items() if row["smoothing"] != "never"}


def score(df: pl.DataFrame, truth: pl.DataFrame) -> str:
    df = df.filter(pl.col("t") >= df["t"][0] + 10.0)
    raw = metrics.evaluate(df, truth).horizontal.rmse
    aligned = metrics.evaluate(df, truth, align=True).horizontal.rmse
    return f"{raw:.3f} / {aligned:.3f}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "isas-walk1")
    parser.add_argument("--methods", nargs="*", choices=uwbimu_rs.FILTERS, default=uwbimu_rs.FILTERS)
    args = parser.parse_args(argv)
    walk = isas_walk1(args.data)
    if walk is None:
        return 0
    imu, ranges, anchors, truth = walk
    print("| method | defaults forward | defaults smoothed | tuned forward | tuned smoothed |")
    print("|---|---|---|---|---|")
    for method in args.methods:
        try:
            tuned = uwbimu_rs.tune(method, imu, ranges, anchors, smooth=False)["config"]
        except ValueError:  # uwb_ls: no noise settings to tune
            tuned = None
        cells = []
        for label, config in (("defaults", None), ("tuned", tuned)):
            for smooth in (False, True):
                if (label == "tuned" and tuned is None) or (smooth and method not in SMOOTHABLE):
                    cells.append("–")
                    continue
                df = uwbimu_rs.run_filter(method, imu, ranges, anchors, config=config, smooth=smooth)
                cells.append(score(df, truth))
        print(f"| `{method}` | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
