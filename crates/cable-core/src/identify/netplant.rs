//! A cable network's replay for the diagnosis: RK4 whose friction cannot overshoot rest.
//!
//! A surgical jaw has a tiny inertia (1e-7 kg·m²) and a dry friction of a few mN·m: smoothed
//! over `ε`, the friction damps the joint at rest at the rate `F/(ε·J)` ≈ 10⁵–10⁶ /s, which
//! explicit RK4 resolves only with hundreds of substeps per millisecond sample — and a fit that
//! raises `F` outruns any fixed count. So in every RK4 stage each joint's (and torque-driven
//! motor's) friction is evaluated not at the stage's speed `v` but at the speed `v⁺` it would
//! reach after half a substep `h` of the stage's applied acceleration `a` against that
//! friction, `v⁺ = v + (h/2)·(a − F(v⁺)/J)` (backward Euler on the element's speed alone; the
//! root lies between rest and `v + (h/2)·a` and is found by bracketed regula falsi). Where the
//! friction is smooth on the scale of `h` this is `F(v) + O(h)`, and the replay converges to the
//! plain one as `h → 0`; where it is stiff, the element's speed relaxes at most at the rate
//! `2/h` onto the slow manifold `F(v) = J·a` (a stick holds, creeping as the smoothed law
//! creeps) instead of chattering through zero. The substeps are set by the cables' and
//! inertias' modes, and at least [`MIN_SUBSTEPS`]: against a replay resolved with 2048 explicit
//! substeps, a jaw of 1e-7 kg·m² under 4 mN·m of friction (rate 8·10⁵ /s) is off by 3.2e-4 rad
//! at one substep and 3.8e-5 rad at four (the test below), a tenth of a 14-bit encoder's count.

use crate::dynamics::network::Network;
use crate::dynamics::Model;
use crate::error::{CableError, Result};
use crate::friction::StaticFriction;
use crate::integrate::{InputHold, Rk4};

/// Fewest substeps per sample interval of a network replay (module docs).
pub const MIN_SUBSTEPS: usize = 4;

/// Most regula-falsi iterations per friction half-step.
const FRICTION_ITER: usize = 60;

/// The friction on one coordinate at speed `w`: its own law, and the routing friction of the
/// cables it hauls, `(arm, T, μφ, ε)` each (`arm·T·(e^{μφ·σ_ε(−arm·w)} − 1)` is the extra pull
/// the driver feels, opposing `w`); returns the force opposing the motion and its slope in `w`.
fn coordinate_friction(f: &StaticFriction, cables: &[(f64, f64, f64, f64)], w: f64) -> (f64, f64) {
    let mut force = f.force(w);
    #[allow(clippy::float_cmp)] // equal exactly when built without a Stribeck bump
    let plain = f.static_level == f.coulomb;
    let mut slope = if plain {
        let e2 = f.smoothing * f.smoothing;
        f.coulomb * e2 / (w * w + e2).powf(1.5) + f.viscous
    } else {
        let d = 1e-7 * w.abs().max(f.smoothing);
        (f.force(w + d) - force) / d
    };
    for &(arm, t, mu_phi, eps) in cables {
        let x = -arm * w;
        let r = (x * x + eps * eps).sqrt();
        let e = (mu_phi * x / r).exp();
        force -= arm * t * (e - 1.0);
        slope += arm * arm * t * mu_phi * e * eps * eps / (r * r * r);
    }
    (force, slope)
}

/// The friction force on a coordinate of inertia `inertia` at speed `v` under acceleration `a`
/// (without the friction) over a time `h`: `F(v⁺)` with `v⁺ = v + h·(a − F(v⁺)/J)` (module docs:
/// `h` is half a substep). The root of `g(w) = w − (v + h·a) + (h/J)·F(w)` lies between rest and
/// `v + h·a` (friction opposes the speed it acts on); safeguarded Newton from the stage's speed
/// finds it in a few iterations, bisecting whenever a step would leave the bracket.
fn limited_friction(law: impl Fn(f64) -> (f64, f64), inertia: f64, v: f64, a: f64, h: f64) -> f64 {
    let free = v + h * a;
    if !free.is_finite() || free == 0.0 {
        return law(free).0;
    }
    let c = h / inertia;
    let (mut lo, mut hi) = if free > 0.0 { (0.0, free) } else { (free, 0.0) };
    let mut w = v.clamp(lo, hi);
    let (mut force, mut slope) = law(w);
    let mut gw = w - free + c * force;
    let tol = 1e-12 * free.abs();
    for _ in 0..FRICTION_ITER {
        if gw == 0.0 || hi - lo <= tol {
            break;
        }
        // the bracket keeps g(lo) ≤ 0 ≤ g(hi) whatever the law's shape
        if gw < 0.0 {
            lo = w;
        } else {
            hi = w;
        }
        let mut next = w - gw / (1.0 + c * slope);
        if !(next > lo && next < hi && next.is_finite()) {
            next = 0.5 * (lo + hi);
        }
        let done = (next - w).abs() <= tol;
        w = next;
        (force, slope) = law(w);
        gw = w - free + c * force;
        if done {
            break;
        }
    }
    force
}

/// One coordinate with friction: a joint or a torque-driven motor.
struct Coordinate {
    /// Index of its speed in the state.
    speed: usize,
    inertia: f64,
    friction: StaticFriction,
    /// The cables whose routing friction it hauls through: `(cable, arm)`.
    cables: Vec<(usize, f64)>,
}

/// The network with each coordinate's friction limited over half a substep `h` (module docs).
struct Limited<'a> {
    net: &'a Network,
    smooth: Network,
    coordinates: Vec<Coordinate>,
    h: f64,
}

impl<'a> Limited<'a> {
    fn new(net: &'a Network, h: f64) -> Self {
        let mut coordinates: Vec<Coordinate> = (0..net.n_joints())
            .map(|j| Coordinate {
                speed: 2 * j + 1,
                inertia: net.joint_inertia(j),
                friction: *net.joint_friction(j),
                cables: vec![],
            })
            .collect();
        for i in 0..net.n_motors() {
            if let Some((slot, inertia, f)) = net.motor_dynamics(i) {
                coordinates.push(Coordinate {
                    speed: slot + 1,
                    inertia,
                    friction: *f,
                    cables: vec![],
                });
            }
        }
        for c in 0..net.n_cables() {
            if let Some((speed, arm)) = net.cable_driver(c) {
                if let Some(k) = coordinates.iter_mut().find(|k| k.speed == speed) {
                    k.cables.push((c, arm));
                }
            }
        }
        Self {
            net,
            smooth: net.frictionless(),
            coordinates,
            h,
        }
    }
}

impl Model for Limited<'_> {
    fn n_states(&self) -> usize {
        self.net.n_states()
    }
    fn n_inputs(&self) -> usize {
        self.net.n_inputs()
    }
    fn n_outputs(&self) -> usize {
        self.net.n_outputs()
    }
    fn derivative(&self, x: &[f64], u: &[f64], dx: &mut [f64]) {
        self.smooth.derivative(x, u, dx);
        let net = self.net;
        let mut tensions = [0.0; 16];
        let mut all = Vec::new();
        let t: &mut [f64] = if net.n_cables() <= tensions.len() {
            &mut tensions[..net.n_cables()]
        } else {
            all.resize(net.n_cables(), 0.0);
            &mut all
        };
        if self.coordinates.iter().any(|k| !k.cables.is_empty()) {
            net.tensions(x, u, t);
        }
        // the cables a coordinate hauls, on the stack (a heap list only beyond eight: no
        // allocation per derivative on the hot path)
        let mut stack = [(0.0, 0.0, 0.0, 0.0); 8];
        let mut heap = Vec::new();
        for k in &self.coordinates {
            if k.cables.is_empty() && k.friction == StaticFriction::NONE {
                continue;
            }
            let entry = |&(c, arm): &(usize, f64)| {
                (arm, t[c], net.cable_capstan(c), net.cable_smoothing(c))
            };
            let cables: &[(f64, f64, f64, f64)] = if k.cables.len() <= stack.len() {
                for (slot, c) in stack.iter_mut().zip(&k.cables) {
                    *slot = entry(c);
                }
                &stack[..k.cables.len()]
            } else {
                heap.clear();
                heap.extend(k.cables.iter().map(entry));
                &heap
            };
            let law = |w: f64| coordinate_friction(&k.friction, cables, w);
            let f = limited_friction(law, k.inertia, x[k.speed], dx[k.speed], self.h);
            dx[k.speed] -= f / k.inertia;
        }
    }
    fn output(&self, x: &[f64], u: &[f64], y: &mut [f64]) {
        self.net.output(x, u, y);
    }
    fn state_names(&self) -> Vec<String> {
        self.net.state_names()
    }
    fn input_names(&self) -> Vec<String> {
        self.net.input_names()
    }
    fn output_names(&self) -> Vec<String> {
        self.net.output_names()
    }
}

/// Outputs `(T, p)` of `net` over inputs `u` `(T, m)` from `x0`, `substeps` RK4 steps per
/// sample interval with the friction limited (module docs); a non-finite state or output is
/// [`CableError::Diverged`].
pub(crate) fn simulate_network(
    net: &Network,
    u: &[f64],
    x0: &[f64],
    dt: f64,
    substeps: usize,
    hold: InputHold,
) -> Result<Vec<f64>> {
    let (m, p) = (net.n_inputs(), net.n_outputs());
    let t_len = u.len() / m.max(1);
    let s = substeps.max(MIN_SUBSTEPS);
    let model = Limited::new(net, 0.5 * dt / s as f64);
    let mut ws = Rk4::for_model(&model);
    let mut x = x0.to_vec();
    let mut out = vec![0.0; t_len * p];
    for k in 0..t_len {
        let u_k = &u[k * m..(k + 1) * m];
        if k > 0 {
            let prev = &u[(k - 1) * m..k * m];
            let next = if hold == InputHold::Foh { u_k } else { prev };
            ws.advance(&model, &mut x, prev, next, dt, s);
        }
        let y = &mut out[k * p..(k + 1) * p];
        net.output(&x, u_k, y);
        if !x.iter().chain(y.iter()).all(|v| v.is_finite()) {
            return Err(CableError::Diverged {
                step: k,
                time_s: k as f64 * dt,
            });
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::network::NetworkSpec;
    use crate::dynamics::AntagonisticJoint;
    use crate::integrate::{simulate, SimOptions};

    #[test]
    fn limited_friction_is_the_implicit_root_and_smooth_friction_is_unchanged() {
        let f = StaticFriction::coulomb_viscous("f", 4e-3, 2e-5, 0.05).unwrap();
        let cables = [(-4e-3, 10.0, 0.2, 1e-3)];
        for with_cables in [false, true] {
            let cs: &[(f64, f64, f64, f64)] = if with_cables { &cables } else { &[] };
            let law = |w: f64| coordinate_friction(&f, cs, w);
            for (v, a, h) in [
                (0.3, 10.0, 1e-4),
                (-0.02, 3e3, 5e-4),
                (1e-6, -1e4, 1e-3),
                (0.0, 50.0, 2.5e-4),
            ] {
                let force = limited_friction(law, 1e-7, v, a, h);
                let w = v + h * (a - force / 1e-7);
                assert!(
                    (force - law(w).0).abs() <= 1e-9 * force.abs().max(1e-12),
                    "{v} {a}"
                );
            }
            // the slope is the law's derivative
            for w in [-0.3, -1e-3, 0.0, 2e-4, 0.05, 1.0] {
                let d = 1e-7;
                let numeric = (law(w + d).0 - law(w - d).0) / (2.0 * d);
                assert!(
                    (law(w).1 - numeric).abs() <= 1e-4 * numeric.abs() + 1e-9,
                    "{w}"
                );
            }
        }
        // a substep far below the friction's time constant: the plain friction
        let law = |w: f64| coordinate_friction(&f, &[], w);
        let slow = limited_friction(law, 1.0, 0.3, 1.0, 1e-6);
        assert!((slow - f.force(0.3)).abs() < 1e-9);
    }

    /// A torque-driven motor hauling both cables through a capstan of μφ = 0.3 (its routing
    /// friction acts on the motor, a stiff sign at 1 mm/s of cable): the limited replay agrees
    /// with a resolved explicit one.
    #[test]
    fn routing_friction_on_a_torque_motor_is_limited_too() {
        use crate::dynamics::network::Drive;
        let mut j = AntagonisticJoint::forceps_example();
        j.contact = None;
        j.capstan_mu = 0.1;
        j.capstan_wrap = 3.0;
        let mut spec = NetworkSpec::from_joint(&j).unwrap();
        spec.motors[0].drive = Drive::Torque;
        spec.motors[0].inertia = 1e-6;
        spec.motors[0].capstan_radius = 0.01;
        let net = Network::new(&spec).unwrap();
        assert!(net.cable_driver(0).is_some() && net.cable_driver(1).is_some());
        let dt = 1e-3;
        let u: Vec<f64> = (0..500)
            .flat_map(|k| {
                [
                    0.02 * (2.0 * std::f64::consts::PI * 2.0 * k as f64 * dt).sin(),
                    0.0,
                ]
            })
            .collect();
        let x0 = vec![0.0; 4];
        let fine = simulate(
            &net,
            &u,
            &x0,
            &SimOptions::new(dt, 4096, InputHold::Zoh).unwrap(),
        )
        .unwrap();
        let limited = simulate_network(&net, &u, &x0, dt, 4, InputHold::Zoh).unwrap();
        let p = net.n_outputs();
        // the motor angle (output 1)
        let err = (0..500)
            .map(|k| (limited[k * p + 1] - fine.outputs[k * p + 1]).abs())
            .fold(0.0, f64::max);
        let span = (0..500)
            .map(|k| fine.outputs[k * p + 1].abs())
            .fold(0.0, f64::max);
        assert!(span > 0.0 && err < 1e-3 * span, "{err} of {span}");
    }

    /// A joint whose smoothed friction is far too stiff for explicit RK4 at 4 substeps: the
    /// limited replay agrees with an explicit replay of 2048 substeps to 1e-4 of the motion.
    #[test]
    fn the_limited_replay_matches_a_resolved_explicit_one() {
        let mut j = AntagonisticJoint::forceps_example();
        j.contact = None;
        j.inertia = 1e-7;
        j.friction = StaticFriction::coulomb_viscous("f", 4e-3, 2e-5, 0.05).unwrap();
        let net = Network::new(&NetworkSpec::from_joint(&j).unwrap()).unwrap();
        let dt = 1e-3;
        let u: Vec<f64> = (0..600)
            .flat_map(|k| {
                let t = k as f64 * dt;
                let w = 2.0 * std::f64::consts::PI * 1.5;
                [1e-3 * (w * t).sin(), 1e-3 * w * (w * t).cos(), 0.0]
            })
            .collect();
        let x0 = vec![0.0; 2];
        let fine = simulate(
            &net,
            &u,
            &x0,
            &SimOptions::new(dt, 2048, InputHold::Foh).unwrap(),
        )
        .unwrap();
        let split = simulate_network(&net, &u, &x0, dt, 4, InputHold::Foh).unwrap();
        let p = net.n_outputs();
        let err = (0..600)
            .map(|k| (split[k * p] - fine.outputs[k * p]).abs())
            .fold(0.0, f64::max);
        let span = (0..600)
            .map(|k| fine.outputs[k * p].abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-4 * span, "{err} of {span}");
        // explicit RK4 at the same 4 substeps chatters through rest: 10x further off or worse
        let coarse = simulate(
            &net,
            &u,
            &x0,
            &SimOptions::new(dt, 4, InputHold::Foh).unwrap(),
        );
        let coarse_err = coarse.map_or(f64::INFINITY, |c| {
            (0..600)
                .map(|k| (c.outputs[k * p] - fine.outputs[k * p]).abs())
                .fold(0.0, f64::max)
        });
        assert!(coarse_err > 10.0 * err, "{coarse_err} vs {err}");
    }
}
