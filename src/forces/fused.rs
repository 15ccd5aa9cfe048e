//! Adding several forces into a block's forces in one pass per component.
//!
//! Run one after the other, gravity and the three spring families would each read and write the
//! block's whole force slice again: with two spring kinds per family and a `+F` and a `-F` run
//! per kind, that is a dozen passes over a slice larger than the L1 cache. Instead, for a strip
//! of particles the running sum stays in registers while each force's contribution is added to
//! it, in the forces' order, and it is stored once. The additions are the ones the forces would
//! make one by one, in the same order, so the result is bitwise the same:
//!
//! - [`Force::Gravity`]: `f += m g`, component by component; a zero component of `g` adds
//!   nothing, not even zero;
//! - [`Force::Drag`]: `f -= c v`;
//! - [`Force::Springs`]: for each kind of the family in order, `+F` of the spring the particle
//!   anchors and `-F` of the spring it ends, read from the block's spring table (where those
//!   springs exist).

use std::ops::Range;

use glam::Vec3;

use super::{Force, SpringTable, StateRef, MAX_STREAMS};
use crate::soa::Vec3SliceMut;
use crate::springs::neighbour_runs;

/// Particles per strip: the running sums of a strip stay in registers (four AVX-512 vectors).
const STRIP: usize = 64;

/// Adds `group`'s forces, in order, to the forces `out` of the particles `range`, springs from
/// `table`. With `fresh`, `out` holds no force yet: its contents are ignored and the sums start
/// from zero, as from a zero-filled buffer. `group` reads at most [`MAX_STREAMS`] arrays per
/// component.
pub(super) fn accumulate(
    state: StateRef,
    table: &SpringTable,
    group: &[Force],
    fresh: bool,
    range: Range<usize>,
    out: &mut Vec3SliceMut,
) {
    crate::simd::dispatch!(accumulate_in(
        state,
        table,
        group,
        fresh,
        range.clone(),
        out
    ))
}

#[inline(always)]
fn accumulate_in(
    state: StateRef,
    table: &SpringTable,
    group: &[Force],
    fresh: bool,
    range: Range<usize>,
    out: &mut Vec3SliceMut,
) {
    debug_assert!(group.iter().map(Force::streams).sum::<usize>() <= MAX_STREAMS);
    let n = state.grid.len();
    // The interior: particles that both anchor and end a spring of every kind in the group.
    let (mut lo, mut hi) = (range.start, range.end);
    for kind in group.iter().flat_map(Force::spring_kinds) {
        let o = state.grid.offset(*kind);
        lo = lo.max(o);
        hi = hi.min(n.saturating_sub(o));
    }
    // A block can be shorter than a spring's index offset (a wide grid's bending springs span
    // two rows): then it has no interior, and `lo` must not run past the block's end.
    let lo = lo.min(range.end);
    let hi = hi.max(lo);
    // Near the grid's first and last rows some of those springs are missing: there, one
    // contribution after the other, each a pass over the few particles concerned.
    for edge in [range.start..lo, hi..range.end] {
        if edge.is_empty() {
            continue;
        }
        let mut f = out.sub_mut(edge.start - range.start..edge.end - range.start);
        if fresh {
            f.fill(Vec3::ZERO);
        }
        for force in group {
            add_one(state, table, force, edge.clone(), &mut f);
        }
    }
    if lo == hi {
        return;
    }
    let interior = lo - range.start..hi - range.start;
    for c in 0..3 {
        let mut ops = [Op::Add(&[]); MAX_STREAMS];
        let mut count = 0;
        let mut push = |op| {
            ops[count] = op;
            count += 1;
        };
        for force in group {
            match *force {
                Force::Gravity { g } if g[c] != 0.0 => {
                    push(Op::AddTimes(&state.mass[lo..hi], g[c]));
                }
                Force::Gravity { .. } => {}
                Force::Drag { c: k } => {
                    push(Op::SubTimes(state.vel.component(c, &(lo..hi)), k));
                }
                Force::Springs { family, .. } => {
                    for &kind in family.kinds_slice() {
                        let o = state.grid.offset(kind);
                        push(Op::Add(table.component(kind, c, &(lo..hi))));
                        push(Op::Sub(table.component(kind, c, &(lo - o..hi - o))));
                    }
                }
            }
        }
        sum_strips(
            &ops[..count],
            fresh,
            &mut out.component_mut(c)[interior.clone()],
        );
    }
}

/// One array's part in a component's sum, over the interior.
#[derive(Clone, Copy)]
enum Op<'a> {
    /// `f += t`
    Add(&'a [f32]),
    /// `f -= t`: exactly `f += -1 * t`, as IEEE 754 defines subtraction.
    Sub(&'a [f32]),
    /// `f += x * s`
    AddTimes(&'a [f32], f32),
    /// `f -= s * x`
    SubTimes(&'a [f32], f32),
}

/// `f[i]` (or zero, with `fresh`) plus each op's term for `i`, in order, for every `i`.
#[inline(always)]
fn sum_strips(ops: &[Op], fresh: bool, f: &mut [f32]) {
    let full = f.len() / STRIP * STRIP;
    for at in (0..full).step_by(STRIP) {
        let f: &mut [f32; STRIP] = (&mut f[at..at + STRIP]).try_into().unwrap();
        let mut acc = if fresh { [0.0; STRIP] } else { *f };
        for op in ops {
            match *op {
                Op::Add(t) => add(&mut acc, &t[at..at + STRIP], |acc, t| acc + t),
                Op::Sub(t) => add(&mut acc, &t[at..at + STRIP], |acc, t| acc - t),
                Op::AddTimes(x, s) => add(&mut acc, &x[at..at + STRIP], |acc, x| acc + x * s),
                Op::SubTimes(x, s) => add(&mut acc, &x[at..at + STRIP], |acc, x| acc - s * x),
            }
        }
        *f = acc;
    }
    for i in full..f.len() {
        let mut acc = if fresh { 0.0 } else { f[i] };
        for op in ops {
            acc = match *op {
                Op::Add(t) => acc + t[i],
                Op::Sub(t) => acc - t[i],
                Op::AddTimes(x, s) => acc + x[i] * s,
                Op::SubTimes(x, s) => acc - s * x[i],
            };
        }
        f[i] = acc;
    }
}

/// `acc[k] = rule(acc[k], t[k])` across a strip: one vector operation per register.
#[inline(always)]
fn add(acc: &mut [f32; STRIP], t: &[f32], rule: impl Fn(f32, f32) -> f32) {
    let t: &[f32; STRIP] = t.try_into().unwrap();
    for k in 0..STRIP {
        acc[k] = rule(acc[k], t[k]);
    }
}

/// Adds one force to the forces `f` of the particles `range`, as a pass of its own.
#[inline(always)]
fn add_one(
    state: StateRef,
    table: &SpringTable,
    force: &Force,
    range: Range<usize>,
    f: &mut Vec3SliceMut,
) {
    match *force {
        Force::Gravity { g } => {
            let mass = &state.mass[range];
            for (component, a) in [(&mut *f.x, g.x), (&mut *f.y, g.y), (&mut *f.z, g.z)] {
                if a != 0.0 {
                    for (f, m) in component.iter_mut().zip(mass) {
                        *f += m * a;
                    }
                }
            }
        }
        Force::Drag { c: k } => {
            let vel = state.vel.slices(range);
            for (f, v) in [(&mut *f.x, vel.x), (&mut *f.y, vel.y), (&mut *f.z, vel.z)] {
                for (f, v) in f.iter_mut().zip(v) {
                    *f -= k * v;
                }
            }
        }
        Force::Springs { family, .. } => {
            let n = state.grid.len();
            for &kind in family.kinds_slice() {
                let [anchors, ends] = neighbour_runs(n, state.grid.offset(kind), range.clone());
                for (run, sign) in [(anchors, 1.0f32), (ends, -1.0)] {
                    let Some(run) = run else { continue };
                    let s = run.slots();
                    let o = run.a - range.start..run.a - range.start + run.len;
                    for (c, f) in [&mut *f.x, &mut *f.y, &mut *f.z].into_iter().enumerate() {
                        let (t, f) = (table.component(kind, c, &s), &mut f[o.clone()]);
                        for i in 0..f.len() {
                            // sign * t is exactly the force the far end computes for itself.
                            f[i] += sign * t[i];
                        }
                    }
                }
            }
        }
    }
}
