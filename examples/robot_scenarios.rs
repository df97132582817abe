//! Every method on the scenarios of the robot loop (TDoA with per-pair biases and impossible
//! values, UWB lost after the first second): horizontal RMSE against the truth, the final error,
//! the error that ended the run, or "no estimate" when a method gives none after the start-up
//! (`uwb_ls` once UWB is lost). Regenerates the tables of docs/streaming.md:
//!
//! ```text
//! cargo run --release --example robot_scenarios [scenario,…] [seeds]
//! ```
//!
//! A scenario with TDoA is run on its TDoA alone by the methods that take TDoA and on its ranges
//! by the others; the start is self-initialised (`self`) and the truth (`given`).

use uwbimu_rs::app::methods::{run_method, BatchInput, BatchOutput, Method};
use uwbimu_rs::app::sim::{simulate, zoo};
use uwbimu_rs::vocabulary::sensors::observations;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scenarios = args.first().map_or("tdoa_drone", String::as_str);
    let seeds: u64 = args.get(1).map_or(Ok(3), |s| s.parse())?;
    for name in scenarios.split(',') {
        println!("## {name} (mean of seeds 0–{}; RMSE / final horizontal error, m)\n", seeds - 1);
        println!("| method | input | given: RMSE | given: final | self: RMSE | self: final |");
        println!("|---|---|---|---|---|---|");
        for &method in Method::ALL {
            let mut cells = Vec::new();
            let mut input_name = "ranges";
            for given in [true, false] {
                let (mut rmse, mut last, mut failed, mut unscored) = (0.0, 0.0, None, false);
                for seed in 0..seeds {
                    let s = zoo(name, seed)?;
                    let data = simulate(&s.sim)?;
                    let tdoa = !data.tdoa.is_empty() && method.takes_tdoa();
                    input_name = if tdoa { "tdoa" } else { "ranges" };
                    let initial = s.true_initial(&data)?;
                    let input = BatchInput {
                        imu: &data.imu,
                        ranges: if tdoa { &[] } else { &data.ranges },
                        anchors: &data.anchors,
                        initial: given.then_some(&initial),
                        config: &s.config,
                        smooth: false,
                        observations: if tdoa { &observations(&data.tdoa) } else { &[] },
                        progress: None,
                        marginals_every_s: None,
                    };
                    let (steps, positions): (Vec<f64>, Vec<_>) = match run_method(method, &input) {
                        Ok(BatchOutput::Inertial { trace, .. }) => trace
                            .steps
                            .iter()
                            .map(|r| (r.t_s, r.state.position + r.state.orientation * s.config.mounting.lever_arm.first()))
                            .unzip(),
                        Ok(BatchOutput::Multilateration(fixes)) => fixes.iter().map(|(t, f)| (*t, f.position)).unzip(),
                        Err(e) => {
                            failed = Some(e.to_string());
                            break;
                        }
                    };
                    let t0 = data.imu[0].t_s + if given { 0.0 } else { 5.0 };
                    let errors: Vec<f64> = steps
                        .iter()
                        .zip(&positions)
                        .filter(|(t, _)| **t >= t0)
                        .map(|(t, p)| {
                            let k = data.truth.partition_point(|g| g.t_s < *t).min(data.truth.len() - 1);
                            let g = &data.truth[k];
                            (p - (g.position + g.orientation * s.sim.lever_arm_m)).xy().norm()
                        })
                        .collect();
                    if errors.is_empty() {
                        unscored = true; // no estimate after the start-up (uwb_ls once UWB is lost)
                        break;
                    }
                    let n = errors.len() as f64;
                    rmse += (errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt() / seeds as f64;
                    last += errors.last().copied().unwrap_or_default() / seeds as f64;
                }
                match failed {
                    Some(e) => cells.push(format!("error: {} | – ", e.chars().take(60).collect::<String>())),
                    None if unscored => cells.push("no estimate | –".to_string()),
                    None => cells.push(format!("{rmse:.3} | {last:.3}")),
                }
            }
            println!("| {} | {input_name} | {} | {} |", method.name(), cells[0], cells[1]);
        }
        println!();
    }
    Ok(())
}
