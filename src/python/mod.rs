//! The Python extension module `rustcloth._core`: the one place that knows about Python.
//!
//! It converts arguments (conv.rs), maps errors (errors.rs) and releases the GIL while the
//! solver steps. The public Python API in `python/rustcloth/` wraps these classes.

mod conv;
mod errors;
mod interaction;

use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::scene::{Scene, INTEGRATORS};
use crate::Simulation;
use conv::{
    f64s_from_array, from_toml, index_from_any, to_toml, vec3_from_any, vec3s_from_array,
    vec3s_to_array,
};
use errors::{value_error, IntoPyResult};

fn scene_from_dict(obj: &Bound<'_, PyAny>) -> PyResult<Scene> {
    Scene::from_toml_value(to_toml(obj, "")?).py()
}

fn scene_to_dict<'py>(py: Python<'py>, scene: &Scene) -> PyResult<Bound<'py, PyAny>> {
    let value = toml::Value::try_from(scene).expect("a scene always serialises");
    let dict = from_toml(py, &value)?;
    // TOML has no null: spell out absent optional keys as None, as users write them.
    let dict = dict.cast_into::<PyDict>()?;
    for key in ["floor", "strain_limit"] {
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

/// Validates a scene dict and returns it with every default filled in.
#[pyfunction]
fn normalize_scene<'py>(py: Python<'py>, scene: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    let scene = scene_from_dict(scene)?;
    scene_to_dict(py, &scene)
}

/// Parses and validates a TOML scene document into a full scene dict.
#[pyfunction]
fn scene_from_toml<'py>(py: Python<'py>, text: &str) -> PyResult<Bound<'py, PyAny>> {
    scene_to_dict(py, &Scene::from_toml_str(text).py()?)
}

/// A scene dict as a TOML document.
#[pyfunction]
fn scene_to_toml(scene: &Bound<'_, PyAny>) -> PyResult<String> {
    Ok(scene_from_dict(scene)?.to_toml_string())
}

/// `(integrator, largest stable dt)` for every integrator.
type StableDts = Vec<(&'static str, Option<f64>)>;

/// Every integrator's largest stable `dt` for a scene dict (None: any `dt`), and the angular
/// frequency (rad/s) of the cloth's stiffest mode.
#[pyfunction]
fn scene_stability(scene: &Bound<'_, PyAny>) -> PyResult<(StableDts, f64)> {
    let scene = scene_from_dict(scene)?;
    let limits = crate::scene::INTEGRATORS
        .iter()
        .map(|&name| (name, scene.stable_dt(name)))
        .collect();
    Ok((limits, scene.max_frequency()))
}

/// Names of the built-in scenes.
#[pyfunction]
fn builtin_scenes() -> Vec<&'static str> {
    Scene::builtin_names()
}

/// The built-in scene `name` as a dict.
#[pyfunction]
fn builtin_scene<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
    scene_to_dict(py, &Scene::builtin(name).py()?)
}

/// The solver. See `rustcloth.Simulation` for the documented API.
#[pyclass(name = "Simulation", module = "rustcloth._core", subclass)]
pub(crate) struct PySimulation {
    pub(crate) inner: Simulation,
    /// Whether the one warning about an unconverged linear solve was given.
    warned_not_converged: bool,
}

impl PySimulation {
    /// Warns once per simulation when the implicit solver stopped at its iteration cap.
    fn warn_if_not_converged(&mut self, py: Python<'_>) -> PyResult<()> {
        let Some(stats) = self.inner.solver_stats() else {
            return Ok(());
        };
        if stats.not_converged > 0 && !self.warned_not_converged {
            self.warned_not_converged = true;
            let scene = self.inner.scene();
            let (what, cap, tolerance, remedy) = if scene.integrator == "projective_dynamics" {
                (
                    "the local-global iterations stopped at pd_iterations",
                    scene.pd_iterations,
                    ("relative gradient", "pd_tolerance", scene.pd_tolerance),
                    "the last iterate. Raise pd_iterations, loosen pd_tolerance",
                )
            } else {
                (
                    "the conjugate gradient stopped at cg_max_iterations",
                    scene.cg_max_iterations,
                    ("relative residual", "cg_tolerance", scene.cg_tolerance),
                    "the partial solution. Raise cg_max_iterations, loosen cg_tolerance",
                )
            };
            let message = format!(
                "{}: {what} = {cap} with {} up to {:.2e} > {} = {:.0e} ({} of {} solves so far); \
                 the step was taken with {remedy} or reduce dt. profile() counts these.",
                scene.integrator,
                tolerance.0,
                stats.worst_residual,
                tolerance.1,
                tolerance.2,
                stats.not_converged,
                stats.solves,
            );
            let message = std::ffi::CString::new(message).expect("no NUL in the message");
            let category = py.get_type::<pyo3::exceptions::PyRuntimeWarning>();
            PyErr::warn(py, category.as_any(), &message, 1)?;
        }
        Ok(())
    }
}

#[pymethods]
impl PySimulation {
    #[new]
    fn new(scene: &Bound<'_, PyAny>) -> PyResult<Self> {
        let scene = scene_from_dict(scene)?;
        Ok(PySimulation {
            inner: Simulation::new(scene).py()?,
            warned_not_converged: false,
        })
    }

    fn step(&mut self, py: Python<'_>, n: i64) -> PyResult<()> {
        if n < 0 {
            return Err(value_error(
                "n",
                format!("must be an integer >= 0, got {n}"),
            ));
        }
        let sim = &mut self.inner;
        let outcome = py.detach(|| sim.step(n as u64)).py();
        self.warn_if_not_converged(py)?;
        outcome
    }

    fn advance(&mut self, py: Python<'_>, seconds: f64) -> PyResult<u64> {
        let sim = &mut self.inner;
        let outcome = py.detach(|| sim.advance(seconds)).py();
        self.warn_if_not_converged(py)?;
        outcome
    }

    /// Statistics of the implicit solver as a dict (`solves`, `iterations`, `last_iterations`,
    /// `last_residual`, `not_converged`, `worst_residual`, `most_iterations`,
    /// `factorizations`, `setup_seconds`, `solve_seconds`), or None for integrators that solve
    /// nothing.
    fn solver_stats<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(stats) = self.inner.solver_stats() else {
            return Ok(None);
        };
        let dict = PyDict::new(py);
        dict.set_item("solves", stats.solves)?;
        dict.set_item("iterations", stats.iterations)?;
        dict.set_item("last_iterations", stats.last_iterations)?;
        dict.set_item("last_residual", stats.last_residual)?;
        dict.set_item("not_converged", stats.not_converged)?;
        dict.set_item("worst_residual", stats.worst_residual)?;
        dict.set_item("most_iterations", stats.most_iterations)?;
        dict.set_item("factorizations", stats.factorizations)?;
        dict.set_item("setup_seconds", stats.setup_seconds)?;
        dict.set_item("solve_seconds", stats.solve_seconds)?;
        Ok(Some(dict))
    }

    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        vec3s_to_array(py, self.inner.positions())
    }

    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        vec3s_to_array(py, self.inner.velocities())
    }

    fn set_positions(&mut self, positions: &Bound<'_, PyAny>) -> PyResult<()> {
        let n = self.inner.grid().len();
        let values = vec3s_from_array(positions, "positions", n)?;
        self.inner.set_positions(&values).py()
    }

    fn set_masses(&mut self, masses: &Bound<'_, PyAny>) -> PyResult<()> {
        let n = self.inner.grid().len();
        let values = f64s_from_array(masses, "masses", n)?;
        self.inner.set_masses(&values).py()
    }

    fn set_velocities(&mut self, velocities: &Bound<'_, PyAny>) -> PyResult<()> {
        let n = self.inner.grid().len();
        let values = vec3s_from_array(velocities, "velocities", n)?;
        self.inner.set_velocities(&values).py()
    }

    #[getter]
    fn triangles<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<u32>>> {
        let tris = self.inner.triangles();
        let flat: Vec<u32> = tris.iter().flatten().copied().collect();
        PyArray1::from_vec(py, flat).reshape([tris.len(), 3])
    }

    #[getter]
    fn normals<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        vec3s_to_array(py, self.inner.normals())
    }

    #[pyo3(signature = (index, target=None))]
    fn pin(&mut self, index: &Bound<'_, PyAny>, target: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        let index = index_from_any(index, "index", self.inner.grid().len())?;
        let target = target.map(|t| vec3_from_any(t, "target")).transpose()?;
        self.inner.pin(index, target).py()
    }

    fn unpin(&mut self, index: &Bound<'_, PyAny>) -> PyResult<()> {
        let index = index_from_any(index, "index", self.inner.grid().len())?;
        self.inner.unpin(index).py()
    }

    fn cut(&mut self, index: &Bound<'_, PyAny>) -> PyResult<()> {
        let index = index_from_any(index, "index", self.inner.grid().len())?;
        self.inner.cut(index).py()
    }

    /// `(kinetic, gravitational, elastic)` in J.
    fn energy(&self) -> (f64, f64, f64) {
        let e = self.inner.energy();
        (e.kinetic, e.gravitational, e.elastic)
    }

    #[getter]
    fn time(&self) -> f64 {
        self.inner.time()
    }

    #[getter]
    fn steps(&self) -> u64 {
        self.inner.steps()
    }

    #[getter]
    fn dt(&self) -> f64 {
        self.inner.dt()
    }

    #[setter]
    fn set_dt(&mut self, dt: f64) -> PyResult<()> {
        self.inner.set_dt(dt).py()
    }

    #[getter]
    fn substeps(&self) -> u32 {
        self.inner.scene().substeps
    }

    #[setter]
    fn set_substeps(&mut self, substeps: i64) -> PyResult<()> {
        self.inner.set_substeps(substeps).py()
    }

    #[getter]
    fn integrator(&self) -> String {
        self.inner.scene().integrator.clone()
    }

    #[setter]
    fn set_integrator(&mut self, name: &str) -> PyResult<()> {
        self.inner.set_integrator(name).py()
    }

    #[getter]
    fn effects(&self) -> Vec<&'static str> {
        self.inner.effects()
    }

    /// `(passes, steps, total_seconds)` with `passes` a list of `(name, seconds, calls)`.
    fn profile<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyList>, u64, f64)> {
        let profile = self.inner.profile();
        let passes = PyList::empty(py);
        for p in profile.passes() {
            passes.append((p.name, p.time.as_secs_f64(), p.calls))?;
        }
        Ok((passes, profile.steps, profile.total.as_secs_f64()))
    }

    /// The largest `dt` (s) at which the current integrator is estimated to stay stable with
    /// the current substeps, or None when any `dt` is (implicit Euler, or no springs).
    fn stable_dt(&self) -> Option<f64> {
        self.inner.stable_dt()
    }

    /// What the watchdog caught and retried since the start.
    fn watchdog_stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let stats = self.inner.watchdog_stats();
        let out = PyDict::new(py);
        out.set_item("caught", stats.caught)?;
        out.set_item("retried", stats.retried)?;
        out.set_item("retry_substeps", stats.retry_substeps)?;
        out.set_item("max_substeps_used", stats.max_substeps_used)?;
        out.set_item("held_steps", stats.held_steps)?;
        Ok(out)
    }

    fn reset(&mut self) -> PyResult<()> {
        self.inner.reset().py()
    }

    #[getter]
    fn pinned<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        PyArray1::from_slice(py, &self.inner.particles().pinned)
    }

    #[getter]
    fn alive<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        PyArray1::from_slice(py, &self.inner.particles().alive)
    }

    #[getter]
    fn masses<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        PyArray1::from_slice(py, &self.inner.particles().mass)
    }

    fn spring_strain<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        PyArray1::from_vec(py, self.inner.spring_strain())
    }

    fn max_stretch(&self) -> f32 {
        self.inner.max_stretch()
    }

    fn memory_bytes(&self) -> usize {
        self.inner.memory_bytes()
    }

    #[getter]
    fn topology_version(&self) -> u64 {
        self.inner.topology_version()
    }

    #[getter]
    fn nx(&self) -> usize {
        self.inner.grid().nx
    }

    #[getter]
    fn ny(&self) -> usize {
        self.inner.grid().ny
    }

    #[getter]
    fn num_particles(&self) -> usize {
        self.inner.grid().len()
    }

    /// The scene with the run-time settings as they are now.
    fn scene_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        scene_to_dict(py, self.inner.scene())
    }
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySimulation>()?;
    m.add_function(wrap_pyfunction!(normalize_scene, m)?)?;
    m.add_function(wrap_pyfunction!(scene_from_toml, m)?)?;
    m.add_function(wrap_pyfunction!(scene_to_toml, m)?)?;
    m.add_function(wrap_pyfunction!(builtin_scenes, m)?)?;
    m.add_function(wrap_pyfunction!(builtin_scene, m)?)?;
    m.add_function(wrap_pyfunction!(scene_stability, m)?)?;
    m.add("INTEGRATORS", INTEGRATORS.to_vec())?;
    Ok(())
}
