"""The tables of docs/power-gap.md: does the gap between a UWB range's received power and its
first-path power (rxp − fpp, dB) mark non-line-of-sight / biased ranges on isas-walk1?

Every valid range (`ra == 1`) of `/rtls_flares` is compared with the distance from the ground-truth
tag position (`gt_anchor_frame.csv`, linearly interpolated at the message's header stamp; the file
is already on the UWB clock) to the anchor. The residual is measured − true range, raw and with the
README's per-anchor constant biases removed. "Bad" means |bias-removed residual| > 0.3 m (or
|raw residual| > 0.3 m for the raw tables). Three cues are checked the same way: the gap
rxp − fpp (large = suspicious), and fpp and rxp alone (low = suspicious). Nothing is fitted or
tuned here: bin edges and thresholds are fixed in the code.

    python examples/power_gap_nlos.py [--data ../shared/data/isas-walk1]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
BAD_M = 0.3
# Per-anchor constant range biases (m) from the data set's README (fitted with the ground truth).
README_BIAS = {7475: -0.01, 9524: -0.09, 10548: 0.12, 15155: -0.19, 20276: 0.01}
# Cue name -> (bin edges, detector thresholds, True if a large value is suspicious).
CUES = {
    "gap": ([3.0, 6.0, 10.0], [4.0, 6.0, 8.0, 10.0, 12.0], True),
    "fpp": ([-36.0, -34.0, -33.0], [-40.0, -38.0, -36.0, -35.0, -34.0], False),
    "rxp": ([-31.0, -30.0, -29.0], [-32.0, -31.0, -30.5, -30.0, -29.5], False),
}


def load(data: Path) -> dict[str, np.ndarray]:
    """Valid ranges with their powers, true distances and residuals."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    rows, n_all = [], 0
    with open(data / "isas-walk1.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _, _, _, msg in reader.iter_decoded_messages(topics=["/rtls_flares"]):
            t = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
            for r in msg.ranges:
                n_all += 1
                if r.ra == 1:
                    rows.append((t, r.id, r.range, r.fpp, r.rxp))
    a = np.array(rows, dtype=float)
    anchors = np.loadtxt(data / "anchors.csv", delimiter=",", skiprows=1)
    pos = {int(row[0]): row[1:4] for row in anchors}
    gt = np.loadtxt(data / "gt_anchor_frame.csv", delimiter=",", skiprows=1)
    t = a[:, 0]
    inside = (t >= gt[0, 0]) & (t <= gt[-1, 0])
    a, t = a[inside], t[inside]
    tag = np.column_stack([np.interp(t, gt[:, 0], gt[:, k]) for k in (1, 2, 3)])
    anchor = a[:, 1].astype(int)
    apos = np.array([pos[i] for i in anchor])
    true = np.linalg.norm(tag - apos, axis=1)
    raw = a[:, 2] - true
    bias = np.array([README_BIAS[i] for i in anchor])
    return {
        "n_all": np.array(n_all),
        "t": t,
        "anchor": anchor,
        "true": true,
        "raw": raw,
        "corr": raw - bias,
        "fpp": a[:, 3],
        "rxp": a[:, 4],
        "gap": a[:, 4] - a[:, 3],
    }


def ranks(x: np.ndarray) -> np.ndarray:
    """Ranks 1..n, ties given their average rank."""
    order = np.argsort(x, kind="stable")
    r = np.empty(len(x))
    r[order] = np.arange(1, len(x) + 1)
    _, inv, counts = np.unique(x, return_inverse=True, return_counts=True)
    sums = np.bincount(inv, weights=r)
    return sums[inv] / counts[inv]


def spearman(x: np.ndarray, y: np.ndarray) -> float:
    return float(np.corrcoef(ranks(x), ranks(y))[0, 1])


def auc(score: np.ndarray, bad: np.ndarray) -> float:
    """P(score of a bad range > score of a good one), ties counted half (Mann–Whitney)."""
    r = ranks(score)
    n1, n0 = bad.sum(), (~bad).sum()
    return float((r[bad].sum() - n1 * (n1 + 1) / 2) / (n1 * n0))


def bins_table(d: dict, cue: str) -> list[str]:
    edges, _, _ = CUES[cue]
    lo = [-np.inf, *edges]
    hi = [*edges, np.inf]
    out = [
        f"| {cue} bin (dB) | residual | n | median (m) | IQR (m) | p95 \\|res\\| (m) | share \\|res\\| > {BAD_M} m |",
        "|---|---|---|---|---|---|---|",
    ]
    for a, b in zip(lo, hi):
        sel = (d[cue] >= a) & (d[cue] < b)
        label = f"< {b:g}" if a == -np.inf else (f"≥ {a:g}" if b == np.inf else f"{a:g} – {b:g}")
        for kind, name in (("raw", "raw"), ("corr", "bias removed")):
            r = d[kind][sel]
            if len(r) == 0:
                out.append(f"| {label} | {name} | 0 | – | – | – | – |")
                continue
            q1, q3 = np.percentile(r, [25, 75])
            p95 = np.percentile(np.abs(r), 95)
            share = np.mean(np.abs(r) > BAD_M)
            out.append(
                f"| {label} | {name} | {len(r)} | {np.median(r):+.3f} | {q3 - q1:.3f} | {p95:.3f} | {100 * share:.1f} % |"
            )
    return out


def correlation_table(d: dict) -> list[str]:
    out = [
        "| anchor | n | median raw res. (m) | README bias (m) | ρ(gap, \\|raw\\|) | ρ(gap, \\|corr\\|) "
        "| ρ(fpp, \\|corr\\|) | ρ(rxp, \\|corr\\|) | ρ(gap, true dist.) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    groups = [(str(i), d["anchor"] == i) for i in sorted(README_BIAS)] + [("all", np.ones(len(d["raw"]), bool))]
    for name, sel in groups:
        bias = f"{README_BIAS[int(name)]:+.2f}" if name != "all" else "–"
        ac = np.abs(d["corr"][sel])
        out.append(
            f"| {name} | {sel.sum()} | {np.median(d['raw'][sel]):+.3f} | {bias} "
            f"| {spearman(d['gap'][sel], np.abs(d['raw'][sel])):+.2f} | {spearman(d['gap'][sel], ac):+.2f} "
            f"| {spearman(d['fpp'][sel], ac):+.2f} | {spearman(d['rxp'][sel], ac):+.2f} "
            f"| {spearman(d['gap'][sel], d['true'][sel]):+.2f} |"
        )
    return out


def detector_table(d: dict, kind: str) -> list[str]:
    bad = np.abs(d[kind]) > BAD_M
    out = [
        "| cue | flag if | AUC | flagged | detection rate | false alarm rate (good dropped) "
        "| share bad, kept | share bad, all |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for cue, (_, thresholds, high) in CUES.items():
        score = d[cue] if high else -d[cue]
        a = auc(score, bad)
        for thr in thresholds:
            flag = d[cue] > thr if high else d[cue] < thr
            det = np.mean(flag[bad])
            fa = np.mean(flag[~bad])
            kept_bad = np.mean(bad[~flag]) if (~flag).any() else float("nan")
            op = ">" if high else "<"
            out.append(
                f"| {cue} | {op} {thr:g} dB | {a:.2f} | {100 * flag.mean():.1f} % | {100 * det:.1f} % "
                f"| {100 * fa:.1f} % | {100 * kept_bad:.1f} % | {100 * bad.mean():.1f} % |"
            )
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "isas-walk1")
    args = parser.parse_args(argv)
    if not (args.data / "isas-walk1.mcap").exists():
        print(f"skipped: {args.data} is not present", file=sys.stderr)
        return 0
    d = load(args.data)
    n = len(d["raw"])
    gross = np.abs(d["raw"]) > 5.0
    print(
        f"{n} valid ranges (ra == 1, inside the ground-truth span) of {int(d['n_all'])} logged; "
        f"{gross.sum()} gross outliers (|raw residual| > 5 m, kept in every table)."
    )
    print(
        "Cue percentiles 1/5/50/95/99: "
        + "; ".join(f"{c} " + " / ".join(f"{v:.1f}" for v in np.percentile(d[c], [1, 5, 50, 95, 99])) for c in CUES)
        + " dB"
    )
    print(
        f"|bias-removed residual| > {BAD_M} m: {(np.abs(d['corr']) > BAD_M).sum()} ranges; "
        f"|raw residual| > {BAD_M} m: {(np.abs(d['raw']) > BAD_M).sum()}"
    )
    bad = np.abs(d["corr"]) > BAD_M
    episodes = 0
    for i in README_BIAS:
        tb = d["t"][bad & (d["anchor"] == i)]
        episodes += int(len(tb) > 0) + int(np.sum(np.diff(tb) > 1.0))
    print(
        f"The {bad.sum()} bias-removed bad ranges: {np.sum(d['corr'][bad] > 0)} too long, "
        f"{np.sum(d['corr'][bad] < 0)} too short; "
        f"{episodes} episodes (runs on one anchor with no gap > 1 s); per anchor "
        + ", ".join(f"{i}: {np.sum(bad & (d['anchor'] == i))}" for i in sorted(README_BIAS))
    )
    print()
    print("### Spearman rank correlation, per anchor")
    print()
    print("\n".join(correlation_table(d)))
    for cue in CUES:
        print()
        print(f"### Residual by {cue} bin")
        print()
        print("\n".join(bins_table(d, cue)))
    for kind, title in (("corr", f"|bias-removed residual| > {BAD_M} m"), ("raw", f"|raw residual| > {BAD_M} m")):
        print()
        print(f"### Detector of {title}")
        print()
        print("\n".join(detector_table(d, kind)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
