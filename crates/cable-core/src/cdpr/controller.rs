//! The per-call API for a control loop: one pose and wrench in, tensions out, with the solver
//! kept warm between calls and no allocation per call once the QP has been built.

use super::kinematics::{inverse_kinematics, CableGeometry, Pose};
use super::qp::Distributor;
use super::robot::{Robot, MAX_CABLES};
use super::tension::{Distribution, Method};
use crate::error::{check, Result};

/// Tension distribution for one robot at the rate of its controller.
#[derive(Debug)]
pub struct Controller {
    robot: Robot,
    method: Method,
    gravity: bool,
    distributor: Distributor,
    geometry: CableGeometry,
    f_min: [f64; MAX_CABLES],
    f_max: [f64; MAX_CABLES],
    /// The previous call's tensions, for the jump.
    last: Option<[f64; MAX_CABLES]>,
}

/// One controller step: the distribution and the largest tension change since the last step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// The distribution (tensions, method, feasibility, residual).
    pub distribution: Distribution,
    /// `max |f − f_prev|` (N); 0 at the first step.
    pub jump: f64,
}

impl Controller {
    /// A controller for `robot` by `method`, adding the platform's weight when `gravity`.
    pub fn new(robot: &Robot, method: Method, gravity: bool) -> Result<Self> {
        let (n, m) = (robot.dof(), robot.n_cables());
        let mut f_min = [0.0; MAX_CABLES];
        let mut f_max = [0.0; MAX_CABLES];
        for (i, c) in robot.cables.iter().enumerate() {
            (f_min[i], f_max[i]) = (c.f_min, c.f_max);
        }
        Ok(Self {
            robot: robot.clone(),
            method,
            gravity,
            distributor: Distributor::new(n, m, None)?,
            geometry: CableGeometry::default(),
            f_min,
            f_max,
            last: None,
        })
    }

    /// The robot.
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    /// The method.
    pub fn method(&self) -> Method {
        self.method
    }

    /// Forget the warm solver, its face and the last tensions.
    pub fn reset(&mut self) {
        self.distributor.reset();
        self.last = None;
    }

    /// Tensions at `pose` (`n` coordinates) against the weight (if enabled) plus `wrench`
    /// (`n` values; `None`: none). The geometry of the step is kept ([`Self::geometry`]).
    pub fn step(&mut self, pose: &[f64], wrench: Option<&[f64]>) -> Result<Step> {
        let (n, m) = (self.robot.dof(), self.robot.n_cables());
        let p = Pose::from_coordinates(self.robot.motion, pose)?;
        let mut w = [0.0; 6];
        if let Some(e) = wrench {
            check::len("wrench", e, n)?;
            check::all_finite("wrench", e, n)?;
            w[..n].copy_from_slice(e);
        }
        inverse_kinematics(&self.robot, &p, &mut self.geometry)?;
        if self.gravity {
            let mut g = [0.0; 6];
            self.robot.gravity_wrench(&p.rotation, &mut g);
            w.iter_mut().zip(g).for_each(|(a, b)| *a += b);
        }
        let d = self.distributor.distribute(
            self.geometry.structure(),
            &w[..n],
            &self.f_min[..m],
            &self.f_max[..m],
            self.method,
        )?;
        let jump = self.last.map_or(0.0, |last| {
            last[..m]
                .iter()
                .zip(d.tensions())
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max)
        });
        self.last = Some(d.f);
        Ok(Step {
            distribution: d,
            jump,
        })
    }

    /// The cable geometry of the last step.
    pub fn geometry(&self) -> &CableGeometry {
        &self.geometry
    }
}
