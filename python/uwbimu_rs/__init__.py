"""uwbimu_rs: UWB + IMU fusion filters for indoor positioning, implemented in Rust.

Start with :func:`run_filter` (``"best"`` for real logs), :func:`replay` for MCAP recordings and
the streaming classes (:class:`Best`, …) for a robot loop; :mod:`uwbimu_rs.sim` simulates runs and
:mod:`uwbimu_rs.metrics` scores them; :func:`compare` runs several methods side by side and
:mod:`uwbimu_rs.plot` draws the comparison; :mod:`uwbimu_rs.fleet` replays many logs on Ray.

Conventions: navigation frame ENU (z up); accelerometer = specific force in the body frame
(≈ [0, 0, +9.81] m/s² level and still); gyroscope rad/s; quaternions Hamilton [w, x, y, z]
rotating body → navigation; error-state order δp, δv, δθ, δb_a, δb_g; times in seconds.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError as _PackageNotFoundError
from importlib.metadata import version as _version

from uwbimu_rs import fleet, metrics, plot, ranging, sim
from uwbimu_rs._batch import crlb, initialize, run_filter, run_filters
from uwbimu_rs._calibration import calibrate, choose_model, tune
from uwbimu_rs._compare import Comparison, MethodRun, compare
from uwbimu_rs._native import (
    FILTERS,
    INPUTS,
    METHODS,
    SENSORS,
    Ackf,
    Arckf,
    Best,
    Ckf,
    ConfigError,
    Criekf,
    DwmDecoder,
    Ekf,
    Eskf,
    FilterConfig,
    FormatError,
    Iekf,
    LinkTrackDecoder,
    MappingError,
    NumericalError,
    Rekf,
    Riekf,
    Rukf,
    Shaf,
    Shfaf,
    Ukf,
    UpdateReport,
    UwbImuError,
    encode_dwm_loc_get,
    encode_linktrack_node_frame2,
    survey_anchors,
)
from uwbimu_rs._recording import read_mcap, replay
from uwbimu_rs._typing import MethodName

try:
    __version__: str = _version("uwbimu_rs")
    """The installed package's version."""
except _PackageNotFoundError:  # pragma: no cover - only when run from a source tree never installed
    __version__ = "0+unknown"

__all__ = [
    "FILTERS",
    "INPUTS",
    "METHODS",
    "SENSORS",
    "Ackf",
    "Arckf",
    "Best",
    "Ckf",
    "Comparison",
    "ConfigError",
    "Criekf",
    "DwmDecoder",
    "Ekf",
    "Eskf",
    "FilterConfig",
    "FormatError",
    "Iekf",
    "LinkTrackDecoder",
    "MappingError",
    "MethodRun",
    "MethodName",
    "NumericalError",
    "Rekf",
    "Riekf",
    "Rukf",
    "Shaf",
    "Shfaf",
    "Ukf",
    "UpdateReport",
    "UwbImuError",
    "__version__",
    "calibrate",
    "choose_model",
    "compare",
    "encode_dwm_loc_get",
    "encode_linktrack_node_frame2",
    "survey_anchors",
    "crlb",
    "fleet",
    "initialize",
    "metrics",
    "plot",
    "ranging",
    "read_mcap",
    "replay",
    "run_filter",
    "run_filters",
    "sim",
    "tune",
]


def __dir__() -> list[str]:
    """The public names only (``dir(uwbimu_rs)`` shows what a user may use)."""
    return sorted(__all__)
