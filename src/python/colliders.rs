//! The scene's `[[colliders]]` for Python: posing them between steps and reading their poses,
//! what a renderer needs to draw them where the cloth sees them.

use numpy::PyArray2;
use pyo3::prelude::*;

use super::conv::{floats_from_any, index_from_any};
use super::errors::IntoPyResult;
use super::simulation::PySimulation;

#[pymethods]
impl PySimulation {
    /// Puts collider ``index`` at ``position`` (m) with ``rotation`` (a unit quaternion
    /// ``(x, y, z, w)``) by the end of the next step; see ``rustcloth.Simulation``.
    fn set_collider_pose(
        &self,
        py: Python<'_>,
        index: &Bound<'_, PyAny>,
        position: &Bound<'_, PyAny>,
        rotation: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let count = self.with(py, |h| Ok(h.sim.scene().colliders.len()))?;
        let index = index_from_any(index, "index", count)?;
        let position = floats_from_any::<3>(position, "position")?;
        let rotation = floats_from_any::<4>(rotation, "rotation")?;
        self.with(py, |h| {
            h.sim.set_collider_pose(index, position, rotation).py()
        })
    }

    /// ``(positions, rotations)``: each collider's position now, ``(K, 3)`` float64 in m, and
    /// orientation, ``(K, 4)`` float64 unit quaternions ``(x, y, z, w)``.
    #[allow(clippy::type_complexity)]
    fn collider_poses<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>)> {
        let poses = self.with(py, |h| Ok(h.sim.collider_poses()))?;
        let positions: Vec<Vec<f64>> = poses
            .iter()
            .map(|p| p.position.to_array().to_vec())
            .collect();
        let rotations: Vec<Vec<f64>> = poses
            .iter()
            .map(|p| p.rotation.to_array().to_vec())
            .collect();
        // `from_vec2` cannot tell the width of no rows.
        let array = |rows: Vec<Vec<f64>>, width: usize| -> PyResult<Bound<'py, PyArray2<f64>>> {
            if rows.is_empty() {
                return Ok(PyArray2::zeros(py, [0, width], false));
            }
            Ok(PyArray2::from_vec2(py, &rows)?)
        };
        Ok((array(positions, 3)?, array(rotations, 4)?))
    }
}
