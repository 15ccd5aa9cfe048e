//! Picking, dragging and cutting (src/interaction.rs) for Python. Queries run detached from the
//! interpreter: the first one after the cloth moved refits a tree over every particle.

use glam::Vec3;
use numpy::ndarray::ArrayView3;
use numpy::PyReadonlyArray3;
use pyo3::prelude::*;

use super::conv::{direction_from_any, float_from_any, str_from_any, vec3_from_any, Plain};
use super::errors::{type_error, value_error, IntoPyResult};
use super::simulation::{reads, PySimulation};
use crate::picking::PickStrategy;
use crate::Simulation;

/// A ray's `(origin, direction)` arguments.
fn ray(origin: &Bound<'_, PyAny>, direction: &Bound<'_, PyAny>) -> PyResult<(Vec3, Vec3)> {
    let origin = vec3_from_any(origin, "origin")?;
    Ok((origin, direction_from_any(direction, "direction")?))
}

/// `(triangle_index, distance, (w0, w1, w2))`.
type TriangleHit = (usize, f32, (f32, f32, f32));

#[pymethods]
impl PySimulation {
    fn pick(
        &self,
        py: Python<'_>,
        origin: &Bound<'_, PyAny>,
        direction: &Bound<'_, PyAny>,
    ) -> PyResult<Option<(usize, f32)>> {
        let hit = self.call(py, ray(origin, direction), |sim, (o, d)| sim.pick(o, d))?;
        Ok(hit.map(|h| (h.index, h.distance)))
    }

    fn pick_triangle(
        &self,
        py: Python<'_>,
        origin: &Bound<'_, PyAny>,
        direction: &Bound<'_, PyAny>,
    ) -> PyResult<Option<TriangleHit>> {
        let hit = self.call(py, ray(origin, direction), |sim, (o, d)| {
            sim.pick_triangle(o, d)
        })?;
        Ok(hit.map(|h| {
            let [a, b, c] = h.barycentric;
            (h.index, h.distance, (a, b, c))
        }))
    }

    fn cut_ray(
        &self,
        py: Python<'_>,
        origin: &Bound<'_, PyAny>,
        direction: &Bound<'_, PyAny>,
    ) -> PyResult<Option<usize>> {
        self.call(py, ray(origin, direction), |sim, (o, d)| sim.cut_ray(o, d))
    }

    #[setter]
    fn set_pick_radius(&self, py: Python<'_>, radius: &Bound<'_, PyAny>) -> PyResult<()> {
        let radius = float_from_any(radius, "pick_radius");
        self.call(py, radius, Simulation::set_pick_radius)
    }

    #[setter]
    fn set_grip_radius(&self, py: Python<'_>, radius: &Bound<'_, PyAny>) -> PyResult<()> {
        let radius = float_from_any(radius, "grip_radius");
        self.call(py, radius, Simulation::set_grip_radius)
    }

    #[setter]
    fn set_pick_strategy(&self, py: Python<'_>, strategy: &Bound<'_, PyAny>) -> PyResult<()> {
        let strategy = str_from_any(strategy, "pick_strategy")?;
        let strategy = PickStrategy::by_name(&strategy).py();
        self.call(py, strategy, |sim, strategy| {
            sim.set_pick_strategy(strategy);
            Ok(())
        })
    }

    fn grab(&self, py: Python<'_>, index: &Bound<'_, PyAny>) -> PyResult<()> {
        self.call(py, self.index(py, index), Simulation::grab)
    }

    fn drag_to(&self, py: Python<'_>, target: &Bound<'_, PyAny>) -> PyResult<()> {
        self.call(py, vec3_from_any(target, "target"), Simulation::drag_to)
    }

    fn release(&self, py: Python<'_>) -> PyResult<()> {
        self.call(py, Ok(()), |sim, ()| {
            sim.release();
            Ok(())
        })
    }

    fn cut_stroke(&self, py: Python<'_>, rays: &Bound<'_, PyAny>) -> PyResult<Vec<usize>> {
        self.call(py, rays_from_any(rays), |sim, rays| sim.cut_stroke(&rays))
    }

    /// Ctrl-C interrupts it, and then nothing is severed.
    fn sever_stroke(&self, py: Python<'_>, rays: &Bound<'_, PyAny>) -> PyResult<usize> {
        let rays = rays_from_any(rays)?;
        self.stepping(py, |sim, stop| sim.sever_stroke_with(&rays, stop))
    }

    fn pieces(&self, py: Python<'_>) -> PyResult<usize> {
        self.call(py, Ok(()), |sim, ()| Ok(sim.pieces()))
    }
}

reads! {
    #[getter] fn pick_radius -> f32 = |h| h.sim.pick_radius();
    #[getter] fn pick_strategy -> &'static str = |h| h.sim.pick_strategy().name();
    #[getter] fn grip_radius -> f32 = |h| h.sim.grip_radius();
    fn grabbed -> Option<usize> = |h| h.sim.grabbed();
    fn gripped -> Vec<usize> = |h| h.sim.gripped();
    fn piece_labels -> super::conv::Rows<u32> = |h| super::conv::Rows(h.sim.piece_labels(), 0);
    fn bvh_stats -> Plain<crate::picking::BvhStats> = |h| Plain(h.sim.bvh_stats());
}

/// `(origin, direction)` of ray `k` of a stroke: any pair of length-3 sequences, or a
/// `(2, 3)` array.
fn ray_from_any(item: &Bound<'_, PyAny>, k: usize) -> PyResult<(Vec3, Vec3)> {
    let name = format!("rays[{k}]");
    let pair = "must be an (origin, direction) pair";
    let len = item
        .len()
        .map_err(|_| type_error(&name, format!("{pair}, got {item}")))?;
    if len != 2 {
        return Err(value_error(&name, format!("{pair}, got {len} items")));
    }
    let origin = vec3_from_any(&item.get_item(0)?, &format!("{name}.origin"))?;
    let direction = direction_from_any(&item.get_item(1)?, &format!("{name}.direction"))?;
    Ok((origin, direction))
}

/// A stroke: a sequence of ``(origin, direction)`` pairs, each named ``rays[k]`` in errors.
fn rays_from_any(rays: &Bound<'_, PyAny>) -> PyResult<Vec<(Vec3, Vec3)>> {
    let not_rays = || {
        let message = format!("must be a sequence of (origin, direction) pairs, got {rays}");
        type_error("rays", message)
    };
    if rays.is_instance_of::<pyo3::types::PyString>()
        || rays.is_instance_of::<pyo3::types::PyBytes>()
    {
        return Err(not_rays());
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
    rays.try_iter()
        .map_err(|_| not_rays())?
        .enumerate()
        .map(|(k, item)| ray_from_any(&item?, k))
        .collect()
}

/// The `(origin, direction)` pairs of an `(M, 2, 3)` float32 or float64 array (read in f64, so
/// that a float64 value beyond float32's range becomes infinite and is refused by name); `None`
/// for any other shape, which the item-by-item reading names.
fn rays_from_array<T: Copy + Into<f64>>(array: ArrayView3<'_, T>) -> Option<Vec<(Vec3, Vec3)>> {
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
