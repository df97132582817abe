//! The method registry: one row per named method of the batch API (the `methods!` declaration)
//! and what the library says about each — [`Method`], its name, how it runs ([`Run`]: the filter
//! it runs, whose type is its streaming class), what it takes ([`Input`]), its smoothing
//! ([`Smoothing`]), its doc ([`MethodInfo`]). It depends on no other module of this crate; the
//! runner runs a method by its [`Run`] ([`crate::run`], [`crate::methods`]).

use uwbimu_estimation::filters::InertialKind;
use uwbimu_estimation::planar::PlanarKind;
use uwbimu_vocabulary::error::{Error, Result};
use uwbimu_vocabulary::sensors::SensorKind;

/// What a method takes besides IMU samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    /// Ranges to anchors.
    Ranges,
    /// Ranges from several tags (a `tag` column beyond 0), each at its lever arm.
    Tags,
    /// A sensor of the registry ([`uwbimu_vocabulary::sensors`]).
    Sensor(SensorKind),
    /// In a row: every sensor the registry marks `aiding` (those every filter that applies
    /// scalar measurement models takes), so a new such sensor needs no row changed.
    Aiding,
}

impl Input {
    /// Every input a method may take, in this order: ranges, ranges from several tags, then each
    /// sensor of the registry (`uwbimu_rs.INPUTS`; [`Input::Aiding`] is a row's shorthand, not an
    /// input).
    pub fn all() -> impl Iterator<Item = Input> {
        [Self::Ranges, Self::Tags].into_iter().chain(SensorKind::ALL.iter().map(|k| Self::Sensor(*k)))
    }

    /// The input's name in Python (`METHODS[name]["takes"]`) and the docs: `ranges`, or the
    /// sensor's name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ranges => "ranges",
            Self::Tags => "tags",
            Self::Sensor(kind) => kind.info().name,
            Self::Aiding => "aiding",
        }
    }
}

/// Whether and when the batch API RTS-smooths a method's run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Smoothing {
    /// Never: the method has no inertial 15-state record to smooth.
    Never,
    /// When asked (`smooth=True`, `--smooth`).
    OnRequest,
    /// Unless a forward pass is asked for.
    ByDefault,
}

impl Smoothing {
    /// The smoothing's name in Python (`METHODS[name]["smoothing"]`) and the docs.
    pub fn name(self) -> &'static str {
        match self {
            Self::Never => "never",
            Self::OnRequest => "on_request",
            Self::ByDefault => "by_default",
        }
    }
}

/// How a method runs: the solver or filter of its registry row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Run {
    /// UWB-only least squares per epoch ([`uwbimu_estimation::multilateration::uwb_ls`]); not
    /// streamed.
    Multilateration,
    /// The 15-state filter of the type the kind names, which is also the method's streaming
    /// class.
    Inertial(InertialKind),
    /// A planar filter of Wang et al. (2018) ([`uwbimu_estimation::planar::PlanarFilter`]).
    Planar(PlanarKind),
}

/// One row of the method registry (the `methods!` declaration in this module): everything the
/// library says about a method.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MethodInfo {
    /// The name the batch API, replay files and the CLI take.
    pub name: &'static str,
    /// How it runs.
    pub run: Run,
    /// The measurements it takes besides IMU samples, as its row lists them ([`Method::takes`]
    /// reads [`Input::Aiding`]).
    pub takes: &'static [Input],
    /// When it is smoothed.
    pub smoothing: Smoothing,
    /// Whether the batch method chooses its range-error model, NLOS skew and range noise on the
    /// log ([`crate::select`]); a row says `chooses_model: true`, the others leave it out.
    pub chooses_model: bool,
    /// Its doc comment (one line per doc line): the composition and where it comes from.
    pub doc: &'static str,
}

impl MethodInfo {
    /// Its streaming class in Python (`uwbimu_rs.<class>`), if it has one: the type of its
    /// inertial filter ([`InertialKind::type_name`]).
    pub fn streaming_class(&self) -> Option<&'static str> {
        match self.run {
            Run::Inertial(kind) => Some(kind.type_name()),
            Run::Multilateration | Run::Planar(_) => None,
        }
    }
}

/// Declares [`Method`] (a variant per row, with the row's doc), [`Method::ALL`] and
/// [`Method::info`] from the rows it is given; its one invocation below is the registry. A row
/// gives the variant, then its name, how it runs (`run:`, a [`Run`] with its [`InertialKind`] or
/// [`PlanarKind`] named without the enum: `Inertial(Ekf)`), what it takes (an [`Input`] or a
/// sensor of [`SensorKind`]), its smoothing, and `chooses_model: true` when it chooses its model.
macro_rules! methods {
    ($(
        $(#[doc = $doc:literal])+
        $variant:ident {
            name: $name:literal,
            run: $run:ident $(($kind:ident))?,
            takes: [$($input:ident),+],
            smoothing: $smoothing:ident
            $(, chooses_model: $chooses:literal)? $(,)?
        }
    ),+ $(,)?) => {
        /// A method name accepted by the batch API, one per row of the registry.
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        pub enum Method {
            $($(#[doc = $doc])+ $variant,)+
        }

        impl Method {
            /// Every method, in registry order (the order of `uwbimu_rs.FILTERS`).
            pub const ALL: &'static [Method] = &[$(Method::$variant),+];

            /// The method's registry row.
            pub const fn info(self) -> &'static MethodInfo {
                match self {
                    $(Method::$variant => &MethodInfo {
                        name: $name,
                        run: methods!(@run $run $($kind)?),
                        takes: &[$(methods!(@input $input)),+],
                        smoothing: Smoothing::$smoothing,
                        chooses_model: methods!(@chooses $($chooses)?),
                        doc: concat!($($doc, "\n"),+),
                    },)+
                }
            }
        }
    };
    (@run Multilateration) => { Run::Multilateration };
    (@run Inertial $kind:ident) => { Run::Inertial(InertialKind::$kind) };
    (@run Planar $kind:ident) => { Run::Planar(PlanarKind::$kind) };
    (@input Ranges) => { Input::Ranges };
    (@input Tags) => { Input::Tags };
    (@input Aiding) => { Input::Aiding };
    (@input $sensor:ident) => { Input::Sensor(SensorKind::$sensor) };
    (@chooses) => { false };
    (@chooses $chooses:literal) => { $chooses };
}

// The registry: one row per method. Adding a method is adding a row (and, for a new inertial
// filter type, the type: docs/architecture.md, "Adding things").
methods! {
    /// UWB-only least squares per epoch (Liu et al. 2019 eqs. (8)–(13), then Gauss–Newton).
    UwbLs { name: "uwb_ls", run: Multilateration, takes: [Ranges], smoothing: Never },
    /// The tightly coupled EKF of Li & Wang (2020).
    Ekf { name: "ekf", run: Inertial(Ekf), takes: [Ranges, Tags, Aiding], smoothing: OnRequest },
    /// The iterated EKF (Li & Wang 2020, Algorithm 1 without re-weighting).
    Iekf { name: "iekf", run: Inertial(Iekf), takes: [Ranges, Tags, Aiding], smoothing: OnRequest },
    /// The robust EKF of Li & Wang (2020) (χ² inflation against the prior).
    Rekf { name: "rekf", run: Inertial(Rekf), takes: [Ranges, Tags, Aiding], smoothing: OnRequest },
    /// The robust iterated EKF of Li & Wang (2020) (Algorithm 1).
    Riekf { name: "riekf", run: Inertial(Riekf), takes: [Ranges, Tags, Aiding], smoothing: OnRequest },
    /// RIEKF with zero-velocity, pseudo-velocity and plane constraints (Li & Wang 2020, CRIEKF).
    Criekf { name: "criekf", run: Inertial(Criekf), takes: [Ranges, Tags, Aiding], smoothing: OnRequest },
    /// The complementary Kalman filter of the ARCKF paper (Sensors 2018).
    Ckf { name: "ckf", run: Inertial(Ckf), takes: [Ranges, Tags, Aiding], smoothing: OnRequest },
    /// The adaptive-robust complementary Kalman filter of the ARCKF paper (Sensors 2018).
    Arckf { name: "arckf", run: Inertial(Arckf), takes: [Ranges, Tags, Aiding], smoothing: OnRequest },
    /// The adaptive complementary Kalman filter with gravity and geomagnetic aiding (the ACKF paper).
    Ackf {
        name: "ackf",
        run: Inertial(Ackf),
        takes: [Ranges, Tags, Aiding, Magnetometer],
        smoothing: OnRequest,
    },
    /// The loosely coupled error-state filter of Liu et al. (2019).
    Eskf { name: "eskf", run: Inertial(Eskf), takes: [Ranges], smoothing: OnRequest },
    /// The Sage–Husa adaptive ESKF of Liu et al. (2019).
    Shaf { name: "shaf", run: Inertial(Shaf), takes: [Ranges], smoothing: OnRequest },
    /// The Sage–Husa fuzzy adaptive ESKF of Liu et al. (2019).
    Shfaf { name: "shfaf", run: Inertial(Shfaf), takes: [Ranges], smoothing: OnRequest },
    /// The 15-state error-state UKF (Wang et al. 2018 eqs. (11)–(14) on the INS error state).
    Ukf { name: "ukf", run: Inertial(Ukf), takes: [Ranges, Tags, Aiding], smoothing: OnRequest },
    /// The robust 15-state error-state UKF (ours): ukf's update with rekf's χ² inflation.
    Rukf { name: "rukf", run: Inertial(Rukf), takes: [Ranges, Tags, Aiding], smoothing: OnRequest },
    /// The planar 4-state EKF of Wang et al. (2018) (eqs. (5)–(10)).
    Ekf2d { name: "ekf2d", run: Planar(Ekf), takes: [Ranges], smoothing: Never },
    /// The planar 4-state UKF of Wang et al. (2018) (eqs. (11)–(14)).
    Ukf2d { name: "ukf2d", run: Planar(Ukf), takes: [Ranges], smoothing: Never },
    /// The planar errors-complementary EKF of Wang et al. (2018), eqs. (15)–(18).
    ///
    /// Ranges pass through a moving average first.
    Cekf2d { name: "cekf2d", run: Planar(Cekf), takes: [Ranges], smoothing: Never },
    /// The recommended method for real logs (ours), smoothed unless a forward pass is asked for.
    ///
    /// RIEKF with its range test skewed against long ranges, updates in the invariant error and
    /// the zero-velocity constraint while still ([`uwbimu_estimation::filters::Best`]),
    /// re-acquisition on divergence, a heading watch that resets a wrong heading, and
    /// self-initialisation when no initial state is given. Before it runs it chooses its
    /// range-error model, NLOS skew and range noise on the log by held-out anchors
    /// ([`crate::select`]).
    Best { name: "best", run: Inertial(Best), takes: [Ranges, Tags, Aiding], smoothing: ByDefault, chooses_model: true },
}

impl Method {
    /// The method's name.
    pub fn name(self) -> &'static str {
        self.info().name
    }

    /// The first line of the method's doc: one sentence that says what it is (every row's doc
    /// starts with one; `tests::every_summary_is_a_sentence`).
    pub fn summary(self) -> &'static str {
        self.info().doc.lines().next().unwrap_or_default().trim()
    }

    /// Every method name, in registry order.
    pub fn names() -> impl Iterator<Item = &'static str> {
        Self::ALL.iter().map(|m| m.name())
    }

    /// Whether the method's run can be RTS-smoothed: the inertial 15-state filters (not
    /// `uwb_ls` and the planar filters).
    pub fn smoothable(self) -> bool {
        self.info().smoothing != Smoothing::Never
    }

    /// Whether the batch API smooths the method's run when the caller does not say (`best`).
    pub fn smooths_by_default(self) -> bool {
        self.info().smoothing == Smoothing::ByDefault
    }

    /// Whether to smooth: as `asked`, else the method's default ([`Method::smooths_by_default`]).
    pub fn smooth(self, asked: Option<bool>) -> bool {
        asked.unwrap_or(self.smooths_by_default())
    }

    /// Whether the batch method chooses its range-error model, NLOS skew and range noise on the
    /// log ([`crate::select`]; its registry row).
    pub fn chooses_its_model(self) -> bool {
        self.info().chooses_model
    }

    /// Whether the method takes `input`: its row lists it, or lists [`Input::Aiding`] and the
    /// registry marks the sensor `aiding`.
    pub fn takes(self, input: Input) -> bool {
        let listed = |i| self.info().takes.contains(&i);
        listed(input) || matches!(input, Input::Sensor(kind) if kind.info().aiding && listed(Input::Aiding))
    }

    /// The inputs the method takes, in [`Input::all`] order (`METHODS[name]["takes"]`).
    pub fn inputs(self) -> impl Iterator<Item = Input> {
        Input::all().filter(move |i| self.takes(*i))
    }

    /// Whether the method takes TDoA (the tightly coupled inertial filters; the loosely coupled
    /// ones fuse a per-epoch fix from ranges, the planar ones and `uwb_ls` take ranges only).
    pub fn takes_tdoa(self) -> bool {
        self.takes(Input::Sensor(SensorKind::Tdoa))
    }

    /// The names of the methods for which `keep` holds, comma-separated (for error messages).
    pub fn names_where(keep: impl Fn(Self) -> bool) -> String {
        Self::ALL.iter().filter(|m| keep(**m)).map(|m| m.name()).collect::<Vec<_>>().join(", ")
    }

    /// The method that runs the inertial filter `kind` (every kind is one method's filter).
    pub fn of_filter(kind: InertialKind) -> Option<Self> {
        Self::ALL.iter().copied().find(|m| m.info().run == Run::Inertial(kind))
    }

    /// Parses a method name; the error lists the allowed names.
    pub fn parse(name: &str) -> Result<Self> {
        Self::ALL
            .iter()
            .copied()
            .find(|m| m.name() == name)
            .ok_or_else(|| Error::unknown_option("method", name, Self::ALL.iter().map(|m| m.name())))
    }
}

/// The method replays use when none is given.
pub const DEFAULT_METHOD: Method = Method::Best;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for name in Method::names() {
            assert_eq!(Method::parse(name).map(Method::name), Ok(name));
        }
        assert!(matches!(Method::parse("rieks"), Err(Error::UnknownOption { .. })));
        let e = Method::parse("rekff").unwrap_err().to_string();
        assert!(e.starts_with("unknown method `rekff` (did you mean `rekf`"), "{e}");
    }

    #[test]
    fn every_summary_is_a_sentence() {
        for m in Method::ALL {
            let s = m.summary();
            assert!(s.len() > 20 && s.ends_with('.') && s.chars().next().is_some_and(char::is_uppercase), "{s}");
        }
    }

    #[test]
    fn capabilities_follow_the_rows() {
        assert_eq!(Method::names_where(Method::smooths_by_default), "best");
        assert_eq!(Method::names_where(|m| m.takes(Input::Sensor(SensorKind::Magnetometer))), "ackf");
        // A sensor marked aiding is taken by every method whose row says `Aiding`, no other.
        let pose_fix = Input::Sensor(SensorKind::PoseFix);
        assert_eq!(Method::names_where(|m| m.takes(pose_fix)), Method::names_where(|m| m.takes(Input::Sensor(SensorKind::Tdoa))));
        let ackf: Vec<&str> = Method::Ackf.inputs().map(Input::name).collect();
        assert_eq!(ackf, ["ranges", "tags", "magnetometer", "tdoa", "altitude", "odometry", "pose_fix"]);
        assert!(!Method::UwbLs.smoothable() && !Method::Ekf2d.takes_tdoa() && Method::Best.takes_tdoa());
        // A method streams exactly when it runs a 15-state filter (the smoothable ones).
        assert!(Method::ALL.iter().all(|m| m.info().streaming_class().is_some() == m.smoothable()));
    }

    #[test]
    fn each_inertial_kind_is_the_filter_of_one_method() {
        for kind in InertialKind::ALL {
            let runs = Method::ALL.iter().filter(|m| m.info().run == Run::Inertial(kind));
            assert_eq!(runs.count(), 1, "{kind:?}");
            assert_eq!(Method::of_filter(kind).and_then(|m| m.info().streaming_class()), Some(kind.type_name()));
        }
    }
}
