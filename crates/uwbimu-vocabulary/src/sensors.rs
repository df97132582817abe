//! The sensor registry: every measurement besides the IMU and the UWB ranges, each declared once
//! as a row of the `sensors!` declaration below — its record type, its name, the Python keyword
//! of its array, its label, the rank of its events at equal times and its clock. From the rows
//! come [`Observation`] (a measurement applied at its own time), [`SensorKind`] with its
//! [`SensorInfo`], and the validation of a table of rows into time-ordered observations
//! ([`SensorKind::observations`]); each record type says how one row becomes a record
//! ([`SensorRecord`]). The layers above derive their lists from [`SensorKind::ALL`] (the inputs a
//! method takes, the Python keyword arguments and the stub, the update columns).
//!
//! Adding a sensor: its record (a [`SensorRecord`]) and configuration section in a module of its
//! own ([`pose_fix`] is the example), a row here, its measurement model (`uwbimu_estimation`), its
//! topic decoder (`uwbimu_io`) and its docs page (docs/architecture.md, "Adding a sensor").

pub mod pose_fix;

use crate::config::sections::{AltitudeConfig, OdometryConfig, SectionVisitor, SectionVisitorMut};
use crate::error::{Error, Result};
use crate::math::Vec3;
use crate::records::{AltitudeSample, MagSample, OdometrySample, TdoaMeasurement};
use crate::validate::anchor_index;
use pose_fix::{PoseFix, PoseFixConfig};

/// How the rows of a sensor's table must be ordered in time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimeOrder {
    /// Strictly increasing (one sample per time: a magnetometer).
    Increasing,
    /// Non-decreasing (several measurements may share a time: TDoA of one round).
    NonDecreasing,
}

/// Which clock a sensor's times are on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Clock {
    /// The IMU's (a magnetometer in the same chip, a sensor of the same computer).
    Imu,
    /// The UWB system's: shifted by `ranging.time_offset_s` like the ranges.
    Uwb,
}

/// What the registry says of a sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SensorInfo {
    /// Its name: the input a method takes (`METHODS[name]["takes"]`), the stream in messages, the
    /// streaming call `add_<name>` and the `sensor` column of the updates.
    pub name: &'static str,
    /// The Python keyword argument of its array (`run_filter(..., <keyword>=...)`).
    pub keyword: &'static str,
    /// What it measures, in messages ("TDoA given, but eskf does not take TDoA").
    pub label: &'static str,
    /// Rank of its events among events at one time (the IMU is 0, ranges come last).
    pub rank: u8,
    /// The columns of its table, one list per accepted layout (the first the full one).
    pub layouts: &'static [&'static [&'static str]],
    /// The time order its table must have.
    pub time_order: TimeOrder,
    /// The clock of its times.
    pub clock: Clock,
    /// The name of the gate's count of its readings no sensor or geometry can produce
    /// (`uwbimu_estimation::gate`, the `health` of a run); None for a sensor the gate passes.
    pub rejection: Option<&'static str>,
    /// Whether every filter that applies scalar measurement models takes it (the registry's
    /// `Aiding` input); false for a sensor only a method of its paper takes (the magnetometer of
    /// `ackf`), which that method's row names.
    pub aiding: bool,
    /// The columns of its table that hold anchor indices ([`SensorRecord::ANCHOR_COLUMNS`]).
    pub anchor_columns: &'static [usize],
    /// Its row's doc comment (one line per doc line): what it is and where it is documented.
    pub doc: &'static str,
}

/// A sensor's record: how one row of its table (in one of its layouts) becomes a record, and its
/// time.
pub trait SensorRecord: Copy + Sized {
    /// The columns of the sensor's table, one list per accepted layout; column 0 is the time, s.
    const LAYOUTS: &'static [&'static [&'static str]];
    /// The time order of its table.
    const TIME_ORDER: TimeOrder;
    /// Whether a value (not the time) may be NaN, meaning "not measured" (an odometry axis).
    const MISSING_ALLOWED: bool = false;
    /// The columns that hold anchor indices (a TDoA's i and j), which anchors known by hardware
    /// ids rewrite from ids to rows ([`crate::anchor_ids::AnchorIds::to_rows`]).
    const ANCHOR_COLUMNS: &'static [usize] = &[];

    /// Time, s.
    fn t_s(&self) -> f64;

    /// The same record at time `t_s` (to shift a clock).
    fn at(&self, t_s: f64) -> Self;

    /// The measured value, in the sensor's unit (a vector's norm).
    fn value(&self) -> f64;

    /// The anchors it refers to (a TDoA's i and j).
    fn anchors(&self) -> [Option<usize>; 2] {
        [None, None]
    }

    /// The axis of a reading along one axis (an odometry reading's body axis).
    fn axis(&self) -> Option<usize> {
        None
    }

    /// The records as a table in one of [`SensorRecord::LAYOUTS`]: `(columns, values row by
    /// row)`; the inverse of [`SensorRecord::from_row`] on rows it accepts.
    fn table(records: &[Self]) -> (usize, Vec<f64>);

    /// Appends the records of row `row` (finite, or NaN where [`SensorRecord::MISSING_ALLOWED`]),
    /// `values` in one of [`SensorRecord::LAYOUTS`] (by its length), to `out`; `anchor_count` for
    /// the anchor columns. Fails naming `name` and the row.
    fn from_row(name: &'static str, row: usize, values: &[f64], anchor_count: usize, out: &mut Vec<Self>) -> Result<()>;
}

impl SensorRecord for MagSample {
    const LAYOUTS: &'static [&'static [&'static str]] = &[&["t", "mx", "my", "mz"]];
    const TIME_ORDER: TimeOrder = TimeOrder::Increasing;

    fn t_s(&self) -> f64 {
        self.t_s
    }

    fn at(&self, t_s: f64) -> Self {
        Self { t_s, ..*self }
    }

    fn value(&self) -> f64 {
        self.field.norm()
    }

    fn table(records: &[Self]) -> (usize, Vec<f64>) {
        (4, records.iter().flat_map(|m| [m.t_s, m.field.x, m.field.y, m.field.z]).collect())
    }

    fn from_row(_: &'static str, _: usize, v: &[f64], _: usize, out: &mut Vec<Self>) -> Result<()> {
        out.push(Self { t_s: v[0], field: Vec3::new(v[1], v[2], v[3]) });
        Ok(())
    }
}

impl SensorRecord for TdoaMeasurement {
    const LAYOUTS: &'static [&'static [&'static str]] = &[&["t", "anchor i", "anchor j", "d_ij"]];
    const TIME_ORDER: TimeOrder = TimeOrder::NonDecreasing;
    const ANCHOR_COLUMNS: &'static [usize] = &[1, 2];

    fn t_s(&self) -> f64 {
        self.t_s
    }

    fn at(&self, t_s: f64) -> Self {
        Self { t_s, ..*self }
    }

    fn value(&self) -> f64 {
        self.tdoa_m
    }

    fn anchors(&self) -> [Option<usize>; 2] {
        [Some(self.anchor_i), Some(self.anchor_j)]
    }

    fn table(records: &[Self]) -> (usize, Vec<f64>) {
        (4, records.iter().flat_map(|m| [m.t_s, m.anchor_i as f64, m.anchor_j as f64, m.tdoa_m]).collect())
    }

    /// Both anchors known and distinct.
    fn from_row(name: &'static str, row: usize, v: &[f64], anchor_count: usize, out: &mut Vec<Self>) -> Result<()> {
        let (anchor_i, anchor_j) = (anchor_index(name, row, v[1], anchor_count)?, anchor_index(name, row, v[2], anchor_count)?);
        if anchor_i == anchor_j {
            return Err(Error::InvalidValue { name, row, value: v[1], reason: "anchor i and anchor j must differ" });
        }
        out.push(Self { t_s: v[0], anchor_i, anchor_j, tdoa_m: v[3] });
        Ok(())
    }
}

impl SensorRecord for AltitudeSample {
    const LAYOUTS: &'static [&'static [&'static str]] = &[&["t", "z"]];
    const TIME_ORDER: TimeOrder = TimeOrder::Increasing;

    fn t_s(&self) -> f64 {
        self.t_s
    }

    fn at(&self, t_s: f64) -> Self {
        Self { t_s, ..*self }
    }

    fn value(&self) -> f64 {
        self.z_m
    }

    fn table(records: &[Self]) -> (usize, Vec<f64>) {
        (2, records.iter().flat_map(|m| [m.t_s, m.z_m]).collect())
    }

    fn from_row(_: &'static str, _: usize, v: &[f64], _: usize, out: &mut Vec<Self>) -> Result<()> {
        out.push(Self { t_s: v[0], z_m: v[1] });
        Ok(())
    }
}

impl SensorRecord for OdometrySample {
    const LAYOUTS: &'static [&'static [&'static str]] = &[&["t", "speed"], &["t", "vx", "vy", "vz"]];
    const TIME_ORDER: TimeOrder = TimeOrder::Increasing;
    const MISSING_ALLOWED: bool = true;

    fn t_s(&self) -> f64 {
        self.t_s
    }

    fn at(&self, t_s: f64) -> Self {
        Self { t_s, ..*self }
    }

    fn value(&self) -> f64 {
        self.speed_mps
    }

    fn axis(&self) -> Option<usize> {
        Some(self.axis)
    }

    /// `t, speed` when every record is of the x axis, else `t, vx, vy, vz` with one row per time
    /// (consecutive records of one time) and NaN for an axis not read.
    fn table(records: &[Self]) -> (usize, Vec<f64>) {
        if records.iter().all(|m| m.axis == 0) {
            return (2, records.iter().flat_map(|m| [m.t_s, m.speed_mps]).collect());
        }
        let mut values: Vec<f64> = Vec::new();
        let mut last_t = None;
        for m in records {
            if last_t != Some(m.t_s) {
                values.extend([m.t_s, f64::NAN, f64::NAN, f64::NAN]);
                last_t = Some(m.t_s);
            }
            let row = values.len() - 4;
            values[row + 1 + m.axis] = m.speed_mps;
        }
        (4, values)
    }

    /// One record per axis measured (not NaN); a row that measures none is refused.
    fn from_row(name: &'static str, row: usize, v: &[f64], _: usize, out: &mut Vec<Self>) -> Result<()> {
        let before = out.len();
        out.extend(v[1..].iter().enumerate().filter(|(_, s)| !s.is_nan()).map(|(axis, &speed_mps)| Self {
            t_s: v[0],
            axis,
            speed_mps,
        }));
        if out.len() == before {
            return Err(Error::InvalidValue { name, row, value: f64::NAN, reason: "the row measures no axis (all NaN)" });
        }
        Ok(())
    }
}

/// Declares the sensor registry (see the module doc): one row per sensor — its [`Observation`]
/// variant and record type, its name, keyword, label, rank and clock, with its doc.
macro_rules! sensors {
    ($(
        $(#[doc = $doc:literal])+
        $variant:ident($record:ty) {
            name: $name:literal,
            keyword: $keyword:literal,
            label: $label:literal,
            rank: $rank:literal,
            clock: $clock:ident,
            rejection: $rejection:expr,
            aiding: $aiding:literal
            $(, section: $sfield:ident: $sty:ty)? $(,)?
        }
    ),+ $(,)?) => {
        /// A measurement applied on its own at its own time (not gathered into range epochs):
        /// what the pipeline hands to `uwbimu_estimation::filters::Filter::observe`, one variant
        /// per row of the sensor registry.
        #[derive(Debug, Clone, Copy, PartialEq)]
        pub enum Observation {
            $($(#[doc = $doc])+ $variant($record),)+
        }

        /// The kinds of [`Observation`], one per registry row.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum SensorKind {
            $($(#[doc = $doc])+ $variant,)+
        }

        impl SensorKind {
            /// Every sensor, in registry order.
            pub const ALL: &'static [SensorKind] = &[$(SensorKind::$variant),+];

            /// The sensor's row.
            pub const fn info(self) -> &'static SensorInfo {
                match self {
                    $(SensorKind::$variant => &SensorInfo {
                        name: $name,
                        keyword: $keyword,
                        label: $label,
                        rank: $rank,
                        layouts: <$record as SensorRecord>::LAYOUTS,
                        time_order: <$record as SensorRecord>::TIME_ORDER,
                        clock: Clock::$clock,
                        rejection: $rejection,
                        aiding: $aiding,
                        anchor_columns: <$record as SensorRecord>::ANCHOR_COLUMNS,
                        doc: concat!($($doc, "\n"),+),
                    },)+
                }
            }

            /// The observations of this sensor among `observations`, as its table
            /// ([`SensorRecord::table`]: `(columns, values row by row)`).
            pub fn table(self, observations: &[Observation]) -> (usize, Vec<f64>) {
                match self {
                    $(SensorKind::$variant => {
                        let records: Vec<$record> = observations
                            .iter()
                            .filter_map(|o| match o {
                                Observation::$variant(m) => Some(*m),
                                _ => None,
                            })
                            .collect();
                        <$record as SensorRecord>::table(&records)
                    })+
                }
            }

            /// Validates the rows of a table of this sensor (`rows` of one of its layouts, time
            /// order as declared) into observations.
            pub fn observations(self, rows: &[&[f64]], anchor_count: usize) -> Result<Vec<Observation>> {
                match self {
                    $(SensorKind::$variant => Ok(validate_records::<$record>($keyword, rows, anchor_count)?
                        .into_iter()
                        .map(Observation::$variant)
                        .collect()),)+
                }
            }
        }

        impl Observation {
            /// Measurement time, s.
            pub fn t_s(&self) -> f64 {
                match self {
                    $(Self::$variant(m) => m.t_s(),)+
                }
            }

            /// The measured value ([`SensorRecord::value`]).
            pub fn value(&self) -> f64 {
                match self {
                    $(Self::$variant(m) => m.value(),)+
                }
            }

            /// The anchors it refers to ([`SensorRecord::anchors`]).
            pub fn anchors(&self) -> [Option<usize>; 2] {
                match self {
                    $(Self::$variant(m) => m.anchors(),)+
                }
            }

            /// The axis of a one-axis reading ([`SensorRecord::axis`]).
            pub fn axis(&self) -> Option<usize> {
                match self {
                    $(Self::$variant(m) => m.axis(),)+
                }
            }

            /// Its kind.
            pub fn kind(&self) -> SensorKind {
                match self {
                    $(Self::$variant(_) => SensorKind::$variant,)+
                }
            }

            /// The same observation at time `t_s` ([`SensorRecord::at`]).
            pub fn at(&self, t_s: f64) -> Self {
                match self {
                    $(Self::$variant(m) => Self::$variant(m.at(t_s)),)+
                }
            }
        }

        /// The configuration sections of the sensors whose row declares one, in registry order:
        /// a field of [`crate::config::FilterConfig`], its keys `<section>.<field>`.
        #[derive(Debug, Clone, Copy, PartialEq, Default)]
        pub struct SensorSections {
            $($(
                #[doc = concat!("The section of ", $label, " (keys `", stringify!($sfield), ".*`).")]
                pub $sfield: $sty,
            )?)+
        }

        impl SensorSections {
            /// Calls `v` with each section, in registry order.
            pub fn visit(&self, v: &mut impl SectionVisitor) {
                $($( v.visit(&self.$sfield); )?)+
            }

            /// Calls `v` with each section, mutably, in registry order.
            pub fn visit_mut(&mut self, v: &mut impl SectionVisitorMut) {
                $($( v.visit(&mut self.$sfield); )?)+
            }
        }

        $(impl From<$record> for Observation {
            fn from(m: $record) -> Self {
                Self::$variant(m)
            }
        })+
    };
}

sensors! {
    /// Magnetometer samples `t, mx, my, mz` in the IMU frame, in the unit of the configured
    /// field (µT, T), time strictly increasing; only `ackf` uses them (the ACKF paper's
    /// geomagnetic aiding).
    Magnetometer(MagSample) {
        name: "magnetometer", keyword: "mag", label: "magnetometer samples", rank: 1, clock: Imu, rejection: None, aiding: false,
    },
    /// Time differences of arrival `t, i, j, d_ij`, `d_ij = ‖p − a_j‖ − ‖p − a_i‖` in m (Loco
    /// Positioning TDoA2/TDoA3), time non-decreasing, each applied at its own time with σ
    /// `ranging.tdoa_std`, with ranges or alone (docs/tdoa.md).
    Tdoa(TdoaMeasurement) {
        name: "tdoa", keyword: "tdoa", label: "TDoA", rank: 2, clock: Uwb, rejection: Some("tdoa_beyond_baseline"), aiding: true,
    },
    /// Heights `t, z` in m of the body origin, navigation frame, up, time strictly increasing,
    /// σ `altitude.std`: a time-of-flight sensor over a flat floor or a barometer
    /// (docs/altitude.md).
    Altitude(AltitudeSample) {
        name: "altitude", keyword: "altitude", label: "altitude", rank: 3, clock: Imu, rejection: Some("altitude_beyond_hall"), aiding: true,
        section: altitude: AltitudeConfig,
    },
    /// Wheel odometry `t, speed` along the body x axis, or `t, vx, vy, vz` in the body frame
    /// with NaN for an axis not measured, m/s, time strictly increasing, σ `odometry.std` per
    /// axis (docs/odometry.md).
    Odometry(OdometrySample) {
        name: "odometry", keyword: "odometry", label: "odometry", rank: 4, clock: Imu, rejection: Some("speed_beyond_range"), aiding: true,
        section: odometry: OdometryConfig,
    },
    /// External pose fixes `t, x, y, z, sx, sy, sz`, optionally with `yaw, s_yaw` (NaN where a
    /// fix gives none): the position in m of the point at `pose_fix.lever_arm` and the body's
    /// yaw in rad (ENU, from east), navigation frame, each with its σ, time strictly increasing
    /// (docs/pose-fix.md).
    PoseFix(PoseFix) {
        name: "pose_fix", keyword: "pose_fix", label: "pose fixes", rank: 5, clock: Imu, rejection: Some("pose_fix_beyond_hall"), aiding: true,
        section: pose_fix: PoseFixConfig,
    },
}

/// Rank of a range among events at one time: after every sensor of the registry.
pub const RANGE_RANK: u8 = SensorKind::ALL.len() as u8 + 1;

impl Observation {
    /// The sensor's name ([`SensorInfo::name`]).
    pub fn stream(&self) -> &'static str {
        self.kind().info().name
    }

    /// Rank among events at one time ([`SensorInfo::rank`]).
    pub fn rank(&self) -> u8 {
        self.kind().info().rank
    }
}

impl SensorKind {
    /// Parses a sensor name ([`SensorInfo::name`]); the error lists them.
    pub fn parse(name: &str) -> Result<Self> {
        Self::ALL
            .iter()
            .copied()
            .find(|k| k.info().name == name)
            .ok_or_else(|| Error::unknown_option("sensor", name, Self::ALL.iter().map(|k| k.info().name)))
    }
}

/// Validates `rows` (each finite, in one of `R`'s layouts, in its time order) into records; errors
/// name the table `name`, the row and the column.
pub fn validate_records<R: SensorRecord>(name: &'static str, rows: &[&[f64]], anchor_count: usize) -> Result<Vec<R>> {
    let mut out = Vec::with_capacity(rows.len());
    let mut prev = f64::NEG_INFINITY;
    for (row, values) in rows.iter().enumerate() {
        if !R::LAYOUTS.iter().any(|l| l.len() == values.len()) {
            let expected = R::LAYOUTS.iter().map(|l| format!("({}) = {}", l.len(), l.join(", "))).collect::<Vec<_>>();
            return Err(Error::Shape {
                name,
                expected: expected.join(" or "),
                got: format!("{} columns at row {row}", values.len()),
            });
        }
        let missing = |col: usize, v: f64| R::MISSING_ALLOWED && col > 0 && v.is_nan();
        if let Some(col) = values.iter().enumerate().position(|(col, v)| !v.is_finite() && !missing(col, *v)) {
            return Err(Error::NonFinite { name, row, col, value: values[col] });
        }
        let t = values[0];
        let out_of_order = match R::TIME_ORDER {
            TimeOrder::Increasing => t <= prev,
            TimeOrder::NonDecreasing => t < prev,
        };
        if out_of_order {
            return Err(Error::NonMonotonicTime { name, row, prev_s: prev, got_s: t });
        }
        prev = t;
        R::from_row(name, row, values, anchor_count, &mut out)?;
    }
    Ok(out)
}

/// Merges observations of several sensors into one sequence in time order (at equal times by
/// rank, each sensor's own order kept).
pub fn merge(sets: &[&[Observation]]) -> Vec<Observation> {
    let mut all: Vec<Observation> = sets.iter().flat_map(|s| s.iter().copied()).collect();
    all.sort_by(|a, b| a.t_s().total_cmp(&b.t_s()).then(a.rank().cmp(&b.rank())));
    all
}

/// Observations of the records `records` (e.g. a simulated run's TDoA).
pub fn observations<R: Into<Observation> + Copy>(records: &[R]) -> Vec<Observation> {
    records.iter().map(|&r| r.into()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rows_declare_distinct_names_keywords_and_ranks() {
        for (i, a) in SensorKind::ALL.iter().enumerate() {
            assert!(a.info().rank > 0 && a.info().rank < RANGE_RANK, "{a:?}: the IMU is 0, ranges last");
            assert_eq!(SensorKind::parse(a.info().name), Ok(*a));
            for b in &SensorKind::ALL[i + 1..] {
                let (x, y) = (a.info(), b.info());
                assert!(x.name != y.name && x.keyword != y.keyword && x.rank != y.rank, "{a:?} and {b:?}");
            }
        }
        assert!(SensorKind::parse("barometer").is_err());
    }

    #[test]
    fn tables_are_checked_and_merged_in_time_then_rank_order() {
        let tdoa: [&[f64]; 2] = [&[1.0, 0.0, 1.0, 0.5], &[1.0, 2.0, 1.0, -0.3]];
        let tdoa = SensorKind::Tdoa.observations(&tdoa, 3).expect("valid");
        let mag: [&[f64]; 2] = [&[0.5, 20.0, 0.0, -40.0], &[1.0, 21.0, 0.0, -40.0]];
        let mag = SensorKind::Magnetometer.observations(&mag, 3).expect("valid");
        let merged = merge(&[&tdoa, &mag]);
        let kinds: Vec<SensorKind> = merged.iter().map(Observation::kind).collect();
        assert_eq!(kinds, [SensorKind::Magnetometer, SensorKind::Magnetometer, SensorKind::Tdoa, SensorKind::Tdoa]);
        // Two magnetometer samples at one time, a wrong width, a NaN.
        let same: [&[f64]; 2] = [&[1.0, 0.0, 0.0, 1.0], &[1.0, 0.0, 0.0, 1.0]];
        assert!(matches!(SensorKind::Magnetometer.observations(&same, 3), Err(Error::NonMonotonicTime { row: 1, .. })));
        let narrow: [&[f64]; 1] = [&[1.0, 0.0]];
        let e = SensorKind::Tdoa.observations(&narrow, 3).unwrap_err().to_string();
        assert!(e.contains("tdoa") && e.contains("(4) = t, anchor i, anchor j, d_ij"), "{e}");
        let nan: [&[f64]; 1] = [&[1.0, 0.0, 1.0, f64::NAN]];
        assert!(matches!(SensorKind::Tdoa.observations(&nan, 3), Err(Error::NonFinite { row: 0, col: 3, .. })));
    }

    #[test]
    fn odometry_rows_give_one_reading_per_axis_measured_and_tables_give_the_rows_back() {
        let rows: [&[f64]; 3] = [&[0.0, 0.5, 0.0, f64::NAN], &[0.1, 0.6, f64::NAN, f64::NAN], &[0.2, f64::NAN, 0.01, 0.0]];
        let readings = validate_records::<OdometrySample>("odometry", &rows, 0).expect("valid");
        let axes: Vec<(f64, usize)> = readings.iter().map(|m| (m.t_s, m.axis)).collect();
        assert_eq!(axes, [(0.0, 0), (0.0, 1), (0.1, 0), (0.2, 1), (0.2, 2)]);
        let (columns, values) = OdometrySample::table(&readings);
        assert_eq!(columns, 4);
        let flat: Vec<f64> = rows.concat();
        assert!(values.iter().zip(&flat).all(|(a, b)| a == b || (a.is_nan() && b.is_nan())), "{values:?}");
        let none: [&[f64]; 1] = [&[0.0, f64::NAN, f64::NAN, f64::NAN]];
        assert!(validate_records::<OdometrySample>("odometry", &none, 0).is_err());
        let nan_time: [&[f64]; 1] = [&[f64::NAN, 0.5]];
        assert!(matches!(validate_records::<OdometrySample>("odometry", &nan_time, 0), Err(Error::NonFinite { col: 0, .. })));
        let speeds: [&[f64]; 2] = [&[0.0, 0.5], &[0.1, 0.6]];
        let x_only = validate_records::<OdometrySample>("odometry", &speeds, 0).expect("valid");
        assert_eq!(OdometrySample::table(&x_only), (2, speeds.concat()));
        let heights: [&[f64]; 2] = [&[0.0, 1.5], &[0.1, 1.4]];
        let altitude = validate_records::<AltitudeSample>("altitude", &heights, 0).expect("valid");
        assert_eq!(AltitudeSample::table(&altitude), (2, heights.concat()));
    }
}
