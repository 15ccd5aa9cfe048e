//! `rustcloth._core.Simulation`: the solver's methods for Python. Every method takes typed
//! arguments (checked and named by `rustcloth._args`), then runs on the locked simulation
//! (shared.rs); stepping runs detached from the interpreter and checks for Ctrl-C between
//! steps. The documented public API is `rustcloth.Simulation`, which wraps this class.

use numpy::PyReadonlyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::conv::{
    self_collision_from_dict, unvalidated_scene_from_dict, Floats, Plain, Rows, SceneDict,
};
use super::errors::IntoPyResult;
use super::shared::{Held, Shared};
use super::state;
use crate::{Error, Simulation};
use glam::Vec3;

/// The solver. See `rustcloth.Simulation` for the documented API.
#[pyclass(name = "Simulation", module = "rustcloth._core", frozen)]
pub(crate) struct PySimulation {
    pub(crate) shared: Shared,
}

/// The warning to give once per simulation when an implicit solver stopped at its cap.
fn not_converged_warning(held: &mut Held) -> Option<String> {
    let message = held
        .sim
        .solver_stats()?
        .not_converged_message(held.sim.scene());
    let warn = message.is_some() && !held.warned_not_converged;
    held.warned_not_converged |= warn;
    message.filter(|_| warn)
}

/// A simulation continuing a state from `Simulation.get_state()` (what unpickling calls).
#[pyfunction]
pub(crate) fn simulation_from_state(state: &Bound<'_, PyDict>) -> PyResult<PySimulation> {
    Ok(PySimulation {
        shared: Shared::new(state::restore(state)?),
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

    /// Returns what `read` reads from the simulation under its lock.
    pub(crate) fn read<R>(&self, py: Python<'_>, read: impl FnOnce(&mut Held) -> R) -> PyResult<R> {
        self.with(py, |h| Ok(read(h)))
    }

    /// Runs `call` on the simulation under its lock, detached from the interpreter (other
    /// Python threads run meanwhile).
    pub(crate) fn call<R: Send>(
        &self,
        py: Python<'_>,
        call: impl FnOnce(&mut Simulation) -> crate::Result<R> + Send,
    ) -> PyResult<R> {
        self.with(py, |h| py.detach(|| call(&mut h.sim)).py())
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
}

/// `#[pymethods]`, each `fn name(args) -> T = how |..| body;` with its arguments as pyo3
/// extracts them and `body` run as the [`PySimulation`] method `how` runs it, under the lock:
/// `read` (`body` the value, attached to the interpreter), `with` (`body` a `PyResult`,
/// attached), `call` (`body` a core `Result` on the simulation, detached) or `stepping` (as
/// `call`, checking for Ctrl-C).
macro_rules! methods {
    ($($(#[$attr:meta])* fn $name:ident($($arg:ident: $ty:ty),*) -> $ret:ty = $how:ident |$($x:ident),*| $body:expr;)*) => {
        #[pymethods]
        impl PySimulation {
            $($(#[$attr])* fn $name(&self, py: Python<'_>, $($arg: $ty),*) -> PyResult<$ret> {
                self.$how(py, |$($x),*| $body)
            })*
        }
    };
}
pub(super) use methods;

methods! {
    fn step(n: u64) -> () = stepping |sim, stop| sim.step_interruptible(n, stop);
    fn advance(seconds: f64) -> u64 = stepping |sim, stop| sim.advance_interruptible(seconds, stop);
    #[pyo3(signature = (index, target = None))]
    fn pin(index: i64, target: Option<[f32; 3]>) -> () =
        call |sim| sim.pin(index, target.map(Vec3::from));
    fn unpin(index: i64) -> () = call |sim| sim.unpin(index);
    fn cut(index: i64) -> () = call |sim| sim.cut(index);
    #[setter] fn set_dt(dt: f64) -> () = call |sim| sim.set_dt(dt);
    #[setter] fn set_substeps(substeps: i64) -> () = call |sim| sim.set_substeps(substeps);
    #[setter] fn set_integrator(name: &str) -> () = call |sim| sim.set_integrator(name);
    /// Self-collision on with the settings of a `[self_collision]` dict, or off with None.
    fn set_self_collision(settings: Option<&Bound<'_, PyAny>>) -> () = with |h| {
        let spec = settings.map(self_collision_from_dict).transpose()?;
        h.sim.set_self_collision(spec).py()
    };
    fn set_positions(positions: Floats<'_>) -> () =
        with |h| h.sim.set_positions(&positions.vec3s()?).py();
    fn set_velocities(velocities: Floats<'_>) -> () =
        with |h| h.sim.set_velocities(&velocities.vec3s()?).py();
    fn set_masses(masses: Floats<'_>) -> () = with |h| h.sim.set_masses(&masses.rows(&[])?).py();
    /// Pins many particles in one call: `targets` None or one row per index.
    #[pyo3(signature = (indices, targets = None))]
    fn pin_many(indices: PyReadonlyArray1<'_, i64>, targets: Option<Floats<'_>>) -> () =
        with |h| {
            let targets = targets.map(|t| t.vec3s()).transpose()?;
            h.sim.pin_many(&indices.as_array().to_vec(), targets.as_ref()).py()
        };
    fn reset() -> () = with |h| {
        h.warned_not_converged = false;
        h.sim.reset().py()
    };
    /// Makes the next force evaluation panic inside its parallel sweep: a stand-in for a bug,
    /// for the tests of the panic guards.
    fn _inject_panic() -> () = read |h| h.sim.inject_panic();
    /// Panics right here, under the lock: the binding's last-resort guard, for the tests.
    fn _panic_now() -> () = read |_h| panic!("injected panic outside a step");
    #[getter] fn positions() -> Rows<f32> = read |h| Rows::vec3s(h.sim.positions());
    #[getter] fn velocities() -> Rows<f32> = read |h| Rows::vec3s(h.sim.velocities());
    #[getter] fn normals() -> Rows<f32> = read |h| Rows::vec3s(h.sim.normals());
    #[getter] fn masses() -> Rows<f32> = read |h| Rows(h.sim.particles().mass.clone(), 0);
    #[getter] fn pinned() -> Rows<bool> = read |h| Rows(h.sim.particles().pinned.clone(), 0);
    #[getter] fn alive() -> Rows<bool> = read |h| Rows(h.sim.particles().alive.clone(), 0);
    #[getter] fn triangles() -> Rows<u32> =
        read |h| Rows(h.sim.triangles().as_flattened().to_vec(), 3);
    /// The drawn mesh's `(positions, normals)`, particles first, then the cut vertices.
    fn render_positions() -> (Rows<f32>, Rows<f32>) = read |h| {
        let (positions, normals) = h.sim.render_frame();
        (Rows::vec3s(positions), Rows::vec3s(normals))
    };
    /// The drawn mesh's `(triangles, uvs, sources)`: what changes only with the topology.
    fn render_topology() -> (Rows<u32>, Rows<f32>, Rows<u32>) = read |h| {
        let triangles = h.sim.render_triangles().as_flattened().to_vec();
        let grid = h.sim.grid();
        let cut = h.sim.render_cut_vertices().to_vec();
        let uvs = match h.sim.model().mesh() {
            Some(mesh) => crate::render_mesh::mesh_uvs(mesh, &cut),
            None => crate::render_mesh::uvs(grid, &cut),
        };
        let uvs = uvs.as_flattened().to_vec();
        (Rows(triangles, 3), Rows(uvs, 2), Rows(crate::render_mesh::sources(grid, &cut), 0))
    };
    /// The scene with the run-time settings as they are now.
    fn scene_dict() -> SceneDict = read |h| SceneDict(h.sim.scene().clone());
    #[getter] fn time() -> f64 = read |h| h.sim.time();
    #[getter] fn steps() -> u64 = read |h| h.sim.steps();
    #[getter] fn dt() -> f64 = read |h| h.sim.dt();
    #[getter] fn substeps() -> u32 = read |h| h.sim.scene().substeps;
    #[getter] fn integrator() -> &'static str = read |h| h.sim.scene().integrator.name();
    #[getter] fn effects() -> Vec<&'static str> = read |h| h.sim.effects();
    #[getter] fn topology_version() -> u64 = read |h| h.sim.topology_version();
    #[getter] fn state_version() -> u64 = read |h| h.sim.state_version();
    #[getter] fn nx() -> usize = read |h| h.sim.grid().nx;
    #[getter] fn ny() -> usize = read |h| h.sim.grid().ny;
    #[getter] fn num_particles() -> usize = read |h| h.sim.grid().len();
    /// `(kinetic, gravitational, elastic)` in J.
    fn energy() -> (f64, f64, f64) = read |h| {
        let e = h.sim.energy();
        (e.kinetic, e.gravitational, e.elastic)
    };
    fn spring_strain() -> Rows<f32> = read |h| Rows(h.sim.spring_strain(), 0);
    fn max_stretch() -> f32 = read |h| h.sim.max_stretch();
    /// `(passes, steps, total_seconds)` with `passes` a list of `(name, seconds, calls)`.
    fn profile() -> (Vec<(&'static str, f64, u64)>, u64, f64) = read |h| {
        let p = h.sim.profile();
        let passes = p.passes().iter().map(|p| (p.name, p.time.as_secs_f64(), p.calls));
        (passes.collect(), p.steps, p.total.as_secs_f64())
    };
    fn solver_stats() -> Option<Plain<crate::integrators::SolverStats>> =
        read |h| h.sim.solver_stats().map(Plain);
    fn watchdog_stats() -> Plain<crate::stepper::WatchdogStats> =
        read |h| Plain(h.sim.watchdog_stats());
    fn self_collision_stats() -> Option<Plain<crate::self_collision::SelfCollisionStats>> =
        read |h| h.sim.self_collision_stats().map(Plain);
    fn seam_gap() -> Option<f32> = read |h| h.sim.seam_gap();
    /// The largest stable `dt` (s) now, or None when any `dt` is.
    fn stable_dt() -> Option<f64> = read |h| h.sim.stable_dt();
    fn memory_bytes() -> usize = read |h| h.sim.memory_bytes();
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

    /// Replaces the whole simulation (scene included) by a state from `get_state`.
    fn set_state(&self, py: Python<'_>, state: &Bound<'_, PyDict>) -> PyResult<()> {
        let restored = state::restore(state)?;
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
}
