//! `rustcloth._core.Simulation`: the solver's methods for Python. Every method converts its
//! arguments first (naming the parameter on bad input), then runs on the locked simulation
//! (shared.rs); stepping runs detached from the interpreter and checks for Ctrl-C between
//! steps. The documented public API is `rustcloth.Simulation`, which wraps this class.

use numpy::{
    PyArray1, PyArray2, PyArrayDescrMethods, PyReadonlyArray1, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use pythonize::pythonize;

use super::conv::{
    count_from_any, f64s_from_array, float_from_any, index_from_any, int_from_any, interleaved,
    read_only, rows_to_array, scene_from_dict, scene_to_dict, str_from_any, vec3_from_any,
    vec3s_from_array, vec3s_to_array,
};
use super::errors::{type_error, value_error, IntoPyResult, ParticleIndexError};
use super::shared::{Held, Shared};
use super::state;
use crate::{Error, IntegratorKind, Simulation};

type Arrays2<'py> = Bound<'py, PyArray2<f32>>;
/// `(triangles (T, 3), uvs (V, 2), sources (V,))` of the drawn mesh.
type RenderTopology<'py> = (
    Bound<'py, PyArray2<u32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<u32>>,
);

/// The solver. See `rustcloth.Simulation` for the documented API.
#[pyclass(name = "Simulation", module = "rustcloth._core", frozen)]
pub(crate) struct PySimulation {
    pub(crate) shared: Shared,
}

/// The warning to give once per simulation when an implicit solver stopped at its cap.
fn not_converged_warning(held: &mut Held) -> Option<String> {
    let stats = held.sim.solver_stats()?;
    if stats.not_converged == 0 || held.warned_not_converged {
        return None;
    }
    held.warned_not_converged = true;
    let scene = held.sim.scene();
    let (what, cap, tolerance, remedy) = match scene.integrator {
        IntegratorKind::ProjectiveDynamics => (
            "the local-global iterations stopped at pd_iterations",
            scene.pd_iterations,
            ("relative gradient", "pd_tolerance", scene.pd_tolerance),
            "the last iterate. Raise pd_iterations, loosen pd_tolerance",
        ),
        _ => (
            "the conjugate gradient stopped at cg_max_iterations",
            scene.cg_max_iterations,
            ("relative residual", "cg_tolerance", scene.cg_tolerance),
            "the partial solution. Raise cg_max_iterations, loosen cg_tolerance",
        ),
    };
    Some(format!(
        "{}: {what} = {cap} with {} up to {:.2e} > {} = {:.0e} ({} of {} solves so far); the \
         step was taken with {remedy} or reduce dt. profile() counts these.",
        scene.integrator,
        tolerance.0,
        stats.worst_residual,
        tolerance.1,
        tolerance.2,
        stats.not_converged,
        stats.solves,
    ))
}

/// Gives `message` as a `RuntimeWarning`, outside the lock (a warning filter may call back).
fn warn(py: Python<'_>, message: Option<String>) -> PyResult<()> {
    let Some(message) = message else {
        return Ok(());
    };
    let message = std::ffi::CString::new(message).expect("no NUL in the message");
    let category = py.get_type::<pyo3::exceptions::PyRuntimeWarning>();
    PyErr::warn(py, category.as_any(), &message, 1)
}

/// Runs a stepping call detached from the interpreter, asking Python between steps whether a
/// signal (Ctrl-C) arrived; an interrupt comes back as the `KeyboardInterrupt` Python raised.
pub(super) fn stepping<R: Send>(
    py: Python<'_>,
    held: &mut Held,
    call: impl FnOnce(&mut Simulation, &mut dyn FnMut() -> bool) -> crate::Result<R> + Send,
) -> (PyResult<R>, Option<String>) {
    let mut signal: Option<PyErr> = None;
    let outcome = py.detach(|| {
        let mut interrupted = || match Python::attach(|py| py.check_signals()) {
            Ok(()) => false,
            Err(err) => {
                signal = Some(err);
                true
            }
        };
        call(&mut held.sim, &mut interrupted)
    });
    let warning = not_converged_warning(held);
    let outcome = match outcome {
        Err(Error::Interrupted { .. }) if signal.is_some() => Err(signal.take().unwrap()),
        other => other.py(),
    };
    (outcome, warning)
}

fn build(scene: &Bound<'_, PyAny>) -> PyResult<PySimulation> {
    let scene = scene_from_dict(scene)?;
    Ok(PySimulation {
        shared: Shared::new(Simulation::new(scene).py()?),
    })
}

/// A simulation continuing a state from `Simulation.get_state()` (what unpickling calls).
#[pyfunction]
pub(crate) fn simulation_from_state(state: &Bound<'_, PyAny>) -> PyResult<PySimulation> {
    let snapshot = state::from_dict(state)?;
    Ok(PySimulation {
        shared: Shared::new(Simulation::restore(snapshot).py()?),
    })
}

impl PySimulation {
    /// Runs `f` on the simulation under its lock.
    pub(crate) fn with<R>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut Held) -> PyResult<R>,
    ) -> PyResult<R> {
        self.shared.with(py, f)
    }
}

#[pymethods]
impl PySimulation {
    #[new]
    fn new(scene: &Bound<'_, PyAny>) -> PyResult<Self> {
        build(scene)
    }

    // ----- stepping -----------------------------------------------------------------------

    /// Advances exactly `n` steps of `dt`.
    fn step(&self, py: Python<'_>, n: &Bound<'_, PyAny>) -> PyResult<()> {
        let n = count_from_any(n, "n")?;
        let (outcome, warning) = self.with(py, |h| {
            Ok(stepping(py, h, |sim, stop| sim.step_with(n, stop)))
        })?;
        warn(py, warning)?;
        outcome
    }

    /// Adds `seconds` of requested time and runs the whole steps it covers; returns them.
    fn advance(&self, py: Python<'_>, seconds: &Bound<'_, PyAny>) -> PyResult<u64> {
        let seconds = float_from_any(seconds, "seconds")?;
        let (outcome, warning) = self.with(py, |h| {
            Ok(stepping(py, h, |sim, stop| sim.advance_with(seconds, stop)))
        })?;
        warn(py, warning)?;
        outcome
    }

    // ----- state ----------------------------------------------------------------------------

    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let flat = self.with(py, |h| Ok(interleaved(h.sim.positions())))?;
        vec3s_to_array(py, flat)
    }

    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let flat = self.with(py, |h| Ok(interleaved(h.sim.velocities())))?;
        vec3s_to_array(py, flat)
    }

    fn set_positions(&self, py: Python<'_>, positions: &Bound<'_, PyAny>) -> PyResult<()> {
        let n = self.with(py, |h| Ok(h.sim.grid().len()))?;
        let values = vec3s_from_array(positions, "positions", n)?;
        self.with(py, |h| h.sim.set_positions(&values).py())
    }

    fn set_velocities(&self, py: Python<'_>, velocities: &Bound<'_, PyAny>) -> PyResult<()> {
        let n = self.with(py, |h| Ok(h.sim.grid().len()))?;
        let values = vec3s_from_array(velocities, "velocities", n)?;
        self.with(py, |h| h.sim.set_velocities(&values).py())
    }

    fn set_masses(&self, py: Python<'_>, masses: &Bound<'_, PyAny>) -> PyResult<()> {
        let n = self.with(py, |h| Ok(h.sim.grid().len()))?;
        let values = f64s_from_array(masses, "masses", n)?;
        self.with(py, |h| h.sim.set_masses(&values).py())
    }

    #[getter]
    fn masses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let masses = self.with(py, |h| Ok(h.sim.particles().mass.clone()))?;
        read_only_1d(PyArray1::from_vec(py, masses))
    }

    #[getter]
    fn pinned<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let flags = self.with(py, |h| Ok(h.sim.particles().pinned.clone()))?;
        read_only_1d(PyArray1::from_vec(py, flags))
    }

    #[getter]
    fn alive<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let flags = self.with(py, |h| Ok(h.sim.particles().alive.clone()))?;
        read_only_1d(PyArray1::from_vec(py, flags))
    }

    #[getter]
    fn triangles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<u32>>> {
        let flat: Vec<u32> = self.with(py, |h| Ok(h.sim.triangles().as_flattened().to_vec()))?;
        rows_to_array(py, flat, 3)
    }

    /// The drawn mesh's `(positions, normals)`, particles first, then the cut vertices.
    fn render_positions<'py>(&self, py: Python<'py>) -> PyResult<(Arrays2<'py>, Arrays2<'py>)> {
        let (pos, nrm) = self.with(py, |h| {
            let (pos, nrm) = h.sim.render_frame();
            Ok((interleaved(pos), interleaved(nrm)))
        })?;
        Ok((vec3s_to_array(py, pos)?, vec3s_to_array(py, nrm)?))
    }

    /// The drawn mesh's `(triangles, uvs, sources)`: what changes only with the topology.
    fn render_topology<'py>(&self, py: Python<'py>) -> PyResult<RenderTopology<'py>> {
        let (tris, uvs, sources) = self.with(py, |h| {
            let grid = h.sim.grid();
            let tris = h.sim.render_triangles().as_flattened().to_vec();
            let cut = h.sim.render_cut_vertices();
            let uvs = crate::render_mesh::uvs(grid, cut).as_flattened().to_vec();
            Ok((tris, uvs, crate::render_mesh::sources(grid, cut)))
        })?;
        let sources = PyArray1::from_vec(py, sources);
        read_only(sources.as_any())?;
        Ok((
            rows_to_array(py, tris, 3)?,
            rows_to_array(py, uvs, 2)?,
            sources,
        ))
    }

    #[getter]
    fn normals<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let flat = self.with(py, |h| Ok(interleaved(h.sim.normals())))?;
        vec3s_to_array(py, flat)
    }

    #[pyo3(signature = (index, target = None))]
    fn pin(
        &self,
        py: Python<'_>,
        index: &Bound<'_, PyAny>,
        target: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let n = self.with(py, |h| Ok(h.sim.grid().len()))?;
        let index = index_from_any(index, "index", n)?;
        let target = match target {
            Some(t) if !t.is_none() => Some(vec3_from_any(t, "target")?),
            _ => None,
        };
        self.with(py, |h| h.sim.pin(index, target).py())
    }

    /// Pins many particles in one call; `indices` a 1-D integer array, `targets` None or an
    /// `(len(indices), 3)` float array.
    #[pyo3(signature = (indices, targets = None))]
    fn pin_many(
        &self,
        py: Python<'_>,
        indices: &Bound<'_, PyAny>,
        targets: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let n = self.with(py, |h| Ok(h.sim.grid().len()))?;
        let indices = indices_from_array(indices, n)?;
        let targets = match targets {
            Some(t) if !t.is_none() => Some(vec3s_from_array(t, "targets", indices.len())?),
            _ => None,
        };
        self.with(py, |h| h.sim.pin_many(&indices, targets.as_ref()).py())
    }

    fn unpin(&self, py: Python<'_>, index: &Bound<'_, PyAny>) -> PyResult<()> {
        let index = index_from_any(index, "index", self.with(py, |h| Ok(h.sim.grid().len()))?)?;
        self.with(py, |h| h.sim.unpin(index).py())
    }

    fn cut(&self, py: Python<'_>, index: &Bound<'_, PyAny>) -> PyResult<()> {
        let index = index_from_any(index, "index", self.with(py, |h| Ok(h.sim.grid().len()))?)?;
        self.with(py, |h| h.sim.cut(index).py())
    }

    fn reset(&self, py: Python<'_>) -> PyResult<()> {
        self.with(py, |h| {
            h.warned_not_converged = false;
            h.sim.reset().py()
        })
    }

    /// The whole state as a dict of numpy arrays and plain values (see `set_state`).
    fn get_state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let snapshot = self.with(py, |h| Ok(h.sim.snapshot()))?;
        state::to_dict(py, &snapshot)
    }

    /// Replaces the whole simulation (scene included) by a state from `get_state`.
    fn set_state(&self, py: Python<'_>, state: &Bound<'_, PyAny>) -> PyResult<()> {
        let restored = Simulation::restore(state::from_dict(state)?).py()?;
        self.with(py, |h| {
            h.sim = restored;
            h.warned_not_converged = false;
            Ok(())
        })
    }

    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let snapshot = self.with(py, |h| Ok(h.sim.snapshot()))?;
        let constructor = py
            .import("rustcloth._core")?
            .getattr("simulation_from_state")?;
        Ok((
            constructor,
            PyTuple::new(py, [state::to_dict(py, &snapshot)?])?,
        ))
    }

    /// Makes the next force evaluation panic inside its parallel sweep: a stand-in for a bug,
    /// for the tests of the panic guards.
    fn _inject_panic(&self, py: Python<'_>) -> PyResult<()> {
        self.with(py, |h| {
            h.sim.inject_panic();
            Ok(())
        })
    }

    /// Panics right here, under the lock: the binding's last-resort guard, for the tests.
    fn _panic_now(&self, py: Python<'_>) -> PyResult<()> {
        self.with(py, |_| -> PyResult<()> {
            panic!("injected panic outside a step")
        })
    }

    // ----- settings -------------------------------------------------------------------------

    #[getter]
    fn time(&self, py: Python<'_>) -> PyResult<f64> {
        self.with(py, |h| Ok(h.sim.time()))
    }

    #[getter]
    fn steps(&self, py: Python<'_>) -> PyResult<u64> {
        self.with(py, |h| Ok(h.sim.steps()))
    }

    #[getter]
    fn dt(&self, py: Python<'_>) -> PyResult<f64> {
        self.with(py, |h| Ok(h.sim.dt()))
    }

    #[setter]
    fn set_dt(&self, py: Python<'_>, dt: &Bound<'_, PyAny>) -> PyResult<()> {
        let dt = float_from_any(dt, "dt")?;
        self.with(py, |h| h.sim.set_dt(dt).py())
    }

    #[getter]
    fn substeps(&self, py: Python<'_>) -> PyResult<u32> {
        self.with(py, |h| Ok(h.sim.scene().substeps))
    }

    #[setter]
    fn set_substeps(&self, py: Python<'_>, substeps: &Bound<'_, PyAny>) -> PyResult<()> {
        let substeps = int_from_any(substeps, "substeps")?;
        self.with(py, |h| h.sim.set_substeps(substeps).py())
    }

    #[getter]
    fn integrator(&self, py: Python<'_>) -> PyResult<&'static str> {
        self.with(py, |h| Ok(h.sim.scene().integrator.name()))
    }

    #[setter]
    fn set_integrator(&self, py: Python<'_>, name: &Bound<'_, PyAny>) -> PyResult<()> {
        let name = str_from_any(name, "integrator")?;
        self.with(py, |h| h.sim.set_integrator(&name).py())
    }

    /// The scene with the run-time settings as they are now.
    fn scene_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let scene = self.with(py, |h| Ok(h.sim.scene().clone()))?;
        scene_to_dict(py, &scene)
    }

    // ----- diagnostics ----------------------------------------------------------------------

    /// `(kinetic, gravitational, elastic)` in J.
    fn energy(&self, py: Python<'_>) -> PyResult<(f64, f64, f64)> {
        self.with(py, |h| {
            let e = h.sim.energy();
            Ok((e.kinetic, e.gravitational, e.elastic))
        })
    }

    fn spring_strain<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let strain = self.with(py, |h| Ok(h.sim.spring_strain()))?;
        read_only_1d(PyArray1::from_vec(py, strain))
    }

    fn max_stretch(&self, py: Python<'_>) -> PyResult<f32> {
        self.with(py, |h| Ok(h.sim.max_stretch()))
    }

    #[getter]
    fn effects(&self, py: Python<'_>) -> PyResult<Vec<&'static str>> {
        self.with(py, |h| Ok(h.sim.effects()))
    }

    /// `(passes, steps, total_seconds)` with `passes` a list of `(name, seconds, calls)`.
    fn profile<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyList>, u64, f64)> {
        let profile = self.with(py, |h| Ok(h.sim.profile().clone()))?;
        let passes = PyList::empty(py);
        for p in profile.passes() {
            passes.append((p.name, p.time.as_secs_f64(), p.calls))?;
        }
        Ok((passes, profile.steps, profile.total.as_secs_f64()))
    }

    /// Statistics of the implicit solver (`solves`, `iterations`, `last_iterations`,
    /// `last_residual`, `not_converged`, `worst_residual`, `most_iterations`, `factorizations`,
    /// `setup_seconds`, `solve_seconds`), or None for integrators that solve nothing.
    fn solver_stats<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let stats = self.with(py, |h| Ok(h.sim.solver_stats()))?;
        Ok(stats.map(|s| pythonize(py, &s)).transpose()?)
    }

    /// The largest stable `dt` (s) now, or None when any `dt` is.
    fn stable_dt(&self, py: Python<'_>) -> PyResult<Option<f64>> {
        self.with(py, |h| Ok(h.sim.stable_dt()))
    }

    /// What the watchdog caught and retried since the start.
    fn watchdog_stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let stats = self.with(py, |h| Ok(h.sim.watchdog_stats()))?;
        Ok(pythonize(py, &stats)?)
    }

    fn self_collision_stats<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let stats = self.with(py, |h| Ok(h.sim.self_collision_stats()))?;
        Ok(stats.map(|s| pythonize(py, &s)).transpose()?)
    }

    fn memory_bytes(&self, py: Python<'_>) -> PyResult<usize> {
        self.with(py, |h| Ok(h.sim.memory_bytes()))
    }

    #[getter]
    fn topology_version(&self, py: Python<'_>) -> PyResult<u64> {
        self.with(py, |h| Ok(h.sim.topology_version()))
    }

    #[getter]
    fn state_version(&self, py: Python<'_>) -> PyResult<u64> {
        self.with(py, |h| Ok(h.sim.state_version()))
    }

    #[getter]
    fn nx(&self, py: Python<'_>) -> PyResult<usize> {
        self.with(py, |h| Ok(h.sim.grid().nx))
    }

    #[getter]
    fn ny(&self, py: Python<'_>) -> PyResult<usize> {
        self.with(py, |h| Ok(h.sim.grid().ny))
    }

    #[getter]
    fn num_particles(&self, py: Python<'_>) -> PyResult<usize> {
        self.with(py, |h| Ok(h.sim.grid().len()))
    }
}

/// `pin_many`'s indices: a 1-D numpy array of integers (of any dtype when empty), as i64. The
/// core checks each against the particles.
fn indices_from_array(obj: &Bound<'_, PyAny>, n: usize) -> PyResult<Vec<i64>> {
    let array = obj
        .cast::<PyUntypedArray>()
        .map_err(|_| type_error("indices", format!("must be a numpy array, got {obj}")))?;
    if array.ndim() != 1 {
        let shape = obj.getattr("shape")?;
        return Err(value_error(
            "indices",
            format!("must be 1-D, got shape {shape}"),
        ));
    }
    let (dtype, empty) = (array.dtype(), array.len() == 0);
    if !empty && !matches!(dtype.kind(), b'i' | b'u') {
        let message = format!("must hold integers, got dtype {dtype}");
        return Err(type_error("indices", message));
    }
    if !empty && dtype.kind() == b'u' {
        let largest: u64 = obj.call_method0("max")?.extract()?;
        if i64::try_from(largest).is_err() {
            let message = format!("indices: index {largest} is out of range for {n} particles");
            return Err(ParticleIndexError::new_err((message, "indices", i64::MAX)));
        }
    }
    let int64 = obj.call_method1("astype", ("int64",))?;
    Ok(int64
        .extract::<PyReadonlyArray1<'_, i64>>()?
        .as_array()
        .to_vec())
}

fn read_only_1d<T: numpy::Element>(
    array: Bound<'_, PyArray1<T>>,
) -> PyResult<Bound<'_, PyArray1<T>>> {
    read_only(array.as_any())?;
    Ok(array)
}
