//! Cable-driven transmission with 1 to 3 coupled links (seed 001 eqs 2.3–2.8).
//!
//! Per link `i` a motor (inertia `I_m`, gear ratio `N`, capstan radius `r_m`, friction `τ_m`)
//! pulls an antagonistic cable loop wrapped on the joint pulley (radius `r_l`), which drives a
//! link (inertia `I_l`, friction `F_l`, gravity load `g`). Cable routing couples the axes: the
//! motor angles that keep every cable at its rest length are `q_m = T·q_l` with the
//! lower-triangular transmission matrix of eq. (2.8):
//!
//! ```text
//! T_ii = tr_i = r_l,i·N_i / r_m,i          (motor rad per joint rad, or per m when prismatic)
//! T_ij = C_ij·tr_i   (j < i)               (coupling of joint j into cable i, seed C01, C02, C12)
//! ```
//!
//! **Equations** (state per link `[q_m, q̇_m, q_l, q̇_l]`, input motor torque `τ` and external
//! joint load `τ_ext`):
//!
//! ```text
//! ρ_i  = r_m,i / N_i                                   capstan metres per motor radian
//! Δ    = ρ ⊙ (q_m − T·q_l),  Δ̇ = ρ ⊙ (q̇_m − T·q̇_l)    loop stretch (m), eq. (2.6) argument
//! (T_a, T_b) = loop tensions at (Δ, Δ̇)                  see `crate::cable`; γ = T_a − T_b
//! I_m,i q̈_m,i = τ_i − τ_m,i(q̇_m,i) − ρ_i·γ_i           eqs (2.3)–(2.5), τ_rn = r_m·γ/N
//! Γ    = Tᵀ·(ρ ⊙ γ)                                     eq. (2.7) generalised by eq. (2.8)
//! I_l,j q̈_l,j = Γ_j − F_l,j(q̇_l,j) − g_j(q_l,j) + τ_ext,j   eqs (2.1)–(2.2), diagonal inertia
//! ```
//!
//! For an uncoupled link `Γ_i = tr_i·ρ_i·γ_i = r_l,i·γ_i`, eq. (2.7). `Γ = Tᵀρ⊙γ` is the
//! transpose (virtual-work) map of eq. (2.8), so the transmission is power-consistent and the
//! frictionless, undamped system conserves
//! `E = ½Σ I_m q̇_m² + ½Σ I_l q̇_l² + Σ V_loop(Δ) + Σ ∫g`.
//!
//! **Link dynamics** are decoupled: each link has a constant inertia and its own gravity load
//! `g(q) = A·cos(q + φ)` (revolute, N·m) or `A·cos φ` (prismatic, N); configuration-dependent
//! inertia and Coriolis terms of eq. (2.1) are not modelled.
//!
//! **Torque convention**: the input `τ` is the torque of eq. (2.3), entering the motor-shaft
//! equation directly and positive in the direction of positive `q_m`; `τ_ext` is a generalised
//! force applied to the joint, positive in the direction of positive `q_l`.

use super::{Model, GRAVITY};
use crate::cable::{CableLanes, CableLoop};
use crate::error::{check, CableError, Result};
use crate::friction::{FrictionLanes, StaticFriction};
use crate::lanes::{madd, Lanes, LANES};

/// Largest number of coupled links.
pub const MAX_LINKS: usize = 3;

/// Joint type: decides units (rad vs m) and the gravity law.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Rotary joint: `q_l` in rad, torques in N·m, inertia in kg·m².
    Revolute,
    /// Sliding joint: `q_l` in m, forces in N, inertia (mass) in kg.
    Prismatic,
}

impl JointKind {
    /// Parse `"revolute"` / `"prismatic"`.
    pub fn from_name(name: &str, field: &str) -> Result<Self> {
        match name {
            "revolute" => Ok(JointKind::Revolute),
            "prismatic" => Ok(JointKind::Prismatic),
            other => Err(CableError::InvalidOption {
                name: field.to_owned(),
                value: other.to_owned(),
                allowed: "\"revolute\", \"prismatic\"".to_owned(),
            }),
        }
    }
    /// Lower-case name.
    pub fn name(&self) -> &'static str {
        match self {
            JointKind::Revolute => "revolute",
            JointKind::Prismatic => "prismatic",
        }
    }
}

/// Gravity load of one link: `g(q) = A·cos(q + φ)` (revolute) or `A·cos φ` (prismatic).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gravity {
    /// Amplitude `A` = m·g₀·l_c (N·m) for revolute joints or m·g₀ (N) for prismatic joints.
    pub amplitude: f64,
    /// Phase `φ` (rad): for a revolute joint `q + φ` is the link's angle above the horizontal;
    /// for a prismatic joint `φ` is the axis' angle from the vertical, so `A·cos φ` is the
    /// weight along the axis.
    pub offset: f64,
}

impl Gravity {
    /// No gravity load.
    pub const NONE: Gravity = Gravity {
        amplitude: 0.0,
        offset: 0.0,
    };

    /// Gravity from a mass (kg) and centre-of-mass distance (m, ignored for prismatic joints).
    pub fn from_mass(kind: JointKind, mass: f64, com_distance: f64, offset: f64) -> Self {
        let amplitude = match kind {
            JointKind::Revolute => mass * GRAVITY * com_distance,
            JointKind::Prismatic => mass * GRAVITY,
        };
        Gravity { amplitude, offset }
    }

    #[inline]
    pub(crate) fn load(&self, kind: JointKind, q: f64) -> f64 {
        // exact zero is the "no gravity" setting (the Raven-II default): skip the cosine,
        // a tenth of an RK4 step
        #[allow(clippy::float_cmp)]
        if self.amplitude == 0.0 {
            return 0.0;
        }
        match kind {
            JointKind::Revolute => self.amplitude * (q + self.offset).cos(),
            JointKind::Prismatic => self.amplitude * self.offset.cos(),
        }
    }

    pub(crate) fn potential(&self, kind: JointKind, q: f64) -> f64 {
        match kind {
            JointKind::Revolute => self.amplitude * (q + self.offset).sin(),
            JointKind::Prismatic => self.amplitude * self.offset.cos() * q,
        }
    }
}

/// Parameters of one motor–cable–link axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TransmissionLink {
    /// Motor inertia `I_m` (kg·m²) in the torque convention of the module docs.
    pub motor_inertia: f64,
    /// Gear ratio `N` (motor rad per capstan rad).
    pub gear_ratio: f64,
    /// Capstan radius `r_m` (m).
    pub capstan_radius: f64,
    /// Motor friction `τ_m(q̇_m)` (Coulomb `τ_cm` + viscous `τ_vm`, eq. 2.4).
    pub motor_friction: StaticFriction,
    /// The antagonistic cable loop (law `k_e`, damping `b_e`, pretension).
    pub cable: CableLoop,
    /// Joint type.
    pub kind: JointKind,
    /// Joint pulley radius `r_l` (m); for a prismatic joint the metres of cable per metre of
    /// travel (1 for a direct cable drive, as Raven-II's insertion axis).
    pub joint_radius: f64,
    /// Link inertia `I_l` (kg·m², or kg for prismatic).
    pub link_inertia: f64,
    /// Link friction `F_cl`, `F_vl` (eq. 2.2).
    pub link_friction: StaticFriction,
    /// Gravity load.
    pub gravity: Gravity,
}

impl TransmissionLink {
    fn validate(&self, i: usize) -> Result<()> {
        let p = |f: &str| format!("links[{i}].{f}");
        check::positive(&p("motor_inertia"), self.motor_inertia)?;
        check::positive(&p("gear_ratio"), self.gear_ratio)?;
        check::positive(&p("capstan_radius"), self.capstan_radius)?;
        check::positive(&p("joint_radius"), self.joint_radius)?;
        check::positive(&p("link_inertia"), self.link_inertia)?;
        check::finite(&p("gravity_amplitude"), self.gravity.amplitude)?;
        check::finite(&p("gravity_offset"), self.gravity.offset)?;
        self.motor_friction.validate(&p("motor_friction"))?;
        self.link_friction.validate(&p("link_friction"))?;
        self.cable.run.validate(&format!("links[{i}]"))
    }

    /// Transmission ratio `tr = r_l·N/r_m`.
    pub fn ratio(&self) -> f64 {
        self.joint_radius * self.gear_ratio / self.capstan_radius
    }
}

/// Call `self.method::<N>(args)` with the const `N` equal to the run-time link count `n`, so
/// the per-link loops of the hot path are unrolled and their bounds known.
macro_rules! by_links {
    ($self:expr, $n:expr, $method:ident ( $($arg:expr),* )) => {
        match $n {
            1 => $self.$method::<1>($($arg),*),
            2 => $self.$method::<2>($($arg),*),
            _ => $self.$method::<3>($($arg),*),
        }
    };
}

/// The coupled 1–3 link cable transmission; see the module docs for the equations.
#[derive(Debug, Clone, PartialEq)]
pub struct CableTransmission {
    links: Vec<TransmissionLink>,
    coupling: [[f64; MAX_LINKS]; MAX_LINKS],
    t: [[f64; MAX_LINKS]; MAX_LINKS],
    rho: [f64; MAX_LINKS],
    /// `1/I_m`, `1/I_l` per link (multiplications are cheaper than divisions in the hot path).
    inv_motor_inertia: [f64; MAX_LINKS],
    inv_link_inertia: [f64; MAX_LINKS],
    /// Per link, the parameters broadcast for the lane derivative.
    lanes: Vec<LinkLanes>,
}

/// One link's parameters broadcast to [`LANES`] lanes once, at construction: the lane
/// derivative reads them as vector operands (no broadcasts, and the friction form, cable law
/// and gravity switch decided here instead of on every call).
#[derive(Debug, Clone, PartialEq)]
struct LinkLanes {
    /// `T[i][j]`, the row of the transmission matrix.
    t: [Lanes; MAX_LINKS],
    /// `T[i][j]·ρ_i`, this link's share of `Γ_j = Σᵢ T[i][j]·ρ_i·γ_i`.
    t_rho: [Lanes; MAX_LINKS],
    rho: Lanes,
    inv_motor_inertia: Lanes,
    inv_link_inertia: Lanes,
    cable: CableLanes,
    motor_friction: FrictionLanes,
    link_friction: FrictionLanes,
    /// A gravity load (its amplitude is not exactly zero).
    gravity: bool,
}

impl CableTransmission {
    /// Validated constructor. `coupling` is the `n×n` row-major matrix of coupling coefficients
    /// `C_ij` (cable `i`, joint `j`); only the strictly lower triangle may be non-zero
    /// (seed eq. 2.8: `C_10 = C01`, `C_20 = C02`, `C_21 = C12`). Pass an empty slice for none.
    pub fn new(links: Vec<TransmissionLink>, coupling: &[f64]) -> Result<Self> {
        let n = links.len();
        if n == 0 || n > MAX_LINKS {
            return Err(CableError::Shape {
                what: "links".into(),
                expected: format!("1 to {MAX_LINKS} links"),
                got: format!("{n} links"),
            });
        }
        for (i, l) in links.iter().enumerate() {
            l.validate(i)?;
        }
        let mut c = [[0.0; MAX_LINKS]; MAX_LINKS];
        if !coupling.is_empty() {
            if coupling.len() != n * n {
                return Err(CableError::Shape {
                    what: "coupling".into(),
                    expected: format!("({n}, {n})"),
                    got: format!("{} values", coupling.len()),
                });
            }
            for i in 0..n {
                for j in 0..n {
                    let v = coupling[i * n + j];
                    let name = format!("coupling[{i}][{j}]");
                    check::finite(&name, v)?;
                    if j >= i && v != 0.0 {
                        return Err(CableError::InvalidParameter {
                            name,
                            value: v,
                            requirement:
                                "0 on and above the diagonal (eq. 2.8 is lower-triangular)",
                        });
                    }
                    c[i][j] = v;
                }
            }
        }
        let mut t = [[0.0; MAX_LINKS]; MAX_LINKS];
        let mut rho = [0.0; MAX_LINKS];
        let (mut inv_im, mut inv_il) = ([0.0; MAX_LINKS], [0.0; MAX_LINKS]);
        for i in 0..n {
            inv_im[i] = 1.0 / links[i].motor_inertia;
            inv_il[i] = 1.0 / links[i].link_inertia;
            let tr = links[i].ratio();
            t[i][i] = tr;
            for j in 0..i {
                t[i][j] = c[i][j] * tr;
            }
            rho[i] = links[i].capstan_radius / links[i].gear_ratio;
        }
        let lanes = links
            .iter()
            .enumerate()
            .map(|(i, link)| LinkLanes {
                t: t[i].map(|t| [t; LANES]),
                t_rho: t[i].map(|t| [t * rho[i]; LANES]),
                rho: [rho[i]; LANES],
                inv_motor_inertia: [inv_im[i]; LANES],
                inv_link_inertia: [inv_il[i]; LANES],
                cable: link.cable.lanes(),
                motor_friction: link.motor_friction.lanes(),
                link_friction: link.link_friction.lanes(),
                #[allow(clippy::float_cmp)] // exact zero: no gravity (as `Gravity::load`)
                gravity: link.gravity.amplitude != 0.0,
            })
            .collect();
        Ok(Self {
            links,
            coupling: c,
            t,
            rho,
            inv_motor_inertia: inv_im,
            inv_link_inertia: inv_il,
            lanes,
        })
    }

    /// Number of links `n`.
    pub fn n_links(&self) -> usize {
        self.links.len()
    }

    /// The per-link parameters.
    pub fn links(&self) -> &[TransmissionLink] {
        &self.links
    }

    /// Coupling coefficients `C_ij` (row-major `n×n`).
    pub fn coupling(&self) -> Vec<f64> {
        let n = self.n_links();
        (0..n * n).map(|k| self.coupling[k / n][k % n]).collect()
    }

    /// Transmission matrix `T` of eq. (2.8) (row-major `n×n`): `q_m = T·q_l` at rest length.
    pub fn transmission_matrix(&self) -> Vec<f64> {
        let n = self.n_links();
        (0..n * n).map(|k| self.t[k / n][k % n]).collect()
    }

    /// Rigid-cable transmission kinematics `q_m = T·q_l`.
    pub fn joint_to_motor(&self, q_l: &[f64], q_m: &mut [f64]) {
        let n = self.n_links();
        for i in 0..n {
            q_m[i] = (0..=i).map(|j| self.t[i][j] * q_l[j]).sum();
        }
    }

    /// Inverse kinematics `q_l = T⁻¹·q_m` by forward substitution (joint estimate from motor
    /// encoders alone, the baseline of seed 001 ch. 3).
    pub fn motor_to_joint(&self, q_m: &[f64], q_l: &mut [f64]) {
        let n = self.n_links();
        for i in 0..n {
            let s: f64 = (0..i).map(|j| self.t[i][j] * q_l[j]).sum();
            q_l[i] = (q_m[i] - s) / self.t[i][i];
        }
    }

    /// [`CableTransmission::motor_to_joint`] for each row of row-major `(rows, n)` motor angles
    /// (rad or m), checked: a length that is not a whole number of rows, a non-finite angle or
    /// a non-finite result (a degenerate transmission) is an error naming the row.
    pub fn motor_to_joint_rows(&self, q_m: &[f64]) -> Result<Vec<f64>> {
        let n = self.n_links();
        if !q_m.len().is_multiple_of(n) {
            return Err(CableError::Shape {
                what: "q_m".into(),
                expected: format!("(T, {n})"),
                got: format!("{} values", q_m.len()),
            });
        }
        check::all_finite("q_m", q_m, n)?;
        let mut q_l = vec![0.0; q_m.len()];
        for (a, b) in q_m.chunks_exact(n).zip(q_l.chunks_exact_mut(n)) {
            self.motor_to_joint(a, b);
        }
        check::result_finite(
            "q_l",
            &q_l,
            n,
            "the transmission matrix is too badly scaled",
        )?;
        Ok(q_l)
    }

    /// Loop stretches `Δ` (m) and rates `Δ̇` (m/s) at state `x`, for `N = n_links()` (a
    /// const parameter so that the hot loops unroll; see [`by_links`]).
    #[inline(always)]
    fn stretches<const N: usize>(&self, x: &[f64]) -> ([f64; N], [f64; N]) {
        let (mut d, mut dd) = ([0.0; N], [0.0; N]);
        for i in 0..N {
            let (mut tq, mut tw) = (0.0, 0.0);
            for j in 0..=i {
                tq += self.t[i][j] * x[4 * j + 2];
                tw += self.t[i][j] * x[4 * j + 3];
            }
            d[i] = self.rho[i] * (x[4 * i] - tq);
            dd[i] = self.rho[i] * (x[4 * i + 1] - tw);
        }
        (d, dd)
    }

    /// Side tensions `(T_a, T_b)` per link, net tensions `γ` and joint forces `Γ = Tᵀ·(ρ ⊙ γ)`
    /// at state `x`.
    #[inline(always)]
    fn forces<const N: usize>(&self, x: &[f64]) -> ([(f64, f64); N], [f64; N], [f64; N]) {
        let (d, dd) = self.stretches::<N>(x);
        let mut tens = [(0.0, 0.0); N];
        let mut gamma = [0.0; N];
        for i in 0..N {
            tens[i] = self.links[i].cable.tensions(d[i], dd[i]);
            gamma[i] = tens[i].0 - tens[i].1;
        }
        let mut g = [0.0; N];
        for j in 0..N {
            for i in j..N {
                g[j] += self.t[i][j] * self.rho[i] * gamma[i];
            }
        }
        (tens, gamma, g)
    }

    /// [`Self::derivative_n`] of `W` states (structure of arrays), operation for operation
    /// (or with products and sums fused when `FUSED`). `S = 4·N` states as fixed-size arrays,
    /// so the link loops unroll with no bounds checks; the parameters come broadcast from
    /// [`LinkLanes`] (lane `l` reads `l % LANES`).
    #[inline(always)]
    fn derivative_lanes_n<const N: usize, const S: usize, const FUSED: bool, const W: usize>(
        &self,
        x: &[[f64; W]],
        u: &[f64],
        dx: &mut [[f64; W]],
    ) {
        let x: &[[f64; W]; S] = x.try_into().expect("4 states per link");
        let dx: &mut [[f64; W]; S] = dx.try_into().expect("4 states per link");
        let p: &[LinkLanes; N] = self.lanes[..N].try_into().expect("N links");
        let u = &u[..2 * N];
        let mut gamma = [[0.0; W]; N];
        for i in 0..N {
            let (mut tq, mut tw) = ([0.0; W], [0.0; W]);
            for j in 0..=i {
                let t = &p[i].t[j];
                for l in 0..W {
                    tq[l] = madd::<FUSED>(t[l % LANES], x[4 * j + 2][l], tq[l]);
                    tw[l] = madd::<FUSED>(t[l % LANES], x[4 * j + 3][l], tw[l]);
                }
            }
            let rho = &p[i].rho;
            let d = std::array::from_fn(|l| rho[l % LANES] * (x[4 * i][l] - tq[l]));
            let dd = std::array::from_fn(|l| rho[l % LANES] * (x[4 * i + 1][l] - tw[l]));
            let (ta, tb) = p[i].cable.tensions::<FUSED, W>(&d, &dd);
            gamma[i] = std::array::from_fn(|l| ta[l] - tb[l]);
        }
        let mut g = [[0.0; W]; N];
        for j in 0..N {
            for i in j..N {
                let tr = &p[i].t_rho[j];
                for l in 0..W {
                    g[j][l] = madd::<FUSED>(tr[l % LANES], gamma[i][l], g[j][l]);
                }
            }
        }
        for i in 0..N {
            let q = &p[i];
            let fm = q.motor_friction.force::<FUSED, W>(&x[4 * i + 1]);
            let fl = q.link_friction.force::<FUSED, W>(&x[4 * i + 3]);
            dx[4 * i] = x[4 * i + 1];
            dx[4 * i + 2] = x[4 * i + 3];
            let (um, ul) = (u[i], u[N + i]);
            let (rho, inv_m, inv_l) = (&q.rho, &q.inv_motor_inertia, &q.inv_link_inertia);
            dx[4 * i + 1] = std::array::from_fn(|l| {
                let k = l % LANES;
                madd::<FUSED>(-rho[k], gamma[i][l], um - fm[l]) * inv_m[k]
            });
            // no gravity: `Γ − F − 0` is `Γ − F` to the bit, the subtraction is skipped
            let net: [f64; W] = if q.gravity {
                let link = &self.links[i];
                std::array::from_fn(|l| {
                    g[i][l] - fl[l] - link.gravity.load(link.kind, x[4 * i + 2][l])
                })
            } else {
                std::array::from_fn(|l| g[i][l] - fl[l])
            };
            dx[4 * i + 3] = std::array::from_fn(|l| (net[l] + ul) * inv_l[l % LANES]);
        }
    }

    /// [`Self::derivative_lanes_n`] for the model's link count.
    #[inline(always)]
    fn derivative_lanes_by_links<const FUSED: bool, const W: usize>(
        &self,
        x: &[[f64; W]],
        u: &[f64],
        dx: &mut [[f64; W]],
    ) {
        match self.n_links() {
            1 => self.derivative_lanes_n::<1, 4, FUSED, W>(x, u, dx),
            2 => self.derivative_lanes_n::<2, 8, FUSED, W>(x, u, dx),
            _ => self.derivative_lanes_n::<3, 12, FUSED, W>(x, u, dx),
        }
    }

    #[inline(always)]
    fn derivative_n<const N: usize>(&self, x: &[f64], u: &[f64], dx: &mut [f64]) {
        let (_, gamma, big_gamma) = self.forces::<N>(x);
        for i in 0..N {
            let l = &self.links[i];
            let (wm, ql, wl) = (x[4 * i + 1], x[4 * i + 2], x[4 * i + 3]);
            dx[4 * i] = wm;
            dx[4 * i + 1] = (u[i] - l.motor_friction.force(wm) - self.rho[i] * gamma[i])
                * self.inv_motor_inertia[i];
            dx[4 * i + 2] = wl;
            dx[4 * i + 3] = (big_gamma[i] - l.link_friction.force(wl) - l.gravity.load(l.kind, ql)
                + u[N + i])
                * self.inv_link_inertia[i];
        }
    }

    fn output_n<const N: usize>(&self, x: &[f64], y: &mut [f64]) {
        let (tens, _, big_gamma) = self.forces::<N>(x);
        for i in 0..N {
            y[5 * i] = x[4 * i];
            y[5 * i + 1] = x[4 * i + 2];
            y[5 * i + 2] = tens[i].0;
            y[5 * i + 3] = tens[i].1;
            y[5 * i + 4] = big_gamma[i];
        }
    }

    /// Total mechanical energy (J) at `x`: kinetic + cable (both sides taut) + gravity.
    /// Conserved by the exact flow when friction and cable damping are zero and no cable slacks.
    pub fn energy(&self, x: &[f64]) -> f64 {
        by_links!(self, self.n_links(), energy_n(x))
    }

    fn energy_n<const N: usize>(&self, x: &[f64]) -> f64 {
        let (d, _) = self.stretches::<N>(x);
        (0..N)
            .map(|i| {
                let l = &self.links[i];
                0.5 * l.motor_inertia * x[4 * i + 1].powi(2)
                    + 0.5 * l.link_inertia * x[4 * i + 3].powi(2)
                    + l.cable.energy(d[i])
                    + l.gravity.potential(l.kind, x[4 * i + 2])
            })
            .sum()
    }
}

impl Model for CableTransmission {
    fn n_states(&self) -> usize {
        4 * self.n_links()
    }
    fn n_inputs(&self) -> usize {
        2 * self.n_links()
    }
    fn n_outputs(&self) -> usize {
        5 * self.n_links()
    }

    fn derivative(&self, x: &[f64], u: &[f64], dx: &mut [f64]) {
        by_links!(self, self.n_links(), derivative_n(x, u, dx))
    }

    // always inlined, so that the AVX2 build of the sigma-point propagation compiles it for
    // 256-bit lanes (a call would run the SSE2 build)
    #[inline(always)]
    fn derivative_lanes<const W: usize>(&self, x: &[[f64; W]], u: &[f64], dx: &mut [[f64; W]]) {
        self.derivative_lanes_by_links::<false, W>(x, u, dx);
    }

    #[inline(always)]
    fn derivative_lanes_fused<const W: usize>(
        &self,
        x: &[[f64; W]],
        u: &[f64],
        dx: &mut [[f64; W]],
    ) {
        self.derivative_lanes_by_links::<true, W>(x, u, dx);
    }

    fn output(&self, x: &[f64], _u: &[f64], y: &mut [f64]) {
        by_links!(self, self.n_links(), output_n(x, y))
    }

    fn state_names(&self) -> Vec<String> {
        (1..=self.n_links())
            .flat_map(|i| {
                [
                    format!("q_m{i}"),
                    format!("dq_m{i}"),
                    format!("q_l{i}"),
                    format!("dq_l{i}"),
                ]
            })
            .collect()
    }
    fn input_names(&self) -> Vec<String> {
        let n = self.n_links();
        (1..=n)
            .map(|i| format!("tau_m{i}"))
            .chain((1..=n).map(|i| format!("tau_ext{i}")))
            .collect()
    }
    fn output_names(&self) -> Vec<String> {
        (1..=self.n_links())
            .flat_map(|i| {
                [
                    format!("q_m{i}"),
                    format!("q_l{i}"),
                    format!("tension_a{i}"),
                    format!("tension_b{i}"),
                    format!("joint_torque{i}"),
                ]
            })
            .collect()
    }
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // bit-identity of the lane and scalar paths is the claim under test
mod lane_tests {
    use super::*;
    use crate::cable::{CableLaw, CableRun};
    use crate::dynamics::raven2;
    use crate::lanes::WIDE;

    fn lcg(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        move || {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        }
    }

    /// Raven-II with every branch the lane code has: Stribeck friction (lane by lane), gravity,
    /// a linear cable law.
    fn varied() -> CableTransmission {
        let base = raven2(3).unwrap();
        let mut links = base.links.clone();
        links[0].link_friction =
            StaticFriction::stribeck("l0", 0.5, 0.8, 0.01, 2.0, 0.005, 1e-3).unwrap();
        links[1].gravity = Gravity {
            amplitude: 1.3,
            offset: 0.2,
        };
        links[2].cable = CableLoop {
            run: CableRun::new(CableLaw::Linear { stiffness: 9e3 }, 400.0, 11.0, "l2").unwrap(),
        };
        let c: Vec<f64> = (0..9).map(|k| base.coupling[k / 3][k % 3]).collect();
        CableTransmission::new(links, &c).unwrap()
    }

    /// The trait's default `derivative_lanes` (per-lane scalar calls).
    struct Scalar<'a>(&'a CableTransmission);
    impl Model for Scalar<'_> {
        fn n_states(&self) -> usize {
            self.0.n_states()
        }
        fn n_inputs(&self) -> usize {
            self.0.n_inputs()
        }
        fn n_outputs(&self) -> usize {
            self.0.n_outputs()
        }
        fn derivative(&self, x: &[f64], u: &[f64], dx: &mut [f64]) {
            self.0.derivative(x, u, dx)
        }
        fn output(&self, x: &[f64], u: &[f64], y: &mut [f64]) {
            self.0.output(x, u, y)
        }
        fn state_names(&self) -> Vec<String> {
            self.0.state_names()
        }
        fn input_names(&self) -> Vec<String> {
            self.0.input_names()
        }
        fn output_names(&self) -> Vec<String> {
            self.0.output_names()
        }
    }

    /// Per state, the sum of the sizes of the terms of its derivative (forces over inertia):
    /// the scale of the rounding of the accelerations.
    fn term_sizes(model: &CableTransmission, x: &[f64], u: &[f64]) -> Vec<f64> {
        let k = model.n_links();
        let mut y = vec![0.0; 5 * k];
        model.output(x, u, &mut y);
        let side = |i: usize| model.rho[i] * (y[5 * i + 2] + y[5 * i + 3]);
        let mut out = vec![0.0; 4 * k];
        for (i, link) in model.links.iter().enumerate() {
            let (wm, ql, wl) = (x[4 * i + 1], x[4 * i + 2], x[4 * i + 3]);
            out[4 * i] = wm.abs();
            out[4 * i + 1] = (u[i].abs() + link.motor_friction.force(wm).abs() + side(i))
                * model.inv_motor_inertia[i];
            out[4 * i + 2] = wl.abs();
            let cables: f64 = (i..k).map(|j| model.t[j][i].abs() * side(j)).sum();
            out[4 * i + 3] = (cables
                + link.link_friction.force(wl).abs()
                + link.gravity.load(link.kind, ql).abs()
                + u[k + i].abs())
                * model.inv_link_inertia[i];
        }
        out
    }

    /// Lane `l` of a wide group holds lane `lane_of(l)` of a narrow one: the first half in
    /// order, the second reversed.
    fn lane_of(l: usize) -> usize {
        if l < LANES {
            l
        } else {
            WIDE - 1 - l
        }
    }

    #[test]
    fn lane_derivative_is_the_scalar_derivative_bit_for_bit() {
        let models = [
            raven2(1).unwrap(),
            raven2(2).unwrap(),
            raven2(3).unwrap(),
            varied(),
        ];
        let mut rnd = lcg(7);
        let mut worst = 0.0_f64;
        for model in &models {
            let (n, m) = (model.n_states(), model.n_inputs());
            for trial in 0..200 {
                // motor offsets from 1e-6 rad (Taylor branch of expm1) to 40 rad (libm branch,
                // slack sides) mixed across lanes; velocities through the friction smoothing
                let mut x = vec![[0.0; LANES]; n];
                let mut q_m = [0.0; MAX_LINKS];
                for l in 0..LANES {
                    let q_l: Vec<f64> = (0..n / 4).map(|_| rnd()).collect();
                    model.joint_to_motor(&q_l, &mut q_m[..n / 4]);
                    let scale = [1e-6, 1e-3, 0.5, 40.0][(trial + l) % 4];
                    for i in 0..n / 4 {
                        x[4 * i][l] = q_m[i] + scale * rnd();
                        x[4 * i + 1][l] = 10.0 * rnd() * rnd().abs().powi(3);
                        x[4 * i + 2][l] = q_l[i];
                        x[4 * i + 3][l] = 0.01 * rnd();
                    }
                }
                let u: Vec<f64> = (0..m).map(|_| rnd()).collect();
                let mut lanes = vec![[f64::NAN; LANES]; n];
                model.derivative_lanes(&x, &u, &mut lanes);
                let mut by_default = vec![[f64::NAN; LANES]; n];
                Scalar(model).derivative_lanes(&x, &u, &mut by_default);
                let mut fused = vec![[f64::NAN; LANES]; n];
                model.derivative_lanes_fused(&x, &u, &mut fused);
                // two lane groups side by side (the second reversed): every lane as alone
                let x2: Vec<[f64; WIDE]> = x
                    .iter()
                    .map(|v| std::array::from_fn(|l| v[lane_of(l)]))
                    .collect();
                let (mut wide, mut wide_fused) = (vec![[f64::NAN; WIDE]; n], vec![[0.0; WIDE]; n]);
                model.derivative_lanes(&x2, &u, &mut wide);
                model.derivative_lanes_fused(&x2, &u, &mut wide_fused);
                for s in 0..n {
                    for l in 0..WIDE {
                        assert_eq!(wide[s][l].to_bits(), lanes[s][lane_of(l)].to_bits());
                        assert_eq!(wide_fused[s][l].to_bits(), fused[s][lane_of(l)].to_bits());
                    }
                }
                for l in 0..LANES {
                    let xl: Vec<f64> = x.iter().map(|v| v[l]).collect();
                    let mut want = vec![0.0; n];
                    model.derivative(&xl, &u, &mut want);
                    let terms = term_sizes(model, &xl, &u);
                    for s in 0..n {
                        assert_eq!(
                            lanes[s][l].to_bits(),
                            want[s].to_bits(),
                            "state {s} lane {l}"
                        );
                        assert_eq!(by_default[s][l].to_bits(), want[s].to_bits());
                        // fused: one rounding less per multiply-add; the accelerations are
                        // differences of forces as large as the pretension (and slack
                        // sides), so the gap is measured on the scale of the largest term
                        let scale = want[s].abs().max(terms[s]);
                        let gap = (fused[s][l] - want[s]).abs();
                        worst = worst.max(gap / scale);
                    }
                }
            }
        }
        // the stretch `ρ·(q_m − T·q_l)` cancels motor angles of up to ~120 rad; the fused
        // products round it differently, and the cable stiffness carries that into the
        // forces: measured 1.7e-13 of the terms (the plain build is exact, above)
        assert!(
            worst < 1e-12,
            "fused lane derivative off by {worst:e} of its terms"
        );
        assert!(worst > 0.0, "the fused build fused nothing");
    }
}
