//! [`Robot`]: the geometry, cables and platform of a cable-driven parallel robot, validated.

use crate::error::{check, CableError, Result};

/// Most cables a robot may have (the per-pose work buffers are fixed-size arrays).
pub const MAX_CABLES: usize = 16;

/// Planar (3-DOF: `x`, `y`, `θ` about `z`) or spatial (6-DOF) platform motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Motion {
    /// Motion in the `x`–`y` plane: pose `[x, y, θ]`, wrench `[F_x, F_y, M_z]`.
    Planar,
    /// Spatial motion: pose `[x, y, z, roll, pitch, yaw]`, wrench `[F; M]`.
    Spatial,
}

impl Motion {
    /// Degrees of freedom `n` (3 or 6): the length of a pose and of a wrench.
    pub fn dof(self) -> usize {
        match self {
            Self::Planar => 3,
            Self::Spatial => 6,
        }
    }

    /// From its name (`"planar"`, `"spatial"`).
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "planar" => Ok(Self::Planar),
            "spatial" => Ok(Self::Spatial),
            other => Err(CableError::InvalidOption {
                name: "motion".into(),
                value: other.into(),
                allowed: "planar, spatial".into(),
            }),
        }
    }

    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Planar => "planar",
            Self::Spatial => "spatial",
        }
    }
}

/// One cable: where it leaves the frame, where it attaches to the platform, its limits and its
/// elasticity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cable {
    /// Frame anchor `a_i` (m, world frame; `z` ignored by a planar robot): the point the cable
    /// leaves the frame (or, with a pulley, the point where it enters the pulley).
    pub anchor: [f64; 3],
    /// Platform attachment `b_i` (m, platform frame).
    pub attachment: [f64; 3],
    /// Least tension `f_min` (N, ≥ 0: a cable only pulls; above 0 keeps it taut).
    pub f_min: f64,
    /// Greatest tension `f_max` (N, > `f_min`: winch torque or breaking load).
    pub f_max: f64,
    /// Axial stiffness `E·A` (N): elongation `Δl = l·f/(E·A)` (seed 002 eq. 15).
    pub ea: f64,
    /// Guiding pulley at the anchor, if the cable runs over one.
    pub pulley: Option<Pulley>,
}

/// A guiding pulley that swivels about `axis` through the anchor point; the cable wraps it
/// and leaves tangentially towards the platform.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pulley {
    /// Radius (m, > 0).
    pub radius: f64,
    /// Swivel axis (unit vector, world frame): the direction the cable arrives from the winch
    /// along.
    pub axis: [f64; 3],
}

/// The moving platform.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Platform {
    /// Mass (kg, ≥ 0).
    pub mass: f64,
    /// Centre of mass (m, platform frame).
    pub com: [f64; 3],
    /// Inertia about the centre of mass (kg·m², platform frame), row-major 3 × 3.
    pub inertia: [f64; 9],
}

/// A cable-driven parallel robot: motion type, cables, platform and gravity.
#[derive(Debug, Clone, PartialEq)]
pub struct Robot {
    /// Name (for reports).
    pub name: String,
    /// Planar or spatial.
    pub motion: Motion,
    /// The cables, `m` of them (`n ≤ m ≤` [`MAX_CABLES`]).
    pub cables: Vec<Cable>,
    /// The platform.
    pub platform: Platform,
    /// Gravity (m/s², world frame; a planar robot uses `x`, `y`).
    pub gravity: [f64; 3],
}

fn point(name: &str, p: &[f64; 3]) -> Result<()> {
    check::all_finite(name, p, 1)
}

impl Robot {
    /// A validated robot: at least `n` cables (one more for full constraint is usual, not
    /// required), finite points, `0 ≤ f_min < f_max`, `E·A > 0`, unit pulley axes, distinct
    /// anchors, non-negative mass, symmetric positive semi-definite inertia.
    pub fn new(
        name: &str,
        motion: Motion,
        cables: Vec<Cable>,
        platform: Platform,
        gravity: [f64; 3],
    ) -> Result<Self> {
        let (n, m) = (motion.dof(), cables.len());
        if m < n || m > MAX_CABLES {
            return Err(CableError::Shape {
                what: "cables".into(),
                expected: format!("{n} to {MAX_CABLES} cables for a {} robot", motion.name()),
                got: format!("{m}"),
            });
        }
        for (i, c) in cables.iter().enumerate() {
            let at = |f: &str| format!("cables[{i}].{f}");
            point(&at("anchor"), &c.anchor)?;
            point(&at("attachment"), &c.attachment)?;
            check::non_negative(&at("f_min"), c.f_min)?;
            check::positive(&at("f_max"), c.f_max)?;
            if c.f_max <= c.f_min {
                return Err(CableError::InvalidParameter {
                    name: at("f_max"),
                    value: c.f_max,
                    requirement: "greater than f_min",
                });
            }
            check::positive(&at("ea"), c.ea)?;
            if let Some(p) = c.pulley {
                check::positive(&at("pulley.radius"), p.radius)?;
                point(&at("pulley.axis"), &p.axis)?;
                let norm = p.axis.iter().map(|v| v * v).sum::<f64>().sqrt();
                if (norm - 1.0).abs() > 1e-9 {
                    return Err(CableError::InvalidParameter {
                        name: at("pulley.axis"),
                        value: norm,
                        requirement: "a unit vector (norm 1)",
                    });
                }
            }
            for (j, d) in cables[..i].iter().enumerate() {
                let apart = |a: &[f64; 3], b: &[f64; 3]| {
                    a.iter().zip(b).any(|(x, y)| (x - y).abs() > 1e-12)
                };
                if !apart(&d.anchor, &c.anchor) && !apart(&d.attachment, &c.attachment) {
                    return Err(CableError::InvalidOption {
                        name: at("anchor"),
                        value: format!("{:?}", c.anchor),
                        allowed: format!(
                            "a cable other than cables[{j}] (same anchor and attachment)"
                        ),
                    });
                }
            }
        }
        check::non_negative("platform.mass", platform.mass)?;
        point("platform.com", &platform.com)?;
        check::all_finite("platform.inertia", &platform.inertia, 3)?;
        let j = platform.inertia;
        for (r, c) in [(0, 1), (0, 2), (1, 2)] {
            if (j[3 * r + c] - j[3 * c + r]).abs()
                > 1e-12 * (1.0 + j[0].abs() + j[4].abs() + j[8].abs())
            {
                return Err(CableError::InvalidParameter {
                    name: format!("platform.inertia[{r}][{c}]"),
                    value: j[3 * r + c],
                    requirement: "symmetric (equal to its transpose)",
                });
            }
        }
        for d in 0..3 {
            check::non_negative(&format!("platform.inertia[{d}][{d}]"), j[4 * d])?;
        }
        check::all_finite("gravity", &gravity, 1)?;
        // the weight and its moment about the platform origin must be numbers (a mass of 1e308
        // kg passes every check above and overflows here)
        let weight = gravity
            .iter()
            .map(|g| (g * platform.mass).abs())
            .fold(0.0, f64::max);
        let arm: f64 = platform.com.iter().map(|c| c.abs()).sum();
        if !weight.is_finite() || !(weight * arm).is_finite() {
            return Err(CableError::InvalidParameter {
                name: "platform.mass".into(),
                value: platform.mass,
                requirement: "a weight m·g (and its moment about the platform origin) within the \
                              floating-point range",
            });
        }
        Ok(Self {
            name: name.into(),
            motion,
            cables,
            platform,
            gravity,
        })
    }

    /// A robot from per-cable columns, as front ends and files give them: `anchors` and
    /// `attachments` `(m, 3)` row-major, `f_min`, `f_max`, `ea` `(m,)`, and the pulleys as
    /// `(cable, radius, axis)`.
    #[allow(clippy::too_many_arguments)]
    pub fn from_columns(
        name: &str,
        motion: Motion,
        anchors: &[f64],
        attachments: &[f64],
        (f_min, f_max, ea): (&[f64], &[f64], &[f64]),
        pulleys: &[(usize, f64, [f64; 3])],
        platform: Platform,
        gravity: [f64; 3],
    ) -> Result<Self> {
        let m = f_min.len();
        check::len("anchors", anchors, 3 * m)?;
        check::len("attachments", attachments, 3 * m)?;
        check::len("f_max", f_max, m)?;
        check::len("ea", ea, m)?;
        let xyz = |v: &[f64], i: usize| [v[3 * i], v[3 * i + 1], v[3 * i + 2]];
        let mut cables: Vec<Cable> = (0..m)
            .map(|i| Cable {
                anchor: xyz(anchors, i),
                attachment: xyz(attachments, i),
                f_min: f_min[i],
                f_max: f_max[i],
                ea: ea[i],
                pulley: None,
            })
            .collect();
        for &(i, radius, axis) in pulleys {
            let cable = cables.get_mut(i).ok_or_else(|| CableError::InvalidOption {
                name: "pulleys".into(),
                value: format!("cable {i}"),
                allowed: format!("cables 0 to {}", m.saturating_sub(1)),
            })?;
            cable.pulley = Some(Pulley { radius, axis });
        }
        Self::new(name, motion, cables, platform, gravity)
    }

    /// Cables `m`.
    pub fn n_cables(&self) -> usize {
        self.cables.len()
    }

    /// Degrees of freedom `n`.
    pub fn dof(&self) -> usize {
        self.motion.dof()
    }

    /// The platform's weight as the external wrench `w` it exerts at pose rotation `r`
    /// (row-major 3 × 3): force `m·g`, moment `(R·c) × m·g` about the platform origin.
    pub fn gravity_wrench(&self, r: &[f64; 9], out: &mut [f64]) {
        let mg = self.gravity.map(|g| g * self.platform.mass);
        let c = self.platform.com;
        let rc = [
            r[0] * c[0] + r[1] * c[1] + r[2] * c[2],
            r[3] * c[0] + r[4] * c[1] + r[5] * c[2],
            r[6] * c[0] + r[7] * c[1] + r[8] * c[2],
        ];
        let mom = cross(&rc, &mg);
        match self.motion {
            Motion::Planar => out[..3].copy_from_slice(&[mg[0], mg[1], mom[2]]),
            Motion::Spatial => {
                out[..3].copy_from_slice(&mg);
                out[3..6].copy_from_slice(&mom);
            }
        }
    }
}

/// `a × b`.
pub(crate) fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
