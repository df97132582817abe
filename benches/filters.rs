//! Criterion benches of the hot path: IMU prediction, range and TDoA updates of the named filters.
#![allow(missing_docs)]

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use uwbimu_rs::estimation::filters::{Ackf, Arckf, Best, Ckf, Criekf, Ekf, Eskf, Riekf, Ukf};
use uwbimu_rs::estimation::pipeline::{Estimator, Event, Stream, StreamOptions};
use uwbimu_rs::estimation::planar::{PlanarFilter, PlanarKind};
use uwbimu_rs::estimation::update::UpdateReport;
use uwbimu_rs::vocabulary::config::{FilterConfig, InitialState};
use uwbimu_rs::vocabulary::math::Vec3;
use uwbimu_rs::vocabulary::records::{RangeMeasurement, TdoaMeasurement};
use uwbimu_rs::vocabulary::sensors::Observation;

/// Filters set up per timed batch: few enough that each is still in cache when it is updated
/// (with criterion's large batches every update started from a cold filter).
const WARM_BATCH: BatchSize = BatchSize::NumIterations(8);

#[path = "common/rig.rs"]
mod rig;

/// A filter constructor of the shape shared by the named filters.
type Build<F> = Box<dyn Fn(Vec<Vec3>, &InitialState, FilterConfig) -> uwbimu_rs::vocabulary::error::Result<F>>;

fn setup<F: Estimator>(build: &Build<F>) -> F {
    let mut f = build(rig::anchors(), &rig::initial(), rig::config()).expect("valid filter");
    f.predict(0.0, &Vec3::new(0.1, 0.0, 9.81), &Vec3::new(0.0, 0.0, 0.1)).expect("first sample");
    f
}

fn bench_filter<F: Estimator>(c: &mut Criterion, name: &str, build: Build<F>) {
    let build = &build;
    let mut group = c.benchmark_group(name);
    group.throughput(Throughput::Elements(1));
    let (accel, gyro) = rig::IMU;
    group.bench_function("predict", |b| {
        let mut f = setup(build);
        let mut t = 0.0;
        b.iter(|| {
            t += 0.01;
            f.predict(black_box(t), black_box(&accel), black_box(&gyro)).expect("predict");
        })
    });
    group.bench_function("update_range", |b| {
        b.iter_batched_ref(
            || setup(build),
            |f| {
                let mut report = [UpdateReport::skipped()];
                f.update_ranges(black_box(0.0), black_box(&[(1, 6.3)]), &mut report).expect("update");
                report
            },
            WARM_BATCH,
        )
    });
    let epoch = rig::EPOCH;
    group.throughput(Throughput::Elements(epoch.len() as u64));
    group.bench_function("update_epoch_4", |b| {
        b.iter_batched_ref(
            || setup(build),
            |f| {
                let mut reports = [UpdateReport::skipped(); 4];
                f.update_ranges(black_box(0.0), black_box(&epoch), &mut reports).expect("update");
                reports
            },
            WARM_BATCH,
        )
    });
    // Data arriving in order: no reorder window.
    const IN_ORDER: StreamOptions = StreamOptions { reorder_window_s: 0.0, strict: true };
    // The same epoch through the event loop, staggered 1 ms per anchor: grouping by the epoch
    // rule, alignment to the reference time, then the joint update.
    let staggered: Vec<RangeMeasurement> = epoch
        .iter()
        .enumerate()
        .map(|(k, &(anchor, range_m))| RangeMeasurement { t_s: 0.001 * (k + 1) as f64, anchor, range_m, tag: 0 })
        .collect();
    group.bench_function("stream_epoch_4", |b| {
        b.iter_batched_ref(
            || (Stream::new(setup(build), IN_ORDER).expect("stream"), Vec::with_capacity(4)),
            |(stream, applied)| {
                for r in &staggered {
                    stream.push("range", Event::Range(*black_box(r))).expect("range");
                }
                stream.take_applied(applied);
            },
            WARM_BATCH,
        )
    });
    group.finish();
}

/// One TDoA applied at its own time (the filters that take TDoA).
fn bench_tdoa<F: Estimator>(c: &mut Criterion, name: &str, build: Build<F>) {
    let mut group = c.benchmark_group(name);
    group.throughput(Throughput::Elements(1));
    let tdoa = Observation::Tdoa(TdoaMeasurement { t_s: 0.0, anchor_i: 0, anchor_j: 1, tdoa_m: 1.2 });
    group.bench_function("update_tdoa", |b| {
        b.iter_batched_ref(|| setup(&build), |f| f.observe(black_box(&tdoa)).expect("tdoa"), WARM_BATCH)
    });
    group.finish();
}

fn bench_all(c: &mut Criterion) {
    bench_filter(c, "ekf", Box::new(Ekf::new));
    bench_filter(c, "riekf", Box::new(Riekf::new));
    bench_filter(
        c,
        "riekf_bias",
        Box::new(|anchors, initial, mut config: FilterConfig| {
            config.range_bias.states = true;
            Riekf::new(anchors, initial, config)
        }),
    );
    bench_filter(c, "criekf", Box::new(Criekf::new));
    bench_filter(c, "best", Box::new(Best::new));
    bench_filter(c, "ckf", Box::new(Ckf::new));
    bench_filter(c, "arckf", Box::new(Arckf::new));
    bench_filter(c, "ackf", Box::new(Ackf::new));
    bench_filter(c, "ukf", Box::new(Ukf::new));
    bench_filter(c, "eskf", Box::new(Eskf::new));
    bench_tdoa(c, "ekf", Box::new(Ekf::new));
    bench_tdoa(c, "riekf", Box::new(Riekf::new));
    bench_tdoa(c, "arckf", Box::new(Arckf::new));
    bench_tdoa(c, "ukf", Box::new(Ukf::new));
    for (name, kind) in [("ekf2d", PlanarKind::Ekf), ("ukf2d", PlanarKind::Ukf), ("cekf2d", PlanarKind::Cekf)] {
        bench_filter(c, name, Box::new(move |a, i, cfg| PlanarFilter::new(kind, a, i, &cfg)));
    }
}

criterion_group!(benches, bench_all);
criterion_main!(benches);
