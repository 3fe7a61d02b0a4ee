//! `cablekit._cablekit`: thin PyO3 bindings of cable-core.
//!
//! Each file mirrors a core module and only converts, releases the GIL, calls the core and
//! converts back. No algorithm lives here.

mod cdpr;
mod convert;
mod dynamics;
mod errors;
mod estimate;
mod forceps;
mod friction;
mod identify;
mod integrate;
mod nn;
mod plant;
mod results;
mod sensors;
mod winch;

use pyo3::prelude::*;

/// The compiled extension module; import `cablekit` instead.
#[pymodule]
fn _cablekit(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<dynamics::Model>()?;
    m.add_class::<dynamics::CableTransmission>()?;
    m.add_class::<dynamics::AntagonisticJoint>()?;
    m.add_class::<dynamics::DahlElement>()?;
    m.add_class::<winch::WinchDrive>()?;
    m.add_class::<plant::CdprPlant>()?;
    m.add_class::<plant::PulleyFriction>()?;
    m.add_class::<plant::LoopRun>()?;
    m.add_class::<sensors::LoadCellPulley>()?;
    m.add_class::<sensors::Calibration>()?;
    m.add_class::<sensors::CalibrationFit>()?;
    m.add_class::<sensors::SignalChain>()?;
    m.add_function(wrap_pyfunction!(integrate::simulate_arrays, m)?)?;
    m.add_function(wrap_pyfunction!(integrate::simulate_servo_arrays, m)?)?;
    m.add_function(wrap_pyfunction!(integrate::propose_step_raw, m)?)?;
    m.add_function(wrap_pyfunction!(friction::coulomb_friction, m)?)?;
    m.add_function(wrap_pyfunction!(friction::stribeck_friction, m)?)?;
    m.add_function(wrap_pyfunction!(friction::capstan_ratio, m)?)?;
    m.add_function(wrap_pyfunction!(friction::dahl_rate, m)?)?;
    m.add_function(wrap_pyfunction!(friction::cable_tension, m)?)?;
    m.add_class::<identify::JointProblem>()?;
    m.add_class::<identify::JointRun>()?;
    m.add_class::<estimate::SrUkf>()?;
    m.add_class::<estimate::DualSrUkf>()?;
    m.add_class::<results::FilterRun>()?;
    m.add_class::<results::DualRun>()?;
    m.add_class::<results::FilterHealth>()?;
    m.add_class::<results::FitReport>()?;
    m.add_class::<results::ParamSpec>()?;
    m.add_function(wrap_pyfunction!(identify::effect_catalogue, m)?)?;
    m.add_class::<nn::Mlp>()?;
    m.add_class::<cdpr::Robot>()?;
    m.add_class::<results::Kinematics>()?;
    m.add_class::<results::Tensions>()?;
    m.add_class::<results::Capacity>()?;
    m.add_class::<results::PathRun>()?;
    m.add_class::<results::Step>()?;
    m.add_class::<cdpr::TensionController>()?;
    m.add_class::<forceps::Jtdo>()?;
    m.add_class::<forceps::ClampStep>()?;
    m.add_class::<forceps::ClampRun>()?;
    m.add_class::<winch::Winch>()?;
    m.add_class::<forceps::Twin>()?;
    m.add_class::<forceps::TwinRun>()?;
    m.add_class::<forceps::PhysicsObserver>()?;
    m.add_class::<forceps::PhysicsCalibration>()?;
    m.add_class::<forceps::DriveModel>()?;
    m.add_class::<forceps::JawEstimate>()?;
    m.add_class::<forceps::JawObserver>()?;
    m.add_class::<forceps::JawSample>()?;
    Ok(())
}
