//! Conversions between Python objects and core types. Every failure names the parameter.

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use super::errors::IntoPyResult;
use crate::scene::{Scene, SelfCollisionSpec};
use crate::soa::Vec3s;

/// How deeply lists and tables may nest in a scene. The deepest key of the schema is a mesh
/// collider's vertex coordinate, `colliders[k].vertices[i][j]`, four levels down; this leaves
/// room for any future key while stopping input whose conversion would overflow the stack
/// (`rustcloth._args.scene_data` checks it).
pub const MAX_NESTING: usize = 32;

/// A scene dict, validated by the core (one parse, one validation).
pub fn scene_from_dict(obj: &Bound<'_, PyAny>) -> PyResult<Scene> {
    Scene::from_toml_value(to_toml(obj)?).py()
}

/// As [`scene_from_dict`], not yet validated ([`Scene::read_toml_value`]): for
/// `Simulation::new`, which validates it.
pub fn unvalidated_scene_from_dict(obj: &Bound<'_, PyAny>) -> PyResult<Scene> {
    Scene::read_toml_value(to_toml(obj)?).py()
}

/// A `[self_collision]` table as a dict (missing keys take their defaults), read as the
/// scene's own table is read, with its errors (`self_collision.thickness`, unknown keys).
pub fn self_collision_from_dict(obj: &Bound<'_, PyAny>) -> PyResult<SelfCollisionSpec> {
    let table = PyDict::new(obj.py());
    table.set_item("self_collision", obj)?;
    let scene = Scene::read_toml_value(to_toml(table.as_any())?).py()?;
    Ok(scene.self_collision.unwrap_or_default())
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
        dict.call_method1("setdefault", (key, py.None()))?;
    }
    let watchdog = dict.get_item("watchdog")?.expect("always serialised");
    watchdog.call_method1("setdefault", ("max_stretch", py.None()))?;
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

/// A Python scene dict as a TOML value, so that the core parses dicts and TOML files with the
/// same deserializer and the same errors. `rustcloth._args.scene_data` checks it first (naming
/// what TOML cannot hold, bounding the nesting) and hands over plain values, with numpy arrays
/// of real numbers as float64 or int64, read here in one pass.
fn to_toml(obj: &Bound<'_, PyAny>) -> PyResult<toml::Value> {
    read_plain(&args(obj.py())?.call_method1("scene_data", (obj,))?)
}

/// `rustcloth._args`, the strict readers, which the binding calls for the checks that name
/// what they refuse.
pub fn args(py: Python<'_>) -> PyResult<Bound<'_, PyModule>> {
    py.import("rustcloth._args")
}

/// `scene_data`'s output as a TOML value: `None` is gone, integers fit 64 bits.
fn read_plain(obj: &Bound<'_, PyAny>) -> PyResult<toml::Value> {
    Ok(if let Ok(dict) = obj.cast::<PyDict>() {
        let items = dict
            .iter()
            .map(|(k, v)| Ok((k.extract()?, read_plain(&v)?)));
        toml::Value::Table(items.collect::<PyResult<_>>()?)
    } else if let Ok(list) = obj.cast::<PyList>() {
        let items = list.iter().map(|v| read_plain(&v));
        toml::Value::Array(items.collect::<PyResult<_>>()?)
    } else if obj.cast::<PyUntypedArray>().is_err() {
        pythonize::depythonize(obj)?
    } else if let Ok(a) = obj.extract::<PyReadonlyArrayDyn<'_, f64>>() {
        nest(&mut a.as_array().iter().map(|&x| x.into()), a.shape())
    } else {
        let a = obj.extract::<PyReadonlyArrayDyn<'_, i64>>()?;
        nest(&mut a.as_array().iter().map(|&x| x.into()), a.shape())
    })
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
        let vec3 = |p: usize| glam::DVec3::from_slice(&values[3 * p..]).as_vec3();
        Ok(Vec3s::from_fn(values.len() / 3, vec3))
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
