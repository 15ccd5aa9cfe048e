//! `rustcloth._core.Simulation`: the solver's methods for Python. Every method converts its
//! arguments first (naming the parameter on bad input), then runs on the locked simulation
//! (shared.rs); stepping runs detached from the interpreter and checks for Ctrl-C between
//! steps. The documented public API is `rustcloth.Simulation`, which wraps this class.

use numpy::{PyArrayDescrMethods, PyReadonlyArray1, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::conv::{
    count_from_any, f64s_from_array, float_from_any, index_from_any, int_from_any, str_from_any,
    unvalidated_scene_from_dict, vec3_from_any, vec3s_from_array, Plain, Rows, SceneDict,
};
use super::errors::{type_error, value_error, IntoPyResult, ParticleIndexError};
use super::shared::{Held, Shared};
use super::state;
use crate::{Error, IntegratorKind, Simulation};

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

    /// Runs `call` on the simulation under its lock, once its argument converted, detached
    /// from the interpreter (other Python threads run meanwhile).
    pub(crate) fn call<A: Send, R: Send>(
        &self,
        py: Python<'_>,
        arg: PyResult<A>,
        call: impl FnOnce(&mut Simulation, A) -> crate::Result<R> + Send,
    ) -> PyResult<R> {
        let arg = arg?;
        self.with(py, |h| py.detach(|| call(&mut h.sim, arg)).py())
    }

    /// Runs a stepping call as [`Self::call`] runs one, asking Python between steps whether a
    /// signal (Ctrl-C) arrived: an interrupt comes back as the `KeyboardInterrupt` Python
    /// raised. The warning about an unconverged solve, when due, is given once the lock is
    /// released (a warning filter may call back).
    pub(crate) fn stepping<R: Send>(
        &self,
        py: Python<'_>,
        call: impl FnOnce(&mut Simulation, &mut dyn FnMut() -> bool) -> crate::Result<R> + Send,
    ) -> PyResult<R> {
        let (outcome, warning) = self.with(py, |held| {
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
            let outcome = match outcome {
                Err(Error::Interrupted { .. }) if signal.is_some() => Err(signal.unwrap()),
                other => other.py(),
            };
            Ok((outcome, not_converged_warning(held)))
        })?;
        if let Some(message) = warning {
            let message = std::ffi::CString::new(message).expect("no NUL in the message");
            let category = py.get_type::<pyo3::exceptions::PyRuntimeWarning>();
            PyErr::warn(py, category.as_any(), &message, 1)?;
        }
        outcome
    }

    /// A particle index, checked against the particles.
    pub(crate) fn index(&self, py: Python<'_>, index: &Bound<'_, PyAny>) -> PyResult<i64> {
        let n = self.with(py, |h| Ok(h.sim.grid().len()))?;
        index_from_any(index, "index", n)
    }

    /// Particle values for the setters, read for the particles there are.
    fn per_particle<T>(
        &self,
        py: Python<'_>,
        read: impl FnOnce(usize) -> PyResult<T>,
    ) -> PyResult<T> {
        read(self.with(py, |h| Ok(h.sim.grid().len()))?)
    }
}

/// `#[pymethods]` that return what `$read` reads under the lock, `|h| $read` with `h` the
/// [`Held`] simulation.
macro_rules! reads {
    ($($(#[$attr:meta])* fn $name:ident -> $ty:ty = |$h:ident| $read:expr;)*) => {
        #[pymethods]
        impl PySimulation {
            $($(#[$attr])* fn $name(&self, py: Python<'_>) -> PyResult<$ty> {
                self.with(py, |$h| Ok($read))
            })*
        }
    };
}
pub(super) use reads;

reads! {
    #[getter] fn positions -> Rows<f32> = |h| Rows::vec3s(h.sim.positions());
    #[getter] fn velocities -> Rows<f32> = |h| Rows::vec3s(h.sim.velocities());
    #[getter] fn normals -> Rows<f32> = |h| Rows::vec3s(h.sim.normals());
    #[getter] fn masses -> Rows<f32> = |h| Rows(h.sim.particles().mass.clone(), 0);
    #[getter] fn pinned -> Rows<bool> = |h| Rows(h.sim.particles().pinned.clone(), 0);
    #[getter] fn alive -> Rows<bool> = |h| Rows(h.sim.particles().alive.clone(), 0);
    #[getter] fn triangles -> Rows<u32> = |h| Rows(h.sim.triangles().as_flattened().to_vec(), 3);
    /// The drawn mesh's `(positions, normals)`, particles first, then the cut vertices.
    fn render_positions -> (Rows<f32>, Rows<f32>) = |h| {
        let (positions, normals) = h.sim.render_frame();
        (Rows::vec3s(positions), Rows::vec3s(normals))
    };
    /// The drawn mesh's `(triangles, uvs, sources)`: what changes only with the topology.
    fn render_topology -> (Rows<u32>, Rows<f32>, Rows<u32>) = |h| {
        let triangles = h.sim.render_triangles().as_flattened().to_vec();
        let (grid, cut) = (h.sim.grid(), h.sim.render_cut_vertices());
        let uvs = crate::render_mesh::uvs(grid, cut).as_flattened().to_vec();
        (Rows(triangles, 3), Rows(uvs, 2), Rows(crate::render_mesh::sources(grid, cut), 0))
    };
    /// The scene with the run-time settings as they are now.
    fn scene_dict -> SceneDict = |h| SceneDict(h.sim.scene().clone());
    #[getter] fn time -> f64 = |h| h.sim.time();
    #[getter] fn steps -> u64 = |h| h.sim.steps();
    #[getter] fn dt -> f64 = |h| h.sim.dt();
    #[getter] fn substeps -> u32 = |h| h.sim.scene().substeps;
    #[getter] fn integrator -> &'static str = |h| h.sim.scene().integrator.name();
    #[getter] fn effects -> Vec<&'static str> = |h| h.sim.effects();
    #[getter] fn topology_version -> u64 = |h| h.sim.topology_version();
    #[getter] fn state_version -> u64 = |h| h.sim.state_version();
    #[getter] fn nx -> usize = |h| h.sim.grid().nx;
    #[getter] fn ny -> usize = |h| h.sim.grid().ny;
    #[getter] fn num_particles -> usize = |h| h.sim.grid().len();
    /// `(kinetic, gravitational, elastic)` in J.
    fn energy -> (f64, f64, f64) = |h| {
        let e = h.sim.energy();
        (e.kinetic, e.gravitational, e.elastic)
    };
    fn spring_strain -> Rows<f32> = |h| Rows(h.sim.spring_strain(), 0);
    fn max_stretch -> f32 = |h| h.sim.max_stretch();
    /// `(passes, steps, total_seconds)` with `passes` a list of `(name, seconds, calls)`.
    fn profile -> (Vec<(&'static str, f64, u64)>, u64, f64) = |h| {
        let p = h.sim.profile();
        let passes = p.passes().iter().map(|p| (p.name, p.time.as_secs_f64(), p.calls));
        (passes.collect(), p.steps, p.total.as_secs_f64())
    };
    fn solver_stats -> Option<Plain<crate::integrators::SolverStats>> =
        |h| h.sim.solver_stats().map(Plain);
    fn watchdog_stats -> Plain<crate::stepper::WatchdogStats> = |h| Plain(h.sim.watchdog_stats());
    fn self_collision_stats -> Option<Plain<crate::self_collision::SelfCollisionStats>> =
        |h| h.sim.self_collision_stats().map(Plain);
    /// The largest stable `dt` (s) now, or None when any `dt` is.
    fn stable_dt -> Option<f64> = |h| h.sim.stable_dt();
    fn memory_bytes -> usize = |h| h.sim.memory_bytes();
}

#[pymethods]
impl PySimulation {
    #[new]
    fn new(scene: &Bound<'_, PyAny>) -> PyResult<Self> {
        Ok(PySimulation {
            // Validated once, by `Simulation::new`.
            shared: Shared::new(Simulation::new(unvalidated_scene_from_dict(scene)?).py()?),
        })
    }

    fn step(&self, py: Python<'_>, n: &Bound<'_, PyAny>) -> PyResult<()> {
        let n = count_from_any(n, "n")?;
        self.stepping(py, |sim, stop| sim.step_interruptible(n, stop))
    }

    fn advance(&self, py: Python<'_>, seconds: &Bound<'_, PyAny>) -> PyResult<u64> {
        let seconds = float_from_any(seconds, "seconds")?;
        self.stepping(py, |sim, stop| sim.advance_interruptible(seconds, stop))
    }

    fn set_positions(&self, py: Python<'_>, positions: &Bound<'_, PyAny>) -> PyResult<()> {
        let values = self.per_particle(py, |n| vec3s_from_array(positions, "positions", n));
        self.call(py, values, |sim, v| sim.set_positions(&v))
    }

    fn set_velocities(&self, py: Python<'_>, velocities: &Bound<'_, PyAny>) -> PyResult<()> {
        let values = self.per_particle(py, |n| vec3s_from_array(velocities, "velocities", n));
        self.call(py, values, |sim, v| sim.set_velocities(&v))
    }

    fn set_masses(&self, py: Python<'_>, masses: &Bound<'_, PyAny>) -> PyResult<()> {
        let values = self.per_particle(py, |n| f64s_from_array(masses, "masses", &[n]));
        self.call(py, values, |sim, v| sim.set_masses(&v))
    }

    #[pyo3(signature = (index, target = None))]
    fn pin(
        &self,
        py: Python<'_>,
        index: &Bound<'_, PyAny>,
        target: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let index = self.index(py, index)?;
        let target = target.filter(|t| !t.is_none());
        let target = target.map(|t| vec3_from_any(t, "target")).transpose();
        self.call(py, target, |sim, target| sim.pin(index, target))
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
        let indices = self.per_particle(py, |n| indices_from_array(indices, n))?;
        let targets = targets.filter(|t| !t.is_none());
        let targets = targets.map(|t| vec3s_from_array(t, "targets", indices.len()));
        self.call(py, targets.transpose(), |sim, t| {
            sim.pin_many(&indices, t.as_ref())
        })
    }

    fn unpin(&self, py: Python<'_>, index: &Bound<'_, PyAny>) -> PyResult<()> {
        self.call(py, self.index(py, index), Simulation::unpin)
    }

    fn cut(&self, py: Python<'_>, index: &Bound<'_, PyAny>) -> PyResult<()> {
        self.call(py, self.index(py, index), Simulation::cut)
    }

    fn reset(&self, py: Python<'_>) -> PyResult<()> {
        self.with(py, |h| {
            h.warned_not_converged = false;
            h.sim.reset().py()
        })
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

    /// The whole state as a dict of numpy arrays and plain values (see `set_state`).
    fn get_state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        state::to_dict(py, &self.with(py, |h| Ok(h.sim.snapshot()))?)
    }

    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyDict>,))> {
        let constructor = py.import("rustcloth._core")?;
        let constructor = constructor.getattr("simulation_from_state")?;
        Ok((constructor, (self.get_state(py)?,)))
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

    #[setter]
    fn set_dt(&self, py: Python<'_>, dt: &Bound<'_, PyAny>) -> PyResult<()> {
        self.call(py, float_from_any(dt, "dt"), Simulation::set_dt)
    }

    #[setter]
    fn set_substeps(&self, py: Python<'_>, substeps: &Bound<'_, PyAny>) -> PyResult<()> {
        self.call(
            py,
            int_from_any(substeps, "substeps"),
            Simulation::set_substeps,
        )
    }

    #[setter]
    fn set_integrator(&self, py: Python<'_>, name: &Bound<'_, PyAny>) -> PyResult<()> {
        let name = str_from_any(name, "integrator");
        self.call(py, name, |sim, name| sim.set_integrator(&name))
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
