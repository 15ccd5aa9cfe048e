//! Forces: each effect that pushes on particles is a [`ForceTerm`]; the [`ForceModel`] holds
//! the terms a scene asked for and evaluates them all in one parallel sweep.
//!
//! The sweep cuts the particle range into chunks; inside a chunk every term adds its force into
//! the chunk's slice of the force buffer while that slice is hot in cache. Each particle's force
//! is summed in the same order whatever the chunking, so the result is bitwise independent of
//! the number of threads.

mod drag;
pub mod fused;
mod gravity;
pub mod springs;

use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use glam::Vec3;
use rayon::prelude::*;

pub use drag::AirDrag;
pub use fused::Fused;
pub use gravity::Gravity;
pub use springs::{SpringForce, Springs};

use crate::grid::{Grid, SpringKind};
use crate::profile::Profile;
use crate::soa::{Vec3SliceMut, Vec3s};

/// The state a force evaluation reads.
#[derive(Clone, Copy)]
pub struct StateRef<'a> {
    pub grid: Grid,
    pub pos: &'a Vec3s,
    pub vel: &'a Vec3s,
    /// Particle masses in kg.
    pub mass: &'a [f32],
    pub springs: &'a Springs,
}

/// What a force term may read.
pub struct ForceInput<'a> {
    /// The state being evaluated (masses are the true ones, also for pinned particles).
    pub state: StateRef<'a>,
    /// Force on each spring's anchor, per spring kind, for the springs the particles being
    /// accumulated need; filled by [`ForceTerm::prepare`] before [`ForceTerm::accumulate`].
    pub spring_table: &'a SpringTable,
    /// When set, [`ForceTerm::prepare`] also reports whether a live spring is longer than this
    /// many times its rest length (the watchdog's stretch check).
    pub stretch_watch: Option<f32>,
}

/// Per-spring anchor forces for one block of particles: for each kind, the springs anchored
/// at slots `origin[kind] ..`, which covers every spring touching the block.
#[derive(Clone, Debug, Default)]
pub struct SpringTable {
    pub kinds: [Vec3s; 6],
    pub origin: [usize; 6],
}

impl SpringTable {
    /// The anchor force of spring slot `s` of `kind`, as component slices over `slots`.
    #[inline]
    pub fn component(&self, kind: SpringKind, c: usize, slots: &Range<usize>) -> &[f32] {
        let origin = self.origin[kind.index()];
        self.kinds[kind.index()].component(c, &(slots.start - origin..slots.end - origin))
    }

    fn heap_bytes(&self) -> usize {
        self.kinds.iter().map(Vec3s::heap_bytes).sum()
    }
}

/// One additive force effect.
pub trait ForceTerm: Send + Sync {
    /// Name in `effects` and `profile()`.
    fn name(&self) -> &'static str;

    /// Adds this term's force on the particles `range` into `out`, whose slices cover exactly
    /// `range`. Must only read `input` and write `out`.
    fn accumulate(&self, input: &ForceInput, range: Range<usize>, out: &mut Vec3SliceMut);

    /// Spring kinds whose per-spring force this term computes in [`ForceTerm::prepare`].
    fn prepared_kinds(&self) -> &[SpringKind] {
        &[]
    }

    /// Writes the force on the anchor of each spring of `kind` anchored in `range` into `out`
    /// (slices covering exactly `range`). Runs for every range before any `accumulate`, so a
    /// spring's force is computed once and both its ends read it. Returns whether one of these
    /// springs is stretched beyond `input.stretch_watch` (always false when that is `None`).
    fn prepare(
        &self,
        _input: &ForceInput,
        _kind: SpringKind,
        _range: Range<usize>,
        _out: &mut Vec3SliceMut,
    ) -> bool {
        false
    }

    /// The force `accumulate` adds, as a contribution the sweep may add in one pass together
    /// with its neighbours' (see [`fused`]), bitwise as `accumulate` would; None for a term
    /// that only `accumulate` can add.
    fn fused(&self) -> Option<Fused> {
        None
    }

    /// How the force depends on the state, for implicit integrators.
    fn linearization(&self) -> Linearization;
}

/// The shape of a force term's Jacobians `df/dx`, `df/dv`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Linearization {
    /// Independent of the state, `f = m a` with `a` in m/s^2 (gravity). Implicit Euler reads it
    /// from the evaluated force; projective dynamics puts it in the inertial target
    /// `x + h v + h^2 a`.
    Acceleration(Vec3),
    /// `f = -c v`: `df/dv = -c I`.
    Drag { c: f32 },
    /// The springs of a family with stiffness `k` and damping `c` (see `forces/springs.rs`).
    Springs {
        family: crate::grid::Family,
        k: f32,
        c: f32,
    },
}

/// The force terms of a scene, in the order they are summed.
///
/// An evaluation is one parallel sweep over chunks of particles; each chunk is worked in
/// blocks of at most [`BLOCK`] particles. For a block, the terms first compute, once per
/// spring, the force on each spring's anchor into a small table ([`ForceTerm::prepare`]: the
/// springs anchored in the block and the few rows before it, whose far ends lie in the
/// block), then every term adds its force into the block's slice of the output while table
/// and slice are hot in cache, springs by reading the table (`+F` at the anchor, `-F` at the
/// far end: bitwise the force the far end would compute, so momentum is conserved exactly up
/// to summation order). Consecutive terms with a [`Fused`] form are added in one pass per
/// component ([`fused::accumulate`]), the others one by one. Each particle's force is summed
/// in the same order whatever the chunking, so the result is bitwise independent of the
/// number of threads.
pub struct ForceModel {
    terms: Vec<Box<dyn ForceTerm>>,
    /// The terms' additions into a block, in term order.
    stages: Vec<Stage>,
    /// `(term, kind)` for every spring kind some term prepares.
    prepared: Vec<(usize, SpringKind)>,
    /// The kinds of `prepared`.
    kinds: Vec<SpringKind>,
    /// One table per work item, reused by its blocks; sized on the first evaluation.
    tables: Vec<SpringTable>,
    /// `(particles, chunk)` the tables were sized for.
    tables_for: (usize, usize),
    /// CPU nanoseconds per term during the current evaluation, summed over threads.
    cpu_nanos: Vec<AtomicU64>,
    /// The watchdog's stretch limit (`l / L`), checked by an evaluation only when armed.
    stretch_limit: Option<f32>,
    /// Whether the next evaluation checks the stretch limit.
    watch_armed: bool,
    /// Whether the last armed evaluation found a spring beyond the limit.
    overstretched: AtomicBool,
}

/// One addition into a block's forces.
enum Stage {
    /// A term's own [`ForceTerm::accumulate`].
    Term(usize),
    /// Consecutive terms and their contributions, added in one pass.
    Fused {
        terms: Vec<usize>,
        contributions: Vec<Fused>,
    },
}

impl Stage {
    /// The stages for `terms`: runs of consecutive fusable terms, each run cut where it would
    /// read more than [`fused::MAX_STREAMS`] arrays per component.
    fn plan(terms: &[Box<dyn ForceTerm>]) -> Vec<Stage> {
        let mut stages = Vec::new();
        for (t, term) in terms.iter().enumerate() {
            let Some(contribution) = term.fused().filter(|c| c.streams() <= fused::MAX_STREAMS)
            else {
                stages.push(Stage::Term(t));
                continue;
            };
            match stages.last_mut() {
                Some(Stage::Fused {
                    terms,
                    contributions,
                }) if contributions.iter().map(Fused::streams).sum::<usize>()
                    + contribution.streams()
                    <= fused::MAX_STREAMS =>
                {
                    terms.push(t);
                    contributions.push(contribution);
                }
                _ => stages.push(Stage::Fused {
                    terms: vec![t],
                    contributions: vec![contribution],
                }),
            }
        }
        stages
    }
}

/// Particles per block: its spring table (six kinds, plus up to two grid rows of springs before
/// the block) stays in a core's L2 cache up to 512 x 512 cloths; the rows before the block are
/// evaluated twice, about 10 % extra spring work at 512 wide.
pub const BLOCK: usize = 4096;

impl ForceModel {
    pub fn new(terms: Vec<Box<dyn ForceTerm>>) -> Self {
        let cpu_nanos = terms.iter().map(|_| AtomicU64::new(0)).collect();
        let prepared: Vec<(usize, SpringKind)> = terms
            .iter()
            .enumerate()
            .flat_map(|(t, term)| term.prepared_kinds().iter().map(move |&kind| (t, kind)))
            .collect();
        let kinds = prepared.iter().map(|&(_, kind)| kind).collect();
        ForceModel {
            stages: Stage::plan(&terms),
            terms,
            kinds,
            prepared,
            tables: Vec::new(),
            tables_for: (0, 0),
            cpu_nanos,
            stretch_limit: None,
            watch_armed: false,
            overstretched: AtomicBool::new(false),
        }
    }

    /// Sets the watchdog's stretch limit, a ratio `l / L` (None: no stretch check).
    pub fn set_stretch_limit(&mut self, limit: Option<f32>) {
        self.stretch_limit = limit;
    }

    /// Makes the next evaluation (only) check every live spring against the stretch limit, in
    /// the same loop that computes its force: one compare per spring, no extra pass.
    pub fn arm_stretch_watch(&mut self) {
        self.watch_armed = self.stretch_limit.is_some();
        self.overstretched.store(false, Ordering::Relaxed);
    }

    /// Whether the last armed evaluation found a spring beyond the stretch limit.
    pub fn overstretched(&self) -> bool {
        self.overstretched.load(Ordering::Relaxed)
    }

    pub fn names(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.terms.iter().map(|t| t.name())
    }

    pub fn linearizations(&self) -> impl Iterator<Item = Linearization> + '_ {
        self.terms.iter().map(|t| t.linearization())
    }

    /// The spring kinds whose forces the model computes: those the stretch watch checks.
    pub fn spring_kinds(&self) -> &[SpringKind] {
        &self.kinds
    }

    /// Heap memory of the spring tables.
    pub fn heap_bytes(&self) -> usize {
        self.tables.iter().map(SpringTable::heap_bytes).sum()
    }

    /// One table per work item, each long enough for a block and the springs before it.
    fn size_tables(&mut self, grid: Grid, chunk: usize) {
        let n = grid.len();
        if self.prepared.is_empty() || self.tables_for == (n, chunk) {
            return;
        }
        let longest = chunk.min(BLOCK)
            + self
                .prepared
                .iter()
                .map(|&(_, k)| grid.offset(k))
                .max()
                .unwrap_or(0);
        let mut table = SpringTable::default();
        for &(_, kind) in &self.prepared {
            table.kinds[kind.index()] = Vec3s::zeros(longest);
        }
        self.tables = vec![table; n.div_ceil(chunk)];
        self.tables_for = (n, chunk);
    }

    /// Writes the total force on every particle into `out` and returns the evaluation's wall
    /// time, which it also books into `profile` split among the terms as the CPU time each
    /// measured (a fused stage's time split among its terms as the arrays each reads).
    pub fn evaluate(
        &mut self,
        state: StateRef,
        out: &mut Vec3s,
        chunk: usize,
        profile: &mut Profile,
    ) -> Duration {
        let start = Instant::now();
        self.size_tables(state.grid, chunk);
        let grid = state.grid;
        let stretch_watch = if std::mem::take(&mut self.watch_armed) {
            self.stretch_limit
        } else {
            None
        };
        let Self {
            terms,
            stages,
            prepared,
            tables,
            cpu_nanos,
            overstretched,
            ..
        } = self;
        let clocked = |work: &mut dyn FnMut()| {
            let clock = Instant::now();
            work();
            clock.elapsed().as_nanos() as u64
        };
        let book = |t: usize, nanos: u64| cpu_nanos[t].fetch_add(nanos, Ordering::Relaxed);
        let blank = SpringTable::default();
        let prepare_input = ForceInput {
            state,
            spring_table: &blank,
            stretch_watch,
        };
        // A fused first stage writes every force of the block; otherwise start from zero.
        let fresh = matches!(stages.first(), Some(Stage::Fused { .. }));
        let sweep = |(c, (mut f, table)): (usize, (Vec3SliceMut, &mut SpringTable))| {
            let range = c * chunk..c * chunk + f.len();
            if !fresh {
                f.fill(Vec3::ZERO);
            }
            let mut block_start = range.start;
            while block_start < range.end {
                let block = block_start..(block_start + BLOCK).min(range.end);
                // Each term's kinds (consecutive in `prepared`), timed together.
                for run in prepared.chunk_by(|a, b| a.0 == b.0) {
                    let t = run[0].0;
                    let nanos = clocked(&mut || {
                        for &(_, kind) in run {
                            let lo = block.start.saturating_sub(grid.offset(kind));
                            table.origin[kind.index()] = lo;
                            let mut slots = table.kinds[kind.index()].slices_mut(0..block.end - lo);
                            if terms[t].prepare(&prepare_input, kind, lo..block.end, &mut slots) {
                                overstretched.store(true, Ordering::Relaxed);
                            }
                        }
                    });
                    book(t, nanos);
                }
                let input = ForceInput {
                    state,
                    spring_table: table,
                    stretch_watch: None,
                };
                let mut f_block = f.sub_mut(block.start - range.start..block.end - range.start);
                for (i, stage) in stages.iter().enumerate() {
                    match stage {
                        Stage::Term(t) => {
                            let nanos = clocked(&mut || {
                                terms[*t].accumulate(&input, block.clone(), &mut f_block)
                            });
                            book(*t, nanos);
                        }
                        Stage::Fused {
                            terms: group,
                            contributions,
                        } => {
                            let nanos = clocked(&mut || {
                                let first = fresh && i == 0;
                                fused::accumulate(
                                    &input,
                                    contributions,
                                    first,
                                    block.clone(),
                                    &mut f_block,
                                )
                            });
                            // Split among the group's terms as the arrays each reads.
                            let streams = contributions.iter().map(Fused::streams).sum::<usize>();
                            for (&t, c) in group.iter().zip(contributions) {
                                book(t, nanos * c.streams() as u64 / streams.max(1) as u64);
                            }
                        }
                    }
                }
                block_start = block.end;
            }
        };
        if prepared.is_empty() {
            // No springs: an empty table (no heap memory) per item.
            out.par_chunks_mut(chunk).enumerate().for_each(|(c, f)| {
                sweep((c, (f, &mut SpringTable::default())));
            });
        } else {
            out.par_chunks_mut(chunk)
                .zip(tables.par_iter_mut())
                .enumerate()
                .for_each(sweep);
        }

        let wall = start.elapsed();
        profile.force_time += wall;
        let cpu_total = cpu_nanos
            .iter()
            .map(|n| n.load(Ordering::Relaxed))
            .sum::<u64>();
        for (term, nanos) in terms.iter().zip(cpu_nanos.iter()) {
            let share = nanos.swap(0, Ordering::Relaxed) as f64 / cpu_total.max(1) as f64;
            profile.add(term.name(), wall.mul_f64(share));
        }
        wall
    }
}
