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

use super::{ForceInput, ForceTerm};
use crate::grid::{Family, Grid, SpringKind};
use crate::soa::{Vec3SliceMut, Vec3s};

/// Per-spring data, one array per [`SpringKind`], indexed by the spring's anchor particle.
///
/// Slots whose spring does not exist (off the grid) or was cut have `active = 0`, which makes
/// their force exactly zero; keeping the slots lets the kernel run over whole index ranges
/// without row-boundary branches.
#[derive(Clone, Debug)]
pub struct Springs {
    /// Rest length in m: the distance between the two particles when the cloth was built.
    pub rest: [Vec<f32>; 6],
    /// 1 for a live spring, 0 for none.
    pub active: [Vec<f32>; 6],
}

impl Springs {
    /// Every spring of the stencil, with rest lengths taken from `pos`.
    pub fn new(grid: Grid, pos: &Vec3s) -> Self {
        let n = grid.len();
        let mut rest: [Vec<f32>; 6] = Default::default();
        let mut active: [Vec<f32>; 6] = Default::default();
        for kind in SpringKind::ALL {
            let k = kind.index();
            rest[k] = vec![0.0; n];
            active[k] = vec![0.0; n];
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
            .map(|v| v.capacity() * size_of::<f32>())
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

    fn accumulate(&self, input: &ForceInput, range: Range<usize>, out: &mut Vec3SliceMut) {
        let n = input.grid.len();
        for kind in self.family.kinds() {
            let o = input.grid.offset(kind);
            let rest = &input.springs.rest[kind.index()];
            let active = &input.springs.active[kind.index()];
            // Particles that anchor a spring of this kind: partner a + o, spring slot a.
            let anchors = range.start..range.end.min(n.saturating_sub(o));
            if !anchors.is_empty() {
                let pair = Pair {
                    a: anchors.start,
                    b: anchors.start + o,
                    spring: anchors.start,
                };
                self.gather(input, pair, anchors.len(), rest, active, range.start, out);
            }
            // Particles at the far end of a spring: partner a - o, spring slot a - o.
            let partners = range.start.max(o)..range.end;
            if !partners.is_empty() {
                let pair = Pair {
                    a: partners.start,
                    b: partners.start - o,
                    spring: partners.start - o,
                };
                self.gather(input, pair, partners.len(), rest, active, range.start, out);
            }
        }
    }
}

/// First indices of a run of `len` (particle, neighbour, spring slot) triples.
struct Pair {
    a: usize,
    b: usize,
    spring: usize,
}

impl SpringForce {
    /// Adds to `out[a - out_start ..]` the force on particles `a..a+len` from their springs to
    /// `b..b+len`. One straight loop over equal-length slices: the compiler vectorises it.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn gather(
        &self,
        input: &ForceInput,
        pair: Pair,
        len: usize,
        rest: &[f32],
        active: &[f32],
        out_start: usize,
        out: &mut Vec3SliceMut,
    ) {
        let (pos, vel) = (input.pos, input.vel);
        let a = pair.a..pair.a + len;
        let b = pair.b..pair.b + len;
        let (xa, ya, za) = (&pos.x[a.clone()], &pos.y[a.clone()], &pos.z[a.clone()]);
        let (xb, yb, zb) = (&pos.x[b.clone()], &pos.y[b.clone()], &pos.z[b.clone()]);
        let (vxa, vya, vza) = (&vel.x[a.clone()], &vel.y[a.clone()], &vel.z[a.clone()]);
        let (vxb, vyb, vzb) = (&vel.x[b.clone()], &vel.y[b.clone()], &vel.z[b]);
        let rest = &rest[pair.spring..pair.spring + len];
        let active = &active[pair.spring..pair.spring + len];
        let o = a.start - out_start..a.end - out_start;
        let (fx, fy, fz) = (&mut out.x[o.clone()], &mut out.y[o.clone()], &mut out.z[o]);
        let (k, c) = (self.k, self.c);
        for i in 0..len {
            let (dx, dy, dz) = (xb[i] - xa[i], yb[i] - ya[i], zb[i] - za[i]);
            let l = (dx * dx + dy * dy + dz * dz).sqrt();
            let inv_l = if l > 0.0 { 1.0 / l } else { 0.0 };
            let (ux, uy, uz) = (dx * inv_l, dy * inv_l, dz * inv_l);
            let closing = (vxb[i] - vxa[i]) * ux + (vyb[i] - vya[i]) * uy + (vzb[i] - vza[i]) * uz;
            let s = active[i] * (k * (l - rest[i]) + c * closing);
            fx[i] += s * ux;
            fy[i] += s * uy;
            fz[i] += s * uz;
        }
    }
}
