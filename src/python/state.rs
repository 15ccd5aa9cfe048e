//! A [`Snapshot`] as a Python dict of numpy arrays and plain values, and back: what
//! `Simulation.get_state()` returns, `set_state` takes and pickling sends. Every value survives
//! the trip bit for bit (float32 arrays as float32, f64 as Python floats); every key is checked
//! on the way back, and an error names it (`state.positions`, `state.watchdog.hold`, ...).

use numpy::{PyArray1, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};

use super::conv::{
    count_from_any, float_from_any, interleaved, scene_from_dict, scene_to_dict, str_from_any,
    vec3_from_any, vec3s_from_array, vec3s_to_array,
};
use super::errors::{type_error, value_error};
use crate::collisions::{Pose, PoseKey};
use crate::integrators::History;
use crate::picking::PickStrategy;
use crate::snapshot::{Snapshot, WatchdogSnapshot};
use crate::soa::Vec3s;
use crate::stepper::WatchdogStats;

/// The layout of the dict; a state of another layout is refused rather than guessed at. 2 added
/// `collider_keys`.
const VERSION: u64 = 2;

pub fn to_dict<'py>(py: Python<'py>, s: &Snapshot) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("version", VERSION)?;
    d.set_item("scene", scene_to_dict(py, &s.scene)?)?;
    d.set_item("positions", vec3s_to_array(py, interleaved(&s.positions))?)?;
    d.set_item(
        "velocities",
        vec3s_to_array(py, interleaved(&s.velocities))?,
    )?;
    d.set_item("masses", PyArray1::from_slice(py, &s.masses))?;
    d.set_item("pinned", PyArray1::from_slice(py, &s.pinned))?;
    d.set_item("alive", PyArray1::from_slice(py, &s.alive))?;
    let springs = PyList::empty(py);
    for flags in &s.springs {
        springs.append(PyArray1::from_slice(py, flags))?;
    }
    d.set_item("springs", springs)?;
    let targets = PyList::empty(py);
    for &(p, t) in &s.targets {
        targets.append((p, t.to_array()))?;
    }
    d.set_item("targets", targets)?;
    d.set_item(
        "grab",
        s.grab
            .map(|(p, was_pinned, previous)| (p, was_pinned, previous.map(|t| t.to_array()))),
    )?;
    d.set_item("pick_radius", s.pick_radius)?;
    d.set_item("pick_strategy", s.pick_strategy.name())?;
    d.set_item("steps", s.steps)?;
    d.set_item("time_base", s.time_base)?;
    d.set_item("steps_base", s.steps_base)?;
    d.set_item("accumulator", s.accumulator)?;
    d.set_item("history", history_to_dict(py, s.history)?)?;
    let w = &s.watchdog;
    let watchdog = PyDict::new(py);
    match &w.previous {
        Some((pos, vel, history)) => watchdog.set_item(
            "previous",
            (
                vec3s_to_array(py, interleaved(pos))?,
                vec3s_to_array(py, interleaved(vel))?,
                history_to_dict(py, *history)?,
            ),
        )?,
        None => watchdog.set_item("previous", py.None())?,
    }
    watchdog.set_item("unjudged", w.unjudged)?;
    watchdog.set_item("last_substeps", w.last_substeps)?;
    watchdog.set_item("hold", w.hold)?;
    let stats = PyDict::new(py);
    stats.set_item("caught", w.stats.caught)?;
    stats.set_item("retried", w.stats.retried)?;
    stats.set_item("retry_substeps", w.stats.retry_substeps)?;
    stats.set_item("max_substeps_used", w.stats.max_substeps_used)?;
    stats.set_item("held_steps", w.stats.held_steps)?;
    watchdog.set_item("stats", stats)?;
    d.set_item("watchdog", watchdog)?;
    let keys = PyList::empty(py);
    for key in &s.collider_keys {
        match key {
            Some(k) => keys.append((
                k.from.position.to_array(),
                k.from.rotation.to_array(),
                k.to.position.to_array(),
                k.to.rotation.to_array(),
                k.start,
                k.end,
            ))?,
            None => keys.append(py.None())?,
        }
    }
    d.set_item("collider_keys", keys)?;
    d.set_item("state_version", s.state_version)?;
    d.set_item("topology_version", s.topology_version)?;
    Ok(d)
}

fn history_to_dict(py: Python<'_>, h: History) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("primed", h.primed)?;
    Ok(d)
}

/// A dict's entries, each named `prefix.key` in errors.
struct Entries<'a, 'py> {
    dict: &'a Bound<'py, PyDict>,
    prefix: &'a str,
}

impl<'py> Entries<'_, 'py> {
    fn of<'a>(obj: &'a Bound<'py, PyAny>, prefix: &'a str) -> PyResult<Entries<'a, 'py>> {
        let dict = obj
            .cast::<PyDict>()
            .map_err(|_| type_error(prefix, format!("must be a dict, got {obj}")))?;
        Ok(Entries { dict, prefix })
    }

    fn name(&self, key: &str) -> String {
        format!("{}.{key}", self.prefix)
    }

    fn get(&self, key: &str) -> PyResult<Bound<'py, PyAny>> {
        self.dict
            .get_item(key)?
            .ok_or_else(|| value_error(&self.name(key), "is missing".into()))
    }

    fn count(&self, key: &str) -> PyResult<u64> {
        count_from_any(&self.get(key)?, &self.name(key))
    }

    fn float(&self, key: &str) -> PyResult<f64> {
        float_from_any(&self.get(key)?, &self.name(key))
    }

    fn flag(&self, key: &str) -> PyResult<bool> {
        bool_from_any(&self.get(key)?, &self.name(key))
    }

    fn flags(&self, key: &str, n: usize) -> PyResult<Vec<bool>> {
        flags_from_any(&self.get(key)?, &self.name(key), n)
    }
}

fn bool_from_any(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<bool> {
    obj.extract::<bool>()
        .map_err(|_| type_error(name, format!("must be a bool, got {obj}")))
}

fn flags_from_any(obj: &Bound<'_, PyAny>, name: &str, n: usize) -> PyResult<Vec<bool>> {
    let array = obj
        .extract::<PyReadonlyArray1<'_, bool>>()
        .map_err(|_| type_error(name, format!("must be a bool array of shape ({n},)")))?;
    let flags = array.as_array().to_vec();
    if flags.len() != n {
        return Err(value_error(
            name,
            format!("must have shape ({n},), got ({},)", flags.len()),
        ));
    }
    Ok(flags)
}

fn history_from_any(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<History> {
    let e = Entries::of(obj, name)?;
    Ok(History {
        primed: e.flag("primed")?,
    })
}

/// A 2-sequence or longer of items, named `name[k]`.
fn items<'py>(obj: &Bound<'py, PyAny>, name: &str, len: usize) -> PyResult<Vec<Bound<'py, PyAny>>> {
    let items: Vec<Bound<'py, PyAny>> = obj
        .try_iter()
        .map_err(|_| type_error(name, format!("must be a sequence, got {obj}")))?
        .collect::<PyResult<_>>()?;
    if items.len() != len {
        return Err(value_error(
            name,
            format!("must have {len} items, got {}", items.len()),
        ));
    }
    Ok(items)
}

fn f32_array(obj: &Bound<'_, PyAny>, name: &str, n: usize) -> PyResult<Vec<f32>> {
    let array = obj
        .extract::<PyReadonlyArray1<'_, f32>>()
        .map_err(|_| type_error(name, format!("must be a float32 array of shape ({n},)")))?;
    let values = array.as_array().to_vec();
    if values.len() != n {
        return Err(value_error(
            name,
            format!("must have shape ({n},), got ({},)", values.len()),
        ));
    }
    Ok(values)
}

/// Exactly float32 `(n, 3)` arrays: a state is bits, and a float64 array would be a different
/// state rounded.
fn state_vectors(obj: &Bound<'_, PyAny>, name: &str, n: usize) -> PyResult<Vec3s> {
    if obj.extract::<PyReadonlyArray2<'_, f32>>().is_err() {
        return Err(type_error(
            name,
            format!("must be a float32 array of shape ({n}, 3)"),
        ));
    }
    vec3s_from_array(obj, name, n)
}

pub fn from_dict(obj: &Bound<'_, PyAny>) -> PyResult<Snapshot> {
    let d = Entries::of(obj, "state")?;
    let version = d.count("version")?;
    if version != VERSION {
        return Err(value_error(
            "state.version",
            format!("this rustcloth reads state version {VERSION}, got {version}"),
        ));
    }
    let scene = scene_from_dict(&d.get("scene")?)?;
    let n = scene.grid().len();
    let springs_obj = d.get("springs")?;
    let springs_items = items(&springs_obj, "state.springs", 6)?;
    let mut springs: [Vec<bool>; 6] = Default::default();
    for (k, item) in springs_items.iter().enumerate() {
        springs[k] = flags_from_any(item, &format!("state.springs[{k}]"), n)?;
    }
    let targets_obj = d.get("targets")?;
    let mut targets = Vec::new();
    for (k, item) in targets_obj
        .try_iter()
        .map_err(|_| type_error("state.targets", "must be a list".into()))?
        .enumerate()
    {
        let name = format!("state.targets[{k}]");
        let pair = items(&item?, &name, 2)?;
        let p = count_from_any(&pair[0], &name)? as usize;
        targets.push((p, vec3_from_any(&pair[1], &name)?));
    }
    let grab_obj = d.get("grab")?;
    let grab = if grab_obj.is_none() {
        None
    } else {
        let parts = items(&grab_obj, "state.grab", 3)?;
        let p = count_from_any(&parts[0], "state.grab")? as usize;
        let was_pinned = bool_from_any(&parts[1], "state.grab")?;
        let previous = if parts[2].is_none() {
            None
        } else {
            Some(vec3_from_any(&parts[2], "state.grab")?)
        };
        Some((p, was_pinned, previous))
    };
    let radius_obj = d.get("pick_radius")?;
    let pick_radius = if radius_obj.is_none() {
        None
    } else {
        Some(float_from_any(&radius_obj, "state.pick_radius")? as f32)
    };
    let strategy = str_from_any(&d.get("pick_strategy")?, "state.pick_strategy")?;
    let pick_strategy = PickStrategy::by_name(&strategy).map_err(|_| {
        value_error(
            "state.pick_strategy",
            format!("unknown strategy {strategy:?}"),
        )
    })?;
    let w = d.get("watchdog")?;
    let w = Entries::of(&w, "state.watchdog")?;
    let previous_obj = w.get("previous")?;
    let previous = if previous_obj.is_none() {
        None
    } else {
        let parts = items(&previous_obj, "state.watchdog.previous", 3)?;
        Some((
            state_vectors(&parts[0], "state.watchdog.previous", n)?,
            state_vectors(&parts[1], "state.watchdog.previous", n)?,
            history_from_any(&parts[2], "state.watchdog.previous")?,
        ))
    };
    let hold_obj = w.get("hold")?;
    let hold = if hold_obj.is_none() {
        None
    } else {
        let parts = items(&hold_obj, "state.watchdog.hold", 2)?;
        let substeps = count_from_any(&parts[0], "state.watchdog.hold")?;
        let substeps = u32::try_from(substeps)
            .map_err(|_| value_error("state.watchdog.hold", "substeps out of range".into()))?;
        Some((substeps, count_from_any(&parts[1], "state.watchdog.hold")?))
    };
    let stats_obj = w.get("stats")?;
    let stats = Entries::of(&stats_obj, "state.watchdog.stats")?;
    let last_substeps = u32::try_from(w.count("last_substeps")?)
        .map_err(|_| value_error("state.watchdog.last_substeps", "out of range".into()))?;
    let max_substeps_used = u32::try_from(stats.count("max_substeps_used")?).map_err(|_| {
        value_error(
            "state.watchdog.stats.max_substeps_used",
            "out of range".into(),
        )
    })?;
    let keys_obj = d.get("collider_keys")?;
    let mut collider_keys = Vec::new();
    for (k, item) in keys_obj
        .try_iter()
        .map_err(|_| type_error("state.collider_keys", "must be a list".into()))?
        .enumerate()
    {
        let item = item?;
        let name = format!("state.collider_keys[{k}]");
        collider_keys.push(if item.is_none() {
            None
        } else {
            Some(pose_key_from_any(&item, &name)?)
        });
    }
    Ok(Snapshot {
        collider_keys,
        positions: state_vectors(&d.get("positions")?, "state.positions", n)?,
        velocities: state_vectors(&d.get("velocities")?, "state.velocities", n)?,
        masses: f32_array(&d.get("masses")?, "state.masses", n)?,
        pinned: d.flags("pinned", n)?,
        alive: d.flags("alive", n)?,
        springs,
        targets,
        grab,
        pick_radius,
        pick_strategy,
        steps: d.count("steps")?,
        time_base: d.float("time_base")?,
        steps_base: d.count("steps_base")?,
        accumulator: d.float("accumulator")?,
        history: history_from_any(&d.get("history")?, "state.history")?,
        watchdog: WatchdogSnapshot {
            previous,
            unjudged: w.flag("unjudged")?,
            last_substeps,
            hold,
            stats: WatchdogStats {
                caught: stats.count("caught")?,
                retried: stats.count("retried")?,
                retry_substeps: stats.count("retry_substeps")?,
                max_substeps_used,
                held_steps: stats.count("held_steps")?,
            },
        },
        state_version: d.count("state_version")?,
        topology_version: d.count("topology_version")?,
        scene,
    })
}

/// A pose key as `to_dict` writes it: `(from position, from rotation, to position, to rotation,
/// start, end)`; its values are checked when the snapshot is applied.
fn pose_key_from_any(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<PoseKey> {
    let parts = items(obj, name, 6)?;
    let floats = |part: &Bound<'_, PyAny>| -> PyResult<Vec<f64>> {
        part.extract::<Vec<f64>>()
            .map_err(|_| type_error(name, format!("must hold lists of floats, got {part}")))
    };
    let pose = |position: &Bound<'_, PyAny>, rotation: &Bound<'_, PyAny>| -> PyResult<Pose> {
        let (p, q) = (floats(position)?, floats(rotation)?);
        if p.len() != 3 || q.len() != 4 {
            return Err(value_error(
                name,
                "a position needs 3 floats and a rotation 4".into(),
            ));
        }
        Ok(Pose {
            position: glam::DVec3::from_slice(&p),
            rotation: glam::DQuat::from_slice(&q),
        })
    };
    Ok(PoseKey {
        from: pose(&parts[0], &parts[1])?,
        to: pose(&parts[2], &parts[3])?,
        start: float_from_any(&parts[4], name)?,
        end: float_from_any(&parts[5], name)?,
    })
}

/// `(state,)`, the arguments `__reduce__` gives the module-level constructor.
pub fn reduce_args<'py>(py: Python<'py>, s: &Snapshot) -> PyResult<Bound<'py, PyTuple>> {
    PyTuple::new(py, [to_dict(py, s)?])
}
