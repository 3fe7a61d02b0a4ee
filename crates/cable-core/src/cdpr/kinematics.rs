//! Inverse kinematics and the structure matrix (seed 002 eqs 1–5; planar: seed 003 eqs 1–5),
//! with pulley-aware cable paths; forward kinematics from cable lengths.
//!
//! Conventions: a pose is `[x, y, θ]` (planar) or `[x, y, z, roll, pitch, yaw]` (spatial, `R =
//! R_z(yaw)·R_y(pitch)·R_x(roll)`); `l_i = a_i − x − R·b_i` points from the platform to the
//! cable's (exit) anchor, `u_i = l_i/‖l_i‖`, and the structure matrix `Aᵀ` (`n × m`) has columns
//! `[u_i; (R·b_i) × u_i]` (planar: `[u_x, u_y, (R·b)_x·u_y − (R·b)_y·u_x]`), so that cable
//! tensions `f` hold an external wrench `w` when `Aᵀ·f + w = 0`.

use super::robot::{cross, Motion, Robot, MAX_CABLES};
use crate::error::{check, CableError, Result};

/// Iteration cap of [`forward_kinematics`].
pub const FK_MAX_ITER: usize = 100;

/// A platform pose: position (m) and rotation (row-major 3 × 3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Position of the platform origin, world frame (m).
    pub position: [f64; 3],
    /// Rotation platform → world, row-major.
    pub rotation: [f64; 9],
}

impl Pose {
    /// The pose of coordinates `q` (`n` of them, see the module docs).
    pub fn from_coordinates(motion: Motion, q: &[f64]) -> Result<Self> {
        Self::from_coordinates_cached(motion, q, &mut None)
    }

    /// The pose of coordinates `q`, reusing the rotation of the last call through `cache`
    /// when the orientation coordinates are the same (bit for bit): a workspace grid at one
    /// orientation computes its rotation once instead of three sines and cosines per pose.
    /// Equal to [`Pose::from_coordinates`].
    pub fn from_coordinates_cached(
        motion: Motion,
        q: &[f64],
        cache: &mut Option<([u64; 3], [f64; 9])>,
    ) -> Result<Self> {
        check::len("pose", q, motion.dof())?;
        check::all_finite("pose", q, 1)?;
        let (position, angles) = match motion {
            Motion::Planar => ([q[0], q[1], 0.0], [0.0, 0.0, q[2]]),
            Motion::Spatial => ([q[0], q[1], q[2]], [q[3], q[4], q[5]]),
        };
        let key = angles.map(f64::to_bits);
        let rotation = match *cache {
            Some((k, r)) if k == key => r,
            _ => {
                let r = rpy(angles[0], angles[1], angles[2]);
                *cache = Some((key, r));
                r
            }
        };
        Ok(Self { position, rotation })
    }

    /// `R·v`.
    pub fn rotate(&self, v: &[f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        [
            r[0] * v[0] + r[1] * v[1] + r[2] * v[2],
            r[3] * v[0] + r[4] * v[1] + r[5] * v[2],
            r[6] * v[0] + r[7] * v[1] + r[8] * v[2],
        ]
    }
}

/// `R_z(yaw)·R_y(pitch)·R_x(roll)`, row-major.
pub fn rpy(roll: f64, pitch: f64, yaw: f64) -> [f64; 9] {
    let (sr, cr) = roll.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    let (sy, cy) = yaw.sin_cos();
    [
        cy * cp,
        cy * sp * sr - sy * cr,
        cy * sp * cr + sy * sr,
        sy * cp,
        sy * sp * sr + cy * cr,
        sy * sp * cr - cy * sr,
        -sp,
        cp * sr,
        cp * cr,
    ]
}

/// Inverse kinematics of one pose, in fixed-size buffers (no allocation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CableGeometry {
    /// Cables `m`.
    pub m: usize,
    /// Degrees of freedom `n`.
    pub n: usize,
    /// Cable length from the anchor (with a pulley: arc on the pulley + free length), m.
    pub length: [f64; MAX_CABLES],
    /// Free length from the (exit) anchor to the platform, m.
    pub free_length: [f64; MAX_CABLES],
    /// Wrap angle on the pulley (rad; 0 without one).
    pub wrap: [f64; MAX_CABLES],
    /// Unit vector from the platform attachment towards the (exit) anchor, world frame.
    pub direction: [[f64; 3]; MAX_CABLES],
    /// Where the cable leaves the frame or its pulley, world frame (m).
    pub exit: [[f64; 3]; MAX_CABLES],
    /// Structure matrix `Aᵀ`, row-major `n × m` (the first `n·m` entries).
    pub structure: [f64; 6 * MAX_CABLES],
}

impl CableGeometry {
    /// The structure matrix `Aᵀ`, row-major `n × m`.
    pub fn structure(&self) -> &[f64] {
        &self.structure[..self.n * self.m]
    }
}

fn norm(v: &[f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn sub(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn degenerate(i: usize, what: &'static str, value: f64) -> CableError {
    CableError::InvalidParameter {
        name: format!("pose (cable {i})"),
        value,
        requirement: what,
    }
}

/// Exit point, wrap angle and arc length of a cable over a swivelling pulley: the pulley turns
/// about `axis` through the anchor `d` so that its plane holds the platform point `p`; the
/// cable arrives along `axis` at `d`, wraps the pulley and leaves tangentially towards `p`.
fn over_pulley(
    i: usize,
    d: &[f64; 3],
    axis: &[f64; 3],
    radius: f64,
    p: &[f64; 3],
) -> Result<([f64; 3], f64)> {
    let v = sub(p, d);
    let along = dot(&v, axis);
    let perp = [
        v[0] - along * axis[0],
        v[1] - along * axis[1],
        v[2] - along * axis[2],
    ];
    let dist = norm(&perp);
    if dist <= 1e-12 * (1.0 + norm(&v)) {
        return Err(degenerate(
            i,
            "off the pulley's swivel axis (the pulley plane is undefined)",
            dist,
        ));
    }
    let e = perp.map(|c| c / dist);
    // pulley-plane coordinates about the centre C = d + r·e: axes e and axis
    let (s, h) = (dist - radius, along);
    let dc = (s * s + h * h).sqrt();
    if dc <= radius {
        return Err(degenerate(
            i,
            "outside the pulley (the platform point is within its radius)",
            dc,
        ));
    }
    let alpha = h.atan2(s) + (radius / dc).acos(); // exit point's angle, from e towards axis
    let wrap = (std::f64::consts::PI - alpha).rem_euclid(std::f64::consts::TAU);
    let (sa, ca) = alpha.sin_cos();
    let exit = [0, 1, 2].map(|k| d[k] + radius * e[k] + radius * (ca * e[k] + sa * axis[k]));
    Ok((exit, wrap))
}

/// Inverse kinematics at `pose`: lengths, directions and the structure matrix into `out`.
/// A cable of zero free length, or a platform point inside or on the axis of a pulley, is an
/// error naming the cable.
pub fn inverse_kinematics(robot: &Robot, pose: &Pose, out: &mut CableGeometry) -> Result<()> {
    let (n, m) = (robot.dof(), robot.n_cables());
    out.n = n;
    out.m = m;
    let planar = robot.motion == Motion::Planar;
    for (i, c) in robot.cables.iter().enumerate() {
        let rb = pose.rotate(&c.attachment);
        let mut p = [
            pose.position[0] + rb[0],
            pose.position[1] + rb[1],
            pose.position[2] + rb[2],
        ];
        let mut anchor = c.anchor;
        if planar {
            p[2] = 0.0;
            anchor[2] = 0.0;
        }
        let (exit, wrap, arc) = match c.pulley {
            None => (anchor, 0.0, 0.0),
            Some(pl) => {
                let (exit, wrap) = over_pulley(i, &anchor, &pl.axis, pl.radius, &p)?;
                (exit, wrap, pl.radius * wrap)
            }
        };
        let l = sub(&exit, &p);
        let len = norm(&l);
        if len <= 1e-12 || !len.is_finite() {
            return Err(degenerate(
                i,
                "a free cable length > 0 (attachment away from the anchor)",
                len,
            ));
        }
        let inv = 1.0 / len;
        let u = l.map(|v| v * inv);
        let mom = cross(&rb, &u);
        out.length[i] = arc + len;
        out.free_length[i] = len;
        out.wrap[i] = wrap;
        out.direction[i] = u;
        out.exit[i] = exit;
        let rows: [f64; 6] = if planar {
            [u[0], u[1], mom[2], 0.0, 0.0, 0.0]
        } else {
            [u[0], u[1], u[2], mom[0], mom[1], mom[2]]
        };
        for (r, v) in rows.iter().take(n).enumerate() {
            out.structure[r * m + i] = *v;
        }
    }
    Ok(())
}

impl Default for CableGeometry {
    fn default() -> Self {
        Self {
            m: 0,
            n: 0,
            length: [0.0; MAX_CABLES],
            free_length: [0.0; MAX_CABLES],
            wrap: [0.0; MAX_CABLES],
            direction: [[0.0; 3]; MAX_CABLES],
            exit: [[0.0; 3]; MAX_CABLES],
            structure: [0.0; 6 * MAX_CABLES],
        }
    }
}

/// Elastic elongation of each cable under tension `f` (seed 002 eq. 15): `Δl_i = l_i·f_i/(E·A)_i`
/// with `l_i` the free length at the pose.
pub fn elongation(
    robot: &Robot,
    geometry: &CableGeometry,
    f: &[f64],
    out: &mut [f64],
) -> Result<()> {
    let m = robot.n_cables();
    check::len("f", f, m)?;
    check::all_finite("f", f, 1)?;
    for i in 0..m {
        out[i] = geometry.free_length[i] * f[i] / robot.cables[i].ea;
    }
    Ok(())
}

/// Result of [`forward_kinematics`].
#[derive(Debug, Clone, PartialEq)]
pub struct ForwardKinematics {
    /// Pose coordinates found.
    pub pose: Vec<f64>,
    /// RMS length error at that pose (m).
    pub rms_error: f64,
    /// Iterations used.
    pub iterations: usize,
    /// Whether the length error fell below `tolerance` (m).
    pub converged: bool,
}

/// The pose whose cable lengths are `lengths`, by damped Gauss–Newton (Levenberg–Marquardt)
/// from the pose coordinates `seed`, using the structure matrix as the length Jacobian
/// (`∂l/∂x = −A` with the rotation updated in world-frame increments). Stops when the RMS error
/// is below `tolerance` (m) or after [`FK_MAX_ITER`] iterations (`converged = false`).
pub fn forward_kinematics(
    robot: &Robot,
    lengths: &[f64],
    seed: &[f64],
    tolerance: f64,
) -> Result<ForwardKinematics> {
    let (n, m) = (robot.dof(), robot.n_cables());
    check::len("lengths", lengths, m)?;
    check::all_finite("lengths", lengths, 1)?;
    for (i, l) in lengths.iter().enumerate() {
        check::non_negative(&format!("lengths[{i}]"), *l)?;
    }
    check::positive("tolerance", tolerance)?;
    let mut pose = Pose::from_coordinates(robot.motion, seed)?;
    let mut geo = CableGeometry::default();
    let residual = |pose: &Pose, geo: &mut CableGeometry, r: &mut [f64]| -> Result<f64> {
        inverse_kinematics(robot, pose, geo)?;
        let mut ss = 0.0;
        for i in 0..m {
            r[i] = geo.length[i] - lengths[i];
            ss += r[i] * r[i];
        }
        let rms = (ss / m as f64).sqrt();
        check::result_finite(
            "length error",
            &[rms],
            1,
            "the lengths are far beyond the robot",
        )?;
        Ok(rms)
    };
    let mut r = [0.0; MAX_CABLES];
    let mut rms = residual(&pose, &mut geo, &mut r)?;
    let mut lambda = 1e-3;
    let mut iterations = 0;
    while rms > tolerance && iterations < FK_MAX_ITER {
        iterations += 1;
        // normal equations of J = −A (m × n): (AᵀA + λ·diag) δ = Aᵀ r  (J δ = −r ⇒ −A δ = −r)
        let at = &geo.structure[..n * m];
        let mut h = [0.0; 36];
        let mut g = [0.0; 6];
        for a in 0..n {
            for b in 0..n {
                h[a * n + b] = (0..m).map(|i| at[a * m + i] * at[b * m + i]).sum();
            }
            g[a] = (0..m).map(|i| at[a * m + i] * r[i]).sum();
        }
        let mut accepted = false;
        for _ in 0..30 {
            let mut hd = h;
            for a in 0..n {
                hd[a * n + a] += lambda * (h[a * n + a] + 1e-12);
            }
            let Some(delta) = solve_spd(&hd, &g, n) else {
                lambda *= 10.0;
                continue;
            };
            let trial = step(robot.motion, &pose, &delta);
            let mut rt = [0.0; MAX_CABLES];
            let mut gt = geo;
            match residual(&trial, &mut gt, &mut rt) {
                Ok(rms_t) if rms_t < rms => {
                    (pose, geo, r, rms) = (trial, gt, rt, rms_t);
                    lambda = (lambda * 0.3).max(1e-12);
                    accepted = true;
                    break;
                }
                _ => lambda *= 10.0,
            }
        }
        if !accepted {
            break;
        }
    }
    Ok(ForwardKinematics {
        pose: coordinates(robot.motion, &pose),
        rms_error: rms,
        iterations,
        converged: rms <= tolerance,
    })
}

/// `pose` moved by `δ = [dx; dω]` (world-frame translation and rotation increment).
pub(super) fn step(motion: Motion, pose: &Pose, delta: &[f64; 6]) -> Pose {
    let mut p = *pose;
    match motion {
        Motion::Planar => {
            p.position[0] += delta[0];
            p.position[1] += delta[1];
            let th = pose.rotation[3].atan2(pose.rotation[0]) + delta[2];
            p.rotation = rpy(0.0, 0.0, th);
        }
        Motion::Spatial => {
            for k in 0..3 {
                p.position[k] += delta[k];
            }
            let w = [delta[3], delta[4], delta[5]];
            let dr = rodrigues(&w);
            p.rotation = matmul(&dr, &pose.rotation);
        }
    }
    p
}

fn rodrigues(w: &[f64; 3]) -> [f64; 9] {
    let th = norm(w);
    if th < 1e-300 {
        return [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    }
    let k = w.map(|v| v / th);
    let (s, c) = th.sin_cos();
    let v = 1.0 - c;
    [
        c + k[0] * k[0] * v,
        k[0] * k[1] * v - k[2] * s,
        k[0] * k[2] * v + k[1] * s,
        k[1] * k[0] * v + k[2] * s,
        c + k[1] * k[1] * v,
        k[1] * k[2] * v - k[0] * s,
        k[2] * k[0] * v - k[1] * s,
        k[2] * k[1] * v + k[0] * s,
        c + k[2] * k[2] * v,
    ]
}

fn matmul(a: &[f64; 9], b: &[f64; 9]) -> [f64; 9] {
    let mut out = [0.0; 9];
    for r in 0..3 {
        for c in 0..3 {
            out[3 * r + c] = (0..3).map(|k| a[3 * r + k] * b[3 * k + c]).sum();
        }
    }
    out
}

/// Pose coordinates of `pose` (roll, pitch, yaw from `R`; pitch in `[−π/2, π/2]`).
pub fn coordinates(motion: Motion, pose: &Pose) -> Vec<f64> {
    let r = &pose.rotation;
    match motion {
        Motion::Planar => vec![pose.position[0], pose.position[1], r[3].atan2(r[0])],
        Motion::Spatial => {
            let pitch = (-r[6]).clamp(-1.0, 1.0).asin();
            let roll = r[7].atan2(r[8]);
            let yaw = r[3].atan2(r[0]);
            let p = pose.position;
            vec![p[0], p[1], p[2], roll, pitch, yaw]
        }
    }
}

/// Solve the `k × k` symmetric positive definite system `h·x = g` by Cholesky (`None` if it is
/// not positive definite).
pub(crate) fn solve_spd(h: &[f64; 36], g: &[f64; 6], k: usize) -> Option<[f64; 6]> {
    let mut l = [0.0; 36];
    let scale = (0..k).map(|i| h[i * k + i].abs()).fold(0.0, f64::max);
    for j in 0..k {
        let mut d = h[j * k + j];
        for p in 0..j {
            d -= l[j * k + p] * l[j * k + p];
        }
        if d.is_nan() || d <= 1e-13 * scale {
            return None;
        }
        let d = d.sqrt();
        l[j * k + j] = d;
        for i in j + 1..k {
            let mut s = h[i * k + j];
            for p in 0..j {
                s -= l[i * k + p] * l[j * k + p];
            }
            l[i * k + j] = s / d;
        }
    }
    let mut y = [0.0; 6];
    for i in 0..k {
        let mut s = g[i];
        for p in 0..i {
            s -= l[i * k + p] * y[p];
        }
        y[i] = s / l[i * k + i];
    }
    let mut x = [0.0; 6];
    for i in (0..k).rev() {
        let mut s = y[i];
        for p in i + 1..k {
            s -= l[p * k + i] * x[p];
        }
        x[i] = s / l[i * k + i];
    }
    Some(x)
}
