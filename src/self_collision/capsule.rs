//! The capsule. Each vertex is also kept within `thickness / 2` of its straight path from
//! `x0` to `x1` (a capsule, inside its grown swept box), so a pair the swept search did not look
//! at stays apart: either their boxes are disjoint, or they were farther at `x0` than their
//! capsules reach. A capsule rather than the box because its reach from `x0` is
//! `|x1 - x0| + thickness / 2`, against `|x1 - x0| + sqrt(3) thickness / 2` to the box's
//! corner: in a layered cloth the pairs within reach grow with its square, so the capsule looks
//! at about half as many. A pair the list leaves out is farther than `needed` at `x0`, and no
//! vertex strayed more than `r + PUSH thickness` (checked at the end), so it stays `thickness`
//! apart. With no triangle pair in contact at the start, none touches at any time of any
//! substep: two triangles sharing no vertex can only start to intersect through a vertex
//! touching a face or an edge touching an edge.

use glam::Vec3;
use rayon::prelude::*;

use super::bvh::Aabb;
use super::SelfCollision;
use crate::soa::Vec3s;

impl SelfCollision {
    /// Each vertex's box, swept from `x0` to `x1` and grown by `thickness / 2 + eps`, what the
    /// swept search overlaps; and its path's end `x1`, for the capsule the pass keeps it in.
    pub(super) fn sweep_boxes(&mut self, x0: &Vec3s, x1: &Vec3s, eps: f32) {
        self.path_radius = 0.5 * self.thickness + eps;
        let grow = Vec3::splat(self.path_radius);
        self.vertex_boxes.resize(x0.len(), Aabb::EMPTY);
        self.path_ends.resize(x0.len(), Vec3::ZERO);
        self.vertex_boxes
            .par_iter_mut()
            .zip(self.path_ends.par_iter_mut())
            .enumerate()
            .for_each(|(v, (b, end))| {
                let (a, c) = (x0.get(v), x1.get(v));
                *b = Aabb {
                    min: a.min(c) - grow,
                    max: a.max(c) + grow,
                };
                *end = c;
            });
    }

    /// `p` moved into vertex `v`'s capsule: the points within `path_radius` of its path from
    /// `x0` to `x1`, and (against round-off) inside its box.
    #[inline]
    pub(super) fn kept_on_path(&self, v: usize, x0: &Vec3s, p: Vec3) -> Vec3 {
        let (a, d) = (x0.get(v), self.path_ends[v] - x0.get(v));
        let len2 = d.length_squared();
        let t = if len2 > 0.0 {
            ((p - a).dot(d) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let on_path = a + t * d;
        let off = p - on_path;
        let r = self.path_radius;
        let p = if off.length_squared() > r * r {
            on_path + off * (r / off.length())
        } else {
            p
        };
        let b = &self.vertex_boxes[v];
        p.clamp(b.min, b.max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The capsule a vertex is kept in: a point within `path_radius` of the straight path
    /// from `x0` to `x1` stays where it is; one farther is brought onto the capsule, so that
    /// it ends no farther from `x0` than `|x1 - x0| + path_radius`, the reach the swept
    /// search's filter counts on.
    #[test]
    fn a_vertex_is_kept_within_its_capsule_and_box() {
        let x0 = Vec3s::from_fn(1, |_| Vec3::new(1.0, 2.0, 3.0));
        let x1 = Vec3s::from_fn(1, |_| Vec3::new(1.01, 2.0, 3.0));
        let mut pass = SelfCollision::new(0.004, 0.0, 1);
        pass.sweep_boxes(&x0, &x1, 1e-7);
        let r = pass.path_radius;
        let (a, c) = (x0.get(0), x1.get(0));
        let inside = Vec3::new(1.005, 2.0015, 3.0);
        assert_eq!(pass.kept_on_path(0, &x0, inside), inside);
        // A box corner is inside the box but outside the capsule: sqrt(2) r off the path.
        let corner = Vec3::new(1.005, 2.0 + r, 3.0 + r);
        let kept = pass.kept_on_path(0, &x0, corner);
        // Up to round-off of coordinates near 3 (the pass's `eps` allows for 1e-6 per unit).
        let round_off = 1e-6;
        let off_path = (kept - Vec3::new(kept.x, 2.0, 3.0)).length();
        assert!(off_path <= r + round_off, "{off_path} > {r}");
        assert!((kept.x - 1.005).abs() < 1e-6);
        // Far beyond the end: onto the end's cap, at most |x1 - x0| + r from the start.
        for far in [Vec3::new(2.0, 2.5, 3.0), Vec3::new(0.0, 1.0, 4.0)] {
            let kept = pass.kept_on_path(0, &x0, far);
            let reach = (c - a).length() + r;
            assert!((kept - a).length() <= reach + round_off, "{kept}");
            let b = pass.vertex_boxes[0];
            assert_eq!(kept.clamp(b.min, b.max), kept);
        }
    }
}
