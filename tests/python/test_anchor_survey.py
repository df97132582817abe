"""Anchors surveyed from anchor-to-anchor ranges (issue 47, deliverable 1), against the site the
ranges were drawn from: the frame it states, NLOS pairs weighed down and named, honest
covariances, clear errors."""

from __future__ import annotations

import numpy as np
import pytest

import uwbimu_rs

SITE = np.array(
    [[0.5, 0.3, 2.4], [9.8, 0.1, 2.6], [10.2, 7.9, 0.4], [0.2, 8.1, 2.5], [5.1, -0.2, 0.5], [4.9, 8.3, 2.2], [7.5, 4.0, 2.9]]
)


def _pairs(site, rng, std=0.05, repeat=6, nlos=(), extra=0.5):
    rows = []
    for i in range(len(site)):
        for j in range(i + 1, len(site)):
            d = np.linalg.norm(site[i] - site[j])
            for _ in range(repeat):
                rows.append([i, j, d + rng.normal(0.0, std) + (extra if (i, j) in nlos else 0.0)])
    return np.array(rows)


def _in_frame(site):
    """The site in the frame with heights: anchor 0 at x = y = 0, anchor 1 on +x, 2 on +y."""
    d = site[1] - site[0]
    c, s = np.cos(-np.arctan2(d[1], d[0])), np.sin(-np.arctan2(d[1], d[0]))
    xy = (site[:, :2] - site[0, :2]) @ np.array([[c, s], [-s, c]])
    out = np.column_stack([xy, site[:, 2]])
    if out[2, 1] < 0:
        out[:, 1] *= -1
    return out


def test_a_survey_with_heights_recovers_the_site_within_its_covariance():
    errors = []
    for seed in range(8):
        rng = np.random.default_rng(seed)
        s = uwbimu_rs.survey_anchors(_pairs(SITE, rng, nlos=[(1, 3)]), heights=SITE[:, 2])
        e = s["positions"] - _in_frame(SITE)
        std = np.sqrt(np.maximum(np.diagonal(s["covariances"], axis1=1, axis2=2), 1e-12))
        assert np.all(np.abs(e) <= 4 * std + 1e-6), (seed, e, std)
        assert any(w.startswith("pair (1, 3)") for w in s["warnings"]), s["warnings"]
        errors.append(np.linalg.norm(e[:, :2], axis=1).max())
    # σ 5 cm ranges, 6 repeats: every anchor within 5 cm horizontally, the NLOS pair (+0.5 m) dropped.
    assert max(errors) < 0.05, errors


def test_without_heights_the_frame_and_the_mirror_are_stated():
    rng = np.random.default_rng(3)
    s = uwbimu_rs.survey_anchors(_pairs(SITE, rng, std=0.01))
    assert np.allclose(s["positions"][0], 0) and abs(s["positions"][1, 1]) < 1e-9 and s["positions"][2, 1] > 0
    assert "anchor 0 at the origin" in s["frame"] and any(w.startswith("mirror") for w in s["warnings"])
    d = np.linalg.norm(s["positions"][:, None] - s["positions"][None], axis=2)
    truth = np.linalg.norm(SITE[:, None] - SITE[None], axis=2)
    assert np.abs(d - truth).max() < 0.03


def test_bad_pairs_raise_value_errors_naming_the_problem():
    rng = np.random.default_rng(0)
    pairs = _pairs(SITE, rng, repeat=1)
    bad = pairs.copy()
    bad[4, 2] = np.nan
    with pytest.raises(ValueError, match="row 4"):
        uwbimu_rs.survey_anchors(bad)
    with pytest.raises(ValueError, match="anchor 7 has no measured pair"):
        uwbimu_rs.survey_anchors(pairs, heights=np.append(SITE[:, 2], 1.0))
    with pytest.raises(ValueError, match=r"pairs: expected shape \(M, 3\) = anchor i, anchor j, range"):
        uwbimu_rs.survey_anchors(pairs[:, :2])
