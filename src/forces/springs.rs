//! Hooke springs with damping along the spring, gathered per particle over the grid stencil.
//!
//! Force on particle `a` from the spring `(a, b)` with rest length `L` and current length
//! `l = |x_b - x_a|`, unit direction `u = (x_b - x_a) / l`:
//!
//! ```text
//! f_a = k (l - L) u + c ((v_b - v_a) . u) u,     f_b = -f_a
//! ```
//!
//! A spring of zero current length has no direction and exerts no force.
//!
//! Instead of scattering each spring's force to both ends (a data race in parallel, or a serial
//! pass), every particle *gathers* the force of the springs it belongs to. That evaluates each
//! spring twice, once from each end, but needs no synchronisation, vectorises along the grid
//! rows, and sums each particle's force in a fixed order. Both ends compute bitwise negated
//! values, so momentum is conserved exactly up to the order of summation.

use std::ops::Range;

use super::{ForceInput, ForceTerm, Fused};
use crate::grid::{Family, Grid, SpringKind};
use crate::soa::{Floats, Vec3SliceMut, Vec3s};

/// Per-spring data, one array per [`SpringKind`], indexed by the spring's anchor particle.
///
/// Slots whose spring does not exist (off the grid) or was cut have `active = 0`, which makes
/// their force exactly zero (selected, whatever the positions of their ends); keeping the slots
/// lets the kernel run over whole index ranges without row-boundary branches.
#[derive(Clone, Debug)]
pub struct Springs {
    /// Rest length in m: the distance between the two particles when the cloth was built.
    pub rest: [Floats; 6],
    /// 1 for a live spring, 0 for none.
    pub active: [Floats; 6],
}

impl Springs {
    /// Every spring of the stencil, with rest lengths taken from `pos`.
    pub fn new(grid: Grid, pos: &Vec3s) -> Self {
        let n = grid.len();
        let mut rest: [Floats; 6] = Default::default();
        let mut active: [Floats; 6] = Default::default();
        for kind in SpringKind::ALL {
            let k = kind.index();
            rest[k] = Floats::zeros(n);
            active[k] = Floats::zeros(n);
            for p in 0..n {
                if let Some(q) = grid.partner(p, kind) {
                    rest[k][p] = (pos.get(q) - pos.get(p)).length();
                    active[k][p] = 1.0;
                }
            }
        }
        Springs { rest, active }
    }

    /// Removes every spring that touches particle `p`, and the bending springs that pass over
    /// it (`(i-1, j)-(i+1, j)` and `(i, j-1)-(i, j+1)`): they span the hole, and left in place
    /// they would hold the cloth together across a cut one particle wide.
    pub fn remove_particle(&mut self, grid: Grid, p: usize) {
        for kind in SpringKind::ALL {
            let k = kind.index();
            self.active[k][p] = 0.0;
            let o = grid.offset(kind);
            if p >= o && grid.partner(p - o, kind) == Some(p) {
                self.active[k][p - o] = 0.0;
            }
        }
        for kind in [SpringKind::BendI, SpringKind::BendJ] {
            let half = grid.offset(kind) / 2;
            if p >= half && grid.partner(p - half, kind) == Some(p + half) {
                self.active[kind.index()][p - half] = 0.0;
            }
        }
    }

    /// Visits every live spring of `kind` as `(anchor, partner, rest length)`.
    pub fn for_each(&self, grid: Grid, kind: SpringKind, mut f: impl FnMut(usize, usize, f32)) {
        let k = kind.index();
        let o = grid.offset(kind);
        for a in 0..grid.len().saturating_sub(o) {
            if self.active[k][a] != 0.0 {
                f(a, a + o, self.rest[k][a]);
            }
        }
    }

    pub fn heap_bytes(&self) -> usize {
        self.rest
            .iter()
            .chain(&self.active)
            .map(Floats::heap_bytes)
            .sum()
    }
}

/// The springs of one family with their stiffness and damping. Only in the pipeline when
/// `k > 0`: a family with zero stiffness is absent, damping included.
pub struct SpringForce {
    pub family: Family,
    /// Stiffness in N/m.
    pub k: f32,
    /// Damping along the spring in N s/m.
    pub c: f32,
}

impl ForceTerm for SpringForce {
    fn name(&self) -> &'static str {
        self.family.pass_name()
    }

    fn linearization(&self) -> super::Linearization {
        super::Linearization::Springs {
            family: self.family,
            k: self.k,
            c: self.c,
        }
    }

    fn prepared_kinds(&self) -> &[SpringKind] {
        self.family.kinds_slice()
    }

    fn prepare(
        &self,
        input: &ForceInput,
        kind: SpringKind,
        range: Range<usize>,
        out: &mut Vec3SliceMut,
    ) -> bool {
        // The check is a separate instantiation, so a scene without a stretch limit pays
        // nothing for it.
        match input.stretch_watch {
            None => crate::simd::dispatch!(self.spring_forces::<false>(
                input,
                kind,
                range.clone(),
                out,
                0.0
            )),
            Some(limit) => crate::simd::dispatch!(self.spring_forces::<true>(
                input,
                kind,
                range.clone(),
                out,
                limit
            )),
        }
    }

    /// Each particle's spring forces from the table: `+F` of the springs it anchors, `-F` of
    /// the springs it ends.
    fn accumulate(&self, input: &ForceInput, range: Range<usize>, out: &mut Vec3SliceMut) {
        super::fused::accumulate(input, &[self.contribution()], false, range, out)
    }

    fn fused(&self) -> Option<Fused> {
        Some(self.contribution())
    }
}

impl SpringForce {
    /// `+F` of the springs each particle anchors, `-F` of those it ends, kind by kind.
    fn contribution(&self) -> Fused {
        Fused::Springs(self.family.kinds_slice())
    }

    /// The force on the anchor of every spring of `kind` anchored in `range`; zero for slots
    /// with no spring. One straight loop over equal-length slices: the compiler vectorises it.
    /// With `WATCH`, also returns whether a live spring is longer than `limit` times its rest
    /// length ([`spring_overstretched`], the same arithmetic, gives the same answer).
    #[inline(always)]
    fn spring_forces<const WATCH: bool>(
        &self,
        input: &ForceInput,
        kind: SpringKind,
        range: Range<usize>,
        out: &mut Vec3SliceMut,
        limit: f32,
    ) -> bool {
        let (n, o) = (input.state.grid.len(), input.state.grid.offset(kind));
        let len = range
            .len()
            .min(n.saturating_sub(o).saturating_sub(range.start));
        let (a, b) = (
            range.start..range.start + len,
            range.start + o..range.start + o + len,
        );
        let (pos, vel) = (input.state.pos, input.state.vel);
        let (xa, ya, za) = (
            pos.component(0, &a),
            pos.component(1, &a),
            pos.component(2, &a),
        );
        let (xb, yb, zb) = (
            pos.component(0, &b),
            pos.component(1, &b),
            pos.component(2, &b),
        );
        let (vxa, vya, vza) = (
            vel.component(0, &a),
            vel.component(1, &a),
            vel.component(2, &a),
        );
        let (vxb, vyb, vzb) = (
            vel.component(0, &b),
            vel.component(1, &b),
            vel.component(2, &b),
        );
        let rest = &input.state.springs.rest[kind.index()][a.clone()];
        let active = &input.state.springs.active[kind.index()][a];
        let (fx, fy, fz) = (&mut out.x[..len], &mut out.y[..len], &mut out.z[..len]);
        let (k, c) = (self.k, self.c);
        // An integer OR, like `FiniteCheck`, so the loop still vectorises.
        let mut over = 0u32;
        for i in 0..len {
            let (dx, dy, dz) = (xb[i] - xa[i], yb[i] - ya[i], zb[i] - za[i]);
            let l = (dx * dx + dy * dy + dz * dz).sqrt();
            if WATCH {
                over |= spring_overstretched(l, rest[i], active[i], limit) as u32;
            }
            let inv_l = if l > 0.0 { 1.0 / l } else { 0.0 };
            let (ux, uy, uz) = (dx * inv_l, dy * inv_l, dz * inv_l);
            let closing = (vxb[i] - vxa[i]) * ux + (vyb[i] - vya[i]) * uy + (vzb[i] - vza[i]) * uz;
            let s = k * (l - rest[i]) + c * closing;
            // A select, not `active * force`: a dead spring to a cut particle far away has an
            // infinite length, and `0 * inf` would put NaN into its live end (issue 14).
            let live = active[i] != 0.0;
            fx[i] = if live { s * ux } else { 0.0 };
            fy[i] = if live { s * uy } else { 0.0 };
            fz[i] = if live { s * uz } else { 0.0 };
        }
        for f in [&mut *out.x, &mut *out.y, &mut *out.z] {
            f[len..].fill(0.0);
        }
        over != 0
    }
}

/// Whether a spring of length `l` (m), rest length `rest` and `active` flag (0 or 1) is longer
/// than `limit` times its rest length. A dead slot (`active = 0`) never is.
#[inline(always)]
pub fn spring_overstretched(l: f32, rest: f32, active: f32, limit: f32) -> bool {
    active * l > limit * rest
}

/// A run of `len` consecutive particles `a..`, their neighbours `b..` along one spring kind,
/// and the slots `spring..` where those springs are stored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Run {
    pub a: usize,
    pub b: usize,
    pub spring: usize,
    pub len: usize,
}

/// The particles of `range` that have a neighbour along a spring kind of index offset `o`, as
/// at most two runs: those that anchor the spring (neighbour `a + o`, slot `a`) and those at its
/// far end (neighbour `a - o`, slot `a - o`). Slots of springs that do not exist are inactive,
/// so the runs need no row-boundary checks.
pub fn neighbour_runs(n: usize, o: usize, range: Range<usize>) -> [Option<Run>; 2] {
    let anchors = range.start..range.end.min(n.saturating_sub(o));
    let ends = range.start.max(o)..range.end;
    [
        (!anchors.is_empty()).then(|| Run {
            a: anchors.start,
            b: anchors.start + o,
            spring: anchors.start,
            len: anchors.len(),
        }),
        (!ends.is_empty()).then(|| Run {
            a: ends.start,
            b: ends.start - o,
            spring: ends.start - o,
            len: ends.len(),
        }),
    ]
}
