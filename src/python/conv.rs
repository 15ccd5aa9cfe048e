//! Conversions between Python objects and core types. Every failure names the parameter.

use numpy::{
    PyArray1, PyArrayDescrMethods, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

use super::errors::{type_error, value_error, IntoPyResult};
use crate::scene::Scene;
use crate::soa::Vec3s;

/// How deeply lists and tables may nest in a scene. The deepest key of the schema is a mesh
/// collider's vertex coordinate, `colliders[k].vertices[i][j]`, four levels down; this leaves
/// room for any future key while stopping input whose conversion would overflow the stack.
pub const MAX_NESTING: usize = 32;

/// A scene dict, validated by the core (one parse, one validation).
pub fn scene_from_dict(obj: &Bound<'_, PyAny>) -> PyResult<Scene> {
    Scene::from_toml_value(to_toml(obj, "", 0)?).py()
}

/// As [`scene_from_dict`], not yet validated ([`Scene::read_toml_value`]): for
/// `Simulation::new`, which validates it.
pub fn unvalidated_scene_from_dict(obj: &Bound<'_, PyAny>) -> PyResult<Scene> {
    Scene::read_toml_value(to_toml(obj, "", 0)?).py()
}

/// A scene as a dict with every key spelled out, absent optional tables as `None`, and each
/// mesh collider's `vertices` and `triangles` as new read-only `(n, 3)` numpy arrays (float64,
/// int64): the scene's own copy, which its users share and nobody can change.
pub fn scene_to_dict<'py>(py: Python<'py>, scene: &Scene) -> PyResult<Bound<'py, PyAny>> {
    // Through a TOML value, whose arrays become lists where serde's tuples (`[f32; 3]`) would
    // become Python tuples. TOML has no null: absent optional keys are spelled out as None
    // below, as users write them.
    // A mesh's vertices and triangles go out as numpy arrays, not through the TOML value:
    // a million triangles as Python lists of lists cost seconds each way.
    let mut light = scene.clone();
    let meshes: Vec<_> = light
        .colliders
        .iter_mut()
        .map(|c| (c.vertices.take(), c.triangles.take()))
        .collect();
    let value = toml::Value::try_from(&light).expect("a scene always serialises");
    let dict = pythonize::pythonize(py, &value)?.cast_into::<PyDict>()?;
    if let Some(colliders) = dict.get_item("colliders")? {
        for (collider, (vertices, triangles)) in colliders.try_iter()?.zip(meshes) {
            let collider = collider?.cast_into::<PyDict>()?;
            if let Some(v) = vertices {
                let rows = Rows(v.into_iter().flatten().collect::<Vec<f64>>(), 3);
                collider.set_item("vertices", rows)?;
            }
            if let Some(t) = triangles {
                let rows = Rows(t.into_iter().flatten().collect::<Vec<i64>>(), 3);
                collider.set_item("triangles", rows)?;
            }
        }
    }
    for key in ["floor", "strain_limit", "self_collision", "tearing", "wind"] {
        if !dict.contains(key)? {
            dict.set_item(key, py.None())?;
        }
    }
    let watchdog = dict.get_item("watchdog")?.expect("always serialised");
    let watchdog = watchdog.cast_into::<PyDict>()?;
    if !watchdog.contains("max_stretch")? {
        watchdog.set_item("max_stretch", py.None())?;
    }
    Ok(dict.into_any())
}

/// A scene on its way to Python as a dict, as [`scene_to_dict`] writes it.
pub struct SceneDict(pub Scene);

impl<'py> IntoPyObject<'py> for SceneDict {
    type Target = PyAny;
    type Output = Bound<'py, PyAny>;
    type Error = PyErr;

    fn into_pyobject(self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        scene_to_dict(py, &self.0)
    }
}

/// A Python scene dict (plain dicts, lists, numbers, strings) as a TOML value, so that the core
/// parses dicts and TOML files with the same deserializer and the same errors. `None` values in
/// a dict mean "absent". `depth` is how many lists and tables hold `obj`, at most
/// [`MAX_NESTING`].
pub fn to_toml(obj: &Bound<'_, PyAny>, path: &str, depth: usize) -> PyResult<toml::Value> {
    let name = if path.is_empty() { "scene" } else { path };
    if depth > MAX_NESTING {
        return Err(value_error(
            name,
            format!("lists and tables nest at most {MAX_NESTING} deep in a scene"),
        ));
    }
    if let Ok(dict) = obj.cast::<PyDict>() {
        let mut table = toml::Table::new();
        for (key, value) in dict.iter() {
            let key: String = key.extract().map_err(|_| {
                type_error(
                    name,
                    format!(
                        "keys must be strings, got {}",
                        key.repr().map(|r| r.to_string()).unwrap_or_default()
                    ),
                )
            })?;
            if value.is_none() {
                continue;
            }
            let child = if path.is_empty() {
                key.clone()
            } else {
                format!("{path}.{key}")
            };
            table.insert(key, to_toml(&value, &child, depth + 1)?);
        }
        Ok(toml::Value::Table(table))
    } else if obj.is_instance_of::<PyBool>() {
        Ok(toml::Value::Boolean(obj.extract()?))
    } else if obj.is_instance_of::<PyInt>() {
        obj.extract::<i64>()
            .map(toml::Value::Integer)
            .map_err(|_| value_error(name, format!("{obj} does not fit a 64-bit integer")))
    } else if obj.is_instance_of::<PyFloat>() {
        Ok(toml::Value::Float(obj.extract()?))
    } else if obj.is_instance_of::<PyString>() {
        Ok(toml::Value::String(obj.extract()?))
    } else if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        let items = obj
            .try_iter()?
            .enumerate()
            .map(|(i, item)| to_toml(&item?, &format!("{name}[{i}]"), depth + 1))
            .collect::<PyResult<Vec<_>>>()?;
        Ok(toml::Value::Array(items))
    } else if let Ok(array) = obj.cast::<PyUntypedArray>() {
        array_to_toml(obj, array, name, depth)
    } else {
        let kind = type_name(obj);
        Err(type_error(
            name,
            format!("unsupported value of type {kind}: {obj}"),
        ))
    }
}

/// A numpy array as nested TOML arrays, as its `tolist()` would be read but without the
/// Python objects: a mesh of a million triangles is read in one pass. Its numbers lie `ndim`
/// levels below it, which counts against [`MAX_NESTING`] as a list's would. Arrays of anything
/// but real numbers (bools, complex numbers, objects) and unsigned 64-bit integers (which may
/// not fit an `i64`) go through `tolist()`, element by element, so that the core's errors
/// name the offending element as they do for lists.
fn array_to_toml(
    obj: &Bound<'_, PyAny>,
    array: &Bound<'_, PyUntypedArray>,
    name: &str,
    depth: usize,
) -> PyResult<toml::Value> {
    let shape = array.shape().to_vec();
    if depth + shape.len() > MAX_NESTING {
        return Err(value_error(
            name,
            format!("lists and tables nest at most {MAX_NESTING} deep in a scene"),
        ));
    }
    let dtype = array.dtype();
    let values = match (dtype.kind(), dtype.itemsize()) {
        (b'f', _) => values_as::<f64>(obj, "float64", toml::Value::Float)?,
        (b'i', _) | (b'u', 1..=4) => values_as::<i64>(obj, "int64", toml::Value::Integer)?,
        _ => return to_toml(&obj.call_method0("tolist")?, name, depth),
    };
    Ok(nest(&mut values.into_iter(), &shape))
}

/// The array's numbers, row-major, as `dtype` (numpy's name for `T`; no copy when it already
/// is), each made a TOML value by `value`.
fn values_as<T: numpy::Element + Copy>(
    obj: &Bound<'_, PyAny>,
    dtype: &str,
    value: fn(T) -> toml::Value,
) -> PyResult<Vec<toml::Value>> {
    let kwargs = PyDict::new(obj.py());
    kwargs.set_item("copy", false)?;
    let native = obj.call_method("astype", (dtype,), Some(&kwargs))?;
    let native = native.extract::<PyReadonlyArrayDyn<'_, T>>()?;
    Ok(native.as_array().iter().map(|&x| value(x)).collect())
}

/// `values`, row-major, as nested arrays of `shape`.
fn nest(values: &mut impl Iterator<Item = toml::Value>, shape: &[usize]) -> toml::Value {
    match shape {
        [] => values.next().expect("as many values as the shape holds"),
        [n, rest @ ..] => toml::Value::Array((0..*n).map(|_| nest(values, rest)).collect()),
    }
}

/// A float32 or float64 numpy array in the machine's byte order, read without a copy (the
/// Python side checks shapes and dtypes and names the parameter).
#[derive(FromPyObject)]
pub enum Floats<'py> {
    F32(PyReadonlyArrayDyn<'py, f32>),
    F64(PyReadonlyArrayDyn<'py, f64>),
}

impl Floats<'_> {
    /// The values of an `(n, *row)` array, row-major, in float64.
    pub fn rows(&self, row: &[usize]) -> PyResult<Vec<f64>> {
        let shape = match self {
            Floats::F32(a) => a.shape(),
            Floats::F64(a) => a.shape(),
        };
        if shape.len() != row.len() + 1 || shape[1..] != *row {
            let message = format!("expected an array of shape (n, {row:?}), got {shape:?}");
            return Err(PyValueError::new_err(message));
        }
        Ok(match self {
            Floats::F32(a) => a.as_array().iter().map(|&x| x as f64).collect(),
            Floats::F64(a) => a.as_array().iter().copied().collect(),
        })
    }

    /// The rows of an `(n, 3)` array as SoA vectors.
    pub fn vec3s(&self) -> PyResult<Vec3s> {
        let values = self.rows(&[3])?;
        let mut out = Vec3s::zeros(values.len() / 3);
        for (p, v) in values.chunks_exact(3).enumerate() {
            out.set(p, glam::DVec3::from_slice(v).as_vec3());
        }
        Ok(out)
    }
}

/// Row-major values on their way to a new read-only numpy array, `(n, width)`, or `(n,)` for
/// width 0: copied under the lock, converted after it. Read-only because it is a copy: a write
/// to it would change nothing in the simulation, so numpy refuses it instead of losing it
/// silently (`set_positions` writes).
pub struct Rows<T>(pub Vec<T>, pub usize);

impl Rows<f32> {
    /// SoA vectors as an `(n, 3)` float32 array.
    pub fn vec3s(v: &Vec3s) -> Self {
        let mut flat = vec![0.0f32; v.len() * 3];
        v.write_interleaved(&mut flat);
        Rows(flat, 3)
    }
}

impl<'py, T: numpy::Element> IntoPyObject<'py> for Rows<T> {
    type Target = PyAny;
    type Output = Bound<'py, PyAny>;
    type Error = PyErr;

    fn into_pyobject(self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let Rows(flat, width) = self;
        let rows = flat.len() / width.max(1);
        let array = PyArray1::from_vec(py, flat);
        let array = match width {
            0 => array.into_any(),
            _ => array.reshape([rows, width])?.into_any(),
        };
        let kwargs = PyDict::new(py);
        kwargs.set_item("write", false)?;
        array.call_method("setflags", (), Some(&kwargs))?;
        Ok(array)
    }
}

/// A serde value on its way to plain Python objects (a stats struct becomes a dict).
pub struct Plain<T>(pub T);

impl<'py, T: serde::Serialize> IntoPyObject<'py> for Plain<T> {
    type Target = PyAny;
    type Output = Bound<'py, PyAny>;
    type Error = PyErr;

    fn into_pyobject(self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        Ok(pythonize::pythonize(py, &self.0)?)
    }
}

/// The Python type name of `obj`, for messages.
fn type_name(obj: &Bound<'_, PyAny>) -> String {
    let name = obj.get_type().name();
    name.map(|n| n.to_string()).unwrap_or_default()
}
