//! A [`Snapshot`] as a Python dict of numpy arrays and plain values, and back: what
//! `Simulation.get_state()` returns, `set_state` takes and pickling sends. Every value survives
//! the trip bit for bit (float32 arrays as float32, f64 as Python floats); every key is checked
//! on the way back, and an error names it (`state.positions`, `state.watchdog.hold`, ...).
//!
//! The plain values go through serde (pythonize); the scene and the per-particle arrays, which
//! serde leaves out, are added and read here. The strict checks that name a bad key (dtypes,
//! shapes, lengths, bools) are `rustcloth._args`'s, as the method arguments' are.

use glam::Vec3;
use numpy::{PyArray1, PyReadonlyArrayDyn};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use pythonize::{pythonize, Depythonizer};
use serde::Deserialize;

use super::conv::{args, scene_to_dict, unvalidated_scene_from_dict, Rows};
use super::errors::{type_error, value_error, IntoPyResult};
use crate::snapshot::Snapshot;
use crate::soa::Vec3s;
use crate::Simulation;

/// The layout of the dict; a state of another layout is refused rather than guessed at.
const VERSION: u64 = 3;

pub fn to_dict<'py>(py: Python<'py>, s: &Snapshot) -> PyResult<Bound<'py, PyDict>> {
    let d = pythonize(py, s)?.cast_into::<PyDict>()?;
    d.set_item("version", VERSION)?;
    d.set_item("scene", scene_to_dict(py, &s.scene)?)?;
    d.set_item("positions", Rows::vec3s(&s.positions))?;
    d.set_item("velocities", Rows::vec3s(&s.velocities))?;
    d.set_item("masses", PyArray1::from_slice(py, &s.masses))?;
    d.set_item("pinned", PyArray1::from_slice(py, &s.pinned))?;
    d.set_item("alive", PyArray1::from_slice(py, &s.alive))?;
    let springs = s.springs.iter().map(|f| PyArray1::from_slice(py, f));
    d.set_item("springs", PyList::new(py, springs)?)?;
    d.set_item("mesh_springs", PyArray1::from_slice(py, &s.mesh_springs))?;
    let previous = match &s.watchdog.previous {
        Some((pos, vel, history)) => {
            Some((Rows::vec3s(pos), Rows::vec3s(vel), pythonize(py, history)?))
        }
        None => None,
    };
    d.get_item("watchdog")?
        .expect("serialised with the snapshot")
        .set_item("previous", previous)?;
    Ok(d)
}

/// `T` from a Python value, errors named `name` and the path below it (`state.targets[0]`).
fn deserialize<'de, T>(obj: &'de Bound<'_, PyAny>, name: &str) -> PyResult<T>
where
    T: Deserialize<'de> + serde::Serialize,
{
    let value =
        serde_path_to_error::deserialize(&mut Depythonizer::from_object(obj)).map_err(|e| {
            let name = match e.path().to_string().as_str() {
                "." => name.to_string(),
                path => format!("{name}.{path}").replace(".[", "["),
            };
            let err = PyErr::from(e.into_inner());
            let message = err.value(obj.py()).to_string();
            match err.is_instance_of::<PyTypeError>(obj.py()) {
                true => type_error(&name, message),
                false => value_error(&name, message),
            }
        })?;
    let read = pythonize(obj.py(), &value)?;
    args(obj.py())?.call_method1("state_bools", (obj, read, name))?;
    Ok(value)
}

/// Item `key` of a mapping, named `name` when missing.
fn item<'py>(obj: &Bound<'py, PyAny>, key: &str, name: &str) -> PyResult<Bound<'py, PyAny>> {
    obj.get_item(key)
        .map_err(|_| value_error(name, "is missing".into()))
}

/// Exactly `len` items of a sequence, named `name`, as `rustcloth._args.state_items` checks
/// them.
fn items<'py>(obj: &Bound<'py, PyAny>, name: &str, len: usize) -> PyResult<Vec<Bound<'py, PyAny>>> {
    args(obj.py())?
        .call_method1("state_items", (obj, name, len))?
        .extract()
}

/// The values, row-major, of exactly a `dtype` array of `shape` (`(n,)` or `(n, 3)`), as
/// `rustcloth._args.state_array` checks it.
fn array<T: numpy::Element + Copy>(
    obj: &Bound<'_, PyAny>,
    (name, dtype): (&str, &str),
    shape: &[usize],
) -> PyResult<Vec<T>> {
    let array = args(obj.py())?.call_method1("state_array", (obj, name, dtype, shape.to_vec()))?;
    let array = array.extract::<PyReadonlyArrayDyn<'_, T>>()?;
    Ok(array.as_array().iter().copied().collect())
}

/// Exactly a float32 `(n, 3)` array, as [`array`].
fn state_vectors(obj: &Bound<'_, PyAny>, name: &str, n: usize) -> PyResult<Vec3s> {
    let values = array::<f32>(obj, (name, "float32"), &[n, 3])?;
    Ok(Vec3s::from_fn(n, |p| Vec3::from_slice(&values[3 * p..])))
}

/// The simulation a state continues. The Python side has checked that `obj` is a dict and its
/// version an integer. The scene is validated once, as the simulation is built from it, and
/// the arrays are checked against its particles.
pub fn restore(obj: &Bound<'_, PyDict>) -> PyResult<Simulation> {
    let obj = obj.as_any();
    let version: u64 = item(obj, "version", "state.version")?.extract()?;
    if version != VERSION {
        return Err(value_error(
            "state.version",
            format!("this rustcloth reads state version {VERSION}, got {version}"),
        ));
    }
    let scene = unvalidated_scene_from_dict(&item(obj, "scene", "state.scene")?)?;
    let sim = Simulation::new(scene).py()?;
    let n = sim.grid().len();
    let mut s: Snapshot = deserialize(obj, "state")?;
    let get = |key: &str| item(obj, key, &format!("state.{key}"));
    s.positions = state_vectors(&get("positions")?, "state.positions", n)?;
    s.velocities = state_vectors(&get("velocities")?, "state.velocities", n)?;
    s.masses = array(&get("masses")?, ("state.masses", "float32"), &[n])?;
    s.pinned = array(&get("pinned")?, ("state.pinned", "bool"), &[n])?;
    s.alive = array(&get("alive")?, ("state.alive", "bool"), &[n])?;
    let springs = items(&get("springs")?, "state.springs", 6)?;
    for (k, flags) in springs.iter().enumerate() {
        s.springs[k] = array(flags, (&format!("state.springs[{k}]"), "bool"), &[n])?;
    }
    // Optional: a state without it has no mesh spring severed. With it, one flag per spring
    // of a mesh cloth (none on the grid).
    if let Ok(flags) = obj.get_item("mesh_springs") {
        let springs = sim.model().mesh().map_or(0, |m| m.springs.len());
        s.mesh_springs = array(&flags, ("state.mesh_springs", "bool"), &[springs])?;
    }
    let name = "state.watchdog.previous";
    let previous = item(&get("watchdog")?, "previous", name)?;
    if !previous.is_none() {
        let parts = items(&previous, name, 3)?;
        s.watchdog.previous = Some((
            state_vectors(&parts[0], name, n)?,
            state_vectors(&parts[1], name, n)?,
            deserialize(&parts[2], name)?,
        ));
    }
    sim.continuing(s).py()
}
