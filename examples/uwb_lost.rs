//! Runs every inertial method on the zoo scenarios where UWB is lost (`still_tdoa_lost`,
//! `moving_uwb_lost`, issue 20) and prints, per method, start and seed: the horizontal error at
//! the end, the yaw swing and mean speed while UWB is there, the share of rows the still column
//! marks still, and the speed when UWB is lost. The table in docs/design-notes.md#uwb-lost comes
//! from it:
//!
//! ```text
//! cargo run --release --example uwb_lost                  # still_tdoa_lost, seeds 0..3
//! cargo run --release --example uwb_lost -- moving_uwb_lost 3
//! cargo run --release --example uwb_lost -- still_tdoa_lost 3 defaults   # config = None
//! ```
//!
//! In `still_tdoa_lost` the tightly coupled methods get the TDoA only, the loosely coupled ones
//! (which take no TDoA) the ranges of the same run.

use uwbimu_rs::app::methods::{run_method, BatchInput, BatchOutput, Method};
use uwbimu_rs::app::sim::{simulate, zoo};
use uwbimu_rs::vocabulary::config::FilterConfig;
use uwbimu_rs::vocabulary::math::Quat;
use uwbimu_rs::vocabulary::sensors::observations;

/// Heading of a body → navigation rotation, rad.
fn yaw(q: &Quat) -> f64 {
    q.euler_angles().2
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let name = args.first().map_or("still_tdoa_lost", String::as_str);
    let seeds: u64 = args.get(1).map_or(Ok(3), |s| s.parse())?;
    let defaults = args.get(2).is_some_and(|a| a == "defaults");
    let only: Option<Vec<Method>> =
        args.get(3).map(|list| list.split(',').map(Method::parse).collect::<Result<_, _>>()).transpose()?;
    println!("scenario {name}, seeds 0..{seeds}, config {}", if defaults { "defaults" } else { "matched" });
    println!("method  start  seed  final_m  max_m  yaw_swing_deg  speed_uwb_mps  speed_lost_mps  still_share  init");
    for &method in Method::ALL.iter().filter(|m| m.smoothable()) {
        if only.as_ref().is_some_and(|o| !o.contains(&method)) {
            continue;
        }
        let mut sums = [[0.0; 2]; 2];
        for seed in 0..seeds {
            let s = zoo(name, seed)?;
            let data = simulate(&s.sim)?;
            let config =
                if defaults { FilterConfig { mounting: s.config.mounting, ..FilterConfig::default() } } else { s.config.clone() };
            let truth_initial = s.true_initial(&data)?;
            let tdoa = method.takes_tdoa() && !data.tdoa.is_empty();
            for (k, initial) in [None, Some(&truth_initial)].into_iter().enumerate() {
                let input = BatchInput {
                    imu: &data.imu,
                    ranges: if tdoa { &[] } else { &data.ranges },
                    anchors: &data.anchors,
                    initial,
                    config: &config,
                    smooth: false,
                    observations: if tdoa { &observations(&data.tdoa) } else { &[] },
                    progress: None,
                    marginals_every_s: None,
                };
                let (trace, init) = match run_method(method, &input) {
                    Ok(BatchOutput::Inertial { trace, init, .. }) => (trace, init),
                    Ok(_) => unreachable!("an inertial method"),
                    Err(e) => {
                        println!("{:<7} {:<5} {seed:>4}  failed: {e}", method.name(), if k == 0 { "self" } else { "true" });
                        continue;
                    }
                };
                let t0 = data.imu[0].t_s;
                let uwb_end =
                    data.tdoa.last().map(|m| m.t_s).into_iter().chain(data.ranges.last().map(|r| r.t_s)).fold(t0, f64::max);
                let err = |i: usize| (trace.steps[i].state.position - data.truth[i].position).xy().norm();
                let last = trace.steps.len() - 1;
                let final_m = err(last);
                let max_m = (0..trace.steps.len()).map(err).fold(0.0, f64::max);
                let with_uwb: Vec<usize> =
                    (0..trace.steps.len()).filter(|&i| trace.steps[i].t_s >= t0 + 0.5 && trace.steps[i].t_s <= uwb_end).collect();
                let yaw_err = |i: usize| {
                    let e = yaw(&trace.steps[i].state.orientation) - yaw(&data.truth[i].orientation);
                    e.sin().atan2(e.cos())
                };
                let swing = with_uwb
                    .iter()
                    .map(|&i| yaw_err(i))
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), e| (lo.min(e), hi.max(e)));
                let speed_uwb =
                    with_uwb.iter().map(|&i| trace.steps[i].state.velocity.norm()).sum::<f64>() / with_uwb.len().max(1) as f64;
                let lost = trace.steps.iter().position(|s| s.t_s > uwb_end).unwrap_or(last);
                let speed_lost = trace.steps[lost].state.velocity.norm();
                let still_share = trace.steps.iter().filter(|s| s.still).count() as f64 / trace.steps.len() as f64;
                let heading = init.as_ref().map_or("-".to_string(), |i| format!("{:?} still={}", i.heading, i.still));
                println!(
                    "{:<7} {:<5} {seed:>4}  {final_m:>7.3}  {max_m:>5.2}  {:>13.1}  {speed_uwb:>13.3}  {speed_lost:>14.3}  {still_share:>11.2}  {heading}",
                    method.name(),
                    if k == 0 { "self" } else { "true" },
                    (swing.1 - swing.0).to_degrees(),
                );
                sums[k][0] += final_m;
                sums[k][1] += (swing.1 - swing.0).to_degrees();
            }
        }
        let n = seeds as f64;
        println!(
            "{:<7} mean final: self {:.3} m, true {:.3} m; mean yaw swing: self {:.1}°, true {:.1}°",
            method.name(),
            sums[0][0] / n,
            sums[1][0] / n,
            sums[0][1] / n,
            sums[1][1] / n
        );
    }
    Ok(())
}
