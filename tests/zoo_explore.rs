//! Exploration: every method on every zoo scenario (printing only).
use rayon::prelude::*;
use uwbimu_rs::generality::{run_cell, Cell, Settings, Start};
use uwbimu_rs::methods::Method;
use uwbimu_rs::sim::ZOO_NAMES;

fn list(var: &str, default: &[&'static str]) -> Vec<&'static str> {
    std::env::var(var)
        .map(|s| s.split(',').map(|x| Box::leak(x.to_string().into_boxed_str()) as &str).collect())
        .unwrap_or_else(|_| default.to_vec())
}

#[test]
#[ignore]
fn explore() {
    let methods = list("METHODS", &Method::NAMES[1..]);
    let scen = list("SCEN", ZOO_NAMES);
    let start = if std::env::var("GIVEN").map(|v| v == "1").unwrap_or(true) { Start::Given } else { Start::SelfInit };
    let settings =
        if std::env::var("DEFAULTS").map(|v| v == "1").unwrap_or(false) { Settings::Defaults } else { Settings::Matched };
    let seeds: u64 = std::env::var("SEEDS").ok().and_then(|s| s.parse().ok()).unwrap_or(1);
    let seed0: u64 = std::env::var("SEED0").ok().and_then(|s| s.parse().ok()).unwrap_or(0);
    let jobs: Vec<(&str, &str, u64)> =
        scen.iter().flat_map(|s| methods.iter().flat_map(move |m| (seed0..seed0 + seeds).map(move |k| (*s, *m, k)))).collect();
    let res: Vec<((&str, &str, u64), (f64, f64))> = jobs
        .par_iter()
        .map(|&(s, m, k)| {
            let mut custom = uwbimu_rs::sim::zoo(s, k).unwrap().config;
            let settings = match std::env::var("CONFIG") {
                Ok(extra) => {
                    if settings == Settings::Defaults {
                        custom = uwbimu_rs::config::FilterConfig {
                            lever_arm: custom.lever_arm,
                            imu_rotation: custom.imu_rotation,
                            ..uwbimu_rs::config::FilterConfig::default()
                        };
                    }
                    for kv in extra.split(',') {
                        let (key, v) = kv.split_once('=').unwrap();
                        let value = match v {
                            "true" => uwbimu_rs::config::ConfigValue::Flag(true),
                            "false" => uwbimu_rs::config::ConfigValue::Flag(false),
                            _ => uwbimu_rs::config::ConfigValue::Scalar(v.parse().unwrap()),
                        };
                        custom.set(key, &value).unwrap();
                    }
                    Settings::Custom(Box::leak(Box::new(custom)))
                }
                Err(_) => settings,
            };
            let cell = Cell { scenario: s, seed: k, method: Method::parse(m).unwrap(), start, settings };
            let r = match run_cell(&cell) {
                Ok(r) if r.finite => (r.rmse_m, r.uwb_ls_rmse_m),
                Ok(r) => (f64::INFINITY, r.uwb_ls_rmse_m),
                Err(e) => {
                    eprintln!("{s} {m} {k}: {e}");
                    (f64::INFINITY, 1.0)
                }
            };
            ((s, m, k), r)
        })
        .collect();
    let bound = if start == Start::Given { 1.2 } else { 1.5 };
    println!("worst ratio to uwb_ls over {seeds} seeds; {start:?} {settings:?}");
    print!("{:<14}{:>8}", "scenario", "uwb_ls");
    for m in &methods {
        print!("{:>8}", m);
    }
    println!();
    for s in &scen {
        let ls: f64 = res.iter().filter(|r| r.0 .0 == *s && r.0 .1 == methods[0]).map(|r| r.1 .1).sum::<f64>() / seeds as f64;
        print!("{:<14}{:>8.3}", s, ls);
        for m in &methods {
            let worst = res.iter().filter(|r| r.0 .0 == *s && r.0 .1 == *m).map(|r| r.1 .0 / r.1 .1).fold(0.0, f64::max);
            let mark = if worst > bound { "*" } else { " " };
            print!("{:>7.2}{}", worst, mark);
        }
        println!();
    }
}

#[test]
#[ignore]
fn trace_one() {
    use uwbimu_rs::methods::{run_method, BatchInput, BatchOutput};
    use uwbimu_rs::sim::{simulate, zoo};
    let name = std::env::var("SCEN").unwrap_or("agv_loop".into());
    let method = std::env::var("METHODS").unwrap_or("shaf".into());
    let seed: u64 = std::env::var("SEED0").ok().and_then(|s| s.parse().ok()).unwrap_or(0);
    let given = std::env::var("GIVEN").map(|v| v == "1").unwrap_or(true);
    let every: f64 = std::env::var("EVERY").ok().and_then(|s| s.parse().ok()).unwrap_or(1.0);
    let sc = zoo(&name, seed).unwrap();
    let data = simulate(&sc.sim).unwrap();
    let init = sc.true_initial(&data).unwrap();
    let mut config =
        if std::env::var("DEFAULTS").is_ok() { uwbimu_rs::config::FilterConfig::default() } else { sc.config.clone() };
    if let Ok(extra) = std::env::var("CONFIG") {
        for kv in extra.split(',') {
            let (key, v) = kv.split_once('=').unwrap();
            config.set(key, &uwbimu_rs::config::ConfigValue::Scalar(v.parse().unwrap())).unwrap();
        }
    }
    let input = BatchInput {
        imu: &data.imu,
        ranges: &data.ranges,
        anchors: &data.anchors,
        initial: if given { Some(&init) } else { None },
        config: &config,
        smooth: false,
        mag: &[],
    };
    let out = run_method(Method::parse(&method).unwrap(), &input).unwrap();
    if let BatchOutput::Inertial { trace, .. } = out {
        let mut k = 0;
        let mut next = 0.0;
        for (s, t) in trace.steps.iter().zip(&data.truth) {
            if s.t_s + 1e-9 >= next {
                next = s.t_s + every;
                while k < trace.updates.len() && trace.updates[k].t_s <= s.t_s {
                    k += 1;
                }
                let u = trace.updates.get(k.saturating_sub(1));
                println!(
                    "t={:6.2} err={:7.3} dz={:6.3} std={:6.3} v_err={:6.3} nis={:8.2} w={:6.3}",
                    s.t_s,
                    (s.state.position - t.position).xy().norm(),
                    s.state.position.z - t.position.z,
                    s.position_cov[(0, 0)].sqrt(),
                    (s.state.velocity - t.velocity).norm(),
                    u.map_or(f64::NAN, |u| u.report.nis),
                    u.map_or(f64::NAN, |u| u.report.weight),
                );
            }
        }
    }
}

#[test]
#[ignore]
fn find_indefinite() {
    use uwbimu_rs::filters::{Iekf, InertialFilter};
    use uwbimu_rs::pipeline::Stream;
    use uwbimu_rs::sim::{simulate, zoo};
    let sc = zoo("outliers", 5).unwrap();
    let data = simulate(&sc.sim).unwrap();
    let init = sc.true_initial(&data).unwrap();
    let f = Iekf::new(data.anchors.clone(), &init, sc.config.clone()).unwrap();
    let mut s = Stream::new(f).unwrap();
    let mut j = 0;
    for imu in &data.imu {
        while j < data.ranges.len() && data.ranges[j].t_s < imu.t_s {
            if let Err(e) = s.range(&data.ranges[j]) {
                println!("error at range {j} t={}: {e}", data.ranges[j].t_s);
                return;
            }
            let p = s.estimator().core().covariance();
            let min = p.symmetric_eigen().eigenvalues.min();
            if min < -1e-9 {
                println!("indefinite after range {j} t={} min eig {min}", data.ranges[j].t_s);
                return;
            }
            j += 1;
        }
        s.imu(imu).unwrap();
        let p = s.estimator().core().covariance();
        let min = p.symmetric_eigen().eigenvalues.min();
        if min < -1e-9 {
            println!("indefinite after imu t={} min eig {min}", imu.t_s);
            return;
        }
    }
}
