//! Many poses at once (rayon, one work buffer per thread): inverse kinematics and tension
//! distribution along a trajectory or over a grid. Errors name the pose row.

use rayon::prelude::*;

use super::kinematics::{inverse_kinematics, CableGeometry, Pose};
use super::qp::Distributor;
use super::robot::Robot;
use super::tension::Method;
use super::workspace::{capacity, Requirement};
use crate::error::{check, CableError, Result};

/// Poses below this count run on the calling thread (thread start-up costs more).
pub const PARALLEL_MIN_POSES: usize = 256;

/// Outputs of [`inverse_kinematics_batch`], row-major: `length` `(T, m)`, `structure` `(T, n, m)`.
#[derive(Debug)]
pub struct KinematicsMut<'a> {
    /// Cable lengths (m).
    pub length: &'a mut [f64],
    /// Structure matrices `Aᵀ`.
    pub structure: &'a mut [f64],
}

/// Outputs of [`distribute_batch`]: `f` `(T, m)`, and per pose the method that answered,
/// whether the tensions are feasible, and the residual wrench norm.
#[derive(Debug)]
pub struct TensionsMut<'a> {
    /// Tensions (N).
    pub f: &'a mut [f64],
    /// The method that answered.
    pub method: &'a mut [Method],
    /// Feasible (equilibrium and bounds).
    pub feasible: &'a mut [bool],
    /// `‖Aᵀ·f + w‖₂`.
    pub residual: &'a mut [f64],
}

/// `err` with the pose row in what it names.
pub(super) fn at_row(err: CableError, row: usize) -> CableError {
    match err {
        CableError::InvalidParameter {
            name,
            value,
            requirement,
        } => CableError::InvalidParameter {
            name: format!("poses[{row}]: {name}"),
            value,
            requirement,
        },
        CableError::NotFinite {
            what,
            index,
            value,
            location,
        } => CableError::NotFinite {
            what: format!("poses[{row}]: {what}"),
            index,
            value,
            location,
        },
        CableError::NonFiniteResult {
            what,
            index,
            value,
            location,
            hint,
        } => CableError::NonFiniteResult {
            what: format!("poses[{row}]: {what}"),
            index,
            value,
            location,
            hint,
        },
        other => other,
    }
}

fn rows(robot: &Robot, poses: &[f64]) -> Result<usize> {
    let n = robot.dof();
    if poses.is_empty() || !poses.len().is_multiple_of(n) {
        return Err(CableError::Shape {
            what: "poses".into(),
            expected: format!("(T, {n}) with T >= 1"),
            got: format!("{} values", poses.len()),
        });
    }
    check::all_finite("poses", poses, n)?;
    Ok(poses.len() / n)
}

fn buffer(what: &str, got: usize, want: usize) -> Result<()> {
    if got == want {
        Ok(())
    } else {
        Err(CableError::Shape {
            what: what.into(),
            expected: format!("{want} values"),
            got: format!("{got}"),
        })
    }
}

/// Inverse kinematics of the poses `(T, n)` (row-major) into `out`.
pub fn inverse_kinematics_batch(
    robot: &Robot,
    poses: &[f64],
    out: KinematicsMut<'_>,
) -> Result<()> {
    let (n, m) = (robot.dof(), robot.n_cables());
    let t = rows(robot, poses)?;
    buffer("length buffer", out.length.len(), t * m)?;
    buffer("structure buffer", out.structure.len(), t * n * m)?;
    let one = |(row, (len, st)): (usize, (&mut [f64], &mut [f64]))| -> Result<()> {
        let mut g = CableGeometry::default();
        let pose = Pose::from_coordinates(robot.motion, &poses[row * n..(row + 1) * n])?;
        inverse_kinematics(robot, &pose, &mut g).map_err(|e| at_row(e, row))?;
        len.copy_from_slice(&g.length[..m]);
        st.copy_from_slice(g.structure());
        Ok(())
    };
    if t < PARALLEL_MIN_POSES {
        out.length
            .chunks_mut(m)
            .zip(out.structure.chunks_mut(n * m))
            .enumerate()
            .try_for_each(one)
    } else {
        out.length
            .par_chunks_mut(m)
            .zip(out.structure.par_chunks_mut(n * m))
            .enumerate()
            .try_for_each(one)
    }
}

/// Tensions at the poses `(T, n)` holding the platform's weight plus the external wrenches
/// `(T, n)` (`None`: weight only; `gravity = false`: the external wrenches only), by `method`
/// with the robot's bounds. A pose no tensions can hold is reported (`feasible = false`),
/// not an error; a degenerate pose is an error naming its row.
pub fn distribute_batch(
    robot: &Robot,
    poses: &[f64],
    external: Option<&[f64]>,
    gravity: bool,
    method: Method,
    out: TensionsMut<'_>,
) -> Result<()> {
    let (n, m) = (robot.dof(), robot.n_cables());
    let t = rows(robot, poses)?;
    if let Some(e) = external {
        buffer("wrenches", e.len(), t * n)?;
        check::all_finite("wrenches", e, n)?;
    }
    buffer("tension buffer", out.f.len(), t * m)?;
    for (what, len) in [
        ("method buffer", out.method.len()),
        ("feasible buffer", out.feasible.len()),
        ("residual buffer", out.residual.len()),
    ] {
        buffer(what, len, t)?;
    }
    let f_min: Vec<f64> = robot.cables.iter().map(|c| c.f_min).collect();
    let f_max: Vec<f64> = robot.cables.iter().map(|c| c.f_max).collect();
    let init = || Distributor::new(n, m, None).map(|d| (d, CableGeometry::default()));
    type Row<'b> = (
        usize,
        (((&'b mut [f64], &'b mut Method), &'b mut bool), &'b mut f64),
    );
    let one = |state: &mut Result<(Distributor, CableGeometry)>,
               (row, (((f, me), fe), re)): Row<'_>|
     -> Result<()> {
        let (dist, geo) = state.as_mut().map_err(|e| e.clone())?;
        let pose = Pose::from_coordinates(robot.motion, &poses[row * n..(row + 1) * n])?;
        inverse_kinematics(robot, &pose, geo).map_err(|e| at_row(e, row))?;
        let mut w = [0.0; 6];
        if gravity {
            robot.gravity_wrench(&pose.rotation, &mut w);
        }
        if let Some(e) = external {
            for (a, v) in w.iter_mut().zip(&e[row * n..(row + 1) * n]) {
                *a += v;
            }
        }
        let d = dist
            .distribute(geo.structure(), &w[..n], &f_min, &f_max, method)
            .map_err(|e| at_row(e, row))?;
        f.copy_from_slice(d.tensions());
        (*me, *fe, *re) = (d.method, d.feasible, d.residual);
        Ok(())
    };
    if t < PARALLEL_MIN_POSES {
        let mut state = init();
        out.f
            .chunks_mut(m)
            .zip(out.method.iter_mut())
            .zip(out.feasible.iter_mut())
            .zip(out.residual.iter_mut())
            .enumerate()
            .try_for_each(|r| one(&mut state, r))
    } else {
        out.f
            .par_chunks_mut(m)
            .zip(out.method.par_iter_mut())
            .zip(out.feasible.par_iter_mut())
            .zip(out.residual.par_iter_mut())
            .enumerate()
            .try_for_each_init(init, one)
    }
}

/// Outputs of [`capacity_batch`], one entry per pose.
#[derive(Debug)]
pub struct CapacityMut<'a> {
    /// Capacity margin.
    pub margin: &'a mut [f64],
    /// Inside the workspace.
    pub feasible: &'a mut [bool],
    /// Rank-deficient structure matrix.
    pub degenerate: &'a mut [bool],
    /// The weakest external wrench direction `(T, n)` (see [`super::Capacity::weakest`]).
    pub weakest: &'a mut [f64],
}

/// Capacity margins at the poses `(T, n)` (row-major) for the requirement: a grid of poses
/// gives the static (`Requirement::default()`) or wrench-feasible workspace.
pub fn capacity_batch(
    robot: &Robot,
    poses: &[f64],
    req: &Requirement,
    out: CapacityMut<'_>,
) -> Result<()> {
    let n = robot.dof();
    let t = rows(robot, poses)?;
    req.validate(n)?;
    for (what, len) in [
        ("margin buffer", out.margin.len()),
        ("feasible buffer", out.feasible.len()),
        ("degenerate buffer", out.degenerate.len()),
    ] {
        buffer(what, len, t)?;
    }
    buffer("weakest buffer", out.weakest.len(), t * n)?;
    type Row<'b> = (
        usize,
        (((&'b mut f64, &'b mut bool), &'b mut bool), &'b mut [f64]),
    );
    // per thread: the geometry's buffers and the last rotation (grids repeat orientations)
    type Work = (CableGeometry, Option<([u64; 3], [f64; 9])>);
    let one = |(geo, last): &mut Work, (row, (((s, fe), de), wk)): Row<'_>| -> Result<()> {
        let q = &poses[row * n..(row + 1) * n];
        let pose = Pose::from_coordinates_cached(robot.motion, q, last)?;
        let c = capacity(robot, &pose, req, geo).map_err(|e| at_row(e, row))?;
        (*s, *fe, *de) = (c.margin, c.feasible, c.degenerate);
        wk.copy_from_slice(&c.weakest[..n]);
        Ok(())
    };
    if t < PARALLEL_MIN_POSES {
        let mut work = Work::default();
        out.margin
            .iter_mut()
            .zip(out.feasible.iter_mut())
            .zip(out.degenerate.iter_mut())
            .zip(out.weakest.chunks_mut(n))
            .enumerate()
            .try_for_each(|r| one(&mut work, r))
    } else {
        out.margin
            .par_iter_mut()
            .zip(out.feasible.par_iter_mut())
            .zip(out.degenerate.par_iter_mut())
            .zip(out.weakest.par_chunks_mut(n))
            .enumerate()
            .with_min_len(64)
            .try_for_each_init(Work::default, one)
    }
}
