//! The UWB measurements as the filters get them, one at a time: moved from the UWB system's clock
//! onto the IMU's by `ranging.time_offset_s` (ranges and the sensors of the UWB clock, such as
//! TDoA) and ranges calibrated by `range_calibration` (Wang et al. 2018 §2.2). The batch runner
//! ([`crate::methods::run_method`]) and the streamed replay apply it alike, so both give the
//! filter the same measurements.

use uwbimu_vocabulary::config::{FilterConfig, RangeCalibration};
use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::records::RangeMeasurement;
use uwbimu_vocabulary::sensors::{Clock, Observation};

/// The time offset and calibration of one run, with the count of ranges calibrated so far (a
/// range's row in the errors).
#[derive(Debug, Clone)]
pub(crate) struct UwbClock<'c> {
    calibration: &'c RangeCalibration,
    offset_s: f64,
    imu_span_s: Option<(f64, f64)>,
    calibrated: usize,
}

impl<'c> UwbClock<'c> {
    /// The clock of `config` for IMU samples spanning `imu_span_s` (first and last time, s; None
    /// without samples). The calibration's anchors are checked by the caller
    /// ([`RangeCalibration::check_anchors`]).
    pub(crate) fn new(config: &'c FilterConfig, imu_span_s: Option<(f64, f64)>) -> Self {
        Self { calibration: &config.range_calibration, offset_s: config.ranging.time_offset_s, imu_span_s, calibrated: 0 }
    }

    /// The time offset, s: a measurement at `t` on the UWB clock is at `t + offset` on the IMU's.
    pub(crate) fn offset_s(&self) -> f64 {
        self.offset_s
    }

    /// `t_s` of the UWB clock on the IMU's: `t + offset`; None when that leaves the IMU span
    /// (never without an offset).
    fn time(&self, t_s: f64) -> Option<f64> {
        if self.offset_s == 0.0 {
            return Some(t_s);
        }
        let t = t_s + self.offset_s;
        self.imu_span_s.filter(|(a, b)| t >= *a && t <= *b).map(|_| t)
    }

    /// The range `r` as the filter gets it: on the IMU's clock, then calibrated (its row the
    /// count of ranges kept before it); None when the offset moves it out of the IMU span.
    ///
    /// # Errors
    /// As [`RangeCalibration::apply_one`] (a calibration giving a negative range).
    pub(crate) fn range(&mut self, r: &RangeMeasurement) -> Result<Option<RangeMeasurement>> {
        let Some(t_s) = self.time(r.t_s) else { return Ok(None) };
        self.calibrated += 1;
        self.calibration.apply_one(self.calibrated - 1, &RangeMeasurement { t_s, ..*r }).map(Some)
    }

    /// The observation `o` as the filter gets it: on the IMU's clock when it is on the UWB
    /// system's (None when the offset moves it out of the IMU span), else as it is.
    pub(crate) fn observation(&self, o: &Observation) -> Option<Observation> {
        match o.kind().info().clock {
            Clock::Uwb => self.time(o.t_s()).map(|t_s| o.at(t_s)),
            Clock::Imu => Some(*o),
        }
    }
}
