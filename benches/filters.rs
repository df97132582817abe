//! Criterion benches of the hot path: one IMU prediction and one range update of `Ekf`.
#![allow(missing_docs)]

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use uwbimu_rs::config::{FilterConfig, InitialState};
use uwbimu_rs::filters::{Ekf, InertialFilter};
use uwbimu_rs::math::Vec3;

fn filter() -> Ekf {
    let anchors = vec![Vec3::new(0.0, 0.0, 2.0), Vec3::new(10.0, 0.0, 1.0), Vec3::new(10.0, 8.0, 2.2), Vec3::new(0.0, 8.0, 0.8)];
    let initial = InitialState { position: Vec3::new(4.0, 3.0, 0.3), ..InitialState::default() };
    let config = FilterConfig { lever_arm: Vec3::new(0.0, 0.0, 0.05), ..FilterConfig::default() };
    let mut f = Ekf::new(anchors, &initial, config).expect("valid filter");
    f.predict(0.0, &Vec3::new(0.1, 0.0, 9.81), &Vec3::new(0.0, 0.0, 0.1)).expect("first sample");
    f
}

fn bench_ekf(c: &mut Criterion) {
    let mut group = c.benchmark_group("ekf");
    group.throughput(Throughput::Elements(1));
    let accel = Vec3::new(0.2, -0.1, 9.8);
    let gyro = Vec3::new(0.01, -0.02, 0.3);
    group.bench_function("predict", |b| {
        let mut f = filter();
        let mut t = 0.0;
        b.iter(|| {
            t += 0.01;
            f.predict(black_box(t), black_box(&accel), black_box(&gyro)).expect("predict");
        })
    });
    group.bench_function("update_range", |b| {
        b.iter_batched(
            filter,
            |mut f| {
                f.update_range(black_box(0.0), black_box(1), black_box(6.3)).expect("update");
                f
            },
            BatchSize::SmallInput,
        )
    });
    group.finish();
}

criterion_group!(benches, bench_ekf);
criterion_main!(benches);
