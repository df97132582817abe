//! Criterion benches of the hot path: IMU prediction and range updates of the named filters.
#![allow(missing_docs)]

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use uwbimu_rs::config::{FilterConfig, InitialState};
use uwbimu_rs::filters::{Criekf, Ekf, InertialFilter, Riekf};
use uwbimu_rs::math::Vec3;
use uwbimu_rs::update::UpdateReport;

fn anchors() -> Vec<Vec3> {
    vec![Vec3::new(0.0, 0.0, 2.0), Vec3::new(10.0, 0.0, 1.0), Vec3::new(10.0, 8.0, 2.2), Vec3::new(0.0, 8.0, 0.8)]
}

fn setup<F: InertialFilter>(build: fn(Vec<Vec3>, &InitialState, FilterConfig) -> uwbimu_rs::Result<F>) -> F {
    let initial = InitialState { position: Vec3::new(4.0, 3.0, 0.3), ..InitialState::default() };
    let config = FilterConfig { lever_arm: Vec3::new(0.0, 0.0, 0.05), ..FilterConfig::default() };
    let mut f = build(anchors(), &initial, config).expect("valid filter");
    f.predict(0.0, &Vec3::new(0.1, 0.0, 9.81), &Vec3::new(0.0, 0.0, 0.1)).expect("first sample");
    f
}

fn bench_filter<F: InertialFilter>(
    c: &mut Criterion,
    name: &str,
    build: fn(Vec<Vec3>, &InitialState, FilterConfig) -> uwbimu_rs::Result<F>,
) {
    let mut group = c.benchmark_group(name);
    group.throughput(Throughput::Elements(1));
    let accel = Vec3::new(0.2, -0.1, 9.8);
    let gyro = Vec3::new(0.01, -0.02, 0.3);
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
            |f| f.update_range(black_box(0.0), black_box(1), black_box(6.3)).expect("update"),
            BatchSize::SmallInput,
        )
    });
    // One epoch of four ranges, one of them 1 m long (an NLOS-like outlier).
    let epoch = [(0, 5.1), (1, 6.3), (2, 8.2), (3, 6.4)];
    group.throughput(Throughput::Elements(epoch.len() as u64));
    group.bench_function("update_epoch_4", |b| {
        b.iter_batched_ref(
            || setup(build),
            |f| {
                let mut reports = [UpdateReport::skipped(); 4];
                f.update_ranges(black_box(0.0), black_box(&epoch), &mut reports).expect("update");
                reports
            },
            BatchSize::SmallInput,
        )
    });
    group.finish();
}

fn bench_all(c: &mut Criterion) {
    bench_filter(c, "ekf", Ekf::new);
    bench_filter(c, "riekf", Riekf::new);
    bench_filter(c, "criekf", Criekf::new);
}

criterion_group!(benches, bench_all);
criterion_main!(benches);
