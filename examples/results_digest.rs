//! Prints one line per run of a comparison set — every method × zoo scenarios × seeds × given or
//! self-initialised start (and smoothed, where the method smooths) — with a 64-bit FNV-1a digest
//! of what the run returned (every recorded state, covariance, report and the
//! self-initialisation; [`described`]), formatted with `{:?}` (shortest round-trip `f64`s, so two digests agree
//! only when the outputs agree bit for bit). A refactor that must not change results is checked
//! by diffing this output before and after:
//!
//! ```text
//! cargo run --release --example results_digest > before.txt
//! # ... change ...
//! cargo run --release --example results_digest > after.txt && diff before.txt after.txt
//! ```
//!
//! Arguments (optional): the scenarios, comma-separated (default
//! `outliers,outage,nlos_two,mixed_rates,forklift,imu_z_down,tdoa_drone,agv_loop+mag`; a `+mag`
//! suffix adds the simulator's magnetometer), and the number of seeds (default 2). Each method
//! gets the TDoA and the magnetometer of the run when it takes them.

use uwbimu_rs::app::methods::{run_method, BatchInput, BatchOutput, Input, Method};
use uwbimu_rs::app::sim::{simulate, zoo, MagConfig};
use uwbimu_rs::vocabulary::config::FilterConfig;

/// FNV-1a over the bytes of `text`.
fn fnv1a(text: &str) -> u64 {
    text.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// What a run returned, as text: for an inertial run its steps, its updates, its health (the
/// gate's counts by kind, those not zero), self-initialisation, smoothed steps, warnings and
/// model choice (its candidates and verdict: the configuration it runs is the input's with the
/// chosen candidate's overrides); for `uwb_ls` its fixes.
fn described(out: &BatchOutput) -> String {
    match out {
        BatchOutput::Inertial { trace, init, smoothed, warnings, model } => {
            let updates: Vec<_> = trace
                .updates
                .iter()
                .filter(|u| u.measured.sensor() != "magnetometer")
                .map(|u| (u.t_s, u.epoch_t_s, u.report))
                .collect();
            let h = &trace.health;
            let rejected: Vec<_> = h.rejected.by_kind().filter(|(_, n)| *n > 0).map(|(k, n)| (k.name(), n)).collect();
            let counts = (h.numerical_repairs, h.ranges_before_start, h.reordered, h.late_dropped, h.smoothing_left_out);
            let model = model.as_ref().map(|m| (&m.candidates, m.chosen, &m.reason));
            format!("{:?} {updates:?} {rejected:?} {counts:?} {init:?} {smoothed:?} {warnings:?} {model:?}", trace.steps)
        }
        fixes => format!("{fixes:?}"),
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scenarios =
        args.first().map_or("outliers,outage,nlos_two,mixed_rates,forklift,imu_z_down,tdoa_drone,agv_loop+mag", String::as_str);
    let seeds: u64 = args.get(1).map_or(Ok(2), |s| s.parse())?;
    for scenario in scenarios.split(',') {
        for seed in 0..seeds {
            let (name, with_mag) = match scenario.strip_suffix("+mag") {
                Some(name) => (name, true),
                None => (scenario, false),
            };
            let mut s = zoo(name, seed)?;
            if with_mag {
                s.sim.magnetometer = Some(MagConfig::default());
            }
            let data = simulate(&s.sim)?;
            let initial = s.true_initial(&data)?;
            let config = FilterConfig { mounting: s.config.mounting, ..FilterConfig::default() };
            for &method in Method::ALL {
                for given in [true, false] {
                    for smooth in [false, true] {
                        if smooth && !method.smoothable() {
                            continue;
                        }
                        let input = BatchInput {
                            imu: &data.imu,
                            ranges: &data.ranges,
                            anchors: &data.anchors,
                            initial: given.then_some(&initial),
                            config: &config,
                            smooth,
                            observations: &data.observations_for(|kind| method.takes(Input::Sensor(kind))),
                            progress: None,
                            marginals_every_s: None,
                        };
                        let digest = match run_method(method, &input) {
                            Ok(out) => format!("{:016x}", fnv1a(&described(&out))),
                            Err(e) => format!("error: {e}"),
                        };
                        let start = if given { "given" } else { "self" };
                        println!("{scenario} {seed} {} {start} smooth={smooth} {digest}", method.name());
                    }
                }
            }
        }
    }
    Ok(())
}
