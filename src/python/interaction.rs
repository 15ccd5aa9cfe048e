//! Picking, dragging and cutting (src/interaction.rs) for Python. Queries run detached from the
//! interpreter: the first one after the cloth moved refits a tree over every particle.

use glam::Vec3;
use pyo3::prelude::*;

use super::conv::{Floats, Plain, Rows};
use super::simulation::{methods, PySimulation};
use crate::picking::PickStrategy;

/// `(triangle_index, distance, (w0, w1, w2))`.
type TriangleHit = (usize, f32, (f32, f32, f32));

/// A stroke's `(origin, direction)` pairs from an `(M, 2, 3)` array, read in f64 so that a
/// float64 value beyond float32's range becomes infinite and is refused by the core, naming
/// the ray.
fn rays(rays: &Floats<'_>) -> PyResult<Vec<(Vec3, Vec3)>> {
    let values = rays.rows(&[2, 3])?;
    let vec3 = |v: &[f64]| glam::DVec3::from_slice(v).as_vec3();
    Ok(values
        .chunks_exact(6)
        .map(|r| (vec3(&r[..3]), vec3(&r[3..])))
        .collect())
}

/// A hit's `(index, distance)`.
type ParticleHit = Option<(usize, f32)>;

methods! {
    fn pick(origin: [f32; 3], direction: [f32; 3]) -> ParticleHit =
        call |sim| Ok(sim.pick(origin.into(), direction.into())?.map(|h| (h.index, h.distance)));
    fn pick_triangle(origin: [f32; 3], direction: [f32; 3]) -> Option<TriangleHit> = call |sim| {
        let hit = sim.pick_triangle(origin.into(), direction.into())?;
        Ok(hit.map(|h| (h.index, h.distance, h.barycentric.into())))
    };
    fn cut_ray(origin: [f32; 3], direction: [f32; 3]) -> Option<usize> =
        call |sim| sim.cut_ray(origin.into(), direction.into());
    #[setter] fn set_pick_radius(radius: f64) -> () = call |sim| sim.set_pick_radius(radius);
    #[setter] fn set_grip_radius(radius: f64) -> () = call |sim| sim.set_grip_radius(radius);
    #[setter] fn set_drag_time(seconds: f64) -> () = call |sim| sim.set_drag_time(seconds);
    fn grab(index: i64) -> () = call |sim| sim.grab(index);
    fn drag_to(target: [f32; 3]) -> () = call |sim| sim.drag_to(target.into());
    fn release() -> () = call |sim| {
        sim.release();
        Ok(())
    };
    fn pieces() -> usize = call |sim| Ok(sim.pieces());
    #[setter] fn set_pick_strategy(strategy: &str) -> () = call |sim| {
        sim.set_pick_strategy(PickStrategy::by_name(strategy)?);
        Ok(())
    };
    #[getter] fn pick_radius() -> f32 = read |h| h.sim.pick_radius();
    #[getter] fn pick_strategy() -> &'static str = read |h| h.sim.pick_strategy().name();
    #[getter] fn grip_radius() -> f32 = read |h| h.sim.grip_radius();
    #[getter] fn drag_time() -> f64 = read |h| h.sim.drag_time();
    fn grabbed() -> Option<usize> = read |h| h.sim.grabbed();
    fn gripped() -> Vec<usize> = read |h| h.sim.gripped();
    fn piece_labels() -> Rows<u32> = read |h| Rows(h.sim.piece_labels(), 0);
    fn bvh_stats() -> Plain<crate::picking::BvhStats> = read |h| Plain(h.sim.bvh_stats());
}

#[pymethods]
impl PySimulation {
    fn cut_stroke(&self, py: Python<'_>, rays: Floats<'_>) -> PyResult<Vec<usize>> {
        let rays = self::rays(&rays)?;
        self.call(py, |sim| sim.cut_stroke(&rays))
    }

    /// Ctrl-C interrupts it, and then nothing is severed.
    fn sever_stroke(&self, py: Python<'_>, rays: Floats<'_>) -> PyResult<usize> {
        let rays = self::rays(&rays)?;
        self.stepping(py, |sim, stop| sim.sever_stroke_with(&rays, stop))
    }

    fn sever_live_stroke(&self, py: Python<'_>, rays: Floats<'_>) -> PyResult<usize> {
        let rays = self::rays(&rays)?;
        self.call(py, |sim| sim.sever_live_stroke(&rays))
    }

    fn end_live_stroke(&self, py: Python<'_>) -> PyResult<()> {
        self.call(py, |sim| {
            sim.end_live_stroke();
            Ok(())
        })
    }
}
