//! The plausibility gate in front of every method, batch and streaming: a measurement no sensor or
//! geometry can produce is counted and never reaches a filter (or the self-initialisation).
//!
//! | rejection | rule (`gate.*` of the configuration) |
//! |---|---|
//! | [`Rejection::ImuBeyondRange`] | an accelerometer axis beyond `accel_range` or a gyroscope axis beyond `gyro_range` |
//! | [`Rejection::NegativeRange`] | a range below 0 m |
//! | [`Rejection::RangeBeyondHall`] | a range longer than the farthest point of the anchors' bounding box, grown by `hall_margin_m`, from its anchor |
//! | [`Rejection::Sensor`] | a reading of a sensor of the registry its rule refuses ([`SensorRule`], beside each model), counted under the sensor's `rejection` name |
//!
//! The sensors' rules: `tdoa_beyond_baseline`, `|d_ij|` beyond the baseline `‖a_i − a_j‖` plus
//! `tdoa_margin_m` (the triangle inequality); `altitude_beyond_hall`, a height outside the grown
//! box; `speed_beyond_range`, an odometry reading beyond `speed_range`; `pose_fix_beyond_hall`,
//! a fix's position outside the grown box. Magnetometer samples pass. A dropped IMU sample leaves
//! the previous one held over the longer interval.

use uwbimu_vocabulary::config::GateConfig;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::sensors::SensorKind;

#[cfg(doc)]
use crate::models::aiding::SensorRule;
use crate::models::aiding::{plausible, Hall};
use crate::pipeline::Event;

/// How many sensors of the registry have a rule (a `rejection` name).
const SENSOR_RULES: usize = {
    let (mut n, mut i) = (0, 0);
    while i < SensorKind::ALL.len() {
        n += SensorKind::ALL[i].info().rejection.is_some() as usize;
        i += 1;
    }
    n
};

/// Why the gate dropped a measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rejection {
    /// An IMU sample beyond the sensor's range.
    ImuBeyondRange,
    /// A negative range.
    NegativeRange,
    /// A range longer than any tag position near the anchors allows.
    RangeBeyondHall,
    /// A reading its sensor's rule refuses (a sensor whose row has a `rejection` name).
    Sensor(SensorKind),
}

impl Rejection {
    /// Every kind, in the order of [`GateCounts::by_kind`]: the IMU's and the ranges', then the
    /// sensors' in registry order.
    pub const ALL: [Rejection; 3 + SENSOR_RULES] = {
        let mut all = [Self::ImuBeyondRange; 3 + SENSOR_RULES];
        all[1] = Self::NegativeRange;
        all[2] = Self::RangeBeyondHall;
        let (mut at, mut i) = (3, 0);
        while i < SensorKind::ALL.len() {
            if SensorKind::ALL[i].info().rejection.is_some() {
                all[at] = Self::Sensor(SensorKind::ALL[i]);
                at += 1;
            }
            i += 1;
        }
        all
    };

    /// The kind's name in reports (`health` in Python, the CLI summary).
    pub fn name(self) -> &'static str {
        match self {
            Self::ImuBeyondRange => "imu_beyond_range",
            Self::NegativeRange => "negative_range",
            Self::RangeBeyondHall => "range_beyond_hall",
            Self::Sensor(kind) => kind.info().rejection.unwrap_or(kind.info().name),
        }
    }

    /// Its place in [`Rejection::ALL`].
    fn index(self) -> usize {
        Self::ALL.iter().position(|r| *r == self).unwrap_or(0)
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
        self.counts[r.index()] += 1;
    }

    /// The count of one kind.
    pub fn of(&self, r: Rejection) -> usize {
        self.counts[r.index()]
    }

    /// Every kind with its count, in [`Rejection::ALL`] order.
    pub fn by_kind(&self) -> impl Iterator<Item = (Rejection, usize)> + '_ {
        Rejection::ALL.into_iter().zip(self.counts)
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
    /// The grown box's lowest and highest corners, m.
    hall: (Vec3, Vec3),
}

impl Gate {
    /// The gate of `config` for `anchors` (navigation frame, m).
    pub fn new(anchors: &[Vec3], config: &GateConfig) -> Self {
        let margin = Vec3::repeat(config.hall_margin_m);
        let lo = anchors.iter().fold(Vec3::repeat(f64::INFINITY), |m, a| m.inf(a)) - margin;
        let hi = anchors.iter().fold(Vec3::repeat(f64::NEG_INFINITY), |m, a| m.sup(a)) + margin;
        // The farthest corner of the box from each anchor.
        let longest_range_m = anchors.iter().map(|a| Vec3::from_fn(|i, _| (a[i] - lo[i]).max(hi[i] - a[i])).norm()).collect();
        Self { config: *config, anchors: anchors.to_vec(), longest_range_m, hall: (lo, hi) }
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
            Event::Observation(o) => {
                let hall = Hall { anchors: &self.anchors, lo: self.hall.0, hi: self.hall.1, config: &self.config };
                (!plausible(o, &hall)).then_some(Rejection::Sensor(o.kind()))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use uwbimu_vocabulary::records::{AltitudeSample, ImuSample, OdometrySample, RangeMeasurement, TdoaMeasurement};
    use uwbimu_vocabulary::sensors::pose_fix::PoseFix;
    use uwbimu_vocabulary::sensors::Observation;

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
        assert_eq!(gate().check(&tdoa(10.6)), Some(Rejection::Sensor(SensorKind::Tdoa)));
        assert_eq!(gate().check(&tdoa(-10.6)), Some(Rejection::Sensor(SensorKind::Tdoa)));
    }

    #[test]
    fn heights_outside_the_grown_hall_and_speeds_beyond_the_range_are_impossible() {
        let altitude = |z_m| Event::Observation(Observation::Altitude(AltitudeSample { t_s: 0.0, z_m }));
        // Anchors' z spans [0, 3], grown by 5 m.
        assert_eq!(gate().check(&altitude(-4.99)), None);
        assert_eq!(gate().check(&altitude(7.99)), None);
        assert_eq!(gate().check(&altitude(-5.01)), Some(Rejection::Sensor(SensorKind::Altitude)));
        assert_eq!(gate().check(&altitude(1200.0)), Some(Rejection::Sensor(SensorKind::Altitude)));
        let speed = |speed_mps| Event::Observation(Observation::Odometry(OdometrySample { t_s: 0.0, axis: 0, speed_mps }));
        assert_eq!(gate().check(&speed(-29.0)), None);
        assert_eq!(gate().check(&speed(-31.0)), Some(Rejection::Sensor(SensorKind::Odometry)));
        assert_eq!(gate().check(&speed(31.0)), Some(Rejection::Sensor(SensorKind::Odometry)));
        let fix = |x: f64, z: f64| {
            let (position, position_std) = (Vec3::new(x, 4.0, z), Vec3::repeat(0.1));
            Event::Observation(Observation::PoseFix(PoseFix {
                t_s: 0.0,
                position,
                position_std,
                yaw_rad: f64::NAN,
                yaw_std_rad: f64::NAN,
            }))
        };
        // The grown box: x in [-5, 15], z in [-5, 8].
        assert_eq!(gate().check(&fix(14.99, 7.99)), None);
        assert_eq!(gate().check(&fix(15.01, 1.0)), Some(Rejection::Sensor(SensorKind::PoseFix)));
        assert_eq!(gate().check(&fix(3.0, -5.01)), Some(Rejection::Sensor(SensorKind::PoseFix)));
        let names: Vec<&str> = Rejection::ALL.iter().map(|r| r.name()).collect();
        assert_eq!(names[3..], ["tdoa_beyond_baseline", "altitude_beyond_hall", "speed_beyond_range", "pose_fix_beyond_hall"]);
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
