"""Learning from a log: per-anchor range biases, time offset and lever arm, noise settings, the
range-error model."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np
from numpy.typing import ArrayLike
import polars as pl

from uwbimu_rs import _native
from uwbimu_rs._convert import model_choice as _model_choice
from uwbimu_rs._convert import plain as _as_dict
from uwbimu_rs._native import FilterConfig
from uwbimu_rs._typing import MethodName

def calibrate(
    imu: np.ndarray,
    ranges: np.ndarray,
    anchors: np.ndarray,
    *,
    truth: np.ndarray | None = None,
    method: MethodName | None = None,
    initial: Mapping[str, Any] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    iterations: int | None = None,
    offsets: bool = False,
    refine_anchors: bool = False,
    anchor_std: float | ArrayLike | None = None,
    range_bias_std: float | None = None,
) -> dict[str, Any]:
    """Estimate a constant range bias per anchor (measured − true) from a log; with
    ``offsets=True`` also the UWB–IMU time offset and the lever arm; with
    ``refine_anchors=True`` the anchor positions themselves (docs/anchors.md).

    With ``truth`` the residuals are taken against the true tag track; without it against the
    Rauch–Tung–Striebel smoothed track of ``method``, refined by expectation–maximisation over
    ``iterations`` passes (the ranges corrected by the current biases, filtered and smoothed
    again). Each anchor's bias is the mean of its residuals within 3 robust σ of their median.

    Parameters
    ----------
    imu, ranges, anchors, initial, config
        As for :func:`run_filter`.
    truth : numpy.ndarray, shape (N, 4), optional
        ``t, x, y, z`` of the tag (UWB antenna) in the navigation frame [s, m], time increasing.
    method : str, optional
        A smoothable inertial method for the no-truth estimate (default ``"riekf"``, with
        ``refine_anchors`` ``"best"``, whose model choice and NLOS handling keep the track's height
        from wandering with wrong anchors).
    iterations : int, optional
        EM passes without truth (default 8, with ``offsets`` 16).
    offsets : bool
        Also estimate, jointly with the biases (Gauss–Newton on
        ``r = ‖p(t + τ) + R(t + τ)·l − a‖ + b_a``), the time offset ``τ`` (a range stamped ``t``
        was measured at ``t + τ``) and, without truth, the lever arm ``l``; the result then also
        has ``time_offset``, ``time_offset_std`` [s], ``lever_arm``, ``lever_arm_std`` [m] (None with
        truth: the truth is already the tag), ``residual_rms`` [m] and ``config`` (the input
        configuration with ``ranging.time_offset_s``, ``mounting.lever_arm`` and
        ``range_calibration`` set: pass it as ``config=``).
    refine_anchors : bool
        Estimate the anchor positions with the track, by EM over ``iterations`` passes (default
        10; it stops earlier once no anchor moves by 1 mm), each a smoothed run of ``method``, the
        given ``anchors`` a prior of σ ``anchor_std``. The translation and yaw of the whole layout
        (which no log fixes) stay those of the given anchors. Not with ``offsets``.
    anchor_std : float or array-like of shape (K,)
        σ of the given anchor positions per axis [m], for every anchor or per anchor (required
        with ``refine_anchors``).
    range_bias_std : float, optional
        With ``refine_anchors``: also estimate a constant range bias per anchor with the positions,
        with this prior σ [m]. The two separate as far as the log sees each anchor from different
        directions (a bias adds the same to every range, a moved anchor ``−u·δa``).

    Returns
    -------
    dict
        ``biases``: polars DataFrame ``anchor, bias, std, used, ranges`` (m; ``std`` is the
        statistical σ/√n: without truth the part the smoothed track absorbs is larger — on
        isas-walk1 each bias lands within 0.052 m of the truth-based one); ``common_offset``,
        ``common_std`` (m); ``iterations``; ``range_calibration`` ``{anchor: [−b, 1, 0, 0]}`` to
        pass as ``config["range_calibration"]``. With ``refine_anchors`` also ``anchors``
        ``(K, 3)`` (the refined positions, to pass to any method; with ``range_bias_std`` pass
        ``config`` too, which holds the biases), ``anchor_std`` ``(K, 3)`` [m],
        ``anchor_covariances`` ``(K, 3, 3)`` [m²], ``directions`` (what the log does not fix: a
        list of dicts ``kind`` ``"gauge"`` or ``"weak"``, ``std_ratio`` posterior over prior σ,
        ``vector`` ``(K, 3)``, ``description``), ``biases_estimated``, ``moves`` (the largest
        anchor move of each iteration, m), ``converged``, ``warnings`` (list of str: a tag that
        stayed at one height, an anchor that moved by more than twice its σ), ``residual_rms`` (m)
        and ``config``; ``biases`` then holds
        the estimated biases, or without ``range_bias_std`` the mean residual each refined anchor
        leaves.
    """
    if iterations is None:
        iterations = 10 if refine_anchors else 16 if offsets else 8
    if method is None:
        method = "best" if refine_anchors else "riekf"
    out = _native.calibrate_log(
        imu,
        ranges,
        anchors,
        truth=truth,
        method=method,
        initial=_as_dict(initial),
        config=_as_dict(config),
        iterations=iterations,
        offsets=offsets,
        refine_anchors=refine_anchors,
        anchor_std=anchor_std,
        range_bias_std=range_bias_std,
    )
    out["biases"] = pl.DataFrame(out["biases"]).with_columns(pl.col("anchor", "used", "ranges").cast(pl.Int64))
    return out


def tune(
    method: MethodName,
    imu: np.ndarray,
    ranges: np.ndarray,
    anchors: np.ndarray,
    *,
    truth: np.ndarray | None = None,
    initial: Mapping[str, Any] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
    smooth: bool | None = None,
    rounds: int = 2,
) -> dict[str, Any]:
    """Pick the noise settings of ``method`` for a log.

    Coordinate search on a log scale over ``ins.accel_noise_density``,
    ``ins.gyro_noise_density`` and ``ranging.range_std`` (``rounds`` passes: factors 1/4 … 4,
    then 0.6 … 1.6), each candidate a whole run, the candidates of a step in parallel on all
    cores. Without ``truth`` it minimises the held-out range RMS — each anchor's ranges predicted
    by a run without them, the criterion of :func:`choose_model` — which, unlike the innovation
    likelihood, does not read range errors correlated in time as precision; with ``truth`` it
    minimises the horizontal RMSE of the tag track (smoothed when ``smooth``; the first 10 s left
    out when self-initialised).

    Parameters
    ----------
    method, imu, ranges, anchors, initial, config, smooth
        As for :func:`run_filter` (``config`` is the starting point; its other settings are kept).
    truth : numpy.ndarray, shape (N, 4), optional
        ``t, x, y, z`` of the tag in the navigation frame [s, m].
    rounds : int
        Passes over the three settings; 0 only scores ``config`` (e.g. to compare two model
        choices, such as ``range_bias.states``, by their held-out range RMS). With ``rounds`` > 0
        ``"best"`` first chooses its model (:func:`choose_model`) and is tuned with it.

    Returns
    -------
    dict
        ``config`` (the tuned configuration, nested dict, to pass as ``config=``), ``objective``
        (``"held_out_ranges"`` or ``"truth_rmse"``), ``initial_score`` and ``score`` (lower
        is better: held-out range RMS or RMSE, m), ``trials`` (polars
        DataFrame: the three settings and ``score`` of every candidate).
    """
    out = _native.tune_noise(
        method,
        imu,
        ranges,
        anchors,
        truth=truth,
        initial=_as_dict(initial),
        config=_as_dict(config),
        smooth=smooth,
        rounds=rounds,
    )
    out["trials"] = pl.DataFrame(out["trials"])
    return out


def choose_model(
    method: MethodName,
    imu: np.ndarray,
    ranges: np.ndarray,
    anchors: np.ndarray,
    *,
    initial: Mapping[str, Any] | None = None,
    config: FilterConfig | Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """What ``best`` chooses on a log before it runs: the range-error model (white noise, a steady
    bias per anchor, or a wandering Gauss–Markov one), the NLOS skew and ``range_std``.

    Each candidate runs once per anchor without that anchor's ranges and is scored by how well it
    predicts them (the held-out range RMS, m, each anchor's residuals centred on their median, the
    half nearest it kept); a candidate must beat the current choice by 10 %. With four anchors it
    holds out 2 s blocks of time instead (4 folds; each range of a block predicted through it by
    the IMU alone, less the anchor's bias as estimated before it; 15 %). The same
    computation ``run_filter("best", ...)`` makes: the returned ``config`` (selection off) given
    to ``run_filter`` reproduces its run, and the streaming :class:`Best` takes it. Runs over the
    first ``model_selection.window_s`` of the log (300 s), (6 + 2) candidates × up to 8 folds in
    parallel. See docs/model-selection.md.

    Parameters
    ----------
    method, imu, ranges, anchors, initial, config
        As for :func:`run_filter`; ``config`` is the first candidate.

    Returns
    -------
    dict
        ``config`` (nested dict of the chosen configuration), ``overrides`` (``{key: value}`` it
        changes against ``config``), ``chosen`` (label, None when no selection ran), ``reason``
        (the scores behind it, or why no selection ran: fewer than 4 anchors, no ranges),
        ``candidates`` (polars DataFrame: ``label``, ``score`` m, ``per_anchor`` list of m).

    Raises
    ------
    ValueError
        As :func:`run_filter`.
    """
    return _model_choice(_native.choose_model(method, imu, ranges, anchors, initial=_as_dict(initial), config=_as_dict(config)))
