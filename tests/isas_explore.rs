//! Exploration on isas-walk1 (printing only).
use rayon::prelude::*;
use std::path::PathBuf;
use uwbimu_rs::config::{ConfigValue, FilterConfig};
use uwbimu_rs::io::truth_file::read_truth_csv;
use uwbimu_rs::io::{read_recording_file, ReplayConfig};
use uwbimu_rs::methods::Method;
use uwbimu_rs::replay::{compare_with_truth, replay};

fn repo(path: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(path)
}

#[test]
#[ignore]
fn isas() {
    let cfg = ReplayConfig::read(&repo("examples/isas-walk1.toml")).unwrap();
    let rec = read_recording_file(&repo("../shared/data/isas-walk1/isas-walk1.mcap"), &cfg.mapping, |_| {}).unwrap();
    let truth = read_truth_csv(&repo("../shared/data/isas-walk1/gt_anchor_frame.csv")).unwrap();
    let mut config = FilterConfig::default();
    if let Ok(extra) = std::env::var("CONFIG") {
        for kv in extra.split(',') {
            let (k, v) = kv.split_once('=').unwrap();
            let value = match v {
                "true" => ConfigValue::Flag(true),
                "false" => ConfigValue::Flag(false),
                _ => ConfigValue::Scalar(v.parse().unwrap()),
            };
            config.set(k, &value).unwrap();
        }
    }
    let methods: Vec<&str> = std::env::var("METHODS")
        .map(|s| s.split(',').map(|x| Box::leak(x.to_string().into_boxed_str()) as &str).collect())
        .unwrap_or_else(|_| Method::NAMES.to_vec());
    let res: Vec<(&str, String)> = methods
        .par_iter()
        .map(|m| {
            let r = replay(&rec, Method::parse(m).unwrap(), &config, false);
            let s = match r {
                Ok(r) => match compare_with_truth(&r.trajectory(), &truth) {
                    Ok((raw, al)) => format!(
                        "raw {:8.3}  aligned {:8.3}  max {:8.3}  nis {:?}",
                        raw.horizontal.rmse,
                        al.horizontal.rmse,
                        raw.horizontal.max,
                        r.mean_nis.map(|x| (x * 100.0).round() / 100.0)
                    ),
                    Err(e) => format!("eval error {e}"),
                },
                Err(e) => format!("error {e}"),
            };
            (*m, s)
        })
        .collect();
    for (m, s) in res {
        println!("{m:<8} {s}");
    }
}
