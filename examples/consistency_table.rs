//! Prints the Monte Carlo consistency of every method on the consistency scenarios
//! (`uwbimu_rs::app::consistency`), with the simulator's true noise: the NEES of position,
//! velocity and attitude averaged over runs and sample times, the NIS, and the mean horizontal
//! RMSE with the true noise and with the library defaults. The tables in
//! docs/testing.md#consistency come from it:
//!
//! ```text
//! cargo run --release --example consistency_table                      # per method, 40 runs
//! cargo run --release --example consistency_table -- 40 full           # per method and scenario
//! cargo run --release --example consistency_table -- 24 full moving_start
//! ```
//!
//! A scenario with a sensor besides UWB runs the methods that take it
//! (`uwbimu_rs::app::consistency::runs_on`). The summary gives, per method, the smallest and
//! largest pooled figure over the scenarios it runs on but `heading_uncertain` (the start pose known to 3°), then that scenario's (heading known to 11°);
//! the full table each scenario with the 99 % χ² interval of the pooled NEES and NIS and how many
//! sample times fall outside the 99 % interval of a single time.

use uwbimu_rs::app::consistency::{monte_carlo, runs_on, Consistency, NeesSeries, SCENARIOS};
use uwbimu_rs::app::generality::Settings;
use uwbimu_rs::app::methods::Method;

type Res<T> = Result<T, Box<dyn std::error::Error>>;

/// `mean [lo, hi] k/K` of a NEES series at 99 %: pooled, its interval, the times outside.
fn full_cell(series: Option<&NeesSeries>) -> Res<String> {
    let Some(s) = series else { return Ok("—".into()) };
    let (lo, hi) = s.interval(0.01)?;
    Ok(format!("{:.2} [{lo:.2}, {hi:.2}] {}/{}", s.pooled(), s.outside(0.01)?.len(), s.mean.len()))
}

/// `min–max` of the figures `values` over scenarios (one figure when they agree to 2 decimals).
fn range(values: &[f64], digits: usize) -> String {
    if values.is_empty() {
        return "—".into();
    }
    let (lo, hi) = values.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(*v), hi.max(*v)));
    let (lo, hi) = (format!("{lo:.digits$}"), format!("{hi:.digits$}"));
    if lo == hi {
        lo
    } else {
        format!("{lo}–{hi}")
    }
}

/// The pooled figures of one block of `runs`.
fn pooled(runs: &[&Consistency], block: impl Fn(&Consistency) -> Option<f64>) -> Vec<f64> {
    runs.iter().filter_map(|c| block(c)).collect()
}

fn main() -> Res<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let runs: u64 = args.first().map_or(Ok(40), |s| s.parse())?;
    let full = args.get(1).is_some_and(|a| a == "full");
    let scenarios: Vec<&str> = match args.get(2) {
        Some(name) => vec![name.as_str()],
        None => SCENARIOS.to_vec(),
    };
    let seeds: Vec<u64> = (0..runs).collect();
    let mut results: Vec<(Vec<Consistency>, Vec<Consistency>)> = Vec::new();
    for name in &scenarios {
        let methods: Vec<Method> = Method::ALL.iter().copied().filter(|m| runs_on(*m, name)).collect();
        results.push((
            monte_carlo(&methods, name, &seeds, Settings::Matched)?,
            monte_carlo(&methods, name, &seeds, Settings::Defaults)?,
        ));
    }
    if full {
        println!("| scenario | method | NEES position | NEES velocity | NEES attitude | NIS | RMSE true noise / defaults (m) |");
        println!("|---|---|---|---|---|---|---|");
        for (name, (true_noise, defaults)) in scenarios.iter().zip(&results) {
            for (c, d) in true_noise.iter().zip(defaults) {
                let nis = match c.nis {
                    Some(n) => {
                        let (lo, hi) = n.interval(0.01)?;
                        format!("{:.3} [{lo:.3}, {hi:.3}]", n.mean)
                    }
                    None => "—".into(),
                };
                println!(
                    "| {name} | {} | {} | {} | {} | {nis} | {:.3} / {:.3} |",
                    c.method.name(),
                    full_cell(Some(&c.position))?,
                    full_cell(c.velocity.as_ref())?,
                    full_cell(c.attitude.as_ref())?,
                    c.mean_rmse_m(),
                    d.mean_rmse_m()
                );
            }
        }
        return Ok(());
    }
    println!("| method | NEES position | NEES velocity | NEES attitude | NIS | attitude, heading σ 0.2 rad | RMSE true noise / defaults |");
    println!("|---|---|---|---|---|---|---|");
    for method in Method::ALL {
        let (mut main, mut uncertain) = (Vec::new(), Vec::new());
        let mut ratios = Vec::new();
        for (name, (true_noise, defaults)) in scenarios.iter().zip(&results) {
            let Some(k) = true_noise.iter().position(|c| c.method == *method) else { continue };
            if *name == "heading_uncertain" {
                uncertain.push(&true_noise[k]);
            } else {
                main.push(&true_noise[k]);
                ratios.push(true_noise[k].mean_rmse_m() / defaults[k].mean_rmse_m());
            }
        }
        println!(
            "| {} | {} | {} | {} | {} | {} | {} |",
            method.name(),
            range(&pooled(&main, |c| Some(c.position.pooled())), 2),
            range(&pooled(&main, |c| c.velocity.as_ref().map(NeesSeries::pooled)), 2),
            range(&pooled(&main, |c| c.attitude.as_ref().map(NeesSeries::pooled)), 2),
            range(&pooled(&main, |c| c.nis.map(|n| n.mean)), 3),
            range(&pooled(&uncertain, |c| c.attitude.as_ref().map(NeesSeries::pooled)), 2),
            range(&ratios, 2),
        );
    }
    Ok(())
}
