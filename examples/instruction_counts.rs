//! Runs one hot-path call of one streaming filter `n` times, for instruction counts under
//! valgrind (`scripts/instruction_counts.sh` runs it at two `n` and takes the difference, which
//! leaves out the set-up):
//!
//! ```text
//! cargo run --release --example instruction_counts -- <filter> <call> <n>
//! cargo run --release --example instruction_counts -- list
//! ```
//!
//! `filter` is a streaming filter's type name (`Ekf`, `Riekf`, … ; `Ekf2d` etc. for the planar
//! filters; `RiekfBias` for `Riekf` with range bias states; `list` prints them all, from the
//! method registry), `call` one of `predict` (an IMU sample at 100 Hz), `range` (one range at the filter
//! time), `epoch` (four ranges, one 1 m long, at the filter time) or `restore` (what `range` and
//! `epoch` do before each call: copy the filter back to its state after set-up, so that every
//! update does the same work). The rig is the criterion benches' (`benches/common/rig.rs`).

use uwbimu_rs::estimation::pipeline::Estimator;
use uwbimu_rs::estimation::planar::{PlanarFilter, PlanarKind};
use uwbimu_rs::estimation::update::UpdateReport;

#[path = "../benches/common/rig.rs"]
mod rig;

fn run<F: Estimator + Clone>(mut set_up: F, call: &str, n: usize) -> Result<(), Box<dyn std::error::Error>> {
    let (accel, gyro) = rig::IMU;
    set_up.predict(0.0, &accel, &gyro)?;
    let mut f = set_up.clone();
    let epoch = rig::EPOCH;
    let mut reports = [UpdateReport::skipped(); 4];
    for k in 0..n {
        match call {
            "predict" => f.predict(0.01 * (k + 1) as f64, std::hint::black_box(&accel), &gyro)?,
            "restore" => f.clone_from(&set_up),
            "range" => {
                f.clone_from(&set_up);
                f.update_ranges(0.0, std::hint::black_box(&epoch[1..2]), &mut reports[..1])?;
            }
            "epoch" => {
                f.clone_from(&set_up);
                f.update_ranges(0.0, std::hint::black_box(&epoch), &mut reports)?;
            }
            other => return Err(format!("unknown call {other:?}: predict, range, epoch or restore").into()),
        }
    }
    std::hint::black_box(&f);
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (list, filter, call, n) = match args.as_slice() {
        [l] if l == "list" => (true, "", "", 0),
        [filter, call, n] => (false, filter.as_str(), call.as_str(), n.parse()?),
        _ => return Err("usage: instruction_counts <filter> <call> <n> | list".into()),
    };
    let (initial, config) = (rig::initial(), rig::config());
    let mut found = false;
    macro_rules! dispatch {
        (inertial $ty:ident, [], $($doc:literal),+) => {
            if list {
                println!(stringify!($ty));
            } else if filter == stringify!($ty) {
                found = true;
                run(uwbimu_rs::estimation::filters::$ty::new(rig::anchors(), &initial, config.clone())?, call, n)?;
            }
        };
        (planar $kind:ident, [], $($doc:literal),+) => {
            let name = format!("{}2d", stringify!($kind));
            if list {
                println!("{name}");
            } else if filter == name {
                found = true;
                run(PlanarFilter::new(PlanarKind::$kind, rig::anchors(), &initial, &config)?, call, n)?;
            }
        };
        (multilateration, [], $($doc:literal),+) => {};
    }
    uwbimu_rs::app::for_each_streaming_filter!(dispatch);
    // The range-bias-state variant of one filter (the issue's bar: within 2× of its base).
    if list {
        println!("RiekfBias");
        return Ok(());
    } else if filter == "RiekfBias" {
        found = true;
        let mut config = config.clone();
        config.range_bias.states = true;
        run(uwbimu_rs::estimation::filters::Riekf::new(rig::anchors(), &initial, config)?, call, n)?;
    }
    if !found {
        return Err(format!("unknown filter {filter:?} (a streaming filter's type name, e.g. Ekf, Riekf, Ekf2d)").into());
    }
    Ok(())
}
