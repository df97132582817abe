//! The tables of docs/altitude.md and docs/odometry.md: what an altitude sensor and wheel
//! odometry add, on scenarios built for them and on zoo scenarios built before them, each with
//! and without the sensor, mean over seeds, the filter started from the truth.
//!
//! ```text
//! cargo run --release --example sensor_tables -- altitude [seeds] [method,…]
//! cargo run --release --example sensor_tables -- odometry [seeds] [method,…]
//! cargo run --release --example sensor_tables -- tags [seeds] [method,…]
//! ```
//!
//! - **altitude**: coplanar anchors, where the ranges barely fix the height: the hall figure-8
//!   under four anchors at 2.2 m (the consistency scenario `coplanar_altitude`), the zoo's
//!   `stop_and_go` (four anchors at 2.6 m) and `outliers` (eight at 2.8 m, 7 % outliers); a
//!   time-of-flight sensor (σ 0.05 m, 25 Hz) and a barometer whose offset starts at 0.3 m and
//!   wanders by 0.02 m/√s, not modelled, and with the offset state (`altitude.offset_std` 0.5 m,
//!   `offset_walk` the true 0.02 m/√s). Vertical and horizontal RMSE.
//! - **odometry**: a ground vehicle losing UWB for 20, 40 and 60 s: the hall figure-8 (four laps),
//!   the zoo's `agv_loop` and `forklift` (IMU mounted z down, declared); wheel speed along x
//!   (σ 0.05 m/s, 50 Hz), and with the lateral and vertical velocity too. Horizontal RMSE and
//!   largest error inside the outage, and RMSE over the whole run.
//! - **tags**: a second tag 0.3, 0.5 or 1 m ahead of the first (body x) against one tag, on the
//!   hall figure-8 (four anchors) and the zoo's `agv_loop` (eight) and `forklift`: started from
//!   the truth with the heading 0.3 rad off (told σ 0.5 rad), the heading error at 2 s and 5 s and
//!   its RMSE after 5 s, and the horizontal RMSE; self-initialised, the heading error 5 s and 10 s
//!   after the start and the horizontal RMSE after 10 s.

use uwbimu_rs::app::methods::{run_method, BatchInput, BatchOutput, Input, Method};
use uwbimu_rs::app::sim::{
    lever_arms_seen, matched_config, simulate, true_initial, zoo, AltimeterConfig, OdometerConfig, Outage, SimConfig, SimData,
    Trajectory,
};
use uwbimu_rs::estimation::filters::Ekf;
use uwbimu_rs::estimation::pipeline::{Builder, Stream, StreamOptions, Streams};
use uwbimu_rs::vocabulary::config::{FilterConfig, InitialState};
use uwbimu_rs::vocabulary::math::{Quat, Vec3};

type Res<T> = Result<T, Box<dyn std::error::Error>>;

/// The methods of the tables unless others are named.
const METHODS: &str = "ekf,riekf,best";

/// Per step: time, estimated and true body-origin position.
type Track = Vec<(f64, Vec3, Vec3)>;

/// Runs `method` forward on `data` from the truth, with the observations of the sensors in
/// `sensors` (all that the method takes when true).
fn track(method: Method, sim: &SimConfig, config: &FilterConfig, data: &SimData, sensors: bool) -> Res<Track> {
    let initial = true_initial(sim, config, data)?;
    let observations = data.observations_for(|k| sensors && method.takes(Input::Sensor(k)));
    let input = BatchInput {
        initial: Some(&initial),
        observations: &observations,
        ..BatchInput::forward(&data.imu, &data.ranges, &data.anchors, config)
    };
    let BatchOutput::Inertial { trace, .. } = run_method(method, &input)? else { return Err("not inertial".into()) };
    Ok(trace.steps.iter().zip(&data.truth).map(|(s, t)| (s.t_s, s.state.position, t.position)).collect())
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    (sum / n.max(1) as f64).sqrt()
}

/// A zoo scenario's simulator and filter configuration, seed `seed`, with `edit` applied to the
/// simulator and the configuration matched to the sensors afterwards (its mounting kept).
fn zoo_run(name: &str, seed: u64, edit: impl Fn(&mut SimConfig)) -> Res<(SimConfig, FilterConfig)> {
    let s = zoo(name, seed)?;
    let mut sim = s.sim;
    edit(&mut sim);
    let config = FilterConfig { mounting: s.config.mounting, ..matched_config(&sim) };
    Ok((sim, config))
}

/// The hall figure-8 at 0.4 m (`laps` laps of 37 s after 2 s still), seed `seed`.
fn hall_run(seed: u64, laps: u32, edit: impl Fn(&mut SimConfig)) -> Res<(SimConfig, FilterConfig)> {
    let mut sim = SimConfig {
        trajectory: Trajectory::figure_eight(Vec3::new(5.0, 4.0, 0.4), 3.5, 4.5, 37.0, laps, 2.0)?,
        seed,
        ..SimConfig::default()
    };
    edit(&mut sim);
    let config = matched_config(&sim);
    Ok((sim, config))
}

fn altitude(seeds: u64, methods: &[Method]) -> Res<()> {
    let coplanar = |sim: &mut SimConfig| sim.anchors.iter_mut().for_each(|a| a.z = 2.2);
    let tof = AltimeterConfig::default();
    let baro = AltimeterConfig { offset_m: 0.3, offset_walk: 0.02, ..AltimeterConfig::default() };
    println!("| scenario | altitude | method | z RMSE without → with (m) | horizontal RMSE without → with (m) |");
    println!("|---|---|---|---|---|");
    for scenario in ["hall, 4 coplanar at 2.2 m", "stop_and_go", "outliers"] {
        let sensors = [
            ("time of flight", &tof, false),
            ("barometer, offset 0.3 m + 0.02 m/√s, not modelled", &baro, false),
            ("barometer, offset 0.3 m + 0.02 m/√s, offset state", &baro, true),
        ];
        for (sensor, altimeter, offset_state) in sensors {
            for &method in methods {
                let mut sums = [0.0; 4];
                for seed in 0..seeds {
                    let edit = |sim: &mut SimConfig| sim.altimeter = Some(altimeter.clone());
                    let (sim, mut config) = match scenario {
                        "stop_and_go" | "outliers" => zoo_run(scenario, seed, edit)?,
                        _ => hall_run(seed, 2, |sim| {
                            coplanar(sim);
                            edit(sim);
                        })?,
                    };
                    if offset_state {
                        (config.sensors.altitude.offset_std, config.sensors.altitude.offset_walk) = (0.5, altimeter.offset_walk);
                    }
                    let data = simulate(&sim)?;
                    for (k, with) in [false, true].into_iter().enumerate() {
                        let t = track(method, &sim, &config, &data, with)?;
                        sums[k] += rms(t.iter().map(|(_, e, x)| e.z - x.z));
                        sums[2 + k] += rms(t.iter().map(|(_, e, x)| (e - x).xy().norm()));
                    }
                }
                let m = |k: usize| sums[k] / seeds as f64;
                println!("| {scenario} | {sensor} | {} | {:.3} → {:.3} | {:.3} → {:.3} |", method.name(), m(0), m(1), m(2), m(3));
            }
        }
    }
    Ok(())
}

fn odometry(seeds: u64, methods: &[Method]) -> Res<()> {
    println!("| scenario | outage (s) | method | odometry | in the outage: RMSE / largest (m) | whole run RMSE (m) |");
    println!("|---|---|---|---|---|---|");
    let wheel = OdometerConfig::default();
    let full = OdometerConfig { lateral: true, ..OdometerConfig::default() };
    for scenario in ["hall figure-8", "agv_loop", "forklift"] {
        for outage_s in [20.0, 40.0, 60.0] {
            for &method in methods {
                for (label, odometer) in [("none", None), ("speed (x)", Some(&wheel)), ("x, y, z", Some(&full))] {
                    let (mut in_rmse, mut in_max, mut whole) = (0.0, 0.0, 0.0);
                    let mut skipped = false;
                    for seed in 0..seeds {
                        let edit = |sim: &mut SimConfig| {
                            let start_s = sim.start_s + 10.0;
                            sim.uwb.outages.push(Outage { start_s, end_s: start_s + outage_s });
                            sim.odometer = odometer.cloned().or(Some(wheel.clone()));
                        };
                        let (sim, config) = match scenario {
                            "agv_loop" | "forklift" => zoo_run(scenario, seed, edit)?,
                            _ => hall_run(seed, 4, edit)?,
                        };
                        let window = (sim.start_s + 10.0, sim.start_s + 10.0 + outage_s);
                        if window.1 + 5.0 > sim.trajectory.duration_s() {
                            skipped = true;
                            break;
                        }
                        let data = simulate(&sim)?;
                        let t = track(method, &sim, &config, &data, odometer.is_some())?;
                        let inside: Vec<f64> = t
                            .iter()
                            .filter(|(s, ..)| (window.0..window.1).contains(s))
                            .map(|(_, e, x)| (e - x).xy().norm())
                            .collect();
                        in_rmse += rms(inside.iter().copied());
                        in_max += inside.iter().fold(0.0_f64, |m, e| m.max(*e));
                        whole += rms(t.iter().map(|(_, e, x)| (e - x).xy().norm()));
                    }
                    if skipped {
                        continue;
                    }
                    let n = seeds as f64;
                    println!(
                        "| {scenario} | {outage_s:.0} | {} | {label} | {:.2} / {:.2} | {:.3} |",
                        method.name(),
                        in_rmse / n,
                        in_max / n,
                        whole / n
                    );
                }
            }
        }
    }
    Ok(())
}

/// Heading error (rad, navigation z of `est · truth⁻¹`, the truth in the filter's body frame) and
/// horizontal error (m) per IMU step of a run of `method` on `data` (of `sim`) from `initial`
/// (None: self-initialised).
fn heading_track(
    method: Method,
    sim: &SimConfig,
    config: &FilterConfig,
    data: &SimData,
    initial: Option<&InitialState>,
) -> Res<Vec<(f64, f64, f64)>> {
    let body_from_filter_body = sim.imu_rotation * config.mounting.imu_rotation.inverse();
    let input = BatchInput { initial, ..BatchInput::forward(&data.imu, &data.ranges, &data.anchors, config) };
    let BatchOutput::Inertial { trace, .. } = run_method(method, &input)? else { return Err("not inertial".into()) };
    let truth = |t: f64| &data.truth[data.truth.partition_point(|s| s.t_s < t).min(data.truth.len() - 1)];
    Ok(trace
        .steps
        .iter()
        .map(|s| {
            let x = truth(s.t_s);
            let heading = (s.state.orientation * (x.orientation * body_from_filter_body).inverse()).scaled_axis().z;
            (s.t_s, heading, (s.state.position - x.position).xy().norm())
        })
        .collect())
}

/// Seconds from the first IMU sample until a self-initialising stream (an `ekf`) has started on
/// `data`, and where its heading came from.
fn start_after(config: &FilterConfig, data: &SimData) -> Res<(f64, &'static str)> {
    let anchors = data.anchors.clone();
    let build: Builder<Ekf> = {
        let (anchors, config) = (anchors.clone(), config.clone());
        Box::new(move |initial: &InitialState| Ekf::new(anchors.clone(), initial, config.clone()))
    };
    let mut stream = Stream::self_initializing(anchors, config.clone(), build, StreamOptions::default())?;
    let streams = Streams { imu: &data.imu, ranges: &data.ranges, ..Streams::default() };
    for event in streams.events() {
        let t = event.t_s();
        stream.push("start_after", event)?;
        if let Some(init) = stream.self_init() {
            return Ok((t - data.imu[0].t_s, init.heading.name()));
        }
    }
    Err("never started".into())
}

fn tags(seeds: u64, methods: &[Method]) -> Res<()> {
    println!("| scenario | method | tags | from the truth, heading 0.3 rad off: heading error at 2 s / 5 s (°), RMSE after 5 s (°); horizontal RMSE (m) | self-initialised: started after (s), heading from; heading error at 5 s / 10 s (°); horizontal RMSE after 10 s (m) |");
    println!("|---|---|---|---|---|");
    for scenario in ["hall figure-8", "agv_loop", "forklift"] {
        for &method in methods {
            for separation in [0.0, 0.3, 0.5, 1.0] {
                let (mut sums, mut sources) = ([0.0; 8], std::collections::BTreeMap::<&str, usize>::new());
                for seed in 0..seeds {
                    let edit = |sim: &mut SimConfig| {
                        sim.more_tags_m =
                            if separation > 0.0 { vec![sim.lever_arm_m + Vec3::new(separation, 0.0, 0.0)] } else { Vec::new() };
                    };
                    let (sim, config) = match scenario {
                        "agv_loop" | "forklift" => zoo_run(scenario, seed, edit)?,
                        _ => hall_run(seed, 2, edit)?,
                    };
                    let mut config = config;
                    config.mounting.lever_arm = lever_arms_seen(&sim, &config.mounting.imu_rotation);
                    let data = simulate(&sim)?;
                    let t0 = data.imu[0].t_s;
                    let mut initial = true_initial(&sim, &config, &data)?;
                    initial.orientation = Quat::from_axis_angle(&Vec3::z_axis(), 0.3) * initial.orientation;
                    initial.orientation_std.z = 0.5;
                    let at = |track: &[(f64, f64, f64)], t: f64| {
                        track.iter().find(|s| s.0 >= t0 + t).map_or(f64::NAN, |s| s.1.abs().to_degrees())
                    };
                    let from = heading_track(method, &sim, &config, &data, Some(&initial))?;
                    let after = |t: f64| move |s: &&(f64, f64, f64)| s.0 >= t0 + t;
                    sums[0] += at(&from, 2.0);
                    sums[1] += at(&from, 5.0);
                    sums[2] += rms(from.iter().filter(after(5.0)).map(|s| s.1)).to_degrees();
                    sums[3] += rms(from.iter().filter(after(5.0)).map(|s| s.2));
                    let own = heading_track(method, &sim, &config, &data, None)?;
                    sums[4] += at(&own, 5.0);
                    sums[5] += at(&own, 10.0);
                    sums[6] += rms(own.iter().filter(after(10.0)).map(|s| s.2));
                    let (started, source) = start_after(&config, &data)?;
                    sums[7] += started;
                    *sources.entry(source).or_default() += 1;
                }
                let sources: Vec<String> = sources.iter().map(|(k, n)| format!("{k} {n}")).collect();
                let m = |k: usize| sums[k] / seeds as f64;
                let label = if separation > 0.0 { format!("two, {separation} m apart") } else { "one".into() };
                println!(
                    "| {scenario} | {} | {label} | {:.1} / {:.1}, {:.2}; {:.3} | {:.1} s, {}; {:.1} / {:.1}; {:.3} |",
                    method.name(),
                    m(0),
                    m(1),
                    m(2),
                    m(3),
                    m(7),
                    sources.join(", "),
                    m(4),
                    m(5),
                    m(6)
                );
            }
        }
    }
    Ok(())
}

fn main() -> Res<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let seeds: u64 = args.get(1).map_or(Ok(8), |s| s.parse())?;
    let methods = args.get(2).map_or(METHODS, String::as_str).split(',').map(Method::parse).collect::<Result<Vec<_>, _>>()?;
    match args.first().map(String::as_str) {
        Some("altitude") => altitude(seeds, &methods),
        Some("odometry") => odometry(seeds, &methods),
        Some("tags") => tags(seeds, &methods),
        _ => Err("usage: sensor_tables altitude|odometry|tags [seeds] [method,…]".into()),
    }
}
