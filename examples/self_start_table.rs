//! Prints the self-initialised consistency of the methods (`uwbimu_rs::app::consistency`,
//! self-initialised scenarios): per scenario, when the filter started, how many runs had their
//! heading within 3σ of the σ they reported at the start, the heading error 5 s later and the
//! attitude NEES over the 20 s after the start with its 99 % interval. The tables of
//! docs/heading.md come from it:
//!
//! ```text
//! cargo run --release --example self_start_table                    # best, ekf, riekf; 32 runs
//! cargo run --release --example self_start_table -- 32 all          # every inertial method
//! ```

use uwbimu_rs::app::consistency::{self_start_inputs, self_start_monte_carlo, SELF_START_SCENARIOS};
use uwbimu_rs::app::generality::Settings;
use uwbimu_rs::app::methods::Method;

type Res<T> = Result<T, Box<dyn std::error::Error>>;

fn main() -> Res<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let runs: u64 = args.first().map_or(Ok(32), |s| s.parse())?;
    let methods: Vec<Method> = match args.get(1).map(String::as_str) {
        Some("all") => Method::ALL.iter().copied().filter(|m| *m != Method::UwbLs).collect(),
        Some(list) => list.split(',').map(Method::parse).collect::<Result<_, _>>()?,
        None => vec![Method::Best, Method::Ekf, Method::Riekf],
    };
    let seeds: Vec<u64> = (0..runs).collect();
    println!("| scenario | method | start, s (mean) | within 3σ at the start | heading error 5 s later, ° (mean / max) | attitude NEES (pooled) [99 % interval] |");
    println!("|---|---|---|---|---|---|");
    for name in SELF_START_SCENARIOS {
        let takes: Vec<Method> =
            methods.iter().copied().filter(|m| self_start_inputs(name).iter().all(|i| m.takes(*i))).collect();
        for r in self_start_monte_carlo(&takes, name, &seeds, Settings::Matched)? {
            let n = r.starts.len() as f64;
            let within = r.starts.iter().filter(|s| s.within_3_sigma()).count();
            let decided = r.starts.iter().map(|s| s.decided_s).sum::<f64>() / n;
            let e5: Vec<f64> = r.heading_error_5s_rad.iter().map(|e| e.abs().to_degrees()).collect();
            let (lo, hi) = r.attitude.interval(0.01)?;
            println!(
                "| {name} | {} | {decided:.1} | {within}/{} | {:.2} / {:.2} | {:.2} [{lo:.2}, {hi:.2}] |",
                r.method.name(),
                r.starts.len(),
                e5.iter().sum::<f64>() / n,
                e5.iter().copied().fold(0.0, f64::max),
                r.attitude.pooled(),
            );
        }
    }
    Ok(())
}
