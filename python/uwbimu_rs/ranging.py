"""UWB ranging of Wang et al. 2018 §2: SDS-TWR (eqs. (1)–(2)), SS-TWR for comparison, DW1000 40-bit
timestamps, antenna delays, and the per-anchor cubic range calibration (§2.2, §4.1).

A thin wrapper over the native core: every function is element-wise over NumPy arrays of equal
shape and returns float64 arrays of that shape. Intervals and delays in seconds, ranges in metres.
Calibration coefficients are ascending, ``[c0, c1, c2, c3]`` with
``true ≈ c0 + c1·m + c2·m² + c3·m³`` (the reverse of :func:`numpy.polyfit`); a dict
``{anchor: [c0, c1, c2, c3]}`` is what ``run_filter(..., config={"range_calibration": ...})``
takes.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from uwbimu_rs import _native

__all__ = [
    "DW1000_TICK_S",
    "SPEED_OF_LIGHT_MPS",
    "apply_calibration",
    "calibrate_ranges",
    "dw1000_elapsed",
    "fit_calibration",
    "fit_range_calibration",
    "sds_twr",
    "ss_twr",
]

DW1000_TICK_S: float = _native.DW1000_TICK_S
"""One DW1000 timestamp tick, 1/(128·499.2 MHz) ≈ 15.65 ps, in s."""

SPEED_OF_LIGHT_MPS: float = _native.SPEED_OF_LIGHT_MPS
"""Speed of light, m/s."""


def sds_twr(
    t_round1: ArrayLike, t_reply1: ArrayLike, t_round2: ArrayLike, t_reply2: ArrayLike, *, antenna_delay_s: float = 0.0
) -> np.ndarray:
    """Distances by symmetric double-sided two-way ranging (Wang et al. 2018 eqs. (1)–(2)).

    ``T_prop = (T_round1·T_round2 − T_reply1·T_reply2) / (T_round1 + T_round2 + T_reply1 + T_reply2)``,
    ``D = C·(T_prop − antenna_delay_s)``. Clock drift of the two devices cancels to first order.

    Parameters
    ----------
    t_round1, t_reply1, t_round2, t_reply2 : array_like, same shape
        Intervals in s, each on the clock of the device that measured it (round 1 and reply 2 on
        the initiator, reply 1 and round 2 on the responder).
    antenna_delay_s : float
        Sum of both devices' antenna delays (each the mean of its TX and RX delays), s.

    Returns
    -------
    numpy.ndarray
        Distances, m, same shape as the inputs.

    Raises
    ------
    ValueError
        Shapes differ, an interval is negative or non-finite, or rounds shorter than replies.
    """
    return _native.sds_twr(t_round1, t_reply1, t_round2, t_reply2, antenna_delay_s=antenna_delay_s)


def ss_twr(t_round: ArrayLike, t_reply: ArrayLike, *, antenna_delay_s: float = 0.0) -> np.ndarray:
    """Distances by single-sided TWR, ``C·((T_round − T_reply)/2 − antenna_delay_s)``, m (no drift
    compensation: 20 ppm over a 300 µs reply is ≈ 0.9 m)."""
    return _native.ss_twr(t_round, t_reply, antenna_delay_s=antenna_delay_s)


def dw1000_elapsed(start_ticks: ArrayLike, end_ticks: ArrayLike) -> np.ndarray:
    """Seconds from ``start_ticks`` to ``end_ticks`` on a DW1000 40-bit counter (ticks of
    :data:`DW1000_TICK_S`), undoing one wrap-around; whole ticks in ``[0, 2**40)``."""
    return _native.dw1000_elapsed(start_ticks, end_ticks)


def fit_calibration(measured: ArrayLike, true_range: ArrayLike) -> np.ndarray:
    """Least-squares cubic ``[c0, c1, c2, c3]`` (ascending) with ``true ≈ c0 + c1·m + c2·m² + c3·m³``.

    Raises ValueError for unequal shapes, NaN/inf or fewer than 4 distinct measured values.
    """
    return np.asarray(_native.calibration_fit(measured, true_range), dtype=np.float64)


def apply_calibration(coefficients: Sequence[float], measured: ArrayLike) -> np.ndarray:
    """The calibrated ranges ``c0 + c1·m + c2·m² + c3·m³`` for measured ranges ``m`` (m)."""
    return _native.calibration_apply(list(coefficients), measured)


def fit_range_calibration(anchor: ArrayLike, measured: ArrayLike, true_range: ArrayLike) -> dict[int, list[float]]:
    """One cubic per anchor from (anchor index, measured, true) triples: ``{anchor: [c0, c1, c2, c3]}``,
    usable as ``config["range_calibration"]``."""
    return _native.calibration_fit_anchors(anchor, measured, true_range)


def calibrate_ranges(ranges: ArrayLike, calibration: Mapping[int, Sequence[float]], anchor_count: int) -> np.ndarray:
    """A calibrated copy of a range table ``(M, 3)`` = t, anchor index, range.

    Raises ValueError for a calibrated anchor index ``>= anchor_count``, bad coefficients or a
    calibrated range below 0.
    """
    return _native.calibrate_ranges(ranges, dict(calibration), anchor_count)
