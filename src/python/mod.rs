//! The Python extension module `rustcloth._core`: the one place that knows about Python.
//!
//! The methods take typed arguments (`f64`, `u64`, `i64`, `[f32; 3]`, strings, float32 or
//! float64 numpy arrays read without a copy), which pyo3 extracts. The strict readers that
//! refuse bools, bytes and complex numbers and name the bad parameter live in Python
//! (`python/rustcloth/_args.py`), where `rustcloth.Simulation` calls them before every method
//! here: this module is private, and bad input to it raises a plain `TypeError` or
//! `ValueError` from pyo3, never a crash or a panic. Values (finite, in range) are checked by
//! the core, which names them. Scene dicts and saved states, which the core reads itself, are
//! checked by `_args` too (`scene_data`, `state_array`, `state_bools`), called from here.
//!
//! Scene dicts are converted in conv.rs, errors in errors.rs, the sharing of a simulation
//! between Python threads (and the panic guard) in shared.rs, the saved state in state.rs, the
//! simulation's methods in simulation.rs, interaction.rs and colliders.rs. The public Python
//! API in `python/rustcloth/` wraps these classes.

mod colliders;
mod conv;
mod errors;
mod interaction;
mod shared;
mod simulation;
mod state;

use pyo3::pymodule;

#[pymodule]
mod _core {
    use pyo3::prelude::*;

    use super::conv::{self, scene_from_dict, SceneDict};
    use super::errors::IntoPyResult;
    #[pymodule_export]
    use super::simulation::{simulation_from_state, PySimulation};
    use crate::integrators::IntegratorKind;
    use crate::scene::Scene;

    /// Validates a scene dict and returns it with every default filled in.
    #[pyfunction]
    fn normalize_scene(scene: &Bound<'_, PyAny>) -> PyResult<SceneDict> {
        Ok(SceneDict(scene_from_dict(scene)?))
    }

    /// Parses and validates a TOML scene document into a full scene dict.
    #[pyfunction]
    fn scene_from_toml(text: &str) -> PyResult<SceneDict> {
        Ok(SceneDict(Scene::from_toml_str(text).py()?))
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
        let limits = IntegratorKind::ALL
            .iter()
            .map(|&kind| (kind.name(), scene.stable_dt(kind)))
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
    fn builtin_scene(name: &str) -> PyResult<SceneDict> {
        Ok(SceneDict(Scene::builtin(name).py()?))
    }

    /// The vector instruction set the solver's loops run with in this process (`baseline`,
    /// `avx2`, `avx512`): the widest the CPU has, or what `RUSTCLOTH_SIMD` asked for.
    #[pyfunction]
    fn instruction_set() -> &'static str {
        crate::simd::isa().name()
    }

    /// The threads of the pool the solver runs on (`RAYON_NUM_THREADS`, or one per core).
    #[pyfunction]
    fn thread_count() -> usize {
        rayon::current_num_threads()
    }

    /// How many scenes this thread has validated (for the tests that count validations).
    #[pyfunction]
    fn _scene_validations() -> u64 {
        crate::scene::validations()
    }

    #[pymodule_init]
    fn init(m: &Bound<'_, PyModule>) -> PyResult<()> {
        m.add("INTEGRATORS", IntegratorKind::names())?;
        m.add("MAX_NESTING", conv::MAX_NESTING)
    }
}
