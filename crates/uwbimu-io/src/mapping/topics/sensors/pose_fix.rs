//! The pose fix's io: positions with a σ per axis and optionally a yaw
//! (`[mapping.pose_fix]`, [`PoseFixMapping`]) read from `geometry_msgs/msg/PoseWithCovarianceStamped`
//! and `nav_msgs/msg/Odometry` (σ from the pose covariance) or `geometry_msgs/msg/PoseStamped` (σ
//! from the mapping), written as `geometry_msgs/msg/PoseWithCovarianceStamped` on `/pose_fix`.
//!
//! The yaw of a pose is that of its orientation quaternion (x, y, z, w as ROS orders them),
//! `yaw = atan2(2(wz + xy), w² + x² − y² − z²)` — for a unit quaternion the usual
//! `atan2(2(wz + xy), 1 − 2(y² + z²))` — in (−π, π]; an all-zero quaternion is no orientation.

use serde::{Deserialize, Serialize};
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::sensors::pose_fix::PoseFix;
use uwbimu_vocabulary::sensors::{Observation, SensorKind};

use super::{positive, DecodeSensor, Reading, SensorIo, StampedSchema};
use crate::mapping::field_path::{FieldPath, PointPath};
use crate::recordings::mcap_read::ChannelInfo;
use crate::ros::cdr::Value;
use crate::ros::payloads::{align8, cdr_with_header};
use crate::{IoError as Error, IoResult as Result, Mapping};

/// How pose messages are read as fixes (section `[mapping.pose_fix]`): the position of the pose
/// (the fix's point, navigation frame), the σ of each axis and, with `use_yaw`, the yaw of its
/// orientation with its σ. A `geometry_msgs/PoseWithCovarianceStamped` or a `nav_msgs/Odometry`
/// gives the σ in its pose covariance (x, y, z, rotation about x, y, z, row-major 6 × 6): the
/// square roots of its diagonal entries 0, 7, 14 and 35; a fix gives a yaw when entry 35 is finite
/// and > 0. A `geometry_msgs/PoseStamped` has no covariance: its σ are `std` and `yaw_std`. A fix
/// with a value that is not finite or a position variance ≤ 0 is dropped and counted.
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PoseFixMapping {
    /// Pose topics (none: no pose fix is read).
    #[serde(default)]
    pub topics: Vec<String>,
    /// σ of each axis of the position of a message without covariance, m (> 0; required for a
    /// `geometry_msgs/PoseStamped`, unused for a message with a covariance).
    pub std: Option<f64>,
    /// σ of the yaw of a message without covariance, rad (> 0; absent: such fixes give no yaw).
    pub yaw_std: Option<f64>,
    /// Whether the fixes give their yaw (default true); false reads the positions alone.
    pub use_yaw: Option<bool>,
    /// Path of the stamp (`sec`/`nanosec` message); default `header.stamp` when present.
    pub stamp: Option<String>,
}

/// The pose fix's io row.
#[derive(Debug, Clone, Copy)]
pub struct PoseFixIo;

/// The ROS 2 type pose fixes are written as, and the first read.
const POSE_WITH_COVARIANCE: &str = "geometry_msgs/msg/PoseWithCovarianceStamped";

/// The entries of a row-major 6 × 6 pose covariance that hold the variances of x, y, z and yaw.
const DIAGONAL: [usize; 4] = [0, 7, 14, 35];

impl SensorIo for PoseFixIo {
    fn kind(&self) -> SensorKind {
        SensorKind::PoseFix
    }

    fn topics<'m>(&self, m: &'m Mapping) -> &'m [String] {
        &m.pose_fix.topics
    }

    fn stamp<'m>(&self, m: &'m Mapping) -> Option<&'m str> {
        m.pose_fix.stamp.as_deref()
    }

    /// `std` and `yaw_std` > 0 when given.
    fn validate(&self, m: &Mapping) -> Result<()> {
        positive("pose_fix.std", m.pose_fix.std)?;
        positive("pose_fix.yaw_std", m.pose_fix.yaw_std)
    }

    fn reads(&self) -> &'static [&'static str] {
        &[POSE_WITH_COVARIANCE, "geometry_msgs/msg/PoseStamped", "nav_msgs/msg/Odometry"]
    }

    /// The pose of the three types it reads; [`Error::Mapping`] for another type, and for a
    /// `geometry_msgs/PoseStamped` without `pose_fix.std`.
    fn decoder(&self, channel: &ChannelInfo, m: &Mapping) -> Result<Box<dyn DecodeSensor>> {
        let m = &m.pose_fix;
        let message = StampedSchema::new(channel, "pose_fix.stamp", m.stamp.as_deref())?;
        let schema = &message.schema;
        let path = |key: &str, text: String| FieldPath::resolve(schema, key, &text)?.require_numeric(key);
        let (pose, sigma) = match schema.name() {
            "geometry_msgs/PoseWithCovarianceStamped" | "nav_msgs/Odometry" => {
                let entry = |k: usize| path("pose_fix.topics", format!("pose.covariance[{k}]"));
                (
                    "pose.pose",
                    Sigma::Covariance(Box::new([
                        entry(DIAGONAL[0])?,
                        entry(DIAGONAL[1])?,
                        entry(DIAGONAL[2])?,
                        entry(DIAGONAL[3])?,
                    ])),
                )
            }
            "geometry_msgs/PoseStamped" => {
                let Some(std) = m.std else {
                    return Err(Error::Mapping {
                        field: "pose_fix.std".into(),
                        reason: format!(
                            "topic `{}` ({}) has no covariance: give the σ of its position, m (and `yaw_std`, rad, for its yaw)",
                            channel.topic,
                            schema.name()
                        ),
                    });
                };
                ("pose", Sigma::Given { std, yaw_std: m.yaw_std })
            }
            other => {
                return Err(Error::Mapping {
                    field: "pose_fix.topics".into(),
                    reason: format!(
                        "topic `{}` ({other}) is not a pose: a pose fix is a {}",
                        channel.topic,
                        self.reads().join(", a ")
                    ),
                })
            }
        };
        let position = PointPath::resolve(schema, "pose_fix.topics", &format!("{pose}.position"))?;
        let q = |c: &str| path("pose_fix.topics", format!("{pose}.orientation.{c}"));
        let orientation = [q("x")?, q("y")?, q("z")?, q("w")?];
        Ok(Box::new(PoseFixDecoder { message, position, orientation, sigma, use_yaw: m.use_yaw.unwrap_or(true) }))
    }

    fn written(&self) -> (&'static str, &'static str) {
        ("/pose_fix", POSE_WITH_COVARIANCE)
    }

    fn encode(&self, observations: &[Observation]) -> Option<(Vec<u8>, usize)> {
        match observations.first()? {
            Observation::PoseFix(f) => Some((pose_fix_cdr(f), 1)),
            _ => None,
        }
    }
}

/// Where a fix's σ come from.
enum Sigma {
    /// The message's pose covariance: the paths of the variances of x, y, z and yaw.
    Covariance(Box<[FieldPath; 4]>),
    /// The mapping's: the σ of each axis, m, and of the yaw, rad (None: no yaw).
    Given { std: f64, yaw_std: Option<f64> },
}

/// Decodes pose fixes.
struct PoseFixDecoder {
    message: StampedSchema,
    position: PointPath,
    /// Paths of the orientation's x, y, z, w.
    orientation: [FieldPath; 4],
    sigma: Sigma,
    use_yaw: bool,
}

/// The numbers at `paths` in `v` (NaN for a value that is not one).
fn numbers<const N: usize>(paths: &[FieldPath; N], v: &Value) -> Result<[f64; N]> {
    let mut out = [f64::NAN; N];
    for (x, path) in out.iter_mut().zip(paths) {
        *x = path.get(v)?.as_f64().unwrap_or(f64::NAN);
    }
    Ok(out)
}

/// The yaw of the quaternion `[x, y, z, w]` (module doc); None for the zero quaternion.
fn yaw_of([x, y, z, w]: [f64; 4]) -> Option<f64> {
    let norm2 = w * w + x * x + y * y + z * z;
    (norm2 != 0.0).then(|| (2.0 * (w * z + x * y)).atan2(w * w + x * x - y * y - z * z))
}

impl DecodeSensor for PoseFixDecoder {
    fn decode(&self, data: &[u8], out: &mut Vec<Reading>) -> Result<Option<i64>> {
        let (v, stamp) = self.message.decode(data)?;
        let position = self.position.point(self.position.path.get(&v)?).ok_or_else(|| Error::Format {
            what: format!("field `{}`", self.position.path.text),
            reason: "not a point".into(),
        })?;
        let q = numbers(&self.orientation, &v)?;
        let (variances, yaw_std) = match &self.sigma {
            Sigma::Covariance(paths) => {
                let [x, y, z, yaw_var] = numbers(paths, &v)?;
                ([x, y, z], (yaw_var.is_finite() && yaw_var > 0.0).then(|| yaw_var.sqrt()))
            }
            Sigma::Given { std, yaw_std } => ([std * std; 3], *yaw_std),
        };
        let position_std = Vec3::from(variances.map(f64::sqrt));
        let (yaw_rad, yaw_std_rad) = match (self.use_yaw, yaw_std, yaw_of(q)) {
            (true, Some(s), Some(yaw)) => (yaw, s),
            _ => (f64::NAN, f64::NAN),
        };
        let usable = position.iter().all(|c| c.is_finite())
            && variances.iter().all(|s| s.is_finite() && *s > 0.0)
            && (yaw_std_rad.is_nan() || yaw_rad.is_finite());
        let fix = PoseFix { t_s: 0.0, position, position_std, yaw_rad, yaw_std_rad };
        out.push(Reading::Sensor((Observation::PoseFix(fix), usable)));
        Ok(stamp)
    }
}

/// A `geometry_msgs/msg/PoseWithCovarianceStamped` as XCDR1 little-endian: stamped `t_s`, frame
/// `map`, the position, the orientation `[x, y, z, w]` and the row-major covariance.
fn pose_with_covariance_cdr(t_s: f64, position: Vec3, orientation: [f64; 4], covariance: &[f64; 36]) -> Vec<u8> {
    let mut b = cdr_with_header(t_s, "map", 376);
    align8(&mut b);
    for v in position.iter().chain(&orientation).chain(covariance) {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b
}

/// One fix as XCDR1 little-endian `geometry_msgs/msg/PoseWithCovarianceStamped` (frame `map`):
/// the position, the orientation of the yaw about z (identity without one), the covariance
/// diagonal the variances σ² of x, y, z and yaw, −1 ("not measured") for roll and pitch and for
/// the yaw of a fix without one, the rest 0. Read back through the default mapping it gives the
/// fix again — the yaw to rounding, in (−π, π].
pub fn pose_fix_cdr(fix: &PoseFix) -> Vec<u8> {
    let mut covariance = [0.0; 36];
    for (k, s) in fix.position_std.iter().enumerate() {
        covariance[DIAGONAL[k]] = s * s;
    }
    covariance[21] = -1.0;
    covariance[28] = -1.0;
    let (orientation, yaw_var) = match fix.has_yaw() {
        true => ([0.0, 0.0, (fix.yaw_rad / 2.0).sin(), (fix.yaw_rad / 2.0).cos()], fix.yaw_std_rad * fix.yaw_std_rad),
        false => ([0.0, 0.0, 0.0, 1.0], -1.0),
    };
    covariance[DIAGONAL[3]] = yaw_var;
    pose_with_covariance_cdr(fix.t_s, fix.position, orientation, &covariance)
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::super::test_channel;
    use super::*;
    use crate::ros::payloads::{align8, cdr_with_header};
    use uwbimu_vocabulary::math::{Cov, Quat};

    /// The fixes of one message through `m`, with whether each is usable, and the stamp.
    fn read(type_name: &str, m: PoseFixMapping, payload: &[u8]) -> (Option<i64>, Vec<(PoseFix, bool)>) {
        let mapping = Mapping { pose_fix: m, ..Mapping::default() };
        let mut out = Vec::new();
        let stamp = PoseFixIo.decoder(&test_channel(type_name), &mapping).unwrap().decode(payload, &mut out).unwrap();
        let fixes = out
            .into_iter()
            .map(|r| match r {
                Reading::Sensor((Observation::PoseFix(f), ok)) => (f, ok),
                other => panic!("{other:?}"),
            })
            .collect();
        (stamp, fixes)
    }

    fn fix(yaw: Option<(f64, f64)>) -> PoseFix {
        let (yaw_rad, yaw_std_rad) = yaw.unwrap_or((f64::NAN, f64::NAN));
        PoseFix {
            t_s: 7.25,
            position: Vec3::new(1.5, -2.25, 0.8),
            position_std: Vec3::new(0.05, 0.07, 0.3),
            yaw_rad,
            yaw_std_rad,
        }
    }

    #[test]
    fn a_fix_reads_back_as_written_with_and_without_yaw() {
        for yaw in [None, Some((2.5, 0.04)), Some((-PI / 3.0, 0.1))] {
            let written = fix(yaw);
            let (payload, n) = PoseFixIo.encode(&[Observation::PoseFix(written)]).unwrap();
            let (stamp, got) = read(POSE_WITH_COVARIANCE, PoseFixMapping::default(), &payload);
            assert_eq!((n, stamp, got.len()), (1, Some(7_250_000_000), 1));
            let (back, usable) = got[0];
            assert!(usable);
            assert_eq!((back.position, back.position_std), (written.position, written.position_std), "{yaw:?}");
            assert_eq!(back.has_yaw(), yaw.is_some());
            if let Some((yaw, s)) = yaw {
                assert!((back.yaw_rad - yaw).abs() < 1e-12, "{} vs {yaw}", back.yaw_rad);
                assert_eq!(back.yaw_std_rad, s);
            }
        }
    }

    #[test]
    fn sigma_is_the_root_of_the_covariance_and_yaw_that_of_the_quaternion() {
        // q = (w, x, y, z) = (0.9, 0.1, −0.2, 0.3), not normalised: 2(wz + xy) = 2(0.27 − 0.02) = 0.5,
        // w² + x² − y² − z² = 0.81 + 0.01 − 0.04 − 0.09 = 0.69.
        let q = [0.1, -0.2, 0.3, 0.9];
        let mut cov = [0.0; 36];
        for (k, var) in DIAGONAL.into_iter().zip([0.04, 0.09, 0.16, 0.0025]) {
            cov[k] = var;
        }
        cov[1] = 0.01; // off the diagonal: not read
        let payload = pose_with_covariance_cdr(3.0, Vec3::new(4.0, 5.0, 6.0), q, &cov);
        let (_, got) = read(POSE_WITH_COVARIANCE, PoseFixMapping::default(), &payload);
        let (f, usable) = got[0];
        assert!(usable);
        assert_eq!(f.position_std, Vec3::new(0.2, 0.3, 0.4));
        assert_eq!(f.yaw_std_rad, 0.05);
        assert!((f.yaw_rad - 0.5f64.atan2(0.69)).abs() < 1e-15, "{}", f.yaw_rad);
        let nalgebra = Quat::from_quaternion(nalgebra::Quaternion::new(0.9, 0.1, -0.2, 0.3)).euler_angles().2;
        assert!((f.yaw_rad - nalgebra).abs() < 1e-12, "{} vs {nalgebra}", f.yaw_rad);
        // No yaw: not asked for, a yaw variance of 0 or NaN, the zero quaternion.
        let off = PoseFixMapping { use_yaw: Some(false), ..Default::default() };
        assert!(!read(POSE_WITH_COVARIANCE, off, &payload).1[0].0.has_yaw());
        for yaw_var in [0.0, f64::NAN] {
            cov[35] = yaw_var;
            let payload = pose_with_covariance_cdr(3.0, Vec3::new(4.0, 5.0, 6.0), q, &cov);
            let (f, usable) = read(POSE_WITH_COVARIANCE, PoseFixMapping::default(), &payload).1[0];
            assert!(usable && !f.has_yaw() && f.yaw_std_rad.is_nan(), "{yaw_var}");
        }
        cov[35] = 0.0025;
        let zero = pose_with_covariance_cdr(3.0, Vec3::new(4.0, 5.0, 6.0), [0.0; 4], &cov);
        assert!(!read(POSE_WITH_COVARIANCE, PoseFixMapping::default(), &zero).1[0].0.has_yaw());
    }

    #[test]
    fn a_variance_of_zero_or_a_value_not_finite_is_unusable() {
        let good = [0.04, 0.04, 0.09];
        let cases: [(Vec3, [f64; 3]); 4] = [
            (Vec3::new(1.0, 2.0, 3.0), [0.04, 0.0, 0.09]),
            (Vec3::new(1.0, 2.0, 3.0), [-1.0, 0.04, 0.09]),
            (Vec3::new(1.0, 2.0, 3.0), [0.04, f64::INFINITY, 0.09]),
            (Vec3::new(f64::NAN, 2.0, 3.0), good),
        ];
        for (position, variances) in cases {
            let mut cov = [0.0; 36];
            for (k, var) in variances.into_iter().enumerate() {
                cov[DIAGONAL[k]] = var;
            }
            let payload = pose_with_covariance_cdr(1.0, position, [0.0, 0.0, 0.0, 1.0], &cov);
            let (_, got) = read(POSE_WITH_COVARIANCE, PoseFixMapping::default(), &payload);
            assert!(!got[0].1, "{position:?} {variances:?}");
        }
    }

    /// A `geometry_msgs/PoseStamped` at `t_s`: `position`, orientation `[x, y, z, w]`.
    fn pose_stamped(t_s: f64, position: Vec3, q: [f64; 4]) -> Vec<u8> {
        let mut b = cdr_with_header(t_s, "map", 96);
        align8(&mut b);
        for v in position.iter().chain(&q) {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b
    }

    #[test]
    fn a_pose_stamped_takes_its_sigma_from_the_mapping() {
        let stamped = "geometry_msgs/msg/PoseStamped";
        let (s, c) = ((0.4f64).sin(), (0.4f64).cos());
        let payload = pose_stamped(2.0, Vec3::new(1.0, 2.0, 3.0), [0.0, 0.0, s, c]);
        let e = PoseFixIo.decoder(&test_channel(stamped), &Mapping::default()).err().map(|e| e.to_string());
        assert!(e.as_deref().is_some_and(|e| e.contains("pose_fix.std") && e.contains("has no covariance")), "{e:?}");
        let m = PoseFixMapping { std: Some(0.1), yaw_std: Some(0.02), ..Default::default() };
        let (stamp, got) = read(stamped, m, &payload);
        let (f, usable) = got[0];
        assert_eq!(
            (stamp, usable, f.position, f.position_std),
            (Some(2_000_000_000), true, Vec3::new(1.0, 2.0, 3.0), Vec3::repeat(0.1))
        );
        assert!((f.yaw_rad - 0.8).abs() < 1e-15 && f.yaw_std_rad == 0.02, "{f:?}");
        let no_yaw = read(stamped, PoseFixMapping { std: Some(0.1), ..Default::default() }, &payload).1[0].0;
        assert!(!no_yaw.has_yaw());
    }

    #[test]
    fn an_odometry_gives_its_pose_and_another_type_is_refused() {
        // The node's own Odometry output: its pose covariance is the filter's, rotated into the
        // navigation frame; a rotation about z keeps diag(a, a, b) of the attitude as it is.
        let mut cov = Cov::<15>::zeros();
        for (i, var) in [(0, 0.04), (1, 0.09), (2, 0.16), (6, 1e-3), (7, 1e-3), (8, 4e-4)] {
            cov[(i, i)] = var;
        }
        let orientation = Quat::from_euler_angles(0.0, 0.0, 1.2);
        let e = crate::ros::out::PoseEstimate {
            t_s: 4.0,
            position: Vec3::new(3.0, -1.0, 0.5),
            velocity: Vec3::zeros(),
            orientation,
            angular_rate: Vec3::zeros(),
            covariance: &cov,
        };
        let payload = crate::ros::out::odometry_cdr(&e, crate::ros::out::Frames { parent: "map", child: "base_link" });
        let (stamp, got) = read("nav_msgs/msg/Odometry", PoseFixMapping::default(), &payload);
        let (f, usable) = got[0];
        assert_eq!((stamp, usable, f.position), (Some(4_000_000_000), true, e.position));
        assert!((f.position_std - Vec3::new(0.2, 0.3, 0.4)).norm() < 1e-15, "{:?}", f.position_std);
        assert!((f.yaw_rad - 1.2).abs() < 1e-12 && (f.yaw_std_rad - 0.02).abs() < 1e-15, "{f:?}");
        let e = PoseFixIo.decoder(&test_channel("sensor_msgs/msg/Imu"), &Mapping::default()).err().map(|e| e.to_string());
        assert!(e.as_deref().is_some_and(|e| e.contains("pose_fix.topics") && e.contains("is not a pose")), "{e:?}");
        let zero = Mapping { pose_fix: PoseFixMapping { std: Some(0.0), ..Default::default() }, ..Default::default() };
        assert!(matches!(PoseFixIo.validate(&zero), Err(Error::Mapping { field, .. }) if field == "pose_fix.std"));
    }
}
