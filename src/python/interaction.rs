//! Picking, dragging and cutting (src/interaction.rs) for Python. Queries release the GIL: the
//! first one after the cloth moved refits a tree over every particle.

use pyo3::prelude::*;

use super::conv::{index_from_any, vec3_from_any};
use super::errors::{type_error, value_error, IntoPyResult};
use super::PySimulation;
use crate::interaction::PickStrategy;

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
    let direction = vec3_from_any(&item.get_item(1)?, &format!("{name}.direction"))?;
    Ok((origin, direction))
}

/// `(triangle_index, distance, (w0, w1, w2))`.
type TriangleHit = (usize, f32, (f32, f32, f32));

#[pymethods]
impl PySimulation {
    /// Picks the live particle the ray ``origin + t * direction`` (``t >= 0``) hits first.
    ///
    /// Each particle is a box of half-size ``pick_radius``; ties along the ray go to the
    /// particle nearer the ray. Returns ``(index, distance)`` with the distance along the ray
    /// in m, or ``None``. Raises ``ValueError`` for a non-finite origin or a zero or non-finite
    /// direction. The BVH is built by the first query and refitted (not rebuilt) after the
    /// cloth moves; stepping never touches it.
    fn pick(
        &mut self,
        py: Python<'_>,
        origin: &Bound<'_, PyAny>,
        direction: &Bound<'_, PyAny>,
    ) -> PyResult<Option<(usize, f32)>> {
        let origin = vec3_from_any(origin, "origin")?;
        let direction = vec3_from_any(direction, "direction")?;
        let sim = &mut self.inner;
        py.detach(|| sim.pick(origin, direction)).py()
    }

    /// Picks the live triangle (a row of ``triangles``) the ray hits first.
    ///
    /// Returns ``(triangle_index, distance, (w0, w1, w2))`` with the barycentric weights of the
    /// triangle's three vertices (in the order of its row; they sum to 1), or ``None``.
    fn pick_triangle(
        &mut self,
        py: Python<'_>,
        origin: &Bound<'_, PyAny>,
        direction: &Bound<'_, PyAny>,
    ) -> PyResult<Option<TriangleHit>> {
        let origin = vec3_from_any(origin, "origin")?;
        let direction = vec3_from_any(direction, "direction")?;
        let sim = &mut self.inner;
        let hit = py.detach(|| sim.pick_triangle(origin, direction)).py()?;
        Ok(hit.map(|(t, d, [a, b, c])| (t, d, (a, b, c))))
    }

    /// Half-size in m of each particle's pick box; defaults to half the smaller grid spacing.
    #[getter]
    fn pick_radius(&self) -> f32 {
        self.inner.pick_radius()
    }

    #[setter]
    fn set_pick_radius(&mut self, radius: f64) -> PyResult<()> {
        self.inner.set_pick_radius(radius).py()
    }

    /// How queries find what a ray hits: ``"auto"`` (default: a scan of every particle for the
    /// first query after the cloth moved, the BVH, refitted, from the second query on the same
    /// state and for cut strokes), ``"bvh"`` (always the tree) or ``"scan"`` (never a tree).
    /// All three give the same answers.
    #[getter]
    fn pick_strategy(&self) -> &'static str {
        self.inner.pick_strategy().name()
    }

    #[setter]
    fn set_pick_strategy(&mut self, strategy: &str) -> PyResult<()> {
        let strategy = PickStrategy::by_name(strategy).py()?;
        self.inner.set_pick_strategy(strategy);
        Ok(())
    }

    /// Grabs particle ``index``: a kinematic pin at its current position that ``drag_to``
    /// moves. Grabbing another particle releases the first. Raises ``IndexError`` out of range
    /// and ``ValueError`` for a cut particle.
    fn grab(&mut self, index: &Bound<'_, PyAny>) -> PyResult<()> {
        let index = index_from_any(index, "index", self.inner.grid().len())?;
        self.inner.grab(index).py()
    }

    /// Moves the grabbed particle's target to ``target`` (3 numbers, m); the particle gets
    /// there over the next step and the cloth follows by its springs. Does nothing without a
    /// grab. Raises ``ValueError`` for a non-finite target.
    fn drag_to(&mut self, target: &Bound<'_, PyAny>) -> PyResult<()> {
        let target = vec3_from_any(target, "target")?;
        self.inner.drag_to(target).py()
    }

    /// Lets go of the grabbed particle and restores the pin state it had before the grab; a
    /// free particle keeps its velocity. Does nothing without a grab.
    fn release(&mut self) {
        self.inner.release();
    }

    /// The index of the grabbed particle, or ``None``.
    fn grabbed(&self) -> Option<usize> {
        self.inner.grabbed()
    }

    /// Cuts the particle ``pick(origin, direction)`` finds; returns its index, or ``None``
    /// when the ray hits nothing.
    fn cut_ray(
        &mut self,
        py: Python<'_>,
        origin: &Bound<'_, PyAny>,
        direction: &Bound<'_, PyAny>,
    ) -> PyResult<Option<usize>> {
        let origin = vec3_from_any(origin, "origin")?;
        let direction = vec3_from_any(direction, "direction")?;
        let sim = &mut self.inner;
        py.detach(|| sim.cut_ray(origin, direction)).py()
    }

    /// Cuts what a mouse stroke passes over: ``rays`` is a sequence of ``(origin, direction)``
    /// pairs (or an ``(M, 2, 3)`` array), each cutting the particle it picks after the cuts of
    /// the rays before it. Returns the indices cut, in order. Every ray is checked first: bad
    /// input raises and cuts nothing.
    fn cut_stroke(&mut self, py: Python<'_>, rays: &Bound<'_, PyAny>) -> PyResult<Vec<usize>> {
        let items = rays.try_iter().map_err(|_| {
            type_error(
                "rays",
                format!("must be a sequence of (origin, direction) pairs, got {rays}"),
            )
        })?;
        let rays = items
            .enumerate()
            .map(|(k, item)| ray_from_any(&item?, k))
            .collect::<PyResult<Vec<_>>>()?;
        let sim = &mut self.inner;
        py.detach(|| sim.cut_stroke(&rays)).py()
    }

    /// Work done on the picking trees so far: queries answered by a scan, builds, refits and
    /// leaves removed by cuts, for the particle and the triangle tree.
    fn bvh_stats(&self) -> std::collections::HashMap<&'static str, u64> {
        let s = self.inner.bvh_stats();
        [
            ("particle_scans", s.particle_scans),
            ("particle_builds", s.particle_builds),
            ("particle_refits", s.particle_refits),
            ("particle_removals", s.particle_removals),
            ("triangle_scans", s.triangle_scans),
            ("triangle_builds", s.triangle_builds),
            ("triangle_refits", s.triangle_refits),
            ("triangle_removals", s.triangle_removals),
        ]
        .into_iter()
        .collect()
    }
}
