//! Picking, dragging and cutting (src/interaction.rs) for Python. Queries run detached from the
//! interpreter: the first one after the cloth moved refits a tree over every particle.

use numpy::ndarray::ArrayView3;
use numpy::PyReadonlyArray3;
use pyo3::prelude::*;

use super::conv::{direction_from_any, float_from_any, str_from_any, vec3_from_any, Plain};
use super::errors::{type_error, value_error, IntoPyResult};
use super::simulation::{reads, stepping, PySimulation};
use crate::picking::PickStrategy;
use crate::Simulation;

/// `(origin, direction)` of ray `k` of a stroke: any pair of length-3 sequences, or a
/// `(2, 3)` array.
fn ray_from_any(item: &Bound<'_, PyAny>, k: usize) -> PyResult<(glam::Vec3, glam::Vec3)> {
    let name = format!("rays[{k}]");
    let len = item.len().map_err(|_| {
        type_error(
            &name,
            format!("must be an (origin, direction) pair, got {item}"),
        )
    })?;
    if len != 2 {
        return Err(value_error(
            &name,
            format!("must be an (origin, direction) pair, got {len} items"),
        ));
    }
    let origin = vec3_from_any(&item.get_item(0)?, &format!("{name}.origin"))?;
    let direction = direction_from_any(&item.get_item(1)?, &format!("{name}.direction"))?;
    Ok((origin, direction))
}

/// `(triangle_index, distance, (w0, w1, w2))`.
type TriangleHit = (usize, f32, (f32, f32, f32));

#[pymethods]
impl PySimulation {
    /// Picks the live particle the ray ``origin + t * direction`` (``t >= 0``) hits first:
    /// ``(index, distance)`` or ``None``.
    fn pick(
        &self,
        py: Python<'_>,
        origin: &Bound<'_, PyAny>,
        direction: &Bound<'_, PyAny>,
    ) -> PyResult<Option<(usize, f32)>> {
        let origin = vec3_from_any(origin, "origin")?;
        let direction = direction_from_any(direction, "direction")?;
        self.with(py, |h| py.detach(|| h.sim.pick(origin, direction)).py())
    }

    /// Picks the live triangle (a row of ``triangles``) the ray hits first:
    /// ``(triangle_index, distance, (w0, w1, w2))`` or ``None``.
    fn pick_triangle(
        &self,
        py: Python<'_>,
        origin: &Bound<'_, PyAny>,
        direction: &Bound<'_, PyAny>,
    ) -> PyResult<Option<TriangleHit>> {
        let origin = vec3_from_any(origin, "origin")?;
        let direction = direction_from_any(direction, "direction")?;
        let hit = self.with(py, |h| {
            py.detach(|| h.sim.pick_triangle(origin, direction)).py()
        })?;
        Ok(hit.map(|(t, d, [a, b, c])| (t, d, (a, b, c))))
    }

    #[setter]
    fn set_pick_radius(&self, py: Python<'_>, radius: &Bound<'_, PyAny>) -> PyResult<()> {
        self.call(
            py,
            float_from_any(radius, "pick_radius"),
            Simulation::set_pick_radius,
        )
    }

    #[setter]
    fn set_pick_strategy(&self, py: Python<'_>, strategy: &Bound<'_, PyAny>) -> PyResult<()> {
        let strategy = PickStrategy::by_name(&str_from_any(strategy, "pick_strategy")?).py()?;
        self.with(py, |h| {
            h.sim.set_pick_strategy(strategy);
            Ok(())
        })
    }

    /// Grabs particle ``index``: a kinematic pin at its current position that ``drag_to``
    /// moves.
    fn grab(&self, py: Python<'_>, index: &Bound<'_, PyAny>) -> PyResult<()> {
        self.call(py, self.index(py, index), Simulation::grab)
    }

    /// Moves the grabbed particle's target to ``target`` (3 numbers, m).
    fn drag_to(&self, py: Python<'_>, target: &Bound<'_, PyAny>) -> PyResult<()> {
        self.call(py, vec3_from_any(target, "target"), Simulation::drag_to)
    }

    /// Lets go of the grabbed particle, restoring the pin state it had before the grab.
    fn release(&self, py: Python<'_>) -> PyResult<()> {
        self.with(py, |h| {
            h.sim.release();
            Ok(())
        })
    }

    /// Cuts the particle ``pick(origin, direction)`` finds; returns its index or ``None``.
    fn cut_ray(
        &self,
        py: Python<'_>,
        origin: &Bound<'_, PyAny>,
        direction: &Bound<'_, PyAny>,
    ) -> PyResult<Option<usize>> {
        let origin = vec3_from_any(origin, "origin")?;
        let direction = direction_from_any(direction, "direction")?;
        self.with(py, |h| py.detach(|| h.sim.cut_ray(origin, direction)).py())
    }

    /// Cuts what a stroke of ``(origin, direction)`` rays passes over; returns the indices.
    fn cut_stroke(&self, py: Python<'_>, rays: &Bound<'_, PyAny>) -> PyResult<Vec<usize>> {
        let rays = rays_from_any(rays)?;
        self.with(py, |h| py.detach(|| h.sim.cut_stroke(&rays)).py())
    }

    /// Severs the springs the surface swept between consecutive rays crosses; returns how
    /// many. No particle is removed.
    /// Ctrl-C interrupts it, and then nothing is severed.
    fn sever_stroke(&self, py: Python<'_>, rays: &Bound<'_, PyAny>) -> PyResult<usize> {
        let rays = rays_from_any(rays)?;
        self.with(py, |h| {
            stepping(py, h, |sim, stop| sim.sever_stroke_with(&rays, stop)).0
        })
    }

    /// Connected pieces of the cloth (live particles joined by live springs).
    fn pieces(&self, py: Python<'_>) -> PyResult<usize> {
        self.with(py, |h| Ok(py.detach(|| h.sim.pieces())))
    }
}

reads! {
    /// Half-size in m of each particle's pick box; defaults to half the smaller grid spacing.
    #[getter] fn pick_radius -> f32 = |h| h.sim.pick_radius();
    /// ``"auto"``, ``"bvh"`` or ``"scan"``: how queries find what a ray hits.
    #[getter] fn pick_strategy -> &'static str = |h| h.sim.pick_strategy().name();
    /// The index of the grabbed particle, or ``None``.
    fn grabbed -> Option<usize> = |h| h.sim.grabbed();
    /// Work done on the picking trees so far.
    fn bvh_stats -> Plain<crate::picking::BvhStats> = |h| Plain(h.sim.bvh_stats());
}

/// A stroke: a sequence of ``(origin, direction)`` pairs, each named ``rays[k]`` in errors.
fn rays_from_any(rays: &Bound<'_, PyAny>) -> PyResult<Vec<(glam::Vec3, glam::Vec3)>> {
    if rays.is_instance_of::<pyo3::types::PyString>()
        || rays.is_instance_of::<pyo3::types::PyBytes>()
    {
        return Err(type_error(
            "rays",
            format!("must be a sequence of (origin, direction) pairs, got {rays}"),
        ));
    }
    // An (M, 2, 3) float array, read in one pass without the interpreter: a stroke of
    // millions of rays took seconds item by item, under the interpreter's lock, where Ctrl-C
    // could not reach it. Values are checked by the core, naming the ray.
    if let Ok(array) = rays.extract::<PyReadonlyArray3<'_, f64>>() {
        if let Some(rays) = rays_from_array(array.as_array()) {
            return Ok(rays);
        }
    }
    if let Ok(array) = rays.extract::<PyReadonlyArray3<'_, f32>>() {
        if let Some(rays) = rays_from_array(array.as_array()) {
            return Ok(rays);
        }
    }
    let items = rays.try_iter().map_err(|_| {
        type_error(
            "rays",
            format!("must be a sequence of (origin, direction) pairs, got {rays}"),
        )
    })?;
    items
        .enumerate()
        .map(|(k, item)| ray_from_any(&item?, k))
        .collect()
}

/// The `(origin, direction)` pairs of an `(M, 2, 3)` float32 or float64 array (read in f64, so
/// that a float64 value beyond float32's range becomes infinite and is refused by name); `None`
/// for any other shape, which the item-by-item reading names.
fn rays_from_array<T: Copy + Into<f64>>(
    array: ArrayView3<'_, T>,
) -> Option<Vec<(glam::Vec3, glam::Vec3)>> {
    if array.shape()[1..] != [2, 3] {
        return None;
    }
    let rays = array
        .outer_iter()
        .map(|ray| {
            let v = |i: usize| {
                let c = |j: usize| ray[[i, j]].into();
                glam::DVec3::new(c(0), c(1), c(2)).as_vec3()
            };
            (v(0), v(1))
        })
        .collect();
    Some(rays)
}
