"""Seeded UWB + IMU simulator: paper presets and custom trajectories.

A thin wrapper over the native core (``uwbimu_rs._native``): all maths runs in Rust with the GIL
released. Conventions: navigation frame ENU (z up), gravity ``[0, 0, -9.80665]`` m/s², accelerometer
= specific force in the body frame (``≈ [0, 0, +9.81]`` level and still), gyroscope in rad/s,
quaternions Hamilton ``[w, x, y, z]`` body → navigation, times in s, ranges in m.
"""

from __future__ import annotations

import os

from dataclasses import dataclass
from typing import Any, Literal, Mapping

import numpy as np
import polars as pl

from uwbimu_rs import _native
from uwbimu_rs._native import Trajectory

__all__ = [
    "OVERRIDE_KEYS",
    "PRESET_ALIASES",
    "PRESET_NAMES",
    "PresetName",
    "SimResult",
    "Trajectory",
    "ZOO_NAMES",
    "ZooName",
    "preset",
    "simulate",
    "write_mcap",
    "zoo",
    "zoo_matrix",
]

PresetName = Literal[
    "hall_vehicle_nlos",
    "hall_vehicle",
    "lab_robot",
    "lab_robot_nlos",
    "garage_rectangle",
    "garage_figure8",
    "square_diagonal",
    "square_diagonal_outliers",
    "seed000",
    "seed000_los",
    "seed001",
    "seed001_nlos",
    "seed002_rectangle",
    "seed002_figure8",
    "seed004_s1",
    "seed004_s2",
]
"""Names accepted by :func:`preset`: :data:`PRESET_NAMES`, then their former names :data:`PRESET_ALIASES`."""

PRESET_NAMES: tuple[str, ...] = tuple(_native.SIM_PRESET_NAMES)
"""Names accepted by :func:`preset`, each saying what it simulates, from the native module."""

PRESET_ALIASES: tuple[str, ...] = tuple(_native.SIM_PRESET_ALIASES)
"""The former name of each of :data:`PRESET_NAMES` (same index); :func:`preset` accepts them too."""

OVERRIDE_KEYS: tuple[str, ...] = tuple(_native.SIM_OVERRIDE_KEYS)
"""Keys accepted as overrides by :func:`preset` and :func:`simulate`."""

ZooName = Literal[
    "agv_loop",
    "stop_and_go",
    "handheld_walk",
    "drone_flight",
    "imu_20hz",
    "imu_z_down",
    "mixed_rates",
    "nlos_one",
    "nlos_two",
    "outliers",
    "outage",
    "survey_error",
    "far_start",
    "corridor",
    "walk_nlos",
    "forklift",
    "tdoa_drone",
    "tilted_walk",
    "shelf_aisles",
    "still_tdoa_lost",
    "moving_uwb_lost",
]
"""Names accepted by :func:`zoo`."""

ZOO_NAMES: tuple[str, ...] = tuple(_native.SIM_ZOO_NAMES)
"""Scenario names accepted by :func:`zoo` and :func:`zoo_matrix`, from the native module."""


@dataclass(frozen=True)
class SimResult:
    """One simulated run.

    Attributes
    ----------
    imu : numpy.ndarray, shape (N, 7), float64
        ``t`` (s), ``ax, ay, az`` (specific force, IMU frame, m/s²), ``gx, gy, gz`` (rad/s).
    ranges : numpy.ndarray, shape (M, 3) or (M, 4), float64
        ``t`` (s), anchor index (as float), range (m); time-ordered; with a second tag
        (``tag_separation_m=0.6``: tag 1 that far ahead of tag 0 along body x) a fourth column,
        the tag, and ``config["mounting"]["lever_arm"]`` gives both lever arms.
    range_labels : numpy.ndarray, shape (M,), uint8
        0 = line of sight, 1 = inside an NLOS shielding window, 2 = gross outlier.
    anchors : numpy.ndarray, shape (K, 3), float64
        Anchor positions, navigation frame, m.
    truth : polars.DataFrame
        One row per IMU sample: ``t`` (s), ``x, y, z`` (m), ``vx, vy, vz`` (m/s),
        ``qw, qx, qy, qz`` (body → navigation) of the body (IMU) origin.
    mag : numpy.ndarray of shape (N, 4) or None
        ``t`` (s), ``mx, my, mz`` (IMU frame, unit of the configured field, e.g. µT); ``None``
        without a magnetometer.
    tdoa : numpy.ndarray of shape (M, 4) or None
        ``t`` (s), anchor ``i``, anchor ``j`` (as float), ``d_ij = |p − a_j| − |p − a_i|`` (m)
        with ``i`` the anchor that sent before ``j``; ``None`` without TDoA (override
        ``tdoa=True``, with ``tdoa_rate_hz``, ``tdoa_std_m``, ``tdoa_outlier_prob``).
    tdoa_labels : numpy.ndarray, shape (M,), uint8
        0 = clean, 2 = gross outlier (random sign).
    altitude : numpy.ndarray, shape (M, 2), float64, or None
        Altitude readings ``t, z`` (override ``altimeter=True``), as :func:`uwbimu_rs.run_filter`
        takes them (``altitude=``).
    altitude_offsets : numpy.ndarray, shape (M,), float64
        The true offset of each altitude reading, m (a barometer's wandering reference; overrides
        ``altimeter_offset_m``, ``altimeter_offset_walk``).
    pose_fix : numpy.ndarray, shape (M, 7) or (M, 9), float64, or None
        External pose fixes ``t, x, y, z, sx, sy, sz`` (with ``yaw, s_yaw`` when
        ``pose_fix_yaw_std_rad`` > 0; override ``pose_fix=True``), as
        :func:`uwbimu_rs.run_filter` takes them (``pose_fix=``).
    odometry : numpy.ndarray, shape (M, 2) or (M, 4), float64, or None
        Wheel odometry ``t, speed`` (body x), or ``t, vx, vy, vz`` with ``odometer_lateral=True``
        (override ``odometer=True``), as :func:`uwbimu_rs.run_filter` takes it (``odometry=``).
    accel_bias : numpy.ndarray, shape (N, 3), float64
        True accelerometer bias at each IMU sample, IMU frame, m/s².
    gyro_bias : numpy.ndarray, shape (N, 3), float64
        True gyroscope bias at each IMU sample, IMU frame, rad/s.
    nlos_windows : numpy.ndarray, shape (W, 4), float64
        Realised shielding windows: anchor index, start (s), end (s), range bias (m).
    accel_outlier_times : numpy.ndarray, shape (P,), float64
        Times (s) of the abnormal accelerometer samples (override ``accel_outlier_count``,
        the ARCKF paper's §4.1); empty by default.
    true_anchors : numpy.ndarray, shape (K, 3), float64
        The true anchor positions (``anchors`` is the surveyed table a filter gets; they differ
        only in the zoo's ``survey_error``).
    config : dict
        A filter configuration matched to the simulated sensors (range σ, IMU noise densities
        and bias sizes, lever arm, mounting): pass it as ``config=`` to compare methods on equal
        terms. The library defaults are chosen for real logs, not for this simulator.
    initial : dict
        The true state at the first IMU sample as the filter configured by ``config`` sees it
        (pass as ``initial=``).
    """

    imu: np.ndarray
    ranges: np.ndarray
    range_labels: np.ndarray
    anchors: np.ndarray
    truth: pl.DataFrame
    mag: np.ndarray | None
    tdoa: np.ndarray | None
    tdoa_labels: np.ndarray
    altitude: np.ndarray | None
    altitude_offsets: np.ndarray
    odometry: np.ndarray | None
    pose_fix: np.ndarray | None
    accel_bias: np.ndarray
    gyro_bias: np.ndarray
    nlos_windows: np.ndarray
    accel_outlier_times: np.ndarray
    true_anchors: np.ndarray
    config: dict
    initial: dict

    def __repr__(self) -> str:
        """Shapes and a few figures, never the arrays: duration, IMU rate, ranges, anchors, NLOS."""
        t = self.imu[:, 0]
        duration = float(t[-1] - t[0]) if len(t) > 1 else 0.0
        rate = (len(t) - 1) / duration if duration > 0 else float("nan")
        nlos = float(np.mean(self.range_labels == 1)) if len(self.range_labels) else 0.0
        parts = [
            f"duration_s={duration:.1f}",
            f"imu_rate_hz={rate:.0f}",
            f"imu={self.imu.shape}",
            f"ranges={self.ranges.shape}",
            f"anchors={len(self.anchors)}",
            f"nlos_fraction={nlos:.3f}",
            f"outliers={int(np.sum(self.range_labels == 2))}",
        ]
        if self.tdoa is not None:
            parts.append(f"tdoa={self.tdoa.shape}")
        parts += [f"{k}={v.shape}" for k, v in self.sensors().items() if k != "tdoa"]
        return f"SimResult({', '.join(parts)})"

    def sensors(self) -> dict[str, np.ndarray]:
        """The run's arrays of the sensors of :data:`uwbimu_rs.SENSORS` it has, by keyword, as
        :func:`uwbimu_rs.run_filter` takes them (``run_filter(m, r.imu, r.ranges, r.anchors,
        **r.sensors())``)."""
        tables = {row["keyword"]: getattr(self, row["keyword"]) for row in _native.SENSORS.values()}
        return {k: v for k, v in tables.items() if v is not None}


def _result(d: dict) -> SimResult:
    return SimResult(
        imu=d["imu"],
        ranges=d["ranges"],
        range_labels=d["range_labels"],
        anchors=d["anchors"],
        truth=pl.DataFrame(d["truth"]),
        mag=d["mag"],
        tdoa=d["tdoa"],
        tdoa_labels=d["tdoa_labels"],
        altitude=d["altitude"],
        altitude_offsets=d["altitude_offsets"],
        odometry=d["odometry"],
        pose_fix=d["pose_fix"],
        accel_bias=d["accel_bias"],
        gyro_bias=d["gyro_bias"],
        nlos_windows=d["nlos_windows"],
        accel_outlier_times=d["accel_outlier_times"],
        true_anchors=d["true_anchors"],
        config=d["config"],
        initial=d["initial"],
    )


def preset(name: PresetName, *, seed: int = 0, **overrides: float | bool) -> SimResult:
    """Simulate a paper setup.

    Parameters
    ----------
    name : str
        One of :data:`PRESET_NAMES` (or its former name in :data:`PRESET_ALIASES`).
        ``hall_vehicle_nlos``: 4 anchors in a 10 m × 8 m hall (heights 0.8–2.2 m), figure-8 ×4, UWB 2 Hz
        σ 0.1 m, IMU 100 Hz, 1–2 anchors randomly shielded (NLOS). ``hall_vehicle``: the same without
        NLOS, outliers or dropouts. ``garage_rectangle`` / ``garage_figure8``: the 10 m × 5 m garage site of the ARCKF paper,
        rectangle or figure-8 ×2 (the latter with 10 % outliers on beacons 2 and 4).
        ``square_diagonal`` / ``square_diagonal_outliers``: the planar simulation of Liu et al. 2019 (anchors (−5,−1), (1,−1),
        (1,5), (−5,5), 0.4 m/s along a diagonal, UWB 5 Hz σ 0.1 m + U(−0.2, 0.2)); the second adds gross
        outliers. The (0.57, 0) start of scenario 1 is a filter initial error, not part of the data.
    seed : int, default 0
        Seed of all random draws; the same seed gives identical output.
    **overrides : float or bool
        Any of :data:`OVERRIDE_KEYS`, e.g. ``nlos=False``, ``outlier_prob=0.05``,
        ``range_std_m=0.2``, ``uwb_rate_hz=5.0``, ``magnetometer=True``, ``imu_noise=False``,
        ``stagger_s=0.003`` (anchor k's range ``k·stagger_s`` after the sweep starts),
        ``jitter_s=0.002`` (plus U(0, jitter) per range), ``start_s=10.0`` (the log starts 10 s in,
        already moving).

    Returns
    -------
    SimResult

    Raises
    ------
    ValueError
        (``uwbimu_rs.ConfigError``) for an unknown preset or override key (the message lists the
        allowed ones) or an invalid value.
    """
    return _result(_native.sim_preset(name, seed, dict(overrides)))


def simulate(
    trajectory: Trajectory,
    anchors: np.ndarray,
    *,
    seed: int = 0,
    imu_rate_hz: float = 100.0,
    uwb_rate_hz: float = 2.0,
    range_std_m: float = 0.1,
    uniform_noise_m: float = 0.0,
    nlos: bool = False,
    outlier_prob: float = 0.0,
    dropout_prob: float = 0.0,
    magnetometer: bool = False,
    imu_noise: bool = True,
    lever_arm_m: np.ndarray | tuple[float, float, float] = (0.0, 0.0, 0.05),
    imu_rotation: np.ndarray | tuple[float, float, float, float] | None = None,
    **overrides: float | bool,
) -> SimResult:
    """Simulate IMU, UWB ranges and truth along a trajectory.

    Parameters
    ----------
    trajectory : Trajectory
        E.g. ``Trajectory.figure_eight(centre, a_m, b_m, lap_time_s, laps)`` or
        ``Trajectory.waypoints(points)``.
    anchors : array_like, shape (K, 3)
        Anchor positions, navigation frame, m (K ≥ 1).
    seed : int, default 0
        Seed of all random draws.
    imu_rate_hz : float, default 100.0
        IMU sample rate, Hz (consumer-MEMS noise: 0.003 m/s²/√Hz, 0.0005 rad/s/√Hz, biases
        0.05 m/s² and 0.005 rad/s).
    uwb_rate_hz : float, default 2.0
        Ranging epochs per second, Hz.
    range_std_m : float, default 0.1
        Gaussian range noise std, m.
    uniform_noise_m : float, default 0.0
        Half-width of additional uniform range noise, m.
    nlos : bool, default False
        Random NLOS shielding of 1–2 anchors at a time (bias U(0.3, 1.5) m).
    outlier_prob : float, default 0.0
        Probability of a gross outlier (+U(1, 5) m) per range.
    dropout_prob : float, default 0.0
        Probability that a range is lost.
    magnetometer : bool, default False
        Add a magnetometer (field [20, 0, −40] µT, noise 0.5 µT).
    imu_noise : bool, default True
        ``False`` makes the IMU perfect.
    lever_arm_m : array_like, shape (3,), default (0, 0, 0.05)
        UWB antenna position in the body frame, m.
    imu_rotation : array_like, shape (4,), optional
        Mounting rotation IMU frame → body, ``[w, x, y, z]``; identity by default.
    **overrides : float or bool
        Further keys from :data:`OVERRIDE_KEYS` (e.g. ``accel_noise_density``, ``nlos_bias_max_m``,
        ``stagger_s``, ``jitter_s``, ``start_s``).

    Returns
    -------
    SimResult

    Raises
    ------
    ValueError
        (``uwbimu_rs.ConfigError`` or ``uwbimu_rs.UwbImuError``) for an unknown override key, an
        invalid value or a bad array shape.
    """
    options: dict[str, float | bool] = {
        "imu_rate_hz": imu_rate_hz,
        "uwb_rate_hz": uwb_rate_hz,
        "range_std_m": range_std_m,
        "uniform_noise_m": uniform_noise_m,
        "nlos": nlos,
        "outlier_prob": outlier_prob,
        "dropout_prob": dropout_prob,
        "magnetometer": magnetometer,
        "imu_noise": imu_noise,
        **overrides,
    }
    return _result(
        _native.simulate(
            trajectory,
            np.asarray(anchors, dtype=np.float64),
            seed,
            np.asarray(lever_arm_m, dtype=np.float64),
            None if imu_rotation is None else np.asarray(imu_rotation, dtype=np.float64),
            options,
        )
    )


def write_mcap(run: SimResult, path: str | os.PathLike[str], *, range_std: float | None = None) -> None:
    """Write a simulated run as an MCAP recording that ``uwbimu-replay`` and :func:`uwbimu_rs.replay`
    read: CDR ``sensor_msgs/msg/Imu`` on ``/imu``, JSON ``uwbimu.UwbRange`` on ``/uwb`` (anchor
    ids ``A0``, ``A1``, ...; a tag beyond 0 in ``tag``; ``variance = range_std²`` when given; no
    ``/uwb`` when the run has TDoA and no ranges), each of its other sensors (:meth:`SimResult.sensors`)
    as its row of the io writes it — TDoA as CDR ``uwbimu_msgs/msg/Tdoa`` on ``/tdoa`` (fields
    ``idA``, ``idB``, ``distanceDiff``, the ``[mapping.tdoa]`` defaults), heights as
    ``sensor_msgs/msg/Range`` on ``/altitude``, body velocities as ``nav_msgs/msg/Odometry`` on
    ``/odom``, magnetometer samples as ``sensor_msgs/msg/MagneticField`` on ``/mag`` (in µT, as
    simulated), pose fixes as ``geometry_msgs/msg/PoseWithCovarianceStamped`` on ``/pose_fix`` —
    and the anchor positions in the ``uwbimu.anchors`` metadata record. Read back with ``{"uwb":
    {"topics": ["/uwb"]}, "altitude": {"topics": ["/altitude"]}, "odometry": {"topics": ["/odom"],
    "axes": ["x", "y", "z"]}, "magnetometer": {"topics": ["/mag"]}, "pose_fix": {"topics":
    ["/pose_fix"]}}`` (TDoA is found without a mapping)."""
    _native.write_mcap(os.fspath(path), run.imu, run.ranges, run.anchors, range_std=range_std, **run.sensors())


def zoo(name: ZooName, *, seed: int = 0, **overrides: float | bool) -> SimResult:
    """Simulate a scenario of the zoo: deployment-like runs built to check that a method holds up
    on data it was not tuned on (staggered and jittered range times, anchors at different rates,
    4–8 coplanar or cuboid anchors, IMUs at 20–1000 Hz, an upside-down mounting, vehicle, walking
    and flight motion, sustained NLOS, outliers, an outage, a survey error, a far start).

    Parameters
    ----------
    name : str
        One of :data:`ZOO_NAMES` (the README's "Generality" section describes each).
    seed : int, default 0
        Seed of all random draws.
    **overrides : float or bool
        As for :func:`preset`, applied to the scenario (e.g. ``tdoa=True, tdoa_rate_hz=10.0,
        tdoa_std_m=0.05, tdoa_outlier_prob=0.03`` adds TDoA; ``config["ranging"]["tdoa_std"]`` follows).

    Returns
    -------
    SimResult
        With ``config`` the scenario's filter configuration (matched to its sensors; the mounting
        of ``imu_z_down`` is left to the filter to find) and ``initial`` the true start.

    Raises
    ------
    ValueError
        (``uwbimu_rs.ConfigError``) for an unknown name (the message lists the allowed ones).
    """
    return _result(_native.sim_zoo(name, seed, overrides))


def zoo_matrix(
    methods: list[str] | None = None,
    scenarios: list[str] | None = None,
    *,
    seeds: list[int] | tuple[int, ...] = (0,),
    start: Literal["given", "self"] = "given",
    settings: Literal["matched", "defaults", "custom"] = "matched",
    config: Mapping[str, Any] | None = None,
) -> pl.DataFrame:
    """The generality matrix: each method on each zoo scenario and seed against ``uwb_ls`` on the
    same run, in parallel on all cores (GIL released).

    A cell's horizontal RMSE leaves out the first 10 s when self-initialised and the time inside
    range outages (gaps over 1 s, where ``uwb_ls`` has no output; the worst error there is the
    ``outage_max_error`` column).

    Parameters
    ----------
    methods : list of str, optional
        Filters of ``uwbimu_rs.FILTERS`` (default: all but ``uwb_ls``, the baseline).
    scenarios : list of str, optional
        Names of :data:`ZOO_NAMES` (default: all).
    seeds : sequence of int, default (0,)
        Simulator seeds.
    start : {"given", "self"}
        Initial state given (the truth) or self-initialised.
    settings : {"matched", "defaults", "custom"}
        The scenario's matched configuration, the library defaults (with the rig's lever arm and
        declared mounting), or ``config``.
    config : dict, optional
        The configuration for ``settings="custom"``.

    Returns
    -------
    polars.DataFrame
        ``scenario, seed, method, rmse, uwb_ls_rmse, ratio, finite, outage_max_error`` (m).
    """
    from uwbimu_rs import FILTERS

    chosen = [m for m in FILTERS if m != "uwb_ls"] if methods is None else list(methods)
    names = list(ZOO_NAMES) if scenarios is None else list(scenarios)
    plain = None if config is None else dict(config)
    return pl.DataFrame(_native.sim_zoo_matrix(chosen, names, list(seeds), start, settings, plain))
