//! Picking, dragging and cutting (src/interaction.rs) for Python. Queries run detached from the
//! interpreter: the first one after the cloth moved refits a tree over every particle.

use glam::Vec3;
use pyo3::prelude::*;

use super::conv::{Floats, Plain};
use super::errors::IntoPyResult;
use super::simulation::{calls, reads, PySimulation};
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

calls! {
    fn pick(origin: [f32; 3], direction: [f32; 3]) -> ParticleHit =
        |sim| Ok(sim.pick(origin.into(), direction.into())?.map(|h| (h.index, h.distance)));
    fn pick_triangle(origin: [f32; 3], direction: [f32; 3]) -> Option<TriangleHit> = |sim| {
        let hit = sim.pick_triangle(origin.into(), direction.into())?;
        Ok(hit.map(|h| (h.index, h.distance, h.barycentric.into())))
    };
    fn cut_ray(origin: [f32; 3], direction: [f32; 3]) -> Option<usize> =
        |sim| sim.cut_ray(origin.into(), direction.into());
    #[setter] fn set_pick_radius(radius: f64) -> () = |sim| sim.set_pick_radius(radius);
    #[setter] fn set_grip_radius(radius: f64) -> () = |sim| sim.set_grip_radius(radius);
    fn grab(index: i64) -> () = |sim| sim.grab(index);
    fn drag_to(target: [f32; 3]) -> () = |sim| sim.drag_to(target.into());
    fn release() -> () = |sim| {
        sim.release();
        Ok(())
    };
    fn pieces() -> usize = |sim| Ok(sim.pieces());
}

#[pymethods]
impl PySimulation {
    #[setter]
    fn set_pick_strategy(&self, py: Python<'_>, strategy: &str) -> PyResult<()> {
        let strategy = PickStrategy::by_name(strategy).py()?;
        self.call(py, |sim| {
            sim.set_pick_strategy(strategy);
            Ok(())
        })
    }

    fn cut_stroke(&self, py: Python<'_>, rays: Floats<'_>) -> PyResult<Vec<usize>> {
        let rays = self::rays(&rays)?;
        self.call(py, |sim| sim.cut_stroke(&rays))
    }

    /// Ctrl-C interrupts it, and then nothing is severed.
    fn sever_stroke(&self, py: Python<'_>, rays: Floats<'_>) -> PyResult<usize> {
        let rays = self::rays(&rays)?;
        self.stepping(py, |sim, stop| sim.sever_stroke_with(&rays, stop))
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
