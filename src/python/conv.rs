//! Conversions between Python objects and core types. Every failure names the parameter.

use numpy::{
    PyArray1, PyArrayDescrMethods, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::PyOverflowError;
use pyo3::prelude::*;
use pyo3::types::{
    PyBool, PyByteArray, PyBytes, PyComplex, PyDict, PyFloat, PyInt, PyList, PySequence, PyString,
    PyTuple,
};

use super::errors::{to_py, type_error, value_error, IntoPyResult};
use crate::scene::Scene;
use crate::soa::Vec3s;
use crate::Error;

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

/// An `(n, 3)` float32 or float64 numpy array as SoA vectors.
pub fn vec3s_from_array(obj: &Bound<'_, PyAny>, name: &str, n: usize) -> PyResult<Vec3s> {
    let mut out = Vec3s::zeros(n);
    for (p, v) in f64s_from_array(obj, name, &[n, 3])?
        .chunks_exact(3)
        .enumerate()
    {
        out.set(p, glam::DVec3::from_slice(v).as_vec3());
    }
    Ok(out)
}

/// The values of a float32 or float64 numpy array of `shape` (`(n,)` or `(n, k)`), row-major,
/// in float64. A big-endian array is as valid as any: it is read in the machine's order.
pub fn f64s_from_array(obj: &Bound<'_, PyAny>, name: &str, shape: &[usize]) -> PyResult<Vec<f64>> {
    let expected = match shape {
        [n] => format!("({n},)"),
        _ => format!("({}, {})", shape[0], shape[1]),
    };
    let Ok(untyped) = obj.cast::<PyUntypedArray>() else {
        let kind = type_name(obj);
        let message = format!("must be a numpy array of shape {expected}, got {kind}");
        return Err(type_error(name, message));
    };
    if untyped.shape() != shape {
        let message = format!("must have shape {expected}, got {:?}", untyped.shape());
        return Err(value_error(name, message));
    }
    let dtype = untyped.dtype();
    let native = match dtype.kind() == b'f' && !dtype.is_native_byteorder().unwrap_or(true) {
        true => obj.call_method1("astype", (dtype.call_method1("newbyteorder", ("=",))?,))?,
        false => obj.clone(),
    };
    if let Ok(array) = native.extract::<PyReadonlyArrayDyn<'_, f32>>() {
        Ok(array.as_array().iter().map(|&x| x as f64).collect())
    } else if let Ok(array) = native.extract::<PyReadonlyArrayDyn<'_, f64>>() {
        Ok(array.as_array().iter().copied().collect())
    } else {
        let message = format!("must have dtype float32 or float64, got {dtype}");
        Err(type_error(name, message))
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

/// N numbers from a sequence (or array) of N real numbers. Strings, bytes and booleans are
/// not numbers here (`b"abc"` would otherwise be the vector (97, 98, 99)); components must be
/// finite in float32 after conversion, which the core checks.
pub fn floats_from_any<const N: usize>(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<[f64; N]> {
    let kind = type_name(obj);
    let not_numbers = || {
        let message = format!(
            "must be a sequence of {N} numbers, got {kind} {}",
            repr(obj)
        );
        Err(type_error(name, message))
    };
    if obj.is_instance_of::<PyString>()
        || obj.is_instance_of::<PyBytes>()
        || obj.is_instance_of::<PyByteArray>()
    {
        return not_numbers();
    }
    // A sequence (list, tuple, numpy array, any `collections.abc.Sequence`): a dict would be
    // read as its keys, a set in any order.
    let sequence = match obj.cast::<PyUntypedArray>() {
        // An array of anything but numbers is the wrong type whatever its length (its dtype
        // is known before its items are read).
        Ok(array) if !matches!(array.dtype().kind(), b'f' | b'i' | b'u') && array.ndim() == 1 => {
            return not_numbers()
        }
        // A 0-d array is a number, not a sequence.
        Ok(array) => array.ndim() == 1,
        Err(_) => {
            obj.is_instance_of::<PyList>()
                || obj.is_instance_of::<PyTuple>()
                || obj.cast::<PySequence>().is_ok()
        }
    };
    if !sequence {
        return not_numbers();
    }
    let items: Vec<Bound<'_, PyAny>> = obj.try_iter()?.collect::<PyResult<_>>()?;
    if items.len() != N {
        return Err(value_error(
            name,
            format!("must have {N} components, got {}", items.len()),
        ));
    }
    let mut v = [0.0f64; N];
    for (c, item) in items.iter().enumerate() {
        v[c] = float_from_any(item, &format!("{name}[{c}]"))?;
    }
    Ok(v)
}

/// A 3-vector as [`floats_from_any`] reads it.
fn vec3_from_any_f64(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<glam::DVec3> {
    Ok(glam::DVec3::from(floats_from_any::<3>(obj, name)?))
}

/// A 3-vector as [`vec3_from_any_f64`] reads it, in float32.
pub fn vec3_from_any(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<glam::Vec3> {
    Ok(vec3_from_any_f64(obj, name)?.as_vec3())
}

/// A direction: a 3-vector normalised in float64 before it becomes float32, so that a short
/// one such as `(0, 0, 1e-300)`, whose float32 components would be zero, keeps its direction.
/// A vector that is zero, or not finite in float32, passes through unnormalised for the core to
/// refuse with its usual message.
pub fn direction_from_any(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<glam::Vec3> {
    let v = vec3_from_any_f64(obj, name)?;
    let single = v.as_vec3();
    // Scaled by the largest component first: the squared length of (0, 0, 1e-200) underflows
    // even in float64.
    let largest = v.abs().max_element();
    Ok(match single.is_finite() && largest > 0.0 {
        true => (v / largest).normalize().as_vec3(),
        false => single,
    })
}

/// A real number: a Python `int` or `float`, or a numpy scalar, never a `bool` or a string.
/// An integer too large for a float is a value error naming `name`.
pub fn float_from_any(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<f64> {
    if is_bool(obj) {
        return Err(type_error(
            name,
            format!("must be a number, got {}", got(obj)),
        ));
    }
    // Complex numbers convert to float by dropping their imaginary part (numpy's do, with only
    // a warning): not a real number.
    let complex = obj.is_instance_of::<PyComplex>() || dtype_kind(obj).is_some_and(|k| k == "c");
    if obj.is_instance_of::<PyString>()
        || obj.is_instance_of::<PyBytes>()
        || obj.is_instance_of::<PyByteArray>()
        || complex
    {
        return Err(type_error(
            name,
            format!("must be a real number, got {}", got(obj)),
        ));
    }
    obj.extract::<f64>()
        .map_err(|e| match e.is_instance_of::<PyOverflowError>(obj.py()) {
            true => value_error(name, format!("{} is too large for a float", repr(obj))),
            false => type_error(name, format!("must be a number, got {}", got(obj))),
        })
}

/// A whole number: a Python `int` or a numpy integer, never a `bool` or a float (not even
/// `2.0`: a count given as a float is usually a mistake). Values outside `i64` are value
/// errors naming `name`, so the core's range checks report them like any other bad value.
pub fn int_from_any(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<i64> {
    if is_bool(obj) {
        return Err(type_error(
            name,
            format!("must be an integer, got {}", got(obj)),
        ));
    }
    obj.extract::<i64>()
        .map_err(|e| match e.is_instance_of::<PyOverflowError>(obj.py()) {
            true => value_error(name, format!("{} is out of range", repr(obj))),
            false => type_error(name, format!("must be an integer, got {}", got(obj))),
        })
}

/// A count of steps: an integer `>= 0`.
pub fn count_from_any(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<u64> {
    let n = int_from_any(obj, name)?;
    u64::try_from(n).map_err(|_| value_error(name, format!("must be an integer >= 0, got {n}")))
}

/// A string: a Python `str` only.
pub fn str_from_any(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<String> {
    let text = obj.cast::<PyString>();
    text.map(|s| s.to_string())
        .map_err(|_| type_error(name, format!("must be a string, got {}", got(obj))))
}

/// The numpy dtype kind (`'f'`, `'b'`, `'c'`, ...) of a numpy scalar or array, else None.
fn dtype_kind(obj: &Bound<'_, PyAny>) -> Option<String> {
    obj.getattr("dtype")
        .and_then(|d| d.getattr("kind"))
        .and_then(|k| k.extract::<String>())
        .ok()
}

/// Whether `obj` is a bool: Python's, or numpy's (a scalar, not a Python `bool` subclass, or a
/// 0-d array), which would otherwise convert to 0 or 1.
pub fn is_bool(obj: &Bound<'_, PyAny>) -> bool {
    obj.is_instance_of::<PyBool>()
        || type_name(obj) == "bool"
        || type_name(obj) == "bool_"
        || dtype_kind(obj).is_some_and(|k| k == "b")
}

/// `repr(obj)`, shortened for messages.
fn repr(obj: &Bound<'_, PyAny>) -> String {
    let text = obj.repr().map(|r| r.to_string()).unwrap_or_default();
    if text.chars().count() > 60 {
        format!("{}...", text.chars().take(57).collect::<String>())
    } else {
        text
    }
}

/// `obj`'s type and value for messages: `bool True`, `str 'x'`.
fn got(obj: &Bound<'_, PyAny>) -> String {
    let kind = match is_bool(obj) {
        true => "bool".to_string(),
        false => type_name(obj),
    };
    format!("{kind} {}", repr(obj))
}

/// A particle index: any Python integer (`bool` excluded); one too large for 64 bits is out of
/// range like any other.
pub fn index_from_any(obj: &Bound<'_, PyAny>, name: &str, len: usize) -> PyResult<i64> {
    if obj.is_instance_of::<PyBool>() {
        return Err(type_error(
            name,
            format!("must be an integer index, got {obj}"),
        ));
    }
    obj.extract::<i64>()
        .map_err(|e| match e.is_instance_of::<PyOverflowError>(obj.py()) {
            true => to_py(Error::IndexOutOfRange {
                name: name.into(),
                index: i64::MAX,
                len,
            }),
            false => type_error(
                name,
                format!("must be an integer index, got {} {obj}", type_name(obj)),
            ),
        })
}

/// The Python type name of `obj`, for messages.
fn type_name(obj: &Bound<'_, PyAny>) -> String {
    let name = obj.get_type().name();
    name.map(|n| n.to_string()).unwrap_or_default()
}
