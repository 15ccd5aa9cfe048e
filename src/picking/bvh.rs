//! The two picking trees, parry3d [`Bvh`]s over particle boxes and over triangle boxes, keyed by
//! stable ids so that a cut removes leaves and a moved cloth refits them.

use parry3d::bounding_volume::Aabb;
use parry3d::partitioning::{Bvh, BvhBuildStrategy};

use super::ray::{
    hit_particle, nearest_hit, particle_box, ray_triangle, triangle_bounds, triangle_query_margin,
    ParticleHit, Ray, TriangleHit,
};
use crate::grid::{triangle_alive, Grid};
use crate::incidence::Corners;
use crate::model::TriangleIds;
use crate::soa::Vec3s;

/// A binned-SAH BVH over `(leaf id, box)` pairs.
///
/// parry3d 0.31.1's `Bvh::from_iter` special-cases one or two leaves by writing the slots of
/// leaf ids 0 and 1, and panics ("key not present") when the ids are others, as they are once
/// particles have been cut. So few leaves are inserted one by one instead.
fn build_bvh(leaves: impl Iterator<Item = (usize, Aabb)>) -> Bvh {
    let leaves: Vec<(usize, Aabb)> = leaves.collect();
    if leaves.len() > 2 {
        return Bvh::from_iter(BvhBuildStrategy::Binned, leaves);
    }
    let mut bvh = Bvh::new();
    for (id, aabb) in leaves {
        bvh.insert(aabb, id as u32);
    }
    bvh
}

/// The BVH over the boxes of the live particles, leaf id = particle index.
pub struct ParticleBvh {
    bvh: Bvh,
    in_tree: Vec<bool>,
    leaves: usize,
    radius: f32,
}

impl ParticleBvh {
    /// Builds the tree over the live particles (binned SAH build, `O(n log n)`).
    pub fn build(pos: &Vec3s, alive: &[bool], radius: f32) -> Self {
        let leaves = (0..pos.len()).filter(|&p| alive[p]).map(|p| {
            let (lo, hi) = particle_box(pos.get(p), radius);
            (p, Aabb::new(lo, hi))
        });
        let bvh = build_bvh(leaves);
        ParticleBvh {
            bvh,
            in_tree: alive.to_vec(),
            leaves: alive.iter().filter(|&&a| a).count(),
            radius,
        }
    }

    pub fn radius(&self) -> f32 {
        self.radius
    }

    /// Number of leaves (live particles when last synchronised).
    pub fn len(&self) -> usize {
        self.leaves
    }

    pub fn is_empty(&self) -> bool {
        self.leaves == 0
    }

    /// Moves every leaf box to the particle's new position (and size `radius`) and refits the
    /// tree bottom-up: `O(n)`, the topology of the tree is kept. (`refit_without_opt`: parry's
    /// `refit` also copies the nodes into depth-first order, which the build already gave
    /// them, and costs more for nothing; docs/picking.md has the measurement.)
    pub fn refit(&mut self, pos: &Vec3s, radius: f32) {
        self.radius = radius;
        for p in (0..pos.len()).filter(|&p| self.in_tree[p]) {
            let (lo, hi) = particle_box(pos.get(p), radius);
            self.bvh
                .update_partially_if_present(Aabb::new(lo, hi), p as u32, 0.0);
        }
        if !self.is_empty() {
            self.bvh.refit_without_opt();
        }
    }

    /// Heap memory of the tree and its leaf flags, in bytes.
    pub fn heap_bytes(&self) -> usize {
        self.bvh.heap_memory_size() + self.in_tree.capacity()
    }

    /// Removes particle `p`'s leaf (`O(tree height)`); false if it had none.
    pub fn remove(&mut self, p: usize) -> bool {
        if !std::mem::take(&mut self.in_tree[p]) {
            return false;
        }
        self.bvh.remove(p as u32);
        self.leaves -= 1;
        true
    }

    /// Removes the leaves of every particle no longer alive; returns how many.
    pub fn remove_dead(&mut self, alive: &[bool]) -> usize {
        let dead: Vec<usize> = (0..alive.len())
            .filter(|&p| self.in_tree[p] && !alive[p])
            .collect();
        dead.into_iter().filter(|&p| self.remove(p)).count()
    }

    /// The nearest particle along `ray`; `pos` must be the positions the tree was fitted to.
    pub fn cast(&self, ray: &Ray, pos: &Vec3s) -> Option<ParticleHit> {
        nearest_hit(&self.bvh, ray, 0.0, |p| {
            hit_particle(ray, p as usize, pos.get(p as usize), self.radius)
        })
    }
}

/// The BVH over the live triangles, leaf id = stable triangle id ([`TriangleIds`]: a grid
/// cell's, or a mesh's position in its list).
pub struct TriangleBvh {
    ids: TriangleIds,
    bvh: Bvh,
    in_tree: Vec<bool>,
    leaves: usize,
    /// A mesh's triangles by corner, so that a cut finds those around a particle without a
    /// scan of every triangle (the grid's are found from the particle's cell).
    around: Option<Corners>,
}

fn triangle_box(pos: &Vec3s, tri: [usize; 3]) -> Aabb {
    let [a, b, c] = tri.map(|q| pos.get(q));
    let (lo, hi) = triangle_bounds(a, b, c);
    Aabb::new(lo, hi)
}

impl TriangleBvh {
    /// A tree of the grid's triangles whose corners are all `alive`.
    pub fn build(grid: Grid, pos: &Vec3s, alive: &[bool]) -> Self {
        Self::build_where(TriangleIds::Grid(grid), pos, |id| {
            triangle_alive(grid, alive, id)
        })
    }

    /// A tree of the triangles `drawn` says are there (by id).
    pub fn build_where(ids: TriangleIds, pos: &Vec3s, drawn: impl Fn(usize) -> bool) -> Self {
        let in_tree: Vec<bool> = (0..ids.slots()).map(drawn).collect();
        let leaves = (0..in_tree.len())
            .filter(|&id| in_tree[id])
            .map(|id| (id, triangle_box(pos, ids.corners(id))));
        let bvh = build_bvh(leaves);
        let around = match &ids {
            TriangleIds::Grid(_) => None,
            TriangleIds::Mesh(triangles) => {
                let vertices = triangles
                    .iter()
                    .flatten()
                    .max()
                    .map_or(0, |&v| v as usize + 1);
                Some(Corners::new(triangles, vertices))
            }
        };
        TriangleBvh {
            ids,
            bvh,
            leaves: in_tree.iter().filter(|&&t| t).count(),
            in_tree,
            around,
        }
    }

    pub fn len(&self) -> usize {
        self.leaves
    }

    pub fn is_empty(&self) -> bool {
        self.leaves == 0
    }

    /// Heap memory of the tree and its leaf flags, in bytes.
    pub fn heap_bytes(&self) -> usize {
        self.bvh.heap_memory_size() + self.in_tree.capacity()
    }

    /// Whether triangle `id` is a leaf.
    pub fn contains(&self, id: usize) -> bool {
        self.in_tree[id]
    }

    pub fn refit(&mut self, pos: &Vec3s) {
        for id in (0..self.in_tree.len()).filter(|&id| self.in_tree[id]) {
            let aabb = triangle_box(pos, self.ids.corners(id));
            self.bvh.update_partially_if_present(aabb, id as u32, 0.0);
        }
        if !self.is_empty() {
            self.bvh.refit_without_opt();
        }
    }

    /// Removes the leaves of triangles `drawn` says are gone (a cut or tear severed their
    /// cell); returns how many. One pass over the leaf flags, no rebuild.
    pub fn remove_undrawn(&mut self, drawn: impl Fn(usize) -> bool) -> usize {
        let dead: Vec<usize> = (0..self.in_tree.len())
            .filter(|&id| self.in_tree[id] && !drawn(id))
            .collect();
        dead.into_iter().filter(|&id| self.remove(id)).count()
    }

    /// Removes the triangles around particle `p` (at most six on the grid); returns how many.
    pub fn remove_around(&mut self, p: usize) -> usize {
        let grid = match (&self.ids, &self.around) {
            (TriangleIds::Grid(grid), _) => *grid,
            (TriangleIds::Mesh(_), around) => {
                let corners = around
                    .as_ref()
                    .map_or(&[][..], |around| around.at(p))
                    .to_vec();
                return (corners.into_iter())
                    .filter(|&c| self.remove(c as usize / 3))
                    .count();
            }
        };
        let (i, j) = grid.coords(p);
        let mut removed = 0;
        // The four cells with p as a corner, by their lower-left corner.
        for (di, dj) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let (Some(ci), Some(cj)) = (i.checked_sub(di), j.checked_sub(dj)) else {
                continue;
            };
            if ci + 1 >= grid.nx || cj + 1 >= grid.ny {
                continue;
            }
            let cell = cj * (grid.nx - 1) + ci;
            for id in [2 * cell, 2 * cell + 1] {
                if self.ids.corners(id).contains(&p) && self.remove(id) {
                    removed += 1;
                }
            }
        }
        removed
    }

    fn remove(&mut self, id: usize) -> bool {
        if !std::mem::take(&mut self.in_tree[id]) {
            return false;
        }
        self.bvh.remove(id as u32);
        self.leaves -= 1;
        true
    }

    /// The nearest triangle along `ray` (`index` is the stable id).
    pub fn cast(&self, ray: &Ray, pos: &Vec3s) -> Option<TriangleHit> {
        nearest_hit(&self.bvh, ray, triangle_query_margin(ray), |id| {
            let [a, b, c] = self.ids.corners(id as usize).map(|q| pos.get(q));
            ray_triangle(ray, a, b, c).map(|(distance, barycentric)| TriangleHit {
                index: id as usize,
                distance,
                barycentric,
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fan of six triangles around vertex 0 and a strip beside it.
    fn mesh() -> (TriangleIds, Vec3s) {
        let mut tris: Vec<[u32; 3]> = (0..6).map(|k| [0, 1 + k, 1 + (k + 1) % 6]).collect();
        tris.extend([[1, 7, 2], [2, 7, 8]]);
        let mut pos = Vec3s::zeros(9);
        for v in 1..9 {
            let a = v as f32;
            pos.set(v, glam::Vec3::new(a.cos() * a, a.sin() * a, 0.1 * a));
        }
        (TriangleIds::Mesh(tris.into()), pos)
    }

    #[test]
    fn a_cut_removes_exactly_the_mesh_triangles_with_the_particle_as_a_corner() {
        let (ids, pos) = mesh();
        for p in 0..9 {
            let mut tree = TriangleBvh::build_where(ids.clone(), &pos, |_| true);
            let around: Vec<usize> = (0..ids.slots())
                .filter(|&id| ids.corners(id).contains(&p))
                .collect();
            assert_eq!(tree.remove_around(p), around.len(), "particle {p}");
            for id in 0..ids.slots() {
                assert_eq!(
                    tree.contains(id),
                    !around.contains(&id),
                    "particle {p}, triangle {id}"
                );
            }
            assert_eq!(tree.len(), ids.slots() - around.len());
            assert_eq!(
                tree.remove_around(p),
                0,
                "a second cut of {p} finds nothing left"
            );
        }
    }
}
