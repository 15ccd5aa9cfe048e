//! Conversions between Python objects and core types. Every failure names the parameter.

use numpy::{
    PyArray1, PyArray2, PyArrayDescrMethods, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2,
    PyUntypedArray, PyUntypedArrayMethods,
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

/// A scene as a dict with every key spelled out, absent optional tables as `None`.
pub fn scene_to_dict<'py>(py: Python<'py>, scene: &Scene) -> PyResult<Bound<'py, PyAny>> {
    // Through a TOML value, whose arrays become lists where serde's tuples (`[f32; 3]`) would
    // become Python tuples. TOML has no null: absent optional keys are spelled out as None
    // below, as users write them.
    let value = toml::Value::try_from(scene).expect("a scene always serialises");
    let dict = pythonize::pythonize(py, &value)?.cast_into::<PyDict>()?;
    for key in ["floor", "strain_limit", "self_collision", "tearing"] {
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
    } else {
        let kind = type_name(obj);
        Err(type_error(
            name,
            format!("unsupported value of type {kind}: {obj}"),
        ))
    }
}

/// An `(n, 3)` float32 or float64 numpy array as SoA vectors.
pub fn vec3s_from_array(obj: &Bound<'_, PyAny>, name: &str, n: usize) -> PyResult<Vec3s> {
    let Ok(untyped) = obj.cast::<PyUntypedArray>() else {
        let kind = type_name(obj);
        return Err(type_error(
            name,
            format!("must be a numpy array of shape ({n}, 3), got {kind}"),
        ));
    };
    if untyped.shape() != [n, 3] {
        return Err(value_error(
            name,
            format!("must have shape ({n}, 3), got {:?}", untyped.shape()),
        ));
    }
    let native = native_order(obj)?;
    let obj = &native;
    let mut out = Vec3s::zeros(n);
    if let Ok(array) = obj.extract::<PyReadonlyArray2<'_, f32>>() {
        for (p, row) in array.as_array().outer_iter().enumerate() {
            out.set(p, glam::Vec3::new(row[0], row[1], row[2]));
        }
    } else if let Ok(array) = obj.extract::<PyReadonlyArray2<'_, f64>>() {
        for (p, row) in array.as_array().outer_iter().enumerate() {
            out.set(p, glam::DVec3::new(row[0], row[1], row[2]).as_vec3());
        }
    } else {
        return Err(dtype_error(untyped, name));
    }
    Ok(out)
}

/// A float array in the machine's byte order: a big-endian float32 or float64 array is as valid
/// as any, and numpy's typed views accept only the native order.
fn native_order<'py>(obj: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    let dtype = obj.getattr("dtype")?;
    let kind: String = dtype.getattr("kind")?.extract()?;
    let native: bool = dtype.getattr("isnative")?.extract()?;
    if kind == "f" && !native {
        let order = dtype.call_method1("newbyteorder", ("=",))?;
        obj.call_method1("astype", (order,))
    } else {
        Ok(obj.clone())
    }
}

/// `TypeError` for an array that is neither float32 nor float64.
fn dtype_error(array: &Bound<'_, PyUntypedArray>, name: &str) -> PyErr {
    let dtype = array
        .dtype()
        .str()
        .map(|s| s.to_string())
        .unwrap_or_default();
    type_error(
        name,
        format!("must have dtype float32 or float64, got {dtype}"),
    )
}

/// An `(n,)` float32 or float64 numpy array as f64 values.
pub fn f64s_from_array(obj: &Bound<'_, PyAny>, name: &str, n: usize) -> PyResult<Vec<f64>> {
    let Ok(untyped) = obj.cast::<PyUntypedArray>() else {
        let kind = type_name(obj);
        return Err(type_error(
            name,
            format!("must be a numpy array of shape ({n},), got {kind}"),
        ));
    };
    if untyped.shape() != [n] {
        return Err(value_error(
            name,
            format!("must have shape ({n},), got {:?}", untyped.shape()),
        ));
    }
    let native = native_order(obj)?;
    let obj = &native;
    if let Ok(array) = obj.extract::<PyReadonlyArray1<'_, f32>>() {
        Ok(array.as_array().iter().map(|&x| x as f64).collect())
    } else if let Ok(array) = obj.extract::<PyReadonlyArray1<'_, f64>>() {
        Ok(array.as_array().to_vec())
    } else {
        Err(dtype_error(untyped, name))
    }
}

/// SoA vectors as interleaved `x, y, z` floats: the one copy a read costs, made under the lock.
pub fn interleaved(v: &Vec3s) -> Vec<f32> {
    let mut flat = vec![0.0f32; v.len() * 3];
    v.write_interleaved(&mut flat);
    flat
}

/// Interleaved floats as a new read-only `(n, 3)` float32 array. Read-only because it is a
/// copy: a write to it would change nothing in the simulation, so numpy refuses it instead of
/// losing it silently (`set_positions` writes).
pub fn vec3s_to_array(py: Python<'_>, flat: Vec<f32>) -> PyResult<Bound<'_, PyArray2<f32>>> {
    rows_to_array(py, flat, 3)
}

/// Row-major values as a new read-only `(n, width)` array (a copy, as [`vec3s_to_array`]).
pub fn rows_to_array<T: numpy::Element>(
    py: Python<'_>,
    flat: Vec<T>,
    width: usize,
) -> PyResult<Bound<'_, PyArray2<T>>> {
    let n = flat.len() / width;
    let array = PyArray1::from_vec(py, flat).reshape([n, width])?;
    read_only(array.as_any())?;
    Ok(array)
}

/// Marks a numpy array read-only.
pub fn read_only(array: &Bound<'_, PyAny>) -> PyResult<()> {
    let kwargs = PyDict::new(array.py());
    kwargs.set_item("write", false)?;
    array.call_method("setflags", (), Some(&kwargs))?;
    Ok(())
}

/// N numbers from a sequence (or array) of N real numbers. Strings, bytes and booleans are
/// not numbers here (`b"abc"` would otherwise be the vector (97, 98, 99)); components must be
/// finite in float32 after conversion, which the core checks.
pub fn floats_from_any<const N: usize>(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<[f64; N]> {
    let kind = type_name(obj);
    if obj.is_instance_of::<PyString>()
        || obj.is_instance_of::<PyBytes>()
        || obj.is_instance_of::<PyByteArray>()
    {
        return Err(type_error(
            name,
            format!(
                "must be a sequence of {N} numbers, got {kind} {}",
                repr(obj)
            ),
        ));
    }
    // A sequence (list, tuple, numpy array, any `collections.abc.Sequence`): a dict would be
    // read as its keys, a set in any order.
    let sequence = match obj.cast::<PyUntypedArray>() {
        // An array of anything but numbers is the wrong type whatever its length (its dtype
        // is known before its items are read).
        Ok(array) if !matches!(array.dtype().kind(), b'f' | b'i' | b'u') && array.ndim() == 1 => {
            return Err(type_error(
                name,
                format!(
                    "must be a sequence of {N} numbers, got {kind} {}",
                    repr(obj)
                ),
            ))
        }
        // A 0-d array is a number, not a sequence.
        Ok(array) => array.ndim() == 1,
        Err(_) => {
            obj.is_instance_of::<PyList>()
                || obj.is_instance_of::<PyTuple>()
                || obj.cast::<PySequence>().is_ok()
        }
    };
    let items: Vec<Bound<'_, PyAny>> = match sequence {
        true => obj.try_iter()?.collect::<PyResult<_>>()?,
        false => {
            return Err(type_error(
                name,
                format!(
                    "must be a sequence of {N} numbers, got {kind} {}",
                    repr(obj)
                ),
            ))
        }
    };
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
    if obj.is_instance_of::<PyBool>() || is_numpy_bool(obj) {
        return Err(type_error(
            name,
            format!("must be a number, got bool {}", repr(obj)),
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
            format!(
                "must be a real number, got {} {}",
                type_name(obj),
                repr(obj)
            ),
        ));
    }
    match obj.extract::<f64>() {
        Ok(x) => Ok(x),
        Err(e) if e.is_instance_of::<PyOverflowError>(obj.py()) => Err(value_error(
            name,
            format!("{} is too large for a float", repr(obj)),
        )),
        Err(_) => Err(type_error(
            name,
            format!("must be a number, got {} {}", type_name(obj), repr(obj)),
        )),
    }
}

/// A whole number: a Python `int` or a numpy integer, never a `bool` or a float (not even
/// `2.0`: a count given as a float is usually a mistake). Values outside `i64` are value
/// errors naming `name`, so the core's range checks report them like any other bad value.
pub fn int_from_any(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<i64> {
    if obj.is_instance_of::<PyBool>() || is_numpy_bool(obj) {
        return Err(type_error(
            name,
            format!("must be an integer, got bool {}", repr(obj)),
        ));
    }
    match obj.extract::<i64>() {
        Ok(i) => Ok(i),
        Err(e) if e.is_instance_of::<PyOverflowError>(obj.py()) => {
            Err(value_error(name, format!("{} is out of range", repr(obj))))
        }
        Err(_) => Err(type_error(
            name,
            format!("must be an integer, got {} {}", type_name(obj), repr(obj)),
        )),
    }
}

/// A count of steps: an integer `>= 0`.
pub fn count_from_any(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<u64> {
    let n = int_from_any(obj, name)?;
    u64::try_from(n).map_err(|_| value_error(name, format!("must be an integer >= 0, got {n}")))
}

/// A string: a Python `str` only.
pub fn str_from_any(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<String> {
    obj.cast::<PyString>().map(|s| s.to_string()).map_err(|_| {
        type_error(
            name,
            format!("must be a string, got {} {}", type_name(obj), repr(obj)),
        )
    })
}

/// The numpy dtype kind (`'f'`, `'b'`, `'c'`, ...) of a numpy scalar or array, else None.
fn dtype_kind(obj: &Bound<'_, PyAny>) -> Option<String> {
    obj.getattr("dtype")
        .and_then(|d| d.getattr("kind"))
        .and_then(|k| k.extract::<String>())
        .ok()
}

/// Whether `obj` is a numpy boolean: a scalar (not a Python `bool` subclass) or a 0-d array,
/// which would otherwise convert to 0 or 1.
fn is_numpy_bool(obj: &Bound<'_, PyAny>) -> bool {
    type_name(obj) == "bool" && !obj.is_instance_of::<PyBool>()
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

/// A particle index: any Python integer (`bool` excluded); one too large for 64 bits is out of
/// range like any other.
pub fn index_from_any(obj: &Bound<'_, PyAny>, name: &str, len: usize) -> PyResult<i64> {
    if obj.is_instance_of::<PyBool>() {
        return Err(type_error(
            name,
            format!("must be an integer index, got {obj}"),
        ));
    }
    match obj.extract::<i64>() {
        Ok(i) => Ok(i),
        Err(e) if e.is_instance_of::<PyOverflowError>(obj.py()) => {
            Err(to_py(Error::IndexOutOfRange {
                name: name.into(),
                index: i64::MAX,
                len,
            }))
        }
        Err(_) => {
            let kind = type_name(obj);
            Err(type_error(
                name,
                format!("must be an integer index, got {kind} {obj}"),
            ))
        }
    }
}

/// The Python type name of `obj`, for messages.
fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_default()
}
