//! Core errors to Python exceptions. The exception classes live in `rustcloth/errors.py`,
//! where each subclasses both `RustclothError` and the built-in a user would catch.

use pyo3::prelude::*;
use pyo3::{import_exception, PyErr};

use crate::Error;

import_exception!(rustcloth.errors, ParameterError);
import_exception!(rustcloth.errors, ParameterTypeError);
import_exception!(rustcloth.errors, ParticleIndexError);
import_exception!(rustcloth.errors, SimulationDiverged);
import_exception!(rustcloth.errors, InternalError);

pub fn to_py(err: Error) -> PyErr {
    let message = err.to_string();
    match err {
        Error::InvalidValue { name, .. } => ParameterError::new_err((message, name)),
        Error::InvalidType { name, .. } => ParameterTypeError::new_err((message, name)),
        Error::IndexOutOfRange { name, index, .. } => {
            ParticleIndexError::new_err((message, name, index))
        }
        Error::Diverged {
            step,
            particle,
            reason,
            substeps,
        } => SimulationDiverged::new_err((message, step, particle, reason.name(), substeps)),
        Error::Internal { .. } => InternalError::new_err(message),
        // The binding raises the interrupt it caught itself; this is the fallback.
        Error::Interrupted { .. } => pyo3::exceptions::PyKeyboardInterrupt::new_err(message),
    }
}

/// `ValueError` naming the parameter, for checks made in the binding itself.
pub fn value_error(name: &str, message: String) -> PyErr {
    to_py(Error::InvalidValue {
        name: name.into(),
        message,
    })
}

/// `TypeError` naming the parameter, for checks made in the binding itself.
pub fn type_error(name: &str, message: String) -> PyErr {
    to_py(Error::InvalidType {
        name: name.into(),
        message,
    })
}

pub trait IntoPyResult<T> {
    fn py(self) -> PyResult<T>;
}

impl<T> IntoPyResult<T> for crate::Result<T> {
    fn py(self) -> PyResult<T> {
        self.map_err(to_py)
    }
}
