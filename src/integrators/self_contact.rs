//! Self-contact as a penalty inside implicit Euler's linear solve.
//!
//! A pair (a vertex and a triangle without it, or two edges with no shared vertex) has, at the
//! step's start, closest-point weights `c_i` (`sum c_i = 0`) and a unit normal `n`, so its gap
//! is `g(x) = n . sum c_i x_i`, linear in the positions. Over the step the pair is held by the
//! quadratic penalty
//!
//! ```text
//! E = k/2 (delta - g(x))^2,   f_i = k (delta - g) c_i n,   df_i/dx_j = -k c_i c_j n n^T
//! ```
//!
//! with `delta` the pass's `thickness`, taken where the inertial motion would bring the pair
//! within it: `g_pred = g(x) + h n . sum c_i v_i < delta` (Baraff and Witkin 1998, section 6,
//! and Bridson et al. 2002 hold contacts by such springs; newton's VBD and OGC by the same
//! gradient and `k n n^T` Hessian on the pair's vertices). Backward Euler linearised at the
//! step's start, `(M - h^2 df/dx) dv = h (f + h df/dx v)`, then gains
//!
//! ```text
//! A_ij += h^2 k c_i c_j n n^T,   b_i += h k (delta - g_pred) c_i n
//! ```
//!
//! exact for this quadratic. Where `delta` is taken is [`Rest`]'s: the grid's pairs rest at
//! `thickness`; a mesh cloth's at the gap they start with where that is smaller, released where
//! the solve carries them beyond it, so that the penalty is one-sided and zero at the step's
//! start and the term can only take energy from the cloth. The stiffness is
//! `h^2 k = beta m_eff`, `m_eff = 1 / sum w_i c_i^2` the pair's effective mass along `n` (`w`
//! inverse masses): a lone pair ends `(delta - g_pred) / (1 + beta)` short of `delta`, for the
//! pass after the solve. Weights summing to zero make every force and every matrix row pair sum
//! to zero: the term exchanges momentum, it adds none. Held particles (`w = 0`) keep their rows
//! and columns empty, as the springs'.
//!
//! The diagonal blocks go into the assembled matrix, where the preconditioner sees them (the
//! grid's six slot columns or a mesh's blocks, [`DiagonalBlocks`]); the couplings between a
//! pair's vertices are applied matrix-free after the matrix's rows in CG's product, in two
//! passes: over the pairs, each pair's `n . sum_k c_k x_k` once and from it each of its
//! vertices' factor `s c_i (n . sum_{k != i} c_k x_k)`; then over the rows, each row adding its
//! pairs' factors times their normals in pair order, through an index of each row's pairs built
//! once a solve ([`RowIndex`]). Both passes split freely over threads and neither depends on the
//! split; each pair is read once a product, from one compact record ([`Coupling`]), and each
//! row reads only its own pairs. On one thread, where nothing is read twice anyway, one pass
//! pair by pair writes each pair's part straight into its rows, with the same roundings in the
//! same order: the product is the same to the bit for any thread count. Both read the operand
//! (and the one pass adds into the rows) through a copy of the rows with a vertex's three
//! components side by side ([`Lanes`]): a pair's vertices lie anywhere in the arrays, and a
//! vertex's components in three arrays cost three loads, three bounds checks and three stores
//! where one of each serves; the copies cost a pass over the rows up to the last pair's vertex
//! each (the operand's; on one thread also the rows' in and out).

use std::sync::{Mutex, PoisonError};

use glam::Vec3;
use rayon::prelude::*;

use crate::linear::cg::BlockOperator;
use crate::linear::stencil::SlotArrays;
use crate::linear::Sym3;
use crate::self_collision::{Apart, Pair, SelfCollision};
use crate::soa::{Vec3SliceMut, Vec3s};

/// How many times at most a step with pairs held is solved: after a solve, the pairs it brought
/// within `thickness` are held too and the step is solved again: the springs carry vertices
/// into contact that their inertia alone does not.
pub(super) const SOLVES: u32 = 2;

/// A matrix's diagonal blocks, as the term adds to them.
pub(super) trait DiagonalBlocks {
    /// `block * s` onto particle `p`'s diagonal block.
    fn add(&mut self, p: usize, s: f32, block: &Sym3);
}

/// The grid's: six columns `xx, yy, zz, xy, xz, yz`.
impl DiagonalBlocks for SlotArrays {
    fn add(&mut self, p: usize, s: f32, block: &Sym3) {
        for (column, v) in self.iter_mut().zip(block.0) {
            column[p] += s * v;
        }
    }
}

/// A mesh's: one block a vertex.
impl DiagonalBlocks for [Sym3] {
    fn add(&mut self, p: usize, s: f32, block: &Sym3) {
        self[p].add_scaled(s, block);
    }
}

/// Where a held pair's penalty rests: the gap it holds the pair at.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) enum Rest {
    /// At `thickness`: a pair that starts inside it is pushed out to it within the step. The
    /// penalty's energy at the step's start, `k/2 (delta - g(x))^2`, is then given to the
    /// cloth as the pair separates: up to `beta m_eff/2 ((delta - g) / h)^2` a pair a step.
    #[default]
    Thickness,
    /// At `thickness`, or at the pair's gap at the step's start where that is smaller, and
    /// released where the solve leaves it beyond that gap. The penalty is then zero at the
    /// start and pushes only where the pair ends within its rest: the one-sided penalty
    /// `k/2 max(0, rest - g(x))^2`, convex, solved exactly by backward Euler, which can only
    /// take energy from the cloth (kinetic + potential + penalty at the end is at most the
    /// start's). A pair inside `thickness` is kept from closing further, not pushed out: that
    /// is left to the pass after the solve.
    NoCloser,
}

impl Rest {
    /// The gap held for a pair whose gap is `g0` at the step's start.
    fn gap(self, thickness: f32, g0: f32) -> f32 {
        match self {
            Rest::Thickness => thickness,
            Rest::NoCloser => thickness.min(g0),
        }
    }
}

/// One pair held inside the solve.
#[derive(Clone, Copy, Debug)]
struct Held {
    /// Its index among the pairs handed in.
    of: u32,
    verts: [u32; 4],
    /// Closest-point weights, zero at held particles.
    c: [f32; 4],
    n: Vec3,
    /// `h^2 k`, kg.
    s: f32,
    /// The gap held, m ([`Rest`]).
    rest: f32,
    /// `rest - g_pred`, m: how far short of `rest` the inertial motion ends.
    short: f32,
}

/// A vertex's three components side by side and a zero: what the product gathers and
/// scatters a vertex at a time.
type Lanes = [f32; 4];

/// What CG's product reads of one held pair, 48 bytes: the product streams these once and
/// reads nothing else of the pair (on a large cloth, more than the caches hold).
#[derive(Clone, Copy, Debug)]
struct Coupling {
    /// The pair's vertices; a held particle's slot (which has no row) names a free vertex of
    /// the pair instead, so that every slot is a row the product may read.
    verts: [u32; 4],
    /// Closest-point weights, zero at held particles (which get no row).
    c: [f32; 4],
    /// The normal, then `h^2 k` (kg).
    ns: Lanes,
}

impl Coupling {
    /// Per slot `k`, `h^2 k c_k (n . sum_{j != k} c_j x_j)`: the pair's sum once from each
    /// vertex's `c_j n . x_j` in slot order, each slot's own part taken out. Slots with `c = 0`
    /// add nothing to the sum and have no row. Both forms of the product take their factors
    /// here, so they round alike.
    ///
    /// On x86-64 the four slots' dot products are taken as the four lanes of one vector: the
    /// gathered vertices transposed to their x, y and z across the slots, then each lane's
    /// `(n_x x + n_y y) + n_z z`, the rounding and order of [`Vec3::dot`] and of the scalar
    /// form below, lane by lane (the vector unit rounds each lane as the scalar one, and Rust
    /// contracts no multiply-add). A held particle's slot reads a free vertex of the pair
    /// ([`Coupling::verts`]) and is masked to `+0.0`, which the sum from `+0.0` takes as the
    /// scalar form's skip: adding `+0.0` changes only `-0.0`, and a sum from `+0.0` is never
    /// `-0.0`. The product is a fifth of a wound twist's frame; this form and the scalar one
    /// measured in the contact notebook, "2026-12-07 (twistcg)".
    #[cfg(target_arch = "x86_64")]
    #[inline]
    fn factors(&self, x: &[Lanes]) -> [f32; 4] {
        use std::arch::x86_64::*;
        // SAFETY: SSE is part of x86-64's baseline, so every x86-64 CPU runs these
        // instructions; they read and write no memory but their operands.
        unsafe {
            let vertex = |k: usize| {
                let p = x[self.verts[k] as usize];
                _mm_set_ps(p[3], p[2], p[1], p[0])
            };
            let (p0, p1, p2, p3) = (vertex(0), vertex(1), vertex(2), vertex(3));
            let (low01, low23) = (_mm_unpacklo_ps(p0, p1), _mm_unpacklo_ps(p2, p3));
            let (high01, high23) = (_mm_unpackhi_ps(p0, p1), _mm_unpackhi_ps(p2, p3));
            let (xs, ys) = (_mm_movelh_ps(low01, low23), _mm_movehl_ps(low23, low01));
            let zs = _mm_movelh_ps(high01, high23);
            let n = self.ns;
            let dots = _mm_add_ps(
                _mm_add_ps(
                    _mm_mul_ps(_mm_set1_ps(n[0]), xs),
                    _mm_mul_ps(_mm_set1_ps(n[1]), ys),
                ),
                _mm_mul_ps(_mm_set1_ps(n[2]), zs),
            );
            let c = _mm_set_ps(self.c[3], self.c[2], self.c[1], self.c[0]);
            let own = _mm_and_ps(_mm_cmpneq_ps(c, _mm_setzero_ps()), _mm_mul_ps(c, dots));
            // Lane `k` of `v`, by a shuffle: a copy through memory measured slower.
            let lane = |v: __m128, k: usize| {
                _mm_cvtss_f32(match k {
                    0 => v,
                    1 => _mm_shuffle_ps::<0b01_01_01_01>(v, v),
                    2 => _mm_shuffle_ps::<0b10_10_10_10>(v, v),
                    _ => _mm_shuffle_ps::<0b11_11_11_11>(v, v),
                })
            };
            let all = (((0.0 + lane(own, 0)) + lane(own, 1)) + lane(own, 2)) + lane(own, 3);
            // `s c (..)` is `(s c) (..)`, rounded as the pair's own first product.
            let factors = _mm_mul_ps(
                _mm_mul_ps(_mm_set1_ps(n[3]), c),
                _mm_sub_ps(_mm_set1_ps(all), own),
            );
            std::array::from_fn(|k| lane(factors, k))
        }
    }

    /// [`Coupling::factors`] a slot at a time, where no vector form is written.
    #[cfg(not(target_arch = "x86_64"))]
    #[inline]
    fn factors(&self, x: &[Lanes]) -> [f32; 4] {
        let (mut own, mut all) = ([0.0f32; 4], 0.0);
        let n = self.ns;
        for (k, own) in own.iter_mut().enumerate() {
            if self.c[k] != 0.0 {
                let p = x[self.verts[k] as usize];
                // `Vec3::dot`'s order of sums, so that every rounding is the vectors' own.
                *own = self.c[k] * ((n[0] * p[0] + n[1] * p[1]) + n[2] * p[2]);
                all += *own;
            }
        }
        // `s c (..)` is `(s c) (..)`, rounded as the pair's own first product.
        std::array::from_fn(|k| (self.ns[3] * self.c[k]) * (all - own[k]))
    }

    fn normal(&self) -> Vec3 {
        Vec3::new(self.ns[0], self.ns[1], self.ns[2])
    }

    /// The normal with a zero fourth lane, to add into a packed row.
    fn normal_lanes(&self) -> Lanes {
        [self.ns[0], self.ns[1], self.ns[2], 0.0]
    }
}

/// Rows `..rows` of `v` into `out`, a vertex's components side by side.
fn pack(v: &Vec3s, rows: usize, out: &mut Vec<Lanes>) {
    out.clear();
    out.extend((0..rows).map(|i| [v.x[i], v.y[i], v.z[i], 0.0]));
}

/// `packed`'s rows back into the first rows of `v`.
fn unpack(packed: &[Lanes], v: &mut Vec3s) {
    for (i, p) in packed.iter().enumerate() {
        v.x[i] = p[0];
        v.y[i] = p[1];
        v.z[i] = p[2];
    }
}

/// The product's workspace, kept between products so that it is allocated once.
#[derive(Default)]
struct Workspace {
    /// One entry a held pair: per slot `k`, `s c_k` times the pair's `n . sum_{j != k} c_j x_j`.
    factors: Vec<[f32; 4]>,
    /// The operand's rows up to the last held pair's, packed.
    x: Vec<Lanes>,
    /// On one thread, the product's rows up to the last held pair's, packed.
    y: Vec<Lanes>,
}

/// Each row's held pairs, in pair order: a compressed row index over the pairs' slots, so that
/// a row of the product reads its own pairs and no other.
#[derive(Default)]
struct RowIndex {
    /// Row `i`'s entries are `entries[start[i]..start[i + 1]]`; rows past `start.len() - 1`
    /// (beyond every held pair's vertices) have none.
    start: Vec<u32>,
    /// `4 pair + slot` of each free slot (`c != 0`), grouped by row, in pair order in a row.
    entries: Vec<u32>,
    /// The next free entry of each row while the index is filled.
    next: Vec<u32>,
}

/// Pairs a task in the product's pass over the pairs: enough to outweigh a task's cost.
const PAIRS_A_TASK: usize = 512;

/// Rows a task in the product's pass over the rows.
const ROWS_A_TASK: usize = 1024;

/// The pairs of one solve, kept between steps so that their buffers are reused.
#[derive(Default)]
pub(super) struct SelfContactTerm {
    /// Where its pairs rest.
    rest: Rest,
    held: Vec<Held>,
    /// The held pairs as the product reads them, in the same order.
    couplings: Vec<Coupling>,
    /// The rows' pairs of `couplings`.
    rows: RowIndex,
    /// The product's workspace. Behind a lock because the product is taken through `&self`;
    /// one product holds it at a time.
    work: Mutex<Workspace>,
    /// The pairs handed in that the inertial motion leaves beyond their rest, as [`hold`] made
    /// them at the step's start, in pair order: what [`SelfContactTerm::extend`] may still
    /// hold. Kept from the step's start because their records are a function of that state
    /// alone, which no later solve of the step changes (a held pair leaves the list, and a
    /// released one is not held again).
    waiting: Vec<Held>,
}

/// What the pipeline hands the solve: the pairs ahead of it and the pass's settings.
#[derive(Clone, Copy)]
pub struct SelfPairs<'a> {
    pub pairs: &'a [Pair],
    /// The gap held, m.
    pub thickness: f32,
    /// `beta`: the penalty as a multiple of a pair's effective mass over `h^2`.
    pub stiffness: f32,
    /// Where `pairs` is empty because every pair ahead is too far apart to be held: how far,
    /// and the pass to ask for them if the solve moves farther than that allows for.
    pub apart: Option<(Apart, &'a SelfCollision)>,
}

impl SelfPairs<'_> {
    /// Whether the solve asked for the pairs left out: the step must be solved again with them.
    pub fn asked(&self) -> bool {
        self.apart.is_some_and(|(_, pass)| pass.pairs_ahead_asked())
    }
}

impl SelfContactTerm {
    /// A term whose pairs rest as `rest` says.
    pub(super) fn resting(rest: Rest) -> Self {
        SelfContactTerm {
            rest,
            ..SelfContactTerm::default()
        }
    }

    /// The pairs of `pairs` a step of `h` s from `(pos, vel)` would bring within `thickness`.
    pub(super) fn gather(
        &mut self,
        h: f32,
        pairs: SelfPairs,
        (pos, vel, inv_mass): (&Vec3s, &Vec3s, &[f32]),
    ) {
        self.held.clear();
        self.waiting.clear();
        for (i, pair) in pairs.pairs.iter().enumerate() {
            let Some(held) = hold(h, pairs, (i, pair), self.rest, (pos, vel, inv_mass)) else {
                continue;
            };
            match held.short > 0.0 {
                true => self.held.push(held),
                false => self.waiting.push(held),
            }
        }
        self.index_couplings();
    }

    /// Adds the pairs of `pairs` not held yet that the solve's `dv` brought within their rest
    /// gap (their closest points and normal still those at the step's start), with their
    /// diagonal blocks into `d` and their loads into `b`; under [`Rest::NoCloser`] first
    /// releases the held pairs the solve left beyond their rest gap (there the penalty pulls),
    /// taking theirs out of `d` and `b`. Returns how many pairs were added or released.
    pub(super) fn extend<D: DiagonalBlocks + ?Sized>(
        &mut self,
        h: f32,
        pairs: SelfPairs,
        (pos, vel, dv): (&Vec3s, &Vec3s, &Vec3s),
        (d, b): (&mut D, &mut Vec3s),
    ) -> usize {
        let end_gap = |pair: &Pair, n: Vec3| {
            let mut end = 0.0;
            for k in 0..4 {
                let p = pair.verts[k] as usize;
                let x = pos.get(p) + h * (vel.get(p) + dv.get(p));
                end += pair.c[k] as f32 * n.dot(x);
            }
            end
        };
        if let Some((apart, pass)) = pairs.apart {
            // No pair was given, so none is held: ask for them where the solve's motion could
            // have brought one within `thickness`.
            if !apart.holds_none(h, pairs.thickness, vel, dv) {
                pass.ask_for_pairs_ahead();
            }
            return 0;
        }
        let mut released = 0;
        if self.rest == Rest::NoCloser {
            let pulled = |held: &Held| end_gap(&pairs.pairs[held.of as usize], held.n) > held.rest;
            for held in self.held.iter().filter(|held| pulled(held)) {
                add_diagonal_of(held, -1.0, d);
                add_rhs_of(held, -1.0, h, b);
                released += 1;
            }
            if released > 0 {
                self.held.retain(|held| !pulled(held));
            }
        }
        let before = self.held.len();
        let held = &mut self.held;
        self.waiting.retain(|waiting| {
            let brought = end_gap(&pairs.pairs[waiting.of as usize], waiting.n) < waiting.rest;
            if brought {
                held.push(*waiting);
            }
            !brought
        });
        let added = self.held.len() - before;
        if added > 0 {
            self.add_diagonal(before, d);
            self.add_rhs(before, h, b);
        }
        if added + released > 0 {
            self.index_couplings();
        }
        added + released
    }

    /// The held pairs' records for the product, each row's pairs and the product's workspace.
    fn index_couplings(&mut self) {
        self.couplings.clear();
        self.couplings.extend(self.held.iter().map(|held| {
            // A held pair has a free vertex: its effective mass is finite.
            let free = held.c.iter().position(|&c| c != 0.0).unwrap_or(0);
            Coupling {
                verts: std::array::from_fn(|k| match held.c[k] != 0.0 {
                    true => held.verts[k],
                    false => held.verts[free],
                }),
                c: held.c,
                ns: [held.n.x, held.n.y, held.n.z, held.s],
            }
        }));
        let free_slots = || {
            self.couplings.iter().enumerate().flat_map(|(p, pair)| {
                (0..4)
                    .filter(move |&k| pair.c[k] != 0.0)
                    .map(move |k| (pair.verts[k] as usize, (4 * p + k) as u32))
            })
        };
        let rows = free_slots().map(|(v, _)| v + 1).max().unwrap_or(0);
        let index = &mut self.rows;
        index.start.clear();
        index.start.resize(rows + 1, 0);
        for (v, _) in free_slots() {
            index.start[v + 1] += 1;
        }
        let mut total = 0;
        for start in &mut index.start {
            total += *start;
            *start = total;
        }
        index.next.clear();
        index.next.extend_from_slice(&index.start[..rows]);
        index.entries.clear();
        index.entries.resize(index.start[rows] as usize, 0);
        for (v, entry) in free_slots() {
            index.entries[index.next[v] as usize] = entry;
            index.next[v] += 1;
        }
        let work = self.work.get_mut().unwrap_or_else(PoisonError::into_inner);
        work.factors.clear();
        work.factors.resize(self.couplings.len(), [0.0; 4]);
    }

    /// No pair held: the solve is the plain one.
    pub(super) fn clear(&mut self) {
        self.held.clear();
    }

    pub(super) fn is_empty(&self) -> bool {
        self.held.is_empty()
    }

    /// Pairs held in the last solve.
    pub(super) fn len(&self) -> usize {
        self.held.len()
    }

    /// `h^2 k c_i^2 n n^T` of the held pairs from the `from`-th on, onto each free vertex's
    /// diagonal block.
    pub(super) fn add_diagonal<D: DiagonalBlocks + ?Sized>(&self, from: usize, d: &mut D) {
        for held in &self.held[from..] {
            add_diagonal_of(held, 1.0, d);
        }
    }

    /// `h k (delta - g_pred) c_i n` of the held pairs from the `from`-th on, onto each free
    /// vertex's right-hand side.
    pub(super) fn add_rhs(&self, from: usize, h: f32, b: &mut Vec3s) {
        for held in &self.held[from..] {
            add_rhs_of(held, 1.0, h, b);
        }
    }

    /// Every held pair's [`Coupling::factors`] into `factors`, in parallel over the pairs.
    fn pair_factors(&self, x: &[Lanes], factors: &mut [[f32; 4]]) {
        factors
            .par_chunks_mut(PAIRS_A_TASK)
            .zip(self.couplings.par_chunks(PAIRS_A_TASK))
            .for_each(|(factors, pairs)| {
                for (factor, pair) in factors.iter_mut().zip(pairs) {
                    *factor = pair.factors(x);
                }
            });
    }

    /// `out_i += sum over i's pairs of factor n` for the rows `range` (`out` covers exactly
    /// `range`), each row's pairs in pair order: the couplings the diagonal leaves out.
    fn gather_range(
        &self,
        factors: &[[f32; 4]],
        range: std::ops::Range<usize>,
        out: &mut Vec3SliceMut,
    ) {
        let index = &self.rows;
        let indexed = index.start.len().saturating_sub(1);
        for (i, row) in (range.start..range.end.min(indexed)).enumerate() {
            let entries = &index.entries[index.start[row] as usize..index.start[row + 1] as usize];
            if entries.is_empty() {
                continue;
            }
            let mut sum = out.get(i);
            for &entry in entries {
                let (p, k) = (entry as usize / 4, entry as usize % 4);
                sum += factors[p][k] * self.couplings[p].normal();
            }
            out.set(i, sum);
        }
    }

    /// The couplings over all of `y`'s rows in one pass over the pairs: each pair's
    /// [`Coupling::factors`], then its part of each of its vertices' rows, every row adding
    /// its pairs in pair order: the same factors in the same order as
    /// [`SelfContactTerm::gather_range`], so the same to the bit.
    fn pair_by_pair(&self, x: &[Lanes], y: &mut [Lanes]) {
        for pair in &self.couplings {
            let factors = pair.factors(x);
            let n = pair.normal_lanes();
            for ((&v, &c), factor) in pair.verts.iter().zip(&pair.c).zip(factors) {
                if c != 0.0 {
                    // `y + factor n` a component at a time, as `Vec3`'s.
                    let row = &mut y[v as usize];
                    for (y, n) in row.iter_mut().zip(n) {
                        *y += factor * n;
                    }
                }
            }
        }
    }

    /// The couplings over all of `y`'s rows, the operand read through its packed rows. On one
    /// thread, pair by pair: each pair is read once and its part added straight into the packed
    /// rows, with no factors to write and read back. On more, the pairs' factors in parallel
    /// over the pairs, then each row's sum in parallel over the rows through the index, so that
    /// no thread reads pairs outside its rows; neither pass depends on the split.
    fn couple(&self, x: &Vec3s, y: &mut Vec3s) {
        let mut work = self.work.lock().unwrap_or_else(PoisonError::into_inner);
        let work = &mut *work;
        let rows = self.rows.start.len().saturating_sub(1);
        pack(x, rows, &mut work.x);
        if rayon::current_num_threads() == 1 {
            pack(y, rows, &mut work.y);
            self.pair_by_pair(&work.x, &mut work.y);
            unpack(&work.y, y);
            return;
        }
        self.pair_factors(&work.x, &mut work.factors);
        let factors = &work.factors;
        y.par_chunks_mut(ROWS_A_TASK)
            .enumerate()
            .for_each(|(c, mut out)| {
                let range = c * ROWS_A_TASK..c * ROWS_A_TASK + out.len();
                self.gather_range(factors, range, &mut out);
            });
    }
}

/// `sign h^2 k c_i^2 n n^T` of `held` onto each free vertex's diagonal block.
fn add_diagonal_of<D: DiagonalBlocks + ?Sized>(held: &Held, sign: f32, d: &mut D) {
    let block = Sym3::outer(1.0, held.n, 0.0);
    for k in 0..4 {
        let p = held.verts[k] as usize;
        d.add(p, sign * held.s * held.c[k] * held.c[k], &block);
    }
}

/// `sign h k (rest - g_pred) c_i n` of `held` onto each free vertex's right-hand side.
fn add_rhs_of(held: &Held, sign: f32, h: f32, b: &mut Vec3s) {
    let push = sign * held.s / h * held.short * held.n;
    for k in 0..4 {
        let p = held.verts[k] as usize;
        if held.c[k] != 0.0 {
            b.set(p, b.get(p) + held.c[k] * push);
        }
    }
}

/// Pair `i` of those handed in as a held pair of a step of `h` s from `(pos, vel)` resting as
/// `rest` says, however far its inertial motion ends (`short` may be negative); None when its
/// normal is degenerate or no vertex of it moves.
fn hold(
    h: f32,
    given: SelfPairs,
    (i, pair): (usize, &Pair),
    rest: Rest,
    (pos, vel, inv_mass): (&Vec3s, &Vec3s, &[f32]),
) -> Option<Held> {
    let n = pair.n.as_vec3();
    let mut c = [0.0f32; 4];
    let (mut rel_x, mut rel_v, mut w) = (Vec3::ZERO, Vec3::ZERO, 0.0f32);
    for ((ck, &v), &weight) in c.iter_mut().zip(&pair.verts).zip(&pair.c) {
        let (p, weight) = (v as usize, weight as f32);
        rel_x += weight * pos.get(p);
        rel_v += weight * vel.get(p);
        w += inv_mass[p] * weight * weight;
        *ck = if inv_mass[p] > 0.0 { weight } else { 0.0 };
    }
    let rest = rest.gap(given.thickness, n.dot(rel_x));
    (n != Vec3::ZERO && w > 0.0).then(|| Held {
        of: i as u32,
        verts: pair.verts,
        c,
        n,
        s: given.stiffness / w,
        rest,
        short: rest - (n.dot(rel_x) + h * n.dot(rel_v)),
    })
}

/// A matrix with the held pairs' couplings added to its product.
pub(super) struct WithSelfContacts<'a, A> {
    pub matrix: &'a A,
    /// None: the matrix alone.
    pub term: Option<&'a SelfContactTerm>,
}

impl<A: BlockOperator> BlockOperator for WithSelfContacts<'_, A> {
    #[inline(always)]
    fn apply_range(&self, x: &Vec3s, range: std::ops::Range<usize>, out: &mut Vec3SliceMut) {
        self.matrix.apply_range(x, range, out);
    }

    fn prepare(&self, x: &Vec3s) {
        self.matrix.prepare(x);
    }

    fn packs(&self) -> bool {
        self.matrix.packs()
    }

    #[inline(always)]
    fn apply_range_packed(
        &self,
        operand: (&Vec3s, &crate::linear::block_lanes::Packed),
        range: std::ops::Range<usize>,
        out: &mut Vec3SliceMut,
    ) {
        self.matrix.apply_range_packed(operand, range, out);
    }

    fn adds_after(&self) -> bool {
        self.term.is_some() || self.matrix.adds_after()
    }

    fn add_after(&self, x: &Vec3s, y: &mut Vec3s) {
        self.matrix.add_after(x, y);
        if let Some(term) = self.term {
            term.couple(x, y);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::self_collision::Pair;
    use glam::DVec3;

    /// `pairs` held 2 mm apart at 50 times their effective mass.
    fn given(pairs: &[Pair]) -> SelfPairs<'_> {
        SelfPairs {
            pairs,
            thickness: 0.002,
            stiffness: 50.0,
            apart: None,
        }
    }

    /// The pairs of `pairs` a 1/60 s step holds ([`given`]), resting at `thickness`.
    fn held(pairs: &[Pair], state: (&Vec3s, &Vec3s, &[f32])) -> SelfContactTerm {
        held_as(Rest::Thickness, pairs, state)
    }

    /// The same, resting as `rest` says.
    fn held_as(rest: Rest, pairs: &[Pair], state: (&Vec3s, &Vec3s, &[f32])) -> SelfContactTerm {
        let mut term = SelfContactTerm::resting(rest);
        term.gather(1.0 / 60.0, given(pairs), state);
        term
    }

    /// Particle `p`'s diagonal block of `d` times `u`.
    fn block_times(d: &SlotArrays, p: usize, u: Vec3) -> Vec3 {
        let b = |i: usize| d[i][p];
        Vec3::new(
            Vec3::new(b(0), b(3), b(4)).dot(u),
            Vec3::new(b(3), b(1), b(5)).dot(u),
            Vec3::new(b(4), b(5), b(2)).dot(u),
        )
    }

    /// A vertex 1 mm above a triangle, moving down at 1 m/s, and an edge pair beside it.
    fn pairs() -> (Vec<Pair>, Vec3s, Vec3s) {
        let pos = Vec3s::from_fn(8, |v| {
            [
                Vec3::new(0.2, 0.001, 0.2),
                Vec3::ZERO,
                Vec3::X,
                Vec3::Z,
                Vec3::new(2.0, 0.0, 0.0),
                Vec3::new(3.0, 0.0, 0.0),
                Vec3::new(2.5, 0.0015, -0.5),
                Vec3::new(2.5, 0.0015, 0.5),
            ][v]
        });
        let vel = Vec3s::from_fn(8, |v| match v {
            0 => Vec3::new(0.3, -1.0, 0.1),
            6 | 7 => Vec3::new(0.0, -0.5, 0.2),
            _ => Vec3::new(0.1, 0.2, -0.1),
        });
        let vt = Pair {
            verts: [0, 1, 2, 3],
            split: 1,
            c: [1.0, -0.6, -0.2, -0.2],
            n: DVec3::Y,
            d0: 0.001,
        };
        let ee = Pair {
            verts: [6, 7, 4, 5],
            split: 2,
            c: [0.5, 0.5, -0.5, -0.5],
            n: DVec3::Y,
            d0: 0.0015,
        };
        (vec![vt, ee], pos, vel)
    }

    /// The term exchanges momentum and adds none: its forces, and each column of its matrix,
    /// sum to zero over the pair's vertices, because the closest-point weights do.
    #[test]
    fn the_in_solve_contact_term_conserves_momentum() {
        let (pairs, pos, vel) = pairs();
        let inv_mass = vec![1.0f32, 2.0, 0.5, 1.0, 1.0, 3.0, 1.0, 0.25];
        let term = held(&pairs, (&pos, &vel, &inv_mass));
        assert_eq!(term.len(), 2, "both pairs are ahead of the step");
        let mut b = Vec3s::zeros(8);
        term.add_rhs(0, 1.0 / 60.0, &mut b);
        let total: DVec3 = (0..8).map(|p| b.get(p).as_dvec3()).sum();
        let scale: f64 = (0..8).map(|p| b.get(p).as_dvec3().length()).sum();
        assert!(scale > 0.0);
        assert!(total.length() < 1e-6 * scale, "{total} of {scale}");
        // The whole matrix term (diagonal and couplings) applied to any vector sums to zero.
        let x = Vec3s::from_fn(8, |v| Vec3::new(v as f32 * 0.3 - 1.0, (v * v) as f32, -0.5));
        let mut d: SlotArrays = std::array::from_fn(|_| crate::soa::Floats::zeros(8));
        term.add_diagonal(0, &mut d);
        let mut y = Vec3s::zeros(8);
        for p in 0..8 {
            y.set(p, block_times(&d, p, x.get(p)));
        }
        term.couple(&x, &mut y);
        let total: DVec3 = (0..8).map(|p| y.get(p).as_dvec3()).sum();
        let scale: f64 = (0..8).map(|p| y.get(p).as_dvec3().length()).sum();
        assert!(scale > 0.0);
        assert!(total.length() < 1e-5 * scale, "{total} of {scale}");
    }

    /// The couplings as the product takes them (each pair's sum once, a row subtracting its
    /// own part) against the plain sum over each row's pairs of `s c_i c_j n (n . x_j)`,
    /// `j != i`, with a vertex in three pairs and a pinned vertex in one.
    #[test]
    fn the_couplings_are_the_sum_over_each_rows_pairs_of_the_other_vertices() {
        let (mut pairs, pos, vel) = pairs();
        let n = glam::DVec3::new(0.6, 0.8, 0.0);
        for (verts, split, c) in [
            ([0, 4, 5, 6], 1, [1.0, -0.3, -0.3, -0.4]),
            ([0, 6, 2, 3], 2, [-0.5, -0.5, 0.25, 0.75]),
        ] {
            let d0 = 0.0005;
            pairs.push(Pair {
                verts,
                split,
                c,
                n,
                d0,
            });
        }
        let mut inv_mass = vec![1.0f32; 8];
        inv_mass[2] = 0.0;
        let mut vel = vel;
        vel.set(0, Vec3::new(0.0, -3.0, 0.0));
        let term = held(&pairs, (&pos, &vel, &inv_mass));
        assert_eq!(term.len(), 4, "every pair is ahead of the step");
        let x = Vec3s::from_fn(8, |v| {
            Vec3::new(v as f32 * 0.7 - 2.0, 1.0 / (1.0 + v as f32), 0.3)
        });
        let mut y = Vec3s::zeros(8);
        term.couple(&x, &mut y);
        let mut plain = [DVec3::ZERO; 8];
        for held in &term.held {
            let nn = held.n.as_dvec3();
            for i in 0..4 {
                for j in (0..4).filter(|&j| j != i) {
                    let (vi, vj) = (held.verts[i] as usize, held.verts[j] as usize);
                    let cc = (held.s * held.c[i] * held.c[j]) as f64;
                    plain[vi] += cc * nn * nn.dot(x.get(vj).as_dvec3());
                }
            }
        }
        let scale: f64 = plain.iter().map(|v| v.length()).sum();
        assert!(scale > 0.0);
        for (p, want) in plain.iter().enumerate() {
            let got = y.get(p).as_dvec3();
            assert!(
                (got - want).length() < 1e-5 * scale,
                "{p}: {got} against {want}"
            );
        }
        assert_eq!(y.get(2), Vec3::ZERO, "the pinned vertex gets nothing");
    }

    /// `start` plus the term's couplings of `x`, taken on `threads` threads.
    fn coupled_on(threads: usize, term: &SelfContactTerm, x: &Vec3s, start: &Vec3s) -> Vec3s {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let mut y = start.clone();
        pool.install(|| term.couple(x, &mut y));
        y
    }

    /// [`pairs`] and three more pairs (normals `normals`) across its vertices, on a cloth of
    /// `rows` vertices (those past the eighth at rest at (1, 1, 1)) whose vertex `pinned` is
    /// held, held in one term; one of the held pairs has the pinned vertex.
    fn three_more_pairs_held(normals: [DVec3; 3], rows: usize, pinned: usize) -> SelfContactTerm {
        let (mut pairs, pos, vel) = pairs();
        let slots = [
            ([0, 4, 5, 6], 1, [1.0, -0.3, -0.3, -0.4]),
            ([7, 6, 2, 3], 2, [-0.5, -0.5, 0.25, 0.75]),
            ([1, 7, 3, 5], 1, [0.9, -0.2, -0.1, -0.6]),
        ];
        for ((verts, split, c), n) in slots.into_iter().zip(normals) {
            pairs.push(Pair {
                verts,
                split,
                c,
                n,
                d0: 0.0005,
            });
        }
        let mut inv_mass = vec![1.0f32; rows];
        inv_mass[pinned] = 0.0;
        let mut vel = vel;
        vel.set(0, Vec3::new(0.0, -3.0, 0.0));
        let grown =
            |v: &Vec3s, rest: Vec3| Vec3s::from_fn(rows, |p| if p < 8 { v.get(p) } else { rest });
        let (pos, vel) = (grown(&pos, Vec3::ONE), grown(&vel, Vec3::ZERO));
        let term = held(&pairs, (&pos, &vel, &inv_mass));
        assert!(
            term.couplings.iter().any(|pair| pair.c.contains(&0.0)),
            "a held pair has a pinned vertex"
        );
        term
    }

    /// The product's couplings, taken through the rows' index over the rows split into ranges
    /// (one a task) and by [`SelfContactTerm::couple`] on three threads, are the pair by pair
    /// sums (the one thread's product) to the bit: each row adds its pairs in pair order whatever range it falls
    /// in, with the same roundings.
    #[test]
    fn the_couplings_are_the_same_to_the_bit_however_the_rows_are_split() {
        let n = glam::DVec3::new(0.0, 0.6, 0.8);
        let term = three_more_pairs_held([n; 3], 9, 4);
        assert!(term.len() > 2);
        // Row 8 lies beyond every pair's vertices, row 4 is pinned: both are left as they are.
        let x = Vec3s::from_fn(9, |v| {
            Vec3::new(0.3 * v as f32, -1.0 / (2.0 + v as f32), 0.7)
        });
        let start = Vec3s::from_fn(9, |v| Vec3::new(1.0, v as f32, -0.5));
        let whole = coupled_on(1, &term, &x, &start);
        let mut packed_x = Vec::new();
        pack(&x, term.rows.start.len() - 1, &mut packed_x);
        let mut factors = vec![[0.0; 4]; term.len()];
        term.pair_factors(&packed_x, &mut factors);
        for cuts in [
            vec![0, 9],
            vec![0, 3, 9],
            vec![0, 1, 2, 5, 7, 8, 9],
            vec![0, 4, 9],
        ] {
            let mut split = start.clone();
            for range in cuts.windows(2) {
                let mut out = split.slices_mut(range[0]..range[1]);
                term.gather_range(&factors, range[0]..range[1], &mut out);
            }
            for p in 0..9 {
                assert_eq!(split.get(p), whole.get(p), "vertex {p}, cuts {cuts:?}");
            }
        }
        for threads in [2, 3] {
            let y = coupled_on(threads, &term, &x, &start);
            for p in 0..9 {
                assert_eq!(y.get(p), whole.get(p), "vertex {p}, {threads} threads");
            }
        }
        assert_ne!(whole.get(0), start.get(0));
        assert_eq!(whole.get(4), start.get(4), "the pinned vertex gets nothing");
        assert_eq!(whole.get(8), start.get(8));
    }

    /// The normals of [`three_more_pairs_held`]'s pairs in the rounding tests.
    const NORMALS: [DVec3; 3] = [
        DVec3::new(0.0, 0.6, 0.8),
        DVec3::new(0.48, 0.6, 0.64),
        DVec3::new(-0.6, 0.0, 0.8),
    ];

    /// The product gathers and scatters each vertex's three components side by side; that must
    /// change no rounding: on one thread and on two it is, to the bit, the product taken on
    /// the vectors' own three arrays (each pair's `c_k n . x_k` as `Vec3::dot`, their sum in
    /// slot order, `(s c_k) (all - own_k)` times `n` added to the row), with operands of
    /// mixed magnitudes and signs, a pinned vertex, and rows beyond every pair left as they are.
    #[test]
    fn the_product_through_packed_rows_rounds_as_on_the_three_arrays() {
        rounds_as_on_the_three_arrays(3);
    }

    /// A held particle's slot has no row, and the packed operand covers only the rows up to
    /// the last free slot's vertex: a pair whose held vertex lies past all of them must still
    /// be coupled as the plain loop couples it (its slot reads a free vertex of the pair,
    /// masked out), not read past the packed rows.
    #[test]
    fn a_held_vertex_past_every_free_row_is_coupled_as_on_the_three_arrays() {
        let term = three_more_pairs_held(NORMALS, 10, 7);
        assert_eq!(term.rows.start.len() - 1, 7, "rows up to vertex 6 only");
        rounds_as_on_the_three_arrays(7);
    }

    /// [`SelfContactTerm::couple`] on one and two threads against the plain loop over the three
    /// arrays, to the bit, over 200 drawn operands, with vertex `pinned` held.
    fn rounds_as_on_the_three_arrays(pinned: usize) {
        let term = three_more_pairs_held(NORMALS, 10, pinned);
        assert!(term.len() >= 3, "{} pairs held", term.len());
        // Operands of mixed magnitudes and signs, many draws, so that any other order of the
        // roundings shows in some last bit.
        let draw = |trial: u32, v: usize, k: u32| {
            let h = (trial.wrapping_mul(40503)
                ^ (v as u32).wrapping_mul(2654435761)
                ^ k.wrapping_mul(97))
            .wrapping_mul(2246822519)
            .rotate_left(13)
            .wrapping_mul(3266489917);
            ((h >> 8) as f32 / (1u32 << 24) as f32 - 0.5) * 10f32.powi((h % 7) as i32 - 3)
        };
        let mut moved = 0;
        for trial in 0..200 {
            let x = Vec3s::from_fn(10, |v| {
                Vec3::new(draw(trial, v, 0), draw(trial, v, 1), draw(trial, v, 2))
            });
            let start = Vec3s::from_fn(10, |v| {
                Vec3::new(draw(trial, v, 3), draw(trial, v, 4), draw(trial, v, 5))
            });
            let mut want = start.clone();
            for held in &term.held {
                let (mut own, mut all) = ([0.0f32; 4], 0.0f32);
                for ((&v, &c), own) in held.verts.iter().zip(&held.c).zip(&mut own) {
                    if c != 0.0 {
                        *own = c * held.n.dot(x.get(v as usize));
                        all += *own;
                    }
                }
                for ((&v, &c), own) in held.verts.iter().zip(&held.c).zip(own) {
                    let v = v as usize;
                    if c != 0.0 {
                        want.set(v, want.get(v) + ((held.s * c) * (all - own)) * held.n);
                    }
                }
            }
            for threads in [1, 2] {
                let y = coupled_on(threads, &term, &x, &start);
                for p in 0..10 {
                    assert_eq!(
                        y.get(p).to_array().map(f32::to_bits),
                        want.get(p).to_array().map(f32::to_bits),
                        "vertex {p}, {threads} threads, draw {trial}"
                    );
                }
            }
            assert_eq!(
                want.get(pinned),
                start.get(pinned),
                "the pinned vertex gets nothing"
            );
            assert_eq!(want.get(9), start.get(9));
            moved += usize::from(want.get(0) != start.get(0));
        }
        assert!(
            moved > 100,
            "the couplings moved vertex 0 in {moved} of 200 draws"
        );
    }

    /// A mesh's diagonal blocks get what the grid's six columns get, entry for entry.
    #[test]
    fn the_diagonal_blocks_are_the_same_on_a_grid_and_on_a_mesh() {
        let (pairs, pos, vel) = pairs();
        let inv_mass = vec![1.0f32, 2.0, 0.0, 1.0, 1.0, 3.0, 1.0, 0.25];
        let term = held(&pairs, (&pos, &vel, &inv_mass));
        assert_eq!(term.len(), 2);
        let mut columns: SlotArrays = std::array::from_fn(|_| crate::soa::Floats::zeros(8));
        let mut blocks = [Sym3::ZERO; 8];
        term.add_diagonal(0, &mut columns);
        term.add_diagonal(0, &mut blocks[..]);
        for (p, block) in blocks.iter().enumerate() {
            let column = std::array::from_fn(|c| columns[c][p]);
            assert_eq!(block.0, column, "vertex {p}");
        }
        assert_eq!(blocks[2], Sym3::ZERO, "the pinned vertex gets nothing");
        assert_ne!(blocks[0], Sym3::ZERO);
    }

    /// A pair moving apart, or one whose inertial motion stays outside the gap, exerts
    /// nothing; a pinned vertex gets no row.
    #[test]
    fn only_pairs_ahead_of_the_step_are_held_and_pinned_vertices_get_no_row() {
        let (pairs, pos, mut vel) = pairs();
        let mut inv_mass = vec![1.0f32; 8];
        inv_mass[1] = 0.0;
        let term = held(&pairs, (&pos, &vel, &inv_mass));
        assert_eq!(term.len(), 2);
        let rows_of_1 = term
            .couplings
            .iter()
            .flat_map(|pair| (0..4).filter(move |&k| pair.verts[k] == 1 && pair.c[k] != 0.0));
        assert_eq!(rows_of_1.count(), 0, "the pinned vertex has no entry");
        for p in [0, 6, 7] {
            vel.set(p, Vec3::new(0.0, 1.0, 0.0));
        }
        assert!(held(&pairs, (&pos, &vel, &inv_mass)).is_empty());
    }

    /// A pair held at `thickness` that starts inside it holds the penalty's energy
    /// `k/2 (delta - g)^2` at the step's start and gives it to the cloth as the pair
    /// separates; one resting at the gap it starts with (where that is smaller) holds none, and
    /// a pair at rest inside `thickness` is not held at all.
    #[test]
    fn a_passive_term_holds_no_energy_at_the_steps_start() {
        let (pairs, pos, mut vel) = pairs();
        let inv_mass = vec![1.0f32; 8];
        let g0 = |held: &Held| {
            let pair = &pairs[held.of as usize];
            (0..4)
                .map(|k| pair.c[k] as f32 * held.n.dot(pos.get(pair.verts[k] as usize)))
                .sum::<f32>()
        };
        let start_energy = |term: &SelfContactTerm| -> f32 {
            let h2 = (1.0f32 / 60.0).powi(2);
            let one_sided = |held: &Held| (held.rest - g0(held)).max(0.0);
            term.held
                .iter()
                .map(|held| 0.5 * held.s / h2 * one_sided(held).powi(2))
                .sum()
        };
        let at_thickness = held(&pairs, (&pos, &vel, &inv_mass));
        let passive = held_as(Rest::NoCloser, &pairs, (&pos, &vel, &inv_mass));
        assert_eq!(
            (at_thickness.len(), passive.len()),
            (2, 2),
            "both pairs close"
        );
        assert!(start_energy(&at_thickness) > 0.0);
        assert_eq!(start_energy(&passive), 0.0);
        for p in 0..8 {
            vel.set(p, Vec3::ZERO);
        }
        let at_thickness = held(&pairs, (&pos, &vel, &inv_mass));
        let passive = held_as(Rest::NoCloser, &pairs, (&pos, &vel, &inv_mass));
        assert_eq!(at_thickness.len(), 2, "pushed out to thickness");
        assert!(passive.is_empty(), "at rest, nothing held");
    }

    /// A held pair that the solve carries beyond its rest gap would be pulled back by the
    /// penalty (which the one-sided contact never does): the next round releases it, taking its
    /// diagonal blocks and its load out again.
    #[test]
    fn a_held_pair_the_solve_carries_apart_is_released() {
        let (pairs, pos, vel) = pairs();
        let pairs = &pairs[..1];
        let inv_mass = vec![1.0f32; 8];
        let h = 1.0f32 / 60.0;
        let mut term = held_as(Rest::NoCloser, pairs, (&pos, &vel, &inv_mass));
        assert_eq!(term.len(), 1);
        let (mut d, mut b) = ([Sym3::ZERO; 8], Vec3s::zeros(8));
        term.add_diagonal(0, &mut d[..]);
        term.add_rhs(0, h, &mut b);
        let scale = term.held[0].s;
        // The vertex leaves the triangle at 2 m/s.
        let dv = Vec3s::from_fn(8, |p| {
            if p == 0 {
                Vec3::new(0.0, 3.0, 0.0)
            } else {
                Vec3::ZERO
            }
        });
        let state = (&pos, &vel, &dv);
        assert_eq!(term.extend(h, given(pairs), state, (&mut d[..], &mut b)), 1);
        assert!(term.is_empty());
        for (p, block) in d.iter().enumerate() {
            assert!(
                block.0.iter().all(|x| x.abs() < 1e-5 * scale),
                "{p}: {block:?}"
            );
            assert!(b.get(p).length() < 1e-5 * scale / h, "{p}: {}", b.get(p));
        }
        // Held again in no later round of the step.
        let still = Vec3s::zeros(8);
        let state = (&pos, &vel, &still);
        assert_eq!(term.extend(h, given(pairs), state, (&mut d[..], &mut b)), 0);
    }
}
