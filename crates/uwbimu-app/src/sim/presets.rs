//! The paper setups as simulator configurations (table in [`preset`]).
//!
//! Scenario 1 of Liu et al. 2019 starts the *filter* at (0.57, 0) while the robot is at (0, 0): that is an
//! initial-state error for the filter, not a simulator property, so it is not part of the preset.

use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::math::Vec3;

use crate::sim::{DriveOptions, ImuNoise, MagConfig, NlosConfig, RandomShielding, SimConfig, Trajectory, UwbConfig};

/// One preset: its `name` says what it simulates, `alias` is its former name (the number of the
/// paper's file), still accepted by [`preset`].
struct PresetRow {
    name: &'static str,
    alias: &'static str,
    build: fn(u64) -> Result<SimConfig>,
}

/// The presets, in the order of the table of [`preset`]; [`PRESET_NAMES`] and [`PRESET_ALIASES`]
/// are derived from these rows.
const PRESETS: [PresetRow; 8] = [
    PresetRow { name: "hall_vehicle_nlos", alias: "seed000", build: |seed| hall_vehicle(seed, true) },
    PresetRow { name: "hall_vehicle", alias: "seed000_los", build: |seed| hall_vehicle(seed, false) },
    PresetRow { name: "lab_robot", alias: "seed001", build: |seed| lab_robot(seed, false) },
    PresetRow { name: "lab_robot_nlos", alias: "seed001_nlos", build: |seed| lab_robot(seed, true) },
    PresetRow { name: "garage_rectangle", alias: "seed002_rectangle", build: |seed| garage(seed, false) },
    PresetRow { name: "garage_figure8", alias: "seed002_figure8", build: |seed| garage(seed, true) },
    PresetRow { name: "square_diagonal", alias: "seed004_s1", build: |seed| square_diagonal(seed, false) },
    PresetRow { name: "square_diagonal_outliers", alias: "seed004_s2", build: |seed| square_diagonal(seed, true) },
];

/// Names accepted by [`preset`], in the order of its table.
pub const PRESET_NAMES: [&str; PRESETS.len()] = column(false);

/// The former names, one per entry of [`PRESET_NAMES`] at the same index; [`preset`] takes them too.
pub const PRESET_ALIASES: [&str; PRESETS.len()] = column(true);

/// The names (or with `aliases` the former names) of [`PRESETS`], at compile time.
const fn column(aliases: bool) -> [&'static str; PRESETS.len()] {
    let mut out = [""; PRESETS.len()];
    let mut k = 0;
    while k < PRESETS.len() {
        out[k] = if aliases { PRESETS[k].alias } else { PRESETS[k].name };
        k += 1;
    }
    out
}

/// Standard gravity, m/s².
const G_MPS2: f64 = 9.80665;
/// Initial still period of every preset, s.
const STILL_S: f64 = 2.0;

/// The `hall_vehicle` anchors (m): corners of 10 m × 8 m at heights 0.8, 2.2, 1.2 and 1.8 m, so
/// that the height is observable by multilateration.
pub(crate) fn hall_anchors() -> Vec<Vec3> {
    vec![Vec3::new(0.0, 0.0, 0.8), Vec3::new(10.0, 0.0, 2.2), Vec3::new(10.0, 8.0, 1.2), Vec3::new(0.0, 8.0, 1.8)]
}

/// The garage site of the ARCKF paper (m): corners of 10 m × 5 m, brackets at 1.5 and 2.0 m.
fn garage_anchors() -> Vec<Vec3> {
    vec![Vec3::new(0.0, 0.0, 1.5), Vec3::new(10.0, 0.0, 2.0), Vec3::new(10.0, 5.0, 1.5), Vec3::new(0.0, 5.0, 2.0)]
}

/// x-IMU of the ARCKF paper's Table 1: 218 µg/√Hz and 0.01 °/s/√Hz; the ±50 mg zero offset taken as 3σ;
/// a calibrated gyro bias of 0.005 rad/s; small random walks.
fn x_imu() -> ImuNoise {
    ImuNoise {
        accel_noise_density: 218e-6 * G_MPS2,
        gyro_noise_density: 0.01_f64.to_radians(),
        accel_bias_std: 0.05 * G_MPS2 / 3.0,
        gyro_bias_std: 0.005,
        accel_bias_walk: 1e-4,
        gyro_bias_walk: 1e-5,
    }
}

fn hall_vehicle(seed: u64, nlos: bool) -> Result<SimConfig> {
    let imu_height_m = 0.40;
    let trajectory = Trajectory::figure_eight(Vec3::new(5.0, 4.0, imu_height_m), 3.5, 4.5, 37.0, 4, STILL_S)?;
    let uwb = if nlos {
        UwbConfig {
            nlos: Some(NlosConfig {
                random: Some(RandomShielding { start_s: STILL_S, ..RandomShielding::default() }),
                ..NlosConfig::default()
            }),
            outlier_prob: 0.01,
            dropout_prob: 0.02,
            ..UwbConfig::default()
        }
    } else {
        UwbConfig::default()
    };
    Ok(SimConfig { trajectory, anchors: hall_anchors(), uwb, seed, ..SimConfig::default() })
}

/// The Wang et al. 2018 laboratory (m): six anchors around a 4 m × 3 m area — the corners and the middle
/// of the long sides — alternately at 1.0 and 1.6 m.
fn lab_anchors() -> Vec<Vec3> {
    vec![
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::new(2.0, 0.0, 1.6),
        Vec3::new(4.0, 0.0, 1.0),
        Vec3::new(4.0, 3.0, 1.6),
        Vec3::new(2.0, 3.0, 1.0),
        Vec3::new(0.0, 3.0, 1.6),
    ]
}

/// Wang et al. 2018 §4: a small omnidirectional robot (IMU 0.20 m high, tag 5 cm above) driving a
/// figure-8 inside the 4 m × 3 m area (2 laps of 30 s, ≤ 0.4 m/s), six anchors, UWB at 40 Hz with
/// σ 0.0514 m (§3.1), a consumer MEMS IMU at 100 Hz (the MPU9250 class). NLOS: desks and chairs
/// shield 1–2 anchors at a time (windows of 3–8 s), each adding a bias of 0.1–0.6 m and 0.05 m of
/// extra noise, 10 % of the shielded ranges lost.
fn lab_robot(seed: u64, nlos: bool) -> Result<SimConfig> {
    let imu_height_m = 0.20;
    let trajectory = Trajectory::figure_eight(Vec3::new(2.0, 1.5, imu_height_m), 1.5, 1.1, 30.0, 2, STILL_S)?;
    let nlos = nlos.then(|| NlosConfig {
        random: Some(RandomShielding { start_s: STILL_S, ..RandomShielding::default() }),
        bias_min_m: 0.1,
        bias_max_m: 0.6,
        extra_std_m: 0.05,
        dropout_prob: 0.1,
        ..NlosConfig::default()
    });
    let uwb = UwbConfig { rate_hz: 40.0, range_std_m: 0.0514, nlos, ..UwbConfig::default() };
    Ok(SimConfig { trajectory, anchors: lab_anchors(), uwb, seed, ..SimConfig::default() })
}

fn garage(seed: u64, figure8: bool) -> Result<SimConfig> {
    let imu_height_m = 0.85;
    let (trajectory, uwb) = if figure8 {
        let traj = Trajectory::figure_eight(Vec3::new(5.0, 2.5, imu_height_m), 3.5, 3.0, 40.0, 2, STILL_S)?;
        let uwb = UwbConfig {
            outlier_prob: 0.1,
            outlier_min_m: 1.0,
            outlier_max_m: 8.0,
            outlier_anchors: vec![1, 3],
            ..UwbConfig::default()
        };
        (traj, uwb)
    } else {
        let opts = DriveOptions { speed_mps: 0.5, still_s: STILL_S, ..DriveOptions::default() };
        (Trajectory::rectangle(Vec3::new(1.0, 1.0, imu_height_m), 8.0, 3.0, 2, &opts)?, UwbConfig::default())
    };
    Ok(SimConfig { trajectory, imu_noise: x_imu(), anchors: garage_anchors(), uwb, seed, ..SimConfig::default() })
}

fn square_diagonal(seed: u64, outliers: bool) -> Result<SimConfig> {
    let opts = DriveOptions { speed_mps: 0.4, still_s: STILL_S, ..DriveOptions::default() };
    let trajectory = Trajectory::diagonal(Vec3::zeros(), Vec3::new(-4.0, 4.0, 0.0), &opts)?;
    let anchors =
        vec![Vec3::new(-5.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(1.0, 5.0, 0.0), Vec3::new(-5.0, 5.0, 0.0)];
    // Per-sample std 0.06 at 100 Hz (§4.1) → density 0.006 /√Hz; biases drift ("random walk").
    let imu_noise = ImuNoise {
        accel_noise_density: 0.006,
        gyro_noise_density: 0.006,
        accel_bias_std: 0.02,
        gyro_bias_std: 0.002,
        accel_bias_walk: 1e-3,
        gyro_bias_walk: 1e-4,
    };
    let uwb = UwbConfig {
        rate_hz: 5.0,
        range_std_m: 0.1,
        uniform_noise_m: 0.2,
        outlier_prob: if outliers { 0.1 } else { 0.0 },
        ..UwbConfig::default()
    };
    Ok(SimConfig {
        trajectory,
        imu_noise,
        lever_arm_m: Vec3::zeros(),
        anchors,
        uwb,
        magnetometer: Some(MagConfig::default()),
        seed,
        ..SimConfig::default()
    })
}

/// The configuration of a named paper setup; `seed` seeds all noise.
///
/// | preset (alias) | setup |
/// |---|---|
/// | `hall_vehicle_nlos` (`seed000`) | Li & Wang 2020 §3: 4 anchors in a ~10 m × 8 m hall at 0.8–2.2 m, figure-8 ×4 (37 s laps, ≤ 1 m/s), tag 0.45 m high (IMU 5 cm below), UWB 2 Hz σ 0.1 m, IMU 100 Hz consumer MEMS, 1–2 anchors randomly shielded (bias 0.3–1.5 m), 1 % outliers, 2 % dropouts |
/// | `hall_vehicle` (`seed000_los`) | `hall_vehicle_nlos` without NLOS, outliers or dropouts |
/// | `lab_robot` (`seed001`) | Wang et al. 2018 §4: six anchors around a 4 m × 3 m lab (corners and mid long sides, 1.0 / 1.6 m), figure-8 ×2 (30 s laps) of a small robot (IMU 0.20 m, tag 5 cm above), UWB 40 Hz σ 0.0514 m, IMU 100 Hz consumer MEMS |
/// | `lab_robot_nlos` (`seed001_nlos`) | `lab_robot` with 1–2 anchors at a time shielded by furniture: bias 0.1–0.6 m, +0.05 m noise, 10 % of shielded ranges lost |
/// | `garage_rectangle` (`seed002_rectangle`) | the ARCKF paper's §4: 10 m × 5 m site, 4 anchors at 1.5/2.0 m, 8 m × 3 m rectangle ×2 at 0.5 m/s, UWB 2 Hz, IMU 100 Hz with Table 1 densities |
/// | `garage_figure8` (`seed002_figure8`) | same site, figure-8 ×2 (40 s laps); 10 % outliers U(1, 8) m on beacons 2 and 4 (§4.2) |
/// | `square_diagonal` (`seed004_s1`) | Liu et al. 2019 §4.1: anchors (−5,−1), (1,−1), (1,5), (−5,5) and tag at z = 0, diagonal (0,0) → (−4,4) of a 4 m square at 0.4 m/s, UWB 5 Hz σ 0.1 m + U(−0.2, 0.2), IMU 100 Hz with per-sample std 0.06, magnetometer on |
/// | `square_diagonal_outliers` (`seed004_s2`) | `square_diagonal` plus 10 % gross outliers U(1, 5) m |
///
///
/// Liu et al. 2019 scenario 1 starts the *filter* at (0.57, 0) while the robot is at (0, 0): an initial
/// filter error, not a simulator property, so it is not part of the preset.
///
/// A name or its alias; an unknown name → [`Error::UnknownOption`] listing [`PRESET_NAMES`].
pub fn preset(name: &str, seed: u64) -> Result<SimConfig> {
    match PRESETS.iter().find(|row| name == row.name || name == row.alias) {
        Some(row) => (row.build)(seed),
        None => Err(Error::unknown_option("preset", name, PRESET_NAMES.iter().chain(&PRESET_ALIASES).copied())),
    }
}
