//! Tearing: after each step, springs stretched past a strain break, with the same topology
//! update as a cut (`Model::sever`: the spring's `active` flag goes to 0, `topology_version`
//! moves, the mesh and the picking trees follow on their next use). The scene's `[tearing]`
//! adds the pass; without it the pass does not exist.
//!
//! Which springs break is decided on the positions at the end of the step, in a fixed order
//! (most strained first; equal strains by kind, then anchor), and at most `max_per_step` of
//! them, so a tear is the same for any number of threads and a pull rips along the cloth
//! spring after spring instead of a whole stretched region letting go in one step.

use crate::grid::{Family, SpringKind};
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
}

impl Tearing {
    pub const NAME: &'static str = "tearing";

    pub fn new(max_strain: f32, max_per_step: u32) -> Tearing {
        Tearing {
            max_strain,
            max_per_step: max_per_step as usize,
            over: Vec::new(),
            slots: Vec::new(),
        }
    }

    /// Breaks the springs past the limit in `pos` (the most strained first, at most
    /// `max_per_step`); returns how many broke. Only the families that carry a force (non-zero
    /// stiffness) tear: a spring of a family with no stiffness holds nothing.
    pub fn apply(&mut self, model: &mut Model, pos: &Vec3s) -> usize {
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

    pub fn heap_bytes(&self) -> usize {
        self.over.capacity() * size_of::<(f32, SpringKind, usize)>()
            + self.slots.capacity() * size_of::<(SpringKind, usize)>()
    }
}
