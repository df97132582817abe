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

use uwbimu_rs::app::methods::{Method, Run};
use uwbimu_rs::estimation::filters::{InertialVisitor, NamedFilter};
use uwbimu_rs::estimation::pipeline::Estimator;
use uwbimu_rs::estimation::planar::PlanarFilter;
use uwbimu_rs::estimation::update::UpdateReport;
use uwbimu_rs::vocabulary::config::{FilterConfig, InitialState};

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

/// [`run`] on the rig with an inertial filter type.
struct Calls<'a> {
    initial: &'a InitialState,
    config: &'a FilterConfig,
    call: &'a str,
    n: usize,
}

impl InertialVisitor for Calls<'_> {
    type Output = Result<(), Box<dyn std::error::Error>>;

    fn visit<F: NamedFilter>(self) -> Self::Output {
        run(F::build(rig::anchors(), self.initial, self.config.clone())?, self.call, self.n)
    }
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
    for method in Method::ALL {
        let name = match method.info().run {
            Run::Inertial(kind) => kind.type_name().to_string(),
            Run::Planar(kind) => format!("{kind:?}2d"),
            Run::Multilateration => continue,
        };
        if list {
            println!("{name}");
        } else if filter == name {
            found = true;
            match method.info().run {
                Run::Inertial(kind) => kind.visit(Calls { initial: &initial, config: &config, call, n })?,
                Run::Planar(kind) => run(PlanarFilter::new(kind, rig::anchors(), &initial, &config)?, call, n)?,
                Run::Multilateration => {}
            }
        }
    }
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
