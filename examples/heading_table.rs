//! Prints the self-initialised heading of a method per scenario: when the stream started, the
//! heading error then and 5 s later against the σ the filter reported (how many runs within 3σ),
//! and the horizontal RMSE after 10 s over that of the same run given the true start. The tables
//! of docs/heading.md come from it:
//!
//! ```text
//! cargo run --release --example heading_table -- zoo 32            # one tag, every zoo scenario
//! cargo run --release --example heading_table -- tags 32           # a second tag 0.2/0.5/1 m away
//! cargo run --release --example heading_table -- moving 32         # figure-8 and ellipse at speed
//! cargo run --release --example heading_table -- zoo 32 best defaults   # the default noise
//! ```
//!
//! Arguments: suite (`zoo`, `tags`, `moving`), runs per scenario, method (`best`), `matched` (the
//! simulator's noise configured) or `defaults`, and one scenario name. `VERBOSE=1` prints each run.

use uwbimu_rs::app::consistency::heading_error_and_std;
use uwbimu_rs::app::methods::{run_method, BatchInput, BatchOutput, Method};
use uwbimu_rs::app::parallel::map_all;
use uwbimu_rs::app::sim::{self, simulate, zoo, Scenario, SimConfig, Trajectory, ZOO_NAMES};
use uwbimu_rs::vocabulary::config::FilterConfig;
use uwbimu_rs::vocabulary::math::Vec3;

type Res<T> = Result<T, Box<dyn std::error::Error + Send + Sync>>;

/// One run's figures.
#[derive(Debug, Clone)]
struct Row {
    name: String,
    seed: u64,
    from: String,
    decided_s: f64,
    err0: f64,
    sig0: f64,
    err5: f64,
    sig5: f64,
    rmse_self: f64,
    rmse_given: f64,
}

/// A vehicle already driving a figure-8 (`fig8`) or an ellipse at t = 0, at a point of its lap
/// the seed picks; UWB from 4 hall anchors at 5 Hz from 0.5 s, IMU at 100 Hz.
fn moving_start(kind: &str, seed: u64) -> Res<Scenario> {
    let (trajectory, lap) = match kind {
        "fig8" => (Trajectory::figure_eight(Vec3::new(5.0, 4.0, 0.4), 3.5, 4.5, 37.0, 3, 0.0)?, 37.0),
        _ => (Trajectory::ellipse(Vec3::new(5.0, 4.0, 0.4), 4.0, 2.8, 26.0, 4, 0.0)?, 26.0),
    };
    let start_s = 3.0 + (seed as f64 * 0.618_033_988_75).fract() * lap;
    let base = SimConfig { trajectory, start_s, seed, ..SimConfig::default() };
    let uwb = sim::UwbConfig {
        rate_hz: 5.0,
        stagger_s: 2e-3,
        jitter_s: 1e-3,
        outages: vec![sim::Outage { start_s, end_s: start_s + 0.5 }],
        ..base.uwb.clone()
    };
    let sim = SimConfig { uwb, ..base };
    let config = sim::matched_config(&sim);
    Ok(Scenario { name: "moving", sim, config, default_sensors: true })
}

/// `s` with a second tag `sep` metres from the first, along the body x axis (even seeds) or y.
fn with_second_tag(mut s: Scenario, sep: f64, seed: u64) -> Scenario {
    let dir = if seed % 2 == 0 { Vec3::new(sep, 0.0, 0.0) } else { Vec3::new(0.0, sep, 0.0) };
    s.sim.more_tags_m = vec![s.sim.lever_arm_m + dir];
    s.config = FilterConfig { mounting: s.config.mounting, ..sim::matched_config(&s.sim) };
    s.config.mounting.lever_arm = sim::lever_arms_seen(&s.sim, &s.config.mounting.imu_rotation);
    s
}

/// One self-initialised run and the same run given the true start.
fn run(name: &str, s: &Scenario, seed: u64, method: Method, defaults: bool) -> Res<Row> {
    let data = simulate(&s.sim)?;
    let mut config =
        if defaults { FilterConfig { mounting: s.config.mounting, ..FilterConfig::default() } } else { s.config.clone() };
    config.model_selection.enabled = false;
    let body_from_filter = s.sim.imu_rotation * config.mounting.imu_rotation.inverse();
    let t0 = data.imu[0].t_s;
    let input =
        BatchInput { marginals_every_s: Some(0.05), ..BatchInput::forward(&data.imu, &data.ranges, &data.anchors, &config) };
    let BatchOutput::Inertial { trace, init: Some(init), .. } = run_method(method, &input)? else {
        return Err("not a self-initialised inertial run".into());
    };
    let truth_q = |t: f64| {
        let k = data.truth.partition_point(|x| x.t_s <= t).saturating_sub(1);
        data.truth[k].orientation * body_from_filter
    };
    let at = |t: f64| -> (f64, f64) {
        match trace.marginals.iter().find(|m| m.t_s >= t - 1e-9) {
            Some(m) => {
                let (err, std) = heading_error_and_std(m, &truth_q(m.t_s));
                (err.to_degrees(), std.to_degrees())
            }
            None => (f64::NAN, f64::NAN),
        }
    };
    let (err0, sig0) = at(init.decided_s);
    let (err5, sig5) = at(init.decided_s + 5.0);
    let rmse = |steps: &[uwbimu_rs::estimation::pipeline::StepRecord]| {
        let e: Vec<f64> = steps
            .iter()
            .zip(&data.truth)
            .filter(|(st, _)| st.t_s >= t0 + 10.0)
            .map(|(st, x)| (st.state.position - x.position).xy().norm_squared())
            .collect();
        (e.iter().sum::<f64>() / e.len().max(1) as f64).sqrt()
    };
    let rmse_self = rmse(&trace.steps);
    let initial = s.true_initial(&data)?;
    let given = BatchInput { initial: Some(&initial), ..BatchInput::forward(&data.imu, &data.ranges, &data.anchors, &config) };
    let BatchOutput::Inertial { trace: tg, .. } = run_method(method, &given)? else { return Err("not inertial".into()) };
    Ok(Row {
        name: name.to_string(),
        seed,
        from: init.heading.name().to_string(),
        decided_s: init.decided_s - t0,
        err0,
        sig0,
        err5,
        sig5,
        rmse_self,
        rmse_given: rmse(&tg.steps),
    })
}

fn main() -> Res<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let suite = args.first().map_or("zoo", String::as_str).to_string();
    let seeds: u64 = args.get(1).map_or(Ok(8), |s| s.parse())?;
    let method = Method::parse(args.get(2).map_or("best", String::as_str))?;
    let defaults = args.get(3).is_some_and(|a| a == "defaults");
    let only: Option<String> = args.get(4).cloned();
    let mut jobs: Vec<(String, u64)> = Vec::new();
    let names: Vec<String> = match suite.as_str() {
        "zoo" | "tags" => ZOO_NAMES.iter().filter(|n| **n != "still_tdoa_lost").map(|s| s.to_string()).collect(),
        _ => vec!["fig8".into(), "ellipse".into()],
    };
    for n in names {
        if only.as_ref().is_some_and(|o| *o != n) {
            continue;
        }
        for seed in 0..seeds {
            jobs.push((n.clone(), seed));
        }
    }
    let rows = map_all(&jobs, |(n, seed)| -> Res<Row> {
        let s = match suite.as_str() {
            "zoo" => zoo(n, *seed)?,
            "tags" => with_second_tag(zoo(n, *seed)?, [0.2, 0.5, 1.0][*seed as usize % 3], *seed),
            _ => moving_start(n, *seed)?,
        };
        run(n, &s, *seed, method, defaults)
    });
    let mut by: std::collections::BTreeMap<String, Vec<Row>> = Default::default();
    for (job, r) in jobs.iter().zip(rows) {
        match r {
            Ok(r) => by.entry(r.name.clone()).or_default().push(r),
            Err(e) => println!("{} seed {}: error {e}", job.0, job.1),
        }
    }
    let verbose = std::env::var_os("VERBOSE").is_some();
    println!(
        "{:<16} {:>4} {:>6} {:>7} {:>7} {:>6} {:>7} {:>7} {:>6} {:>7} {:>7}",
        "scenario", "n", "t_dec", "|e0|", "max|e0|", "in3σ0", "|e5|", "max|e5|", "in3σ5", "σ5", "rmse×"
    );
    let (mut all0, mut all5, mut total) = (0, 0, 0);
    for (name, rows) in &by {
        let n = rows.len() as f64;
        let mean = |f: &dyn Fn(&Row) -> f64| rows.iter().map(f).sum::<f64>() / n;
        let maxf = |f: &dyn Fn(&Row) -> f64| rows.iter().map(f).fold(0.0, f64::max);
        let in0 = rows.iter().filter(|r| r.err0.abs() <= 3.0 * r.sig0).count();
        let in5 = rows.iter().filter(|r| r.err5.abs() <= 3.0 * r.sig5).count();
        all0 += in0;
        all5 += in5;
        total += rows.len();
        println!(
            "{:<16} {:>4} {:>6.2} {:>7.2} {:>7.2} {:>6} {:>7.2} {:>7.2} {:>6} {:>7.2} {:>7.2}",
            name,
            rows.len(),
            mean(&|r| r.decided_s),
            mean(&|r| r.err0.abs()),
            maxf(&|r| r.err0.abs()),
            in0,
            mean(&|r| r.err5.abs()),
            maxf(&|r| r.err5.abs()),
            in5,
            mean(&|r| r.sig5),
            mean(&|r| r.rmse_self / r.rmse_given),
        );
        if verbose {
            for r in rows {
                println!(
                    "    seed {:>2} {:<8} t {:>5.2} e0 {:>8.2} σ0 {:>6.2} e5 {:>8.2} σ5 {:>6.2} rmse {:.3}/{:.3}",
                    r.seed, r.from, r.decided_s, r.err0, r.sig0, r.err5, r.sig5, r.rmse_self, r.rmse_given
                );
            }
        }
    }
    println!("within 3σ at the start {all0}/{total}, 5 s later {all5}/{total}");
    Ok(())
}
