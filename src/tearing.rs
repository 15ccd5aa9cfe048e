//! Tearing: after each step, springs stretched past a strain break, with the same topology
//! update as a cut (`Model::sever`: the spring's `active` flag goes to 0, `topology_version`
//! moves, the mesh and the picking trees follow on their next use). The scene's `[tearing]`
//! adds the pass; without it the pass does not exist.
//!
//! Which springs break is decided on the positions at the end of the step, in a fixed order
//! (most strained first; equal strains by kind, then anchor), and at most `max_per_step` of
//! them, so a tear is the same for any number of threads and a pull rips along the cloth
//! spring after spring instead of a whole stretched region letting go in one step.
//!
//! On a mesh cloth the stretch springs of the spring list tear ([`Model::sever_mesh`]: the bend
//! springs of the triangles on a torn edge go with it). Bend springs never tear on their own: a
//! bend spring holds the fold between two whole triangles, not material, and is at most as
//! strained as the edges around it. Seams never tear (a seam's rest length closes to zero).
//! The check runs in parallel over blocks of springs, each block marking only whether it holds
//! a spring past the limit; the springs are then listed block after block in spring order, so
//! the result does not depend on the number of threads.

use rayon::prelude::*;

use crate::grid::{Family, SpringKind};
use crate::mesh_cloth::EdgeKind;
use crate::model::Model;
use crate::soa::Vec3s;

/// Anchors tested together before looking for which spring of them is past the limit.
const BLOCK: usize = 64;

/// The tearing pass and its workspace.
#[derive(Clone, Debug)]
pub struct Tearing {
    /// A spring breaks when `l > (1 + max_strain) L`.
    max_strain: f32,
    max_per_step: usize,
    /// The springs over the limit this step, as `(strain, kind, anchor)`; kept between steps
    /// so that a step does not allocate once it has seen its largest tear.
    over: Vec<(f32, SpringKind, usize)>,
    slots: Vec<(SpringKind, usize)>,
    /// A mesh cloth's springs over the limit as `(strain, spring)`, per block whether it has
    /// one, and the springs to sever.
    mesh_over: Vec<(f32, u32)>,
    mesh_blocks: Vec<bool>,
    mesh_springs: Vec<u32>,
}

impl Tearing {
    pub const NAME: &'static str = "tearing";

    pub fn new(max_strain: f32, max_per_step: u32) -> Tearing {
        Tearing {
            max_strain,
            max_per_step: max_per_step as usize,
            over: Vec::new(),
            slots: Vec::new(),
            mesh_over: Vec::new(),
            mesh_blocks: Vec::new(),
            mesh_springs: Vec::new(),
        }
    }

    /// Breaks the springs past the limit in `pos` (the most strained first, at most
    /// `max_per_step`); returns how many broke. Only the families that carry a force (non-zero
    /// stiffness) tear: a spring of a family with no stiffness holds nothing.
    pub fn apply(&mut self, model: &mut Model, pos: &Vec3s) -> usize {
        if model.mesh().is_some() {
            return self.apply_mesh(model, pos);
        }
        self.over.clear();
        let limit = 1.0 + self.max_strain;
        let (grid, springs) = (model.grid, &model.springs);
        for family in Family::ALL
            .into_iter()
            .filter(|&f| model.stiffness(f) > 0.0)
        {
            for kind in family.kinds() {
                let (k, o) = (kind.index(), grid.offset(kind));
                let (rest, active) = (&springs.rest[k], &springs.active[k]);
                let n = grid.len().saturating_sub(o);
                // Blocks of anchors: a branch-free test of the whole block first (it
                // vectorises), the push loop only in the rare block with a spring past it.
                for start in (0..n).step_by(BLOCK) {
                    let block = start..(start + BLOCK).min(n);
                    let (ax, ay, az) = (
                        &pos.x[block.clone()],
                        &pos.y[block.clone()],
                        &pos.z[block.clone()],
                    );
                    let b = block.start + o..block.end + o;
                    let (bx, by, bz) = (&pos.x[b.clone()], &pos.y[b.clone()], &pos.z[b]);
                    let (rest, active) = (&rest[block.clone()], &active[block.clone()]);
                    let len = block.len();
                    let over = |i: usize| {
                        let (dx, dy, dz) = (bx[i] - ax[i], by[i] - ay[i], bz[i] - az[i]);
                        let l2 = dx * dx + dy * dy + dz * dz;
                        let bound = limit * rest[i];
                        // Squared lengths: a square root only for the springs past the limit.
                        (active[i] * l2 > bound * bound, l2)
                    };
                    if !(0..len).fold(false, |any, i| any | over(i).0) {
                        continue;
                    }
                    for (i, &r) in rest.iter().enumerate() {
                        if let (true, l2) = over(i) {
                            self.over.push((l2.sqrt() / r - 1.0, kind, block.start + i));
                        }
                    }
                }
            }
        }
        if self.over.is_empty() {
            return 0;
        }
        // A total order: strain descending (total_cmp: a NaN strain, which the step's checks
        // never let through, would still sort the same every time), then kind, then anchor.
        self.over.sort_unstable_by(|x, y| {
            y.0.total_cmp(&x.0)
                .then(x.1.index().cmp(&y.1.index()))
                .then(x.2.cmp(&y.2))
        });
        self.slots.clear();
        let take = self.over.len().min(self.max_per_step);
        self.slots
            .extend(self.over[..take].iter().map(|&(_, kind, a)| (kind, a)));
        model.sever(&self.slots)
    }

    /// [`Tearing::apply`] on a mesh cloth: its stretch springs past the limit, the most
    /// strained first (equal strains by spring index), at most `max_per_step`.
    fn apply_mesh(&mut self, model: &mut Model, pos: &Vec3s) -> usize {
        let Some(mesh) = model.mesh() else {
            return 0;
        };
        let s = &mesh.springs;
        let limit = 1.0 + self.max_strain;
        // The list is sorted by kind, stretch springs first: only they tear.
        let n = s.kind.partition_point(|&kind| kind == EdgeKind::Stretch);
        let over = |e: usize| {
            let d = pos.get(s.b[e] as usize) - pos.get(s.a[e] as usize);
            let l2 = d.length_squared();
            let bound = limit * s.rest[e];
            (s.active[e] && s.k[e] > 0.0 && l2 > bound * bound, l2)
        };
        let block = |k: usize| k * BLOCK..((k + 1) * BLOCK).min(n);
        self.mesh_blocks.resize(n.div_ceil(BLOCK), false);
        self.mesh_blocks
            .par_iter_mut()
            .enumerate()
            .for_each(|(k, any)| *any = block(k).fold(false, |any, e| any | over(e).0));
        self.mesh_over.clear();
        for (k, _) in self.mesh_blocks.iter().enumerate().filter(|(_, &any)| any) {
            for e in block(k) {
                if let (true, l2) = over(e) {
                    self.mesh_over.push((l2.sqrt() / s.rest[e] - 1.0, e as u32));
                }
            }
        }
        if self.mesh_over.is_empty() {
            return 0;
        }
        self.mesh_over
            .sort_unstable_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
        let take = self.mesh_over.len().min(self.max_per_step);
        self.mesh_springs.clear();
        (self.mesh_springs).extend(self.mesh_over[..take].iter().map(|&(_, e)| e));
        model.sever_mesh(&self.mesh_springs)
    }

    pub fn heap_bytes(&self) -> usize {
        self.over.capacity() * size_of::<(f32, SpringKind, usize)>()
            + self.slots.capacity() * size_of::<(SpringKind, usize)>()
            + self.mesh_over.capacity() * size_of::<(f32, u32)>()
            + self.mesh_blocks.capacity()
            + self.mesh_springs.capacity() * size_of::<u32>()
    }
}
