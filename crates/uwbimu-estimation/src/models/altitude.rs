//! An altitude reading (ours; none of the five papers fuses one): the height of the body origin in
//! the navigation frame, from a time-of-flight height sensor over a flat floor or a barometer
//! whose offset to the frame is removed.

use uwbimu_vocabulary::config::FilterConfig;
use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::records::AltitudeSample;
use uwbimu_vocabulary::state::{ErrVec, NominalState, POS};

use crate::models::aiding::{finite, Hall, ModelSink, ScalarAiding, SensorRule};
use crate::models::{AdditiveBias, Block, Geometry, ScalarModel, ScalarPrediction};
use crate::update::UpdateReport;

/// `h(x) = p_z` (`+ b_alt` with the offset state, `altitude.offset_std` > 0), Jacobian `e_zᵀ` on
/// δp (and 1 on the offset), noise `altitude.std`, the filter's symmetric robust test.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Altitude {
    /// Measured height, navigation frame, m.
    pub z_m: f64,
}

impl ScalarModel for Altitude {
    const OBSERVES: &'static [Block] = &[Block::Position];

    fn value(&self) -> f64 {
        self.z_m
    }

    fn predict(&self, x: &NominalState, _: &Geometry<'_>) -> Option<ScalarPrediction> {
        let mut jacobian = ErrVec::zeros();
        jacobian[POS + 2] = 1.0;
        Some(ScalarPrediction { value: x.position.z, jacobian })
    }

    fn nominal_var(&self, config: &FilterConfig) -> f64 {
        config.sensors.altitude.std.powi(2)
    }

    fn additive_bias(&self) -> Option<AdditiveBias> {
        Some(AdditiveBias::AltitudeOffset)
    }

    fn examples() -> Vec<Self> {
        vec![Self { z_m: 1.2 }]
    }
}

/// The gate passes a height within the grown hall's.
impl SensorRule for AltitudeSample {
    fn plausible(&self, hall: &Hall<'_>) -> bool {
        (hall.lo.z..=hall.hi.z).contains(&self.z_m)
    }
}

/// One [`Altitude`] model per reading; a height leaves the horizontal free, so it is no aiding
/// for the outage guard.
impl ScalarAiding for AltitudeSample {
    const NOTES_AIDING: bool = false;

    fn check(&self) -> Result<()> {
        finite("update_altitude", 1, self.z_m)
    }

    fn apply<S: ModelSink>(&self, sink: &mut S) -> Result<UpdateReport> {
        sink.apply(Altitude { z_m: self.z_m })
    }
}
