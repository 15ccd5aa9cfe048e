//! Conversions between Python objects and core types. Every failure names the parameter.

use numpy::{
    PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::PyOverflowError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

use super::errors::{to_py, type_error, value_error};
use crate::soa::Vec3s;
use crate::Error;

/// A Python scene dict (plain dicts, lists, numbers, strings) as a TOML value, so that the core
/// parses dicts and TOML files with the same deserializer and the same errors. `None` values in
/// a dict mean "absent".
pub fn to_toml(obj: &Bound<'_, PyAny>, path: &str) -> PyResult<toml::Value> {
    let name = if path.is_empty() { "scene" } else { path };
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
            table.insert(key, to_toml(&value, &child)?);
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
            .map(|(i, item)| to_toml(&item?, &format!("{name}[{i}]")))
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

/// A TOML value as plain Python objects.
pub fn from_toml<'py>(py: Python<'py>, value: &toml::Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match value {
        toml::Value::Table(table) => {
            let dict = PyDict::new(py);
            for (k, v) in table {
                dict.set_item(k, from_toml(py, v)?)?;
            }
            dict.into_any()
        }
        toml::Value::Array(items) => {
            let list = PyList::empty(py);
            for v in items {
                list.append(from_toml(py, v)?)?;
            }
            list.into_any()
        }
        toml::Value::String(s) => PyString::new(py, s).into_any(),
        toml::Value::Integer(i) => i.into_pyobject(py)?.into_any(),
        toml::Value::Float(f) => PyFloat::new(py, *f).into_any(),
        toml::Value::Boolean(b) => PyBool::new(py, *b).to_owned().into_any(),
        toml::Value::Datetime(d) => PyString::new(py, &d.to_string()).into_any(),
    })
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
    if let Ok(array) = obj.extract::<PyReadonlyArray1<'_, f32>>() {
        Ok(array.as_array().iter().map(|&x| x as f64).collect())
    } else if let Ok(array) = obj.extract::<PyReadonlyArray1<'_, f64>>() {
        Ok(array.as_array().to_vec())
    } else {
        Err(dtype_error(untyped, name))
    }
}

/// SoA vectors as a new `(n, 3)` float32 array: the one copy a read costs.
pub fn vec3s_to_array<'py>(py: Python<'py>, v: &Vec3s) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let mut flat = vec![0.0f32; v.len() * 3];
    v.write_interleaved(&mut flat);
    PyArray1::from_vec(py, flat).reshape([v.len(), 3])
}

/// A 3-vector from any length-3 sequence of numbers.
pub fn vec3_from_any(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<glam::Vec3> {
    let values: Vec<f64> = obj
        .extract()
        .or_else(|_| obj.call_method0("tolist").and_then(|l| l.extract()))
        .map_err(|_| type_error(name, format!("must be a sequence of 3 numbers, got {obj}")))?;
    match values.as_slice() {
        [x, y, z] => Ok(glam::DVec3::new(*x, *y, *z).as_vec3()),
        _ => Err(value_error(
            name,
            format!("must have 3 components, got {}", values.len()),
        )),
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
