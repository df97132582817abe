//! Analytic ground-vehicle trajectories: a sequence of segments, each evaluated in closed form
//! (position, velocity, acceleration, heading and yaw rate are exact derivatives; nothing is
//! differentiated numerically).
//!
//! The vehicle moves in a horizontal plane at constant height, with roll = pitch = 0 and heading ψ
//! along the path tangent, so the body rate is `[0, 0, ψ̇]`. Every speed change goes through the
//! quintic smoothstep σ(τ) = 10τ³ − 15τ⁴ + 6τ⁵ (σ' = σ'' = 0 at both ends), which keeps velocity
//! and acceleration continuous across segment boundaries.

use std::f64::consts::{PI, TAU};

use nalgebra::Vector2;
use uwbimu_vocabulary::error::Result;
use uwbimu_vocabulary::math::{Quat, Vec3};
use uwbimu_vocabulary::validate::{invalid, non_negative, positive};

use crate::sim::overlay::{attitude_and_body_rate, Overlay};

/// Tolerance on position continuity between segments, m.
const POSITION_TOL_M: f64 = 1e-6;
/// Tolerance on heading continuity between segments, rad.
const HEADING_TOL_RAD: f64 = 1e-6;

/// Exact kinematic state of the body at one time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KinematicSample {
    /// Time, s.
    pub t_s: f64,
    /// Body-origin (IMU) position, navigation frame (ENU), m.
    pub position: Vec3,
    /// Velocity, navigation frame, m/s.
    pub velocity: Vec3,
    /// Acceleration, navigation frame, m/s².
    pub acceleration: Vec3,
    /// Body → navigation rotation (Hamilton); here a pure yaw by the heading ψ.
    pub orientation: Quat,
    /// Angular rate of the body relative to the navigation frame, body frame, rad/s (`[0, 0, ψ̇]`).
    pub angular_rate_body: Vec3,
}

/// A planar closed curve `p(u)`, `u ∈ [0, 2π)` per lap, about a centre (the centre's z is the
/// driving height).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PlanarPath {
    /// Lemniscate of Gerono (figure-8): x = a·sin u, y = b·sin u·cos u, relative to the centre.
    /// It starts at the centre heading along (a, b).
    FigureEight {
        /// Centre (crossing point), navigation frame, m.
        centre: Vec3,
        /// Half-length along x, m.
        a_m: f64,
        /// y amplitude parameter, m (the lobes reach ±b/2).
        b_m: f64,
    },
    /// Ellipse x = a·cos u, y = b·sin u, relative to the centre; it starts at centre + (a, 0),
    /// heading +y (counter-clockwise).
    Ellipse {
        /// Centre, navigation frame, m.
        centre: Vec3,
        /// Semi-axis along x, m.
        a_m: f64,
        /// Semi-axis along y, m.
        b_m: f64,
    },
}

impl PlanarPath {
    /// `(p(u), p'(u), p''(u))` in the horizontal plane, m and m/rad^k.
    fn eval(&self, u: f64) -> (Vector2<f64>, Vector2<f64>, Vector2<f64>) {
        let (s, c) = u.sin_cos();
        match *self {
            PlanarPath::FigureEight { centre, a_m: a, b_m: b } => {
                let (s2, c2) = (2.0 * u).sin_cos();
                (
                    Vector2::new(centre.x + a * s, centre.y + 0.5 * b * s2),
                    Vector2::new(a * c, b * c2),
                    Vector2::new(-a * s, -2.0 * b * s2),
                )
            }
            PlanarPath::Ellipse { centre, a_m: a, b_m: b } => {
                (Vector2::new(centre.x + a * c, centre.y + b * s), Vector2::new(-a * s, b * c), Vector2::new(-a * c, -b * s))
            }
        }
    }

    fn height_m(&self) -> f64 {
        match *self {
            PlanarPath::FigureEight { centre, .. } | PlanarPath::Ellipse { centre, .. } => centre.z,
        }
    }

    fn axes_m(&self) -> (f64, f64) {
        match *self {
            PlanarPath::FigureEight { a_m, b_m, .. } | PlanarPath::Ellipse { a_m, b_m, .. } => (a_m, b_m),
        }
    }
}

/// One piece of a [`Trajectory`]; each starts from the end state of the previous one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Segment {
    /// Standing still.
    Still {
        /// Duration, s.
        duration_s: f64,
    },
    /// Turning on the spot by `delta_rad` with ψ(t) = ψ₀ + Δψ·σ(t/T).
    TurnInPlace {
        /// Heading change (positive = counter-clockwise seen from above), rad.
        delta_rad: f64,
        /// Duration T, s.
        duration_s: f64,
    },
    /// Driving in a straight line from rest to rest: speed v·σ(t/r) up, cruise at v, then down.
    /// If the leg is too short to reach `cruise_speed_mps` (L < v·r), the cruise speed is lowered
    /// to L/r. Duration = L/v + r.
    Straight {
        /// Start point (must equal the previous end position), m.
        from: Vec3,
        /// End point (same height as `from`), m.
        to: Vec3,
        /// Cruise speed, m/s.
        cruise_speed_mps: f64,
        /// Duration of each speed ramp r, s.
        ramp_s: f64,
    },
    /// Driving `laps` laps of a closed planar path with the time warp u(t) = c·W(t), where the
    /// rate u̇ = c·w(t) ramps up from 0 over `ramp_s` (w = σ), is constant, then ramps down to 0;
    /// ψ = atan2(y', x'), ψ̇ = (x'y'' − y'x'')/(x'² + y'²)·u̇, a = p''·u̇² + p'·ü.
    Curve {
        /// The path.
        path: PlanarPath,
        /// Number of laps (u runs from 0 to 2π·laps).
        laps: u32,
        /// Total duration T, s.
        duration_s: f64,
        /// Duration of each rate ramp, s (2·ramp ≤ T).
        ramp_s: f64,
    },
}

/// Options for the waypoint-based constructors ([`Trajectory::waypoints`],
/// [`Trajectory::rectangle`], [`Trajectory::diagonal`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveOptions {
    /// Cruise speed on straight legs, m/s.
    pub speed_mps: f64,
    /// Duration of each speed ramp at the ends of a leg, s.
    pub ramp_s: f64,
    /// Stop at each intermediate waypoint before turning, s.
    pub dwell_s: f64,
    /// Duration of each turn in place, s.
    pub turn_time_s: f64,
    /// Still period at the start (for gravity levelling), s.
    pub still_s: f64,
}

impl Default for DriveOptions {
    /// 0.5 m/s, 1 s ramps, 1 s dwell, 2 s turns, 2 s initial still period.
    fn default() -> Self {
        Self { speed_mps: 0.5, ramp_s: 1.0, dwell_s: 1.0, turn_time_s: 2.0, still_s: 2.0 }
    }
}

/// A segment placed in time, with its start state.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Piece {
    segment: Segment,
    t0_s: f64,
    duration_s: f64,
    start_position: Vec3,
    start_heading_rad: f64,
}

/// A ground-vehicle trajectory: segments evaluated analytically and joined end to start, with an
/// optional periodic [`Overlay`] (walking, flight) on top.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    pieces: Vec<Piece>,
    overlay: Option<Overlay>,
}

/// Quintic smoothstep σ(τ) = 10τ³ − 15τ⁴ + 6τ⁵ and its derivative, τ clamped to [0, 1].
fn smoothstep(tau: f64) -> (f64, f64) {
    let t = tau.clamp(0.0, 1.0);
    let t2 = t * t;
    (t2 * t * (10.0 - 15.0 * t + 6.0 * t2), 30.0 * t2 * (1.0 - 2.0 * t + t2))
}

/// ∫₀^τ σ = 2.5τ⁴ − 3τ⁵ + τ⁶ (equals 1/2 at τ = 1).
fn smoothstep_integral(tau: f64) -> f64 {
    let t = tau.clamp(0.0, 1.0);
    let t4 = t * t * t * t;
    t4 * (2.5 - 3.0 * t + t * t)
}

/// Unit-peak speed window on [0, T] with smoothstep ramps of length r: returns
/// `(W(t) = ∫₀ᵗ w, w(t), w'(t))`; W(T) = T − r.
fn window(t: f64, total_s: f64, ramp_s: f64) -> (f64, f64, f64) {
    let t = t.clamp(0.0, total_s);
    if ramp_s <= 0.0 {
        return (t, 1.0, 0.0);
    }
    if t < ramp_s {
        let tau = t / ramp_s;
        let (s, ds) = smoothstep(tau);
        (ramp_s * smoothstep_integral(tau), s, ds / ramp_s)
    } else if t > total_s - ramp_s {
        let tau = (total_s - t) / ramp_s;
        let (s, ds) = smoothstep(tau);
        (total_s - ramp_s - ramp_s * smoothstep_integral(tau), s, -ds / ramp_s)
    } else {
        (t - 0.5 * ramp_s, 1.0, 0.0)
    }
}

/// Wraps an angle to (−π, π], rad.
fn wrap_pi(a: f64) -> f64 {
    let w = (a + PI).rem_euclid(TAU) - PI;
    if w <= -PI {
        w + TAU
    } else {
        w
    }
}

fn yaw(heading_rad: f64) -> Quat {
    Quat::from_axis_angle(&Vec3::z_axis(), heading_rad)
}

/// Leg geometry of a straight segment: (length m, effective cruise speed m/s, duration s).
fn straight_profile(from: &Vec3, to: &Vec3, cruise_speed_mps: f64, ramp_s: f64) -> (f64, f64, f64) {
    let length_m = (to - from).norm();
    let speed = if ramp_s > 0.0 { cruise_speed_mps.min(length_m / ramp_s) } else { cruise_speed_mps };
    (length_m, speed, length_m / speed + ramp_s)
}

impl Piece {
    /// Duration, end position and end heading of `segment` started from the given state; checks
    /// the segment's parameters and its continuity with the start state.
    fn place(segment: Segment, t0_s: f64, position: Vec3, heading_rad: f64) -> Result<Self> {
        let duration_s = match segment {
            Segment::Still { duration_s } => {
                non_negative("trajectory.still.duration_s", duration_s)?;
                duration_s
            }
            Segment::TurnInPlace { delta_rad, duration_s } => {
                positive("trajectory.turn.duration_s", duration_s)?;
                if !delta_rad.is_finite() {
                    return Err(invalid("trajectory.turn.delta_rad", "must be finite"));
                }
                duration_s
            }
            Segment::Straight { from, to, cruise_speed_mps, ramp_s } => {
                positive("trajectory.straight.cruise_speed_mps", cruise_speed_mps)?;
                non_negative("trajectory.straight.ramp_s", ramp_s)?;
                if !(from.iter().chain(to.iter()).all(|v| v.is_finite())) {
                    return Err(invalid("trajectory.straight", "end points must be finite"));
                }
                if (from - position).norm() > POSITION_TOL_M {
                    return Err(invalid(
                        "trajectory.straight.from",
                        format!("{from:?} is not the previous end position {position:?}"),
                    ));
                }
                if (to.z - from.z).abs() > POSITION_TOL_M {
                    return Err(invalid("trajectory.straight.to", "must be at the same height as `from` (ground vehicle)"));
                }
                let d = to - from;
                if d.norm() <= POSITION_TOL_M {
                    return Err(invalid("trajectory.straight.to", "leg has zero length"));
                }
                if wrap_pi(d.y.atan2(d.x) - heading_rad).abs() > HEADING_TOL_RAD {
                    return Err(invalid(
                        "trajectory.straight",
                        "leg direction differs from the current heading (turn in place first)",
                    ));
                }
                straight_profile(&from, &to, cruise_speed_mps, ramp_s).2
            }
            Segment::Curve { path, laps, duration_s, ramp_s } => {
                positive("trajectory.curve.duration_s", duration_s)?;
                non_negative("trajectory.curve.ramp_s", ramp_s)?;
                let (a, b) = path.axes_m();
                positive("trajectory.curve.a_m", a)?;
                positive("trajectory.curve.b_m", b)?;
                if laps == 0 {
                    return Err(invalid("trajectory.curve.laps", "must be >= 1"));
                }
                if 2.0 * ramp_s >= duration_s {
                    return Err(invalid("trajectory.curve.ramp_s", "two ramps must fit in the duration"));
                }
                let (p, dp, _) = path.eval(0.0);
                let start = Vec3::new(p.x, p.y, path.height_m());
                if !start.iter().all(|v| v.is_finite()) {
                    return Err(invalid("trajectory.curve.centre", "must be finite"));
                }
                if (start - position).norm() > POSITION_TOL_M {
                    return Err(invalid(
                        "trajectory.curve",
                        format!("path starts at {start:?}, not at the previous end position {position:?}"),
                    ));
                }
                if wrap_pi(dp.y.atan2(dp.x) - heading_rad).abs() > HEADING_TOL_RAD {
                    return Err(invalid("trajectory.curve", "path start tangent differs from the current heading"));
                }
                duration_s
            }
        };
        Ok(Self { segment, t0_s, duration_s, start_position: position, start_heading_rad: heading_rad })
    }

    /// Exact state at local time `tl` ∈ [0, duration]: (position, velocity, acceleration,
    /// heading rad, heading rate rad/s).
    fn eval(&self, tl: f64) -> (Vec3, Vec3, Vec3, f64, f64) {
        let tl = tl.clamp(0.0, self.duration_s);
        let zero = Vec3::zeros();
        match self.segment {
            Segment::Still { .. } => (self.start_position, zero, zero, self.start_heading_rad, 0.0),
            Segment::TurnInPlace { delta_rad, duration_s } => {
                let (s, ds) = smoothstep(tl / duration_s);
                (self.start_position, zero, zero, self.start_heading_rad + delta_rad * s, delta_rad * ds / duration_s)
            }
            Segment::Straight { from, to, cruise_speed_mps, ramp_s } => {
                let (length_m, speed, total_s) = straight_profile(&from, &to, cruise_speed_mps, ramp_s);
                let dir = (to - from) / length_m;
                let (w_int, w, dw) = window(tl, total_s, ramp_s);
                (from + dir * (speed * w_int), dir * (speed * w), dir * (speed * dw), self.start_heading_rad, 0.0)
            }
            Segment::Curve { path, laps, duration_s, ramp_s } => {
                let rate = TAU * f64::from(laps) / (duration_s - ramp_s);
                let (w_int, w, dw) = window(tl, duration_s, ramp_s);
                let (u, du, ddu) = (rate * w_int, rate * w, rate * dw);
                let (p, dp, ddp) = path.eval(u);
                let vel = dp * du;
                let acc = ddp * (du * du) + dp * ddu;
                let heading = dp.y.atan2(dp.x);
                let heading_rate = (dp.x * ddp.y - dp.y * ddp.x) / dp.norm_squared() * du;
                (
                    Vec3::new(p.x, p.y, path.height_m()),
                    Vec3::new(vel.x, vel.y, 0.0),
                    Vec3::new(acc.x, acc.y, 0.0),
                    heading,
                    heading_rate,
                )
            }
        }
    }
}

impl Default for Trajectory {
    /// 10 s standing still at the origin, heading 0 (+x).
    fn default() -> Self {
        let segment = Segment::Still { duration_s: 10.0 };
        Self {
            pieces: vec![Piece { segment, t0_s: 0.0, duration_s: 10.0, start_position: Vec3::zeros(), start_heading_rad: 0.0 }],
            overlay: None,
        }
    }
}

impl Trajectory {
    /// Builds a trajectory from segments, starting at rest at `start_position` (m) with heading
    /// `start_heading_rad` (rad from +x towards +y). Each segment must start where the previous one
    /// ended (position and heading); errors are [`Error::InvalidConfig`](uwbimu_vocabulary::error::Error::InvalidConfig).
    pub fn from_segments(start_position: Vec3, start_heading_rad: f64, segments: &[Segment]) -> Result<Self> {
        if segments.is_empty() {
            return Err(invalid("trajectory", "needs at least one segment"));
        }
        if !start_position.iter().all(|v| v.is_finite()) || !start_heading_rad.is_finite() {
            return Err(invalid("trajectory.start", "start position and heading must be finite"));
        }
        let mut pieces = Vec::with_capacity(segments.len());
        let (mut t_s, mut position, mut heading) = (0.0, start_position, start_heading_rad);
        for &segment in segments {
            let piece = Piece::place(segment, t_s, position, heading)?;
            let (p_end, _, _, h_end, _) = piece.eval(piece.duration_s);
            t_s += piece.duration_s;
            position = p_end;
            heading = h_end;
            pieces.push(piece);
        }
        if t_s <= 0.0 {
            return Err(invalid("trajectory", "total duration must be > 0"));
        }
        Ok(Self { pieces, overlay: None })
    }

    /// The same trajectory with `overlay` added (position offsets and attitude oscillations; see
    /// [`Overlay`]); the motion is no longer level or planar.
    pub fn with_overlay(mut self, overlay: Overlay) -> Result<Self> {
        overlay.validate()?;
        self.overlay = Some(overlay);
        Ok(self)
    }

    /// Standing still at `position` with heading `heading_rad` for `duration_s` s.
    pub fn still(position: Vec3, heading_rad: f64, duration_s: f64) -> Result<Self> {
        Self::from_segments(position, heading_rad, &[Segment::Still { duration_s }])
    }

    /// Still for `still_s`, then `laps` laps of the figure-8 (lemniscate of Gerono) x = a·sin u,
    /// y = b·sin u·cos u about `centre` (m; its z is the height), `lap_time_s` s per lap on
    /// average, with 2 s rate ramps (at most a quarter of the total) so it starts and ends at rest
    /// at the centre.
    ///
    /// ```
    /// # use uwbimu_app::sim::Trajectory;
    /// # use uwbimu_vocabulary::math::Vec3;
    /// let traj = Trajectory::figure_eight(Vec3::new(5.0, 4.0, 0.4), 3.5, 4.5, 36.0, 4, 2.0)?;
    /// assert!((traj.duration_s() - 146.0).abs() < 1e-9);
    /// # Ok::<(), uwbimu_vocabulary::error::Error>(())
    /// ```
    pub fn figure_eight(centre: Vec3, a_m: f64, b_m: f64, lap_time_s: f64, laps: u32, still_s: f64) -> Result<Self> {
        Self::closed_curve(PlanarPath::FigureEight { centre, a_m, b_m }, lap_time_s, laps, still_s)
    }

    /// Still for `still_s`, then `laps` counter-clockwise laps of the ellipse x = a·cos u,
    /// y = b·sin u about `centre` (m), starting and ending at rest at centre + (a, 0); ramps as in
    /// [`Trajectory::figure_eight`].
    pub fn ellipse(centre: Vec3, a_m: f64, b_m: f64, lap_time_s: f64, laps: u32, still_s: f64) -> Result<Self> {
        Self::closed_curve(PlanarPath::Ellipse { centre, a_m, b_m }, lap_time_s, laps, still_s)
    }

    fn closed_curve(path: PlanarPath, lap_time_s: f64, laps: u32, still_s: f64) -> Result<Self> {
        positive("trajectory.lap_time_s", lap_time_s)?;
        let duration_s = lap_time_s * f64::from(laps);
        let ramp_s = (0.25 * duration_s).min(2.0);
        let (p, dp, _) = path.eval(0.0);
        let start = Vec3::new(p.x, p.y, path.height_m());
        Self::from_segments(
            start,
            dp.y.atan2(dp.x),
            &[Segment::Still { duration_s: still_s }, Segment::Curve { path, laps, duration_s, ramp_s }],
        )
    }

    /// Still for `opts.still_s` at `points[0]`, then for each leg: drive straight to the next
    /// point (stopping there), dwell `opts.dwell_s`, turn in place to the next leg's heading in
    /// `opts.turn_time_s`. Consecutive duplicate points are skipped; all points must share one
    /// height. The initial heading is that of the first leg.
    pub fn waypoints(points: &[Vec3], opts: &DriveOptions) -> Result<Self> {
        positive("trajectory.speed_mps", opts.speed_mps)?;
        non_negative("trajectory.ramp_s", opts.ramp_s)?;
        non_negative("trajectory.dwell_s", opts.dwell_s)?;
        positive("trajectory.turn_time_s", opts.turn_time_s)?;
        let mut pts: Vec<Vec3> = Vec::with_capacity(points.len());
        for p in points {
            if pts.last().map_or(true, |q: &Vec3| (p - q).norm() > POSITION_TOL_M) {
                pts.push(*p);
            }
        }
        if pts.len() < 2 {
            return Err(invalid("trajectory.points", "need at least two distinct waypoints"));
        }
        let leg_heading = |i: usize| {
            let d = pts[i + 1] - pts[i];
            d.y.atan2(d.x)
        };
        let mut segments = vec![Segment::Still { duration_s: opts.still_s }];
        let mut heading = leg_heading(0);
        for i in 0..pts.len() - 1 {
            if i > 0 {
                segments.push(Segment::Still { duration_s: opts.dwell_s });
                let delta_rad = wrap_pi(leg_heading(i) - heading);
                if delta_rad.abs() > HEADING_TOL_RAD {
                    segments.push(Segment::TurnInPlace { delta_rad, duration_s: opts.turn_time_s });
                }
                heading = leg_heading(i);
            }
            segments.push(Segment::Straight {
                from: pts[i],
                to: pts[i + 1],
                cruise_speed_mps: opts.speed_mps,
                ramp_s: opts.ramp_s,
            });
        }
        Self::from_segments(pts[0], leg_heading(0), &segments)
    }

    /// `laps` counter-clockwise laps around the axis-aligned rectangle with lower-left `corner`
    /// (m) and size `width_m` × `height_m`, stopping and turning in place at each corner
    /// (see [`Trajectory::waypoints`]); starts and ends at `corner`.
    pub fn rectangle(corner: Vec3, width_m: f64, height_m: f64, laps: u32, opts: &DriveOptions) -> Result<Self> {
        positive("trajectory.width_m", width_m)?;
        positive("trajectory.height_m", height_m)?;
        if laps == 0 {
            return Err(invalid("trajectory.laps", "must be >= 1"));
        }
        let mut points = vec![corner];
        for _ in 0..laps {
            points.push(corner + Vec3::new(width_m, 0.0, 0.0));
            points.push(corner + Vec3::new(width_m, height_m, 0.0));
            points.push(corner + Vec3::new(0.0, height_m, 0.0));
            points.push(corner);
        }
        Self::waypoints(&points, opts)
    }

    /// A single straight leg from `from` to `to` (m) after the initial still period, e.g. the
    /// diagonal of a square (Liu et al. 2019 §4.1).
    pub fn diagonal(from: Vec3, to: Vec3, opts: &DriveOptions) -> Result<Self> {
        Self::waypoints(&[from, to], opts)
    }

    /// Total duration, s.
    pub fn duration_s(&self) -> f64 {
        self.pieces.last().map_or(0.0, |p| p.t0_s + p.duration_s)
    }

    /// Exact kinematic state at time `t_s` (clamped to [0, duration]: at rest before and after).
    pub fn sample(&self, t_s: f64) -> KinematicSample {
        let idx = self.pieces.partition_point(|p| p.t0_s <= t_s).saturating_sub(1);
        let piece = &self.pieces[idx.min(self.pieces.len() - 1)];
        let (position, velocity, acceleration, heading, heading_rate) = piece.eval(t_s - piece.t0_s);
        let Some(overlay) = &self.overlay else {
            return KinematicSample {
                t_s,
                position,
                velocity,
                acceleration,
                orientation: yaw(heading),
                angular_rate_body: Vec3::new(0.0, 0.0, heading_rate),
            };
        };
        let o = overlay.sample(t_s);
        let [roll, pitch, (yaw_offset, yaw_rate)] = o.angles;
        let (orientation, angular_rate_body) =
            attitude_and_body_rate(roll, pitch, (heading + yaw_offset, heading_rate + yaw_rate));
        KinematicSample {
            t_s,
            position: position + o.offset[0],
            velocity: velocity + o.offset[1],
            acceleration: acceleration + o.offset[2],
            orientation,
            angular_rate_body,
        }
    }
}

#[cfg(test)]
mod tests {
    use uwbimu_vocabulary::error::Error;

    use super::*;

    #[test]
    fn window_integral_matches_total_and_derivatives() {
        let (total, ramp) = (10.0, 2.0);
        assert!((window(total, total, ramp).0 - (total - ramp)).abs() < 1e-12);
        let h = 1e-5;
        for &t in &[0.3, 1.0, 1.99, 2.0, 5.0, 8.5, 9.9] {
            let (wi, w, dw) = window(t, total, ramp);
            let (wi_p, w_p, _) = window(t + h, total, ramp);
            let (wi_m, w_m, _) = window(t - h, total, ramp);
            assert!(((wi_p - wi_m) / (2.0 * h) - w).abs() < 1e-8, "t = {t}");
            assert!(((w_p - w_m) / (2.0 * h) - dw).abs() < 1e-6, "t = {t}");
            assert!(wi >= 0.0);
        }
    }

    #[test]
    fn wrap_pi_range() {
        for k in -10..10 {
            let a = 0.3 + f64::from(k) * TAU;
            assert!((wrap_pi(a) - 0.3).abs() < 1e-9);
        }
        assert!((wrap_pi(PI) - PI).abs() < 1e-12);
    }

    #[test]
    fn rejects_discontinuous_segments() {
        let r = Trajectory::from_segments(
            Vec3::zeros(),
            0.0,
            &[Segment::Straight {
                from: Vec3::new(1.0, 0.0, 0.0),
                to: Vec3::new(2.0, 0.0, 0.0),
                cruise_speed_mps: 1.0,
                ramp_s: 1.0,
            }],
        );
        assert!(matches!(r, Err(Error::InvalidConfig { .. })));
        let r = Trajectory::from_segments(
            Vec3::zeros(),
            0.5,
            &[Segment::Straight { from: Vec3::zeros(), to: Vec3::new(2.0, 0.0, 0.0), cruise_speed_mps: 1.0, ramp_s: 1.0 }],
        );
        assert!(matches!(r, Err(Error::InvalidConfig { .. })));
    }
}
