//! The plausibility gate in front of every method, batch and streaming: a measurement no sensor or
//! geometry can produce is counted and never reaches a filter (or the self-initialisation).
//!
//! | rejection | rule (`gate.*` of the configuration) |
//! |---|---|
//! | [`Rejection::ImuBeyondRange`] | an accelerometer axis beyond `accel_range` or a gyroscope axis beyond `gyro_range` |
//! | [`Rejection::NegativeRange`] | a range below 0 m |
//! | [`Rejection::RangeBeyondHall`] | a range longer than the farthest point of the anchors' bounding box, grown by `hall_margin_m`, from its anchor |
//! | [`Rejection::TdoaBeyondBaseline`] | `\|d_ij\|` beyond the baseline `‖a_i − a_j‖` plus `tdoa_margin_m` (the triangle inequality) |
//! | [`Rejection::AltitudeBeyondHall`] | a height outside the anchors' bounding box grown by `hall_margin_m` |
//! | [`Rejection::SpeedBeyondRange`] | an odometry reading beyond `speed_range` |
//!
//! A dropped IMU sample leaves the previous one held over the longer interval. Magnetometer
//! samples pass.

use uwbimu_vocabulary::config::GateConfig;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::sensors::Observation;

use crate::pipeline::Event;

/// Why the gate dropped a measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rejection {
    /// An IMU sample beyond the sensor's range.
    ImuBeyondRange,
    /// A negative range.
    NegativeRange,
    /// A range longer than any tag position near the anchors allows.
    RangeBeyondHall,
    /// A TDoA beyond the baseline between its two anchors.
    TdoaBeyondBaseline,
    /// An altitude no tag near the anchors can have.
    AltitudeBeyondHall,
    /// An odometry reading faster than the platform can go.
    SpeedBeyondRange,
}

impl Rejection {
    /// Every kind, in the order of [`GateCounts::by_kind`].
    pub const ALL: [Rejection; 6] = [
        Self::ImuBeyondRange,
        Self::NegativeRange,
        Self::RangeBeyondHall,
        Self::TdoaBeyondBaseline,
        Self::AltitudeBeyondHall,
        Self::SpeedBeyondRange,
    ];

    /// The kind's name in reports (`health` in Python, the CLI summary).
    pub fn name(self) -> &'static str {
        match self {
            Self::ImuBeyondRange => "imu_beyond_range",
            Self::NegativeRange => "negative_range",
            Self::RangeBeyondHall => "range_beyond_hall",
            Self::TdoaBeyondBaseline => "tdoa_beyond_baseline",
            Self::AltitudeBeyondHall => "altitude_beyond_hall",
            Self::SpeedBeyondRange => "speed_beyond_range",
        }
    }
}

/// How many measurements the gate dropped, per kind.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GateCounts {
    counts: [usize; Rejection::ALL.len()],
}

impl GateCounts {
    /// Counts one rejection.
    pub fn count(&mut self, r: Rejection) {
        self.counts[r as usize] += 1;
    }

    /// The count of one kind.
    pub fn of(&self, r: Rejection) -> usize {
        self.counts[r as usize]
    }

    /// Every kind with its count, in [`Rejection::ALL`] order.
    pub fn by_kind(&self) -> impl Iterator<Item = (Rejection, usize)> + '_ {
        Rejection::ALL.into_iter().map(|r| (r, self.of(r)))
    }

    /// All rejections.
    pub fn total(&self) -> usize {
        self.counts.iter().sum()
    }
}

/// The gate for one set of anchors (see the module doc).
#[derive(Debug, Clone, PartialEq)]
pub struct Gate {
    config: GateConfig,
    anchors: Vec<Vec3>,
    longest_range_m: Vec<f64>,
    /// The grown box's lowest and highest z, m.
    heights_m: (f64, f64),
}

impl Gate {
    /// The gate of `config` for `anchors` (navigation frame, m).
    pub fn new(anchors: &[Vec3], config: &GateConfig) -> Self {
        let margin = Vec3::repeat(config.hall_margin_m);
        let lo = anchors.iter().fold(Vec3::repeat(f64::INFINITY), |m, a| m.inf(a)) - margin;
        let hi = anchors.iter().fold(Vec3::repeat(f64::NEG_INFINITY), |m, a| m.sup(a)) + margin;
        // The farthest corner of the box from each anchor.
        let longest_range_m = anchors.iter().map(|a| Vec3::from_fn(|i, _| (a[i] - lo[i]).max(hi[i] - a[i])).norm()).collect();
        Self { config: *config, anchors: anchors.to_vec(), longest_range_m, heights_m: (lo.z, hi.z) }
    }

    /// Why `event` is impossible, or None when it passes (always None when the gate is off).
    /// Anchor indices must be valid.
    pub fn check(&self, event: &Event) -> Option<Rejection> {
        if !self.config.enabled {
            return None;
        }
        match event {
            Event::Imu(s) => {
                let beyond = |v: &Vec3, limit: f64| v.iter().any(|c| c.abs() > limit);
                (beyond(&s.accel, self.config.accel_range) || beyond(&s.gyro, self.config.gyro_range))
                    .then_some(Rejection::ImuBeyondRange)
            }
            Event::Range(r) if r.range_m < 0.0 => Some(Rejection::NegativeRange),
            Event::Range(r) => (r.range_m > self.longest_range_m[r.anchor]).then_some(Rejection::RangeBeyondHall),
            Event::Observation(Observation::Tdoa(m)) => {
                let baseline = (self.anchors[m.anchor_i] - self.anchors[m.anchor_j]).norm();
                (m.tdoa_m.abs() > baseline + self.config.tdoa_margin_m).then_some(Rejection::TdoaBeyondBaseline)
            }
            Event::Observation(Observation::Altitude(m)) => {
                let (lo, hi) = self.heights_m;
                (!(lo..=hi).contains(&m.z_m)).then_some(Rejection::AltitudeBeyondHall)
            }
            Event::Observation(Observation::Odometry(m)) => {
                (m.speed_mps.abs() > self.config.speed_range).then_some(Rejection::SpeedBeyondRange)
            }
            Event::Observation(Observation::Magnetometer(_)) => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use uwbimu_vocabulary::records::{AltitudeSample, ImuSample, OdometrySample, RangeMeasurement, TdoaMeasurement};

    use super::*;

    fn gate() -> Gate {
        let anchors = [Vec3::zeros(), Vec3::new(10.0, 0.0, 0.0), Vec3::new(0.0, 8.0, 3.0)];
        Gate::new(&anchors, &GateConfig { hall_margin_m: 5.0, tdoa_margin_m: 0.5, ..GateConfig::default() })
    }

    #[test]
    fn a_tdoa_beyond_its_baseline_is_impossible_and_one_within_passes() {
        let tdoa = |d| Event::Observation(Observation::Tdoa(TdoaMeasurement { t_s: 0.0, anchor_i: 0, anchor_j: 1, tdoa_m: d }));
        assert_eq!(gate().check(&tdoa(10.4)), None);
        assert_eq!(gate().check(&tdoa(-10.4)), None);
        assert_eq!(gate().check(&tdoa(10.6)), Some(Rejection::TdoaBeyondBaseline));
        assert_eq!(gate().check(&tdoa(-10.6)), Some(Rejection::TdoaBeyondBaseline));
    }

    #[test]
    fn heights_outside_the_grown_hall_and_speeds_beyond_the_range_are_impossible() {
        let altitude = |z_m| Event::Observation(Observation::Altitude(AltitudeSample { t_s: 0.0, z_m }));
        // Anchors' z spans [0, 3], grown by 5 m.
        assert_eq!(gate().check(&altitude(-4.99)), None);
        assert_eq!(gate().check(&altitude(7.99)), None);
        assert_eq!(gate().check(&altitude(-5.01)), Some(Rejection::AltitudeBeyondHall));
        assert_eq!(gate().check(&altitude(1200.0)), Some(Rejection::AltitudeBeyondHall));
        let speed = |speed_mps| Event::Observation(Observation::Odometry(OdometrySample { t_s: 0.0, axis: 0, speed_mps }));
        assert_eq!(gate().check(&speed(-29.0)), None);
        assert_eq!(gate().check(&speed(-31.0)), Some(Rejection::SpeedBeyondRange));
        assert_eq!(gate().check(&speed(31.0)), Some(Rejection::SpeedBeyondRange));
    }

    #[test]
    fn ranges_longer_than_the_grown_hall_allows_are_impossible() {
        let range = |anchor, d| Event::Range(RangeMeasurement { t_s: 0.0, anchor, range_m: d, tag: 0 });
        // Anchor 0 at the origin; the farthest corner of [-5, 15] × [-5, 13] × [-5, 8] is (15, 13, 8).
        let longest = Vec3::new(15.0, 13.0, 8.0).norm();
        assert_eq!(gate().check(&range(0, longest - 0.01)), None);
        assert_eq!(gate().check(&range(0, longest + 0.01)), Some(Rejection::RangeBeyondHall));
        assert_eq!(gate().check(&range(1, -0.1)), Some(Rejection::NegativeRange));
    }

    #[test]
    fn imu_samples_beyond_the_sensor_range_are_impossible_unless_the_gate_is_off() {
        let imu =
            |a: f64, g: f64| Event::Imu(ImuSample { t_s: 0.0, accel: Vec3::new(0.0, a, 9.8), gyro: Vec3::new(g, 0.0, 0.0) });
        assert_eq!(gate().check(&imu(150.0, 30.0)), None);
        assert_eq!(gate().check(&imu(-160.0, 0.0)), Some(Rejection::ImuBeyondRange));
        assert_eq!(gate().check(&imu(0.0, 36.0)), Some(Rejection::ImuBeyondRange));
        let off = Gate::new(&[Vec3::zeros()], &GateConfig { enabled: false, ..GateConfig::default() });
        assert_eq!(off.check(&imu(1e6, 1e6)), None);
    }
}
