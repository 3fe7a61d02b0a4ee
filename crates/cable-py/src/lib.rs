//! `cablekit._cablekit`: thin PyO3 bindings of cable-core.
//!
//! Each file mirrors a core module and only converts, releases the GIL, calls the core and
//! converts back. No algorithm lives here.

mod callback;
mod cdpr;
mod convert;
mod dynamics;
mod errors;
mod estimate;
mod forceps;
mod friction;
mod identify;
mod integrate;
mod network;
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
    dynamics::register(m)?;
    winch::register(m)?;
    plant::register(m)?;
    sensors::register(m)?;
    integrate::register(m)?;
    friction::register(m)?;
    identify::register(m)?;
    estimate::register(m)?;
    results::register(m)?;
    nn::register(m)?;
    cdpr::register(m)?;
    forceps::register(m)?;
    Ok(())
}
