"""Generated inputs (hypothesis) through every method of the registry: shapes, dtypes, NaN/inf,
duplicated and decreasing timestamps, extreme values (ranges 0 or 1e9 m, steps of 1e-9 s or
1e4 s), unknown config keys and values of the wrong type. Each call returns finite output or
raises ValueError / TypeError with a message; never a crash, a hang or a PanicException.

Every commit runs ``UWBIMU_PROPERTY_EXAMPLES`` examples per test (default 60; the slow run in
docs/reliability.md uses 2000 per test, over 10 000 in all)."""

from __future__ import annotations

import os

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

import uwbimu_rs  # noqa: E402

EXAMPLES = int(os.environ.get("UWBIMU_PROPERTY_EXAMPLES", "60"))
SETTINGS = settings(
    max_examples=EXAMPLES, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck)
)
METHODS = list(uwbimu_rs.METHODS)
ANCHORS = np.array([[0.0, 0.0, 2.0], [8.0, 0.0, 1.0], [8.0, 6.0, 2.0], [0.0, 6.0, 1.0]])
AT_REST = {"position": [4.0, 3.0, 0.3], "velocity": [0, 0, 0], "orientation": [1, 0, 0, 0]}
SPECIALS = [0.0, -0.0, 1e-9, 1e9, -1e9, 1e300, np.nan, np.inf, -np.inf]


def still(n: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(n) * dt
    imu = np.zeros((n, 7))
    imu[:, 0] = t
    imu[:, 3] = 9.80665
    tr = t[:: max(1, n // 20)]
    a = np.arange(tr.size) % 4
    r = np.linalg.norm(ANCHORS[a] - np.array([4.0, 3.0, 0.3]), axis=1)
    return imu, np.column_stack([tr, a, r])


@st.composite
def damaged_run(draw):
    """A short still run, then a few damages: special values in cells, time steps, shapes, dtypes."""
    n = draw(st.integers(0, 300))
    dt = draw(st.sampled_from([1e-9, 1e-3, 0.01, 1.0, 1e4]))
    imu, ranges = still(n, dt)
    for _ in range(draw(st.integers(0, 3))):
        target = draw(st.sampled_from(["imu", "ranges"]))
        arr = imu if target == "imu" else ranges
        if arr.size == 0:
            continue
        row = draw(st.integers(0, arr.shape[0] - 1))
        col = draw(st.integers(0, arr.shape[1] - 1))
        arr[row, col] = draw(st.sampled_from(SPECIALS + [arr[row - 1, col] if row else 0.0]))
    if draw(st.booleans()) and n > 2:
        imu = imu[::-1].copy() if draw(st.booleans()) else np.repeat(imu, 2, axis=0)
    shape_change = draw(st.sampled_from([None, "imu_cols", "ranges_cols", "anchors_cols", "1d"]))
    anchors = ANCHORS
    if shape_change == "imu_cols":
        imu = imu[:, :6]
    elif shape_change == "ranges_cols":
        ranges = ranges[:, :2]
    elif shape_change == "anchors_cols":
        anchors = ANCHORS[:, :2]
    elif shape_change == "1d":
        imu = imu.ravel()
    dtype = draw(st.sampled_from([np.float64, np.float32, np.int64, object]))
    return imu.astype(dtype), ranges, anchors


CONFIGS = st.one_of(
    st.none(),
    st.sampled_from(
        [
            {"ranging.range_std": 0.2},
            {"ranging.range_std": -1.0},
            {"ranging.range_std": "wide"},
            {"ranging.range_std": float("nan")},
            {"range_sdt": 0.2},
            {"ins": {"accel_noise": [1, 2]}},
            {"gate.max_range_m": 1e9},
            {"epoch_window_s": 1e4},
        ]
    ),
)


def check(call):
    """Runs `call`: finite output, or a ValueError / TypeError with a message."""
    try:
        frame = call()
    except (ValueError, TypeError) as e:
        assert str(e), "an exception without a message"
        assert "PanicException" not in type(e).__name__
        return
    assert np.isfinite(frame.select(["x", "y", "z"]).to_numpy()).all(), "non-finite positions"


@pytest.mark.filterwarnings("ignore")  # unit-check warnings and numpy casts of the damage
@pytest.mark.parametrize("method", METHODS)
@SETTINGS
@given(run=damaged_run(), config=CONFIGS, given_initial=st.booleans())
def test_damaged_inputs_never_crash(method, run, config, given_initial):
    imu, ranges, anchors = run
    initial = AT_REST if given_initial else None
    check(lambda: uwbimu_rs.run_filter(method, imu, ranges, anchors, initial=initial, config=config))
