//! The estimate as ROS 2 messages (XCDR1 little-endian, the payload a ROS 2 graph exchanges):
//! `geometry_msgs/msg/PoseWithCovarianceStamped`, `nav_msgs/msg/Odometry` and
//! `diagnostic_msgs/msg/DiagnosticArray`.
//!
//! Covariances follow the messages' conventions, not the filter's: the pose covariance is over
//! (x, y, z, rotation about the parent frame's x, y, z); the filter's attitude error δθ is in the
//! body frame, so with `R` the body → navigation rotation the rotation block is `R Σ_θθ Rᵀ` and
//! the cross block `Σ_pθ Rᵀ`. The odometry twist is in the child (body) frame:
//! `v_b = Rᵀ v` with `δv_b = Rᵀ δv + [v_b]× δθ`, and the angular rate's covariance is that of the
//! gyroscope bias.

use uwbimu_vocabulary::math::{skew, Cov, Mat3, Quat, Vec3};
use uwbimu_vocabulary::state::{ATT, BG, POS, VEL};

use crate::ros::payloads::{align8, cdr_with_header, push_cdr_string};

/// One estimate to publish.
#[derive(Debug, Clone, Copy)]
pub struct PoseEstimate<'a> {
    /// Time of the state, s (the stamp of the messages).
    pub t_s: f64,
    /// Position (navigation frame), m.
    pub position: Vec3,
    /// Velocity (navigation frame), m/s.
    pub velocity: Vec3,
    /// Body → navigation rotation.
    pub orientation: Quat,
    /// Body angular rate, bias removed, rad/s.
    pub angular_rate: Vec3,
    /// Error-state covariance, order δp, δv, δθ (body), δb_a, δb_g.
    pub covariance: &'a Cov<15>,
}

/// The frame ids of the messages.
#[derive(Debug, Clone, Copy)]
pub struct Frames<'a> {
    /// The navigation frame (`header.frame_id`), e.g. `map`.
    pub parent: &'a str,
    /// The body frame (`child_frame_id` of the odometry), e.g. `base_link`.
    pub child: &'a str,
}

/// A 3×3 block of the filter covariance at (`row`, `col`).
fn block(c: &Cov<15>, row: usize, col: usize) -> Mat3 {
    c.fixed_view::<3, 3>(row, col).into_owned()
}

/// The 6×6 pose covariance (x, y, z, rotation about the parent's axes), row-major.
fn pose_covariance(e: &PoseEstimate<'_>) -> [f64; 36] {
    let r = e.orientation.to_rotation_matrix().into_inner();
    let pp = block(e.covariance, POS, POS);
    let pt = block(e.covariance, POS, ATT) * r.transpose();
    let tt = r * block(e.covariance, ATT, ATT) * r.transpose();
    six_by_six(&pp, &pt, &tt)
}

/// The 6×6 twist covariance (linear, angular, in the body frame), row-major.
fn twist_covariance(e: &PoseEstimate<'_>) -> [f64; 36] {
    let rt = e.orientation.to_rotation_matrix().into_inner().transpose();
    let v_body = rt * e.velocity;
    // δv_b = J [δv; δθ] with J = [Rᵀ, [v_b]×].
    let (j_v, j_t) = (rt, skew(&v_body));
    let c = e.covariance;
    let vv = j_v * block(c, VEL, VEL) * j_v.transpose()
        + j_v * block(c, VEL, ATT) * j_t.transpose()
        + j_t * block(c, ATT, VEL) * j_v.transpose()
        + j_t * block(c, ATT, ATT) * j_t.transpose();
    six_by_six(&vv, &Mat3::zeros(), &block(c, BG, BG))
}

/// `[[a, b], [bᵀ, d]]` row-major.
fn six_by_six(a: &Mat3, b: &Mat3, d: &Mat3) -> [f64; 36] {
    let mut out = [0.0; 36];
    for i in 0..3 {
        for j in 0..3 {
            out[i * 6 + j] = a[(i, j)];
            out[i * 6 + j + 3] = b[(i, j)];
            out[(i + 3) * 6 + j] = b[(j, i)];
            out[(i + 3) * 6 + j + 3] = d[(i, j)];
        }
    }
    out
}

/// Appends a `geometry_msgs/Pose` then its covariance (`PoseWithCovariance`).
fn push_pose_with_covariance(b: &mut Vec<u8>, e: &PoseEstimate<'_>) {
    align8(b);
    let q = e.orientation.quaternion();
    let values = [e.position.x, e.position.y, e.position.z, q.i, q.j, q.k, q.w];
    for v in values.into_iter().chain(pose_covariance(e)) {
        b.extend_from_slice(&v.to_le_bytes());
    }
}

/// `geometry_msgs/msg/PoseWithCovarianceStamped` of `e`, stamped `e.t_s`, in `frames.parent`.
pub fn pose_with_covariance_cdr(e: &PoseEstimate<'_>, frames: Frames<'_>) -> Vec<u8> {
    let mut b = cdr_with_header(e.t_s, frames.parent, 360);
    push_pose_with_covariance(&mut b, e);
    b
}

/// `nav_msgs/msg/Odometry` of `e`: the pose in `frames.parent`, the twist (body velocity and
/// bias-corrected angular rate) in `frames.child`, both with covariances.
pub fn odometry_cdr(e: &PoseEstimate<'_>, frames: Frames<'_>) -> Vec<u8> {
    let mut b = cdr_with_header(e.t_s, frames.parent, 720);
    push_cdr_string(&mut b, frames.child);
    push_pose_with_covariance(&mut b, e);
    let v_body = e.orientation.inverse() * e.velocity;
    let twist = [v_body.x, v_body.y, v_body.z, e.angular_rate.x, e.angular_rate.y, e.angular_rate.z];
    for v in twist.into_iter().chain(twist_covariance(e)) {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b
}

/// Level of a `diagnostic_msgs/msg/DiagnosticStatus`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DiagnosticLevel {
    /// `OK` (0).
    Ok = 0,
    /// `WARN` (1).
    Warn = 1,
    /// `ERROR` (2).
    Error = 2,
    /// `STALE` (3).
    Stale = 3,
}

/// One `diagnostic_msgs/msg/DiagnosticStatus`.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnosticStatus {
    /// Its level.
    pub level: DiagnosticLevel,
    /// What it is about (`uwbimu: imu`, …).
    pub name: String,
    /// One line for a human.
    pub message: String,
    /// The device (topic or port).
    pub hardware_id: String,
    /// Key–value pairs (counts, rates).
    pub values: Vec<(String, String)>,
}

/// `diagnostic_msgs/msg/DiagnosticArray` of `statuses`, stamped `t_s`.
pub fn diagnostic_array_cdr(t_s: f64, statuses: &[DiagnosticStatus]) -> Vec<u8> {
    let mut b = cdr_with_header(t_s, "", 256);
    push_len(&mut b, statuses.len());
    for s in statuses {
        b.push(s.level as u8);
        push_cdr_string(&mut b, &s.name);
        push_cdr_string(&mut b, &s.message);
        push_cdr_string(&mut b, &s.hardware_id);
        push_len(&mut b, s.values.len());
        for (k, v) in &s.values {
            push_cdr_string(&mut b, k);
            push_cdr_string(&mut b, v);
        }
    }
    b
}

/// Appends a sequence length (uint32, aligned to 4 after the encapsulation header).
fn push_len(b: &mut Vec<u8>, n: usize) {
    while (b.len() - 4) % 4 != 0 {
        b.push(0);
    }
    b.extend_from_slice(&(n as u32).to_le_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros::cdr::{decode, Value};
    use crate::ros::msg_schema::{FieldType, MsgSchema};
    use crate::ros::types::full_definition;
    use nalgebra::Vector3;

    /// The value at `path` below `v`, a value of the schema's type `ty`; with the type it has.
    fn at<'a>(schema: &MsgSchema, ty: usize, v: &'a Value, path: &[&str]) -> (&'a Value, usize) {
        path.iter().fold((v, ty), |(v, ty), name| {
            let t = &schema.types[ty];
            let i = t.field_index(name).unwrap_or_else(|| panic!("no {name} in {}", t.name));
            let next = match t.fields[i].ty {
                FieldType::Nested(n) => n,
                FieldType::Primitive(_) => usize::MAX,
            };
            match v {
                Value::Struct(values) => (&values[i], next),
                other => panic!("{name} of {other:?}"),
            }
        })
    }

    fn field<'a>(schema: &MsgSchema, v: &'a Value, path: &[&str]) -> &'a Value {
        at(schema, 0, v, path).0
    }

    fn numbers(v: &Value) -> Vec<f64> {
        match v {
            Value::Array(items) => items.iter().map(|x| x.as_f64().unwrap()).collect(),
            other => panic!("{other:?}"),
        }
    }

    /// A covariance with distinct entries, so a misplaced block shows.
    fn test_covariance() -> Cov<15> {
        let a = Cov::<15>::from_fn(|i, j| ((i * 7 + j * 3) % 11) as f64 * 0.01);
        a * a.transpose() + Cov::<15>::identity() * 0.1
    }

    #[test]
    fn messages_decode_with_the_bundled_definitions_and_rotate_the_covariance() {
        let cov = test_covariance();
        let yaw = std::f64::consts::FRAC_PI_2;
        let e = PoseEstimate {
            t_s: 12.25,
            position: Vector3::new(1.0, 2.0, 0.5),
            velocity: Vector3::new(0.0, 1.0, 0.0),
            orientation: Quat::from_euler_angles(0.0, 0.0, yaw),
            angular_rate: Vector3::new(0.0, 0.0, 0.3),
            covariance: &cov,
        };
        let frames = Frames { parent: "map", child: "base_link" };
        let name = "nav_msgs/msg/Odometry";
        let schema = MsgSchema::parse(name, &full_definition(name, &[]).unwrap()).unwrap();
        let v = decode(&schema, &odometry_cdr(&e, frames)).unwrap();
        assert_eq!(field(&schema, &v, &["header", "stamp", "nanosec"]).as_f64(), Some(250_000_000.0));
        assert_eq!(field(&schema, &v, &["child_frame_id"]).as_id().as_deref(), Some("base_link"));
        assert_eq!(field(&schema, &v, &["pose", "pose", "position", "y"]).as_f64(), Some(2.0));
        assert!((field(&schema, &v, &["pose", "pose", "orientation", "z"]).as_f64().unwrap() - (yaw / 2.0).sin()).abs() < 1e-12);
        // Moving north with yaw 90°: the body moves along its own x axis.
        assert!((field(&schema, &v, &["twist", "twist", "linear", "x"]).as_f64().unwrap() - 1.0).abs() < 1e-12);
        let pc = numbers(field(&schema, &v, &["pose", "covariance"]));
        // Yaw 90°: rotation about the map's x is rotation about the body's −y.
        assert!((pc[3 * 6 + 3] - cov[(ATT + 1, ATT + 1)]).abs() < 1e-12);
        assert!((pc[5 * 6 + 5] - cov[(ATT + 2, ATT + 2)]).abs() < 1e-12);
        assert!((pc[3] + cov[(POS, ATT + 1)]).abs() < 1e-12, "{} {}", pc[3], cov[(POS, ATT + 1)]);
        assert_eq!(pc[6 + 1], cov[(1, 1)]);
        let tc = numbers(field(&schema, &v, &["twist", "covariance"]));
        assert!((tc[5 * 6 + 5] - cov[(BG + 2, BG + 2)]).abs() < 1e-12);
        // Body x velocity = north velocity (plus a yaw error times speed... none along x).
        assert!((tc[0] - cov[(VEL + 1, VEL + 1)]).abs() < 1e-12);

        let name = "geometry_msgs/msg/PoseWithCovarianceStamped";
        let schema = MsgSchema::parse(name, &full_definition(name, &[]).unwrap()).unwrap();
        let v = decode(&schema, &pose_with_covariance_cdr(&e, frames)).unwrap();
        assert_eq!(field(&schema, &v, &["header", "frame_id"]).as_id().as_deref(), Some("map"));
        assert_eq!(numbers(field(&schema, &v, &["pose", "covariance"])), pc);
    }

    #[test]
    fn twist_covariance_matches_a_finite_difference_of_the_body_velocity() {
        let cov = Cov::<15>::identity() * 1e-4;
        let e = PoseEstimate {
            t_s: 0.0,
            position: Vec3::zeros(),
            velocity: Vector3::new(1.5, -0.5, 0.2),
            orientation: Quat::from_euler_angles(0.1, -0.2, 0.7),
            angular_rate: Vec3::zeros(),
            covariance: &cov,
        };
        // J by differences of v_b(δv, δθ) = (R Exp(δθ))ᵀ (v + δv).
        let v_body = |dv: Vec3, dth: Vec3| (e.orientation * Quat::from_scaled_axis(dth)).inverse() * (e.velocity + dv);
        let h = 1e-6;
        let mut j = nalgebra::SMatrix::<f64, 3, 6>::zeros();
        for k in 0..6 {
            let mut d = [Vec3::zeros(), Vec3::zeros()];
            d[k / 3][k % 3] = h;
            let plus = v_body(d[0], d[1]);
            d[k / 3][k % 3] = -h;
            let minus = v_body(d[0], d[1]);
            j.set_column(k, &((plus - minus) / (2.0 * h)));
        }
        let expected = j * j.transpose() * 1e-4;
        let tc = twist_covariance(&e);
        for r in 0..3 {
            for c in 0..3 {
                assert!((tc[r * 6 + c] - expected[(r, c)]).abs() < 1e-10, "{r} {c}");
            }
        }
    }

    #[test]
    fn diagnostics_decode() {
        let statuses = [
            DiagnosticStatus {
                level: DiagnosticLevel::Warn,
                name: "uwbimu: uwb".into(),
                message: "silent for 2.0 s".into(),
                hardware_id: "/uwb".into(),
                values: vec![("messages".into(), "12".into()), ("rejected".into(), "1".into())],
            },
            DiagnosticStatus {
                level: DiagnosticLevel::Ok,
                name: "uwbimu: imu".into(),
                message: "ok".into(),
                hardware_id: "/imu".into(),
                values: vec![],
            },
        ];
        let name = "diagnostic_msgs/msg/DiagnosticArray";
        let schema = MsgSchema::parse(name, &full_definition(name, &[]).unwrap()).unwrap();
        let v = decode(&schema, &diagnostic_array_cdr(3.5, &statuses)).unwrap();
        let (Value::Array(items), st) = at(&schema, 0, &v, &["status"]) else { panic!() };
        assert_eq!(items.len(), 2);
        let item = |k: usize, path: &[&str]| at(&schema, st, &items[k], path).0.clone();
        assert_eq!(item(0, &["level"]).as_f64(), Some(1.0));
        assert_eq!(item(0, &["message"]).as_id().as_deref(), Some("silent for 2.0 s"));
        let (Value::Array(kv), kvt) = at(&schema, st, &items[0], &["values"]) else { panic!() };
        assert_eq!(at(&schema, kvt, &kv[1], &["value"]).0.as_id().as_deref(), Some("1"));
        assert_eq!(item(1, &["hardware_id"]).as_id().as_deref(), Some("/imu"));
    }
}
