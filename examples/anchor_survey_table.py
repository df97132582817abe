"""The anchor-survey table of docs/anchors.md: sites of 4, 6 and 8 anchors (on walls at 0.4–2.9 m,
or all at one height), every pair ranged 6 times with σ 5 cm, one pair in NLOS (+0.5 m on every
range); the largest anchor error of `survey_anchors` over seeds, with the mounting heights given
and without them (then the pairwise distances, as the frame is the survey's own).

    python examples/anchor_survey_table.py [--seeds 16]
"""

from __future__ import annotations

import argparse

import numpy as np

import uwbimu_rs

WALLS = np.array(
    [[0.5, 0.3, 2.4], [9.8, 0.1, 2.6], [10.2, 7.9, 0.4], [0.2, 8.1, 2.5], [5.1, -0.2, 0.5], [4.9, 8.3, 2.2], [7.5, 4.0, 2.9], [2.5, 4.2, 0.9]]
)


def pairs_of(site: np.ndarray, rng: np.random.Generator, nlos: tuple[int, int]) -> np.ndarray:
    rows = []
    for i in range(len(site)):
        for j in range(i + 1, len(site)):
            d = np.linalg.norm(site[i] - site[j])
            rows += [[i, j, d + rng.normal(0.0, 0.05) + (0.5 if (i, j) == nlos else 0.0)] for _ in range(6)]
    return np.array(rows)


def in_frame(site: np.ndarray) -> np.ndarray:
    d = site[1] - site[0]
    a = -np.arctan2(d[1], d[0])
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    out = np.column_stack([(site[:, :2] - site[0, :2]) @ rot.T, site[:, 2]])
    if out[2, 1] < 0:
        out[:, 1] *= -1
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seeds", type=int, default=16)
    args = parser.parse_args()
    print("| site | anchors | with heights: largest horizontal error (m), mean / worst seed | without: largest distance error (m), mean / worst | NLOS pair named |")
    print("|---|---|---|---|---|")
    for name, flat in (("walls", False), ("one height", True)):
        for k in (4, 6, 8):
            site = WALLS[:k].copy()
            if flat:
                site[:, 2] = 2.5
            with_h, without, named = [], [], 0
            for seed in range(args.seeds):
                rng = np.random.default_rng(seed)
                pairs = pairs_of(site, rng, nlos=(1, 3))
                s = uwbimu_rs.survey_anchors(pairs, heights=site[:, 2])
                with_h.append(np.linalg.norm((s["positions"] - in_frame(site))[:, :2], axis=1).max())
                named += any(w.startswith("pair (1, 3)") for w in s["warnings"])
                free = uwbimu_rs.survey_anchors(pairs)
                d = np.linalg.norm(free["positions"][:, None] - free["positions"][None], axis=2)
                without.append(np.abs(d - np.linalg.norm(site[:, None] - site[None], axis=2)).max())
            print(
                f"| {name} | {k} | {np.mean(with_h):.3f} / {np.max(with_h):.3f} | {np.mean(without):.3f} / {np.max(without):.3f} "
                f"| {named} of {args.seeds} |"
            )


if __name__ == "__main__":
    main()
