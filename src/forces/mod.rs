//! Forces: the closed set of pushes on particles ([`Force`]), and the
//! [`ForceModel`] that holds those a scene asked for and evaluates them all in one parallel
//! sweep.
//!
//! An evaluation is one parallel sweep over chunks of particles; each chunk is worked in blocks
//! of at most [`BLOCK`] particles. For a block, the spring forces are first computed once per
//! spring into a small table (the springs anchored in the block and the few rows before it,
//! whose far ends lie in the block; `springs.rs`), then every force is added into the block's
//! slice of the output while table and slice are hot in cache, springs by reading the table
//! (`+F` at the anchor, `-F` at the far end: bitwise the force the far end would compute, so
//! momentum is conserved exactly up to summation order), all in one pass per component
//! (`fused.rs`). Each particle's force is summed in the same order whatever the chunking, so the
//! result is bitwise independent of the number of threads.

mod fused;
mod springs;

use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use glam::Vec3;
use rayon::prelude::*;

use crate::grid::{Family, Grid, SpringKind};
use crate::mesh_cloth::forces::PassScratch;
use crate::mesh_cloth::MeshCloth;
use crate::profile::Profile;
use crate::soa::{Vec3SliceMut, Vec3s};
use crate::springs::Springs;

/// One additive force, with its parameters. The force law of each is in the module that
/// evaluates it: `m g` and `-c v` in `fused.rs`, the springs in `springs.rs`; implicit
/// integrators read the parameters to linearise them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Force {
    /// Uniform gravity, `f = m g`, `g` in m/s^2. In a scene only when `g` is not zero.
    Gravity { g: Vec3 },
    /// Linear air drag, `f = -c v`, `c` in N s/m. Only when `c > 0`.
    Drag { c: f32 },
    /// The springs of one family: Hooke's law with stiffness `k` (N/m) and damping `c` (N s/m)
    /// along the spring. Only when `k > 0`.
    Springs { family: Family, k: f32, c: f32 },
}

impl Force {
    /// Name in `effects` and `profile()`.
    pub fn name(&self) -> &'static str {
        match self {
            Force::Gravity { .. } => "gravity",
            Force::Drag { .. } => "air_drag",
            Force::Springs { family, .. } => family.pass_name(),
        }
    }

    /// The spring kinds whose per-spring forces this force computes into the block's table.
    pub fn spring_kinds(&self) -> &'static [SpringKind] {
        match self {
            Force::Springs { family, .. } => family.kinds_slice(),
            _ => &[],
        }
    }

    /// Arrays a pass over one component reads to add this force, at most.
    fn streams(&self) -> usize {
        match self {
            Force::Gravity { .. } | Force::Drag { .. } => 1,
            Force::Springs { family, .. } => 2 * family.kinds_slice().len(),
        }
    }
}

/// The state a force evaluation reads.
#[derive(Clone, Copy)]
pub struct StateRef<'a> {
    pub grid: Grid,
    pub pos: &'a Vec3s,
    pub vel: &'a Vec3s,
    /// Particle masses in kg.
    pub mass: &'a [f32],
    pub springs: &'a Springs,
    /// A mesh cloth's springs, added after the sweep; None on the grid.
    pub mesh: Option<&'a MeshCloth>,
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

/// Most arrays one fused pass reads: a group of forces added together must need no more.
const MAX_STREAMS: usize = 16;

/// Particles per block: its spring table (six kinds, plus up to two grid rows of springs before
/// the block) stays in a core's L2 cache up to 512 x 512 cloths; the rows before the block are
/// evaluated twice, a little extra spring work on wide cloths.
pub const BLOCK: usize = 4096;

/// The forces of a scene, in the order they are summed, and the workspace to evaluate them.
pub struct ForceModel {
    forces: Vec<Force>,
    /// Consecutive forces added in one pass each, as ranges of `forces`: cut where a pass would
    /// read more than [`MAX_STREAMS`] arrays per component.
    groups: Vec<Range<usize>>,
    /// `(force, kind)` for every spring kind a force tabulates.
    tabulated: Vec<(usize, SpringKind)>,
    /// The kinds of `tabulated`.
    kinds: Vec<SpringKind>,
    /// One table per work item, reused by its blocks; sized on the first evaluation.
    tables: Vec<SpringTable>,
    /// `(particles, chunk)` the tables were sized for.
    tables_for: (usize, usize),
    /// CPU nanoseconds per force during the current evaluation, summed over threads.
    cpu_nanos: Vec<AtomicU64>,
    /// The watchdog's stretch limit (`l / L`), checked by an evaluation only when armed.
    stretch_limit: Option<f32>,
    /// Whether the next evaluation checks the stretch limit.
    watch_armed: bool,
    /// Whether the last armed evaluation found a spring beyond the limit.
    overstretched: AtomicBool,
    /// Makes the next evaluation panic on a worker thread, to test that a panic anywhere in a
    /// step is caught and rolled back (see [`ForceModel::inject_panic`]).
    panic_next: bool,
    /// Scratch for [`MeshCloth::add_spring_forces`].
    mesh_scratch: PassScratch,
    /// A mesh cloth's per-triangle forces, scratch for
    /// [`crate::mesh_cloth::membrane::Membrane::add_forces`].
    membrane_table: Vec<[glam::Vec3; 3]>,
    /// The simulated time (s) the seams' rest lengths are taken at ([`MeshCloth::sewing`]).
    time: f64,
}

/// The pass name of a mesh cloth's springs in `effects` and `profile()`.
pub const MESH_SPRINGS: &str = "mesh_springs";

/// The pass name of a mesh cloth's triangle membrane in `effects` and `profile()`.
pub const MESH_MEMBRANE: &str = "mesh_membrane";

impl ForceModel {
    pub fn new(forces: Vec<Force>) -> Self {
        let mut groups: Vec<Range<usize>> = Vec::new();
        let mut streams = 0;
        for (f, force) in forces.iter().enumerate() {
            match groups.last_mut() {
                Some(group) if streams + force.streams() <= MAX_STREAMS => {
                    group.end = f + 1;
                    streams += force.streams();
                }
                _ => {
                    groups.push(f..f + 1);
                    streams = force.streams();
                }
            }
        }
        let tabulated: Vec<(usize, SpringKind)> = forces
            .iter()
            .enumerate()
            .flat_map(|(f, force)| force.spring_kinds().iter().map(move |&kind| (f, kind)))
            .collect();
        ForceModel {
            cpu_nanos: forces.iter().map(|_| AtomicU64::new(0)).collect(),
            kinds: tabulated.iter().map(|&(_, kind)| kind).collect(),
            tabulated,
            groups,
            forces,
            tables: Vec::new(),
            tables_for: (0, 0),
            stretch_limit: None,
            watch_armed: false,
            overstretched: AtomicBool::new(false),
            panic_next: false,
            mesh_scratch: PassScratch::default(),
            membrane_table: Vec::new(),
            time: 0.0,
        }
    }

    /// The forces, in the order they are summed.
    pub fn forces(&self) -> &[Force] {
        &self.forces
    }

    /// The spring kinds whose forces the model computes: those the stretch watch checks.
    pub fn spring_kinds(&self) -> &[SpringKind] {
        &self.kinds
    }

    /// Sets the watchdog's stretch limit, a ratio `l / L` (None: no stretch check).
    pub fn set_stretch_limit(&mut self, limit: Option<f32>) {
        self.stretch_limit = limit;
    }

    /// Sets the simulated time (s) of the evaluations that follow: a mesh cloth's seams take
    /// their rest lengths at it. The stepper sets it at each substep's start, so that a
    /// retried or restored step sees the same seams.
    pub fn set_time(&mut self, time: f64) {
        self.time = time;
    }

    /// The fraction of its starting length each seam of `mesh` has at the evaluations' time
    /// ([`MeshCloth::sewing`]): the implicit solvers take a seam's rest length from it, as the
    /// force pass does.
    pub fn sewing(&self, mesh: &MeshCloth) -> f32 {
        mesh.sewing(self.time)
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

    /// Makes the next evaluation panic inside its parallel sweep: a stand-in for a bug, so
    /// that tests can check the guards that keep a panic from escaping or corrupting a step.
    #[doc(hidden)]
    pub fn inject_panic(&mut self) {
        self.panic_next = true;
    }

    /// Forgets what an evaluation interrupted by a panic left behind: per-force clocks, the
    /// stretch watch.
    pub fn reset_after_panic(&mut self) {
        for nanos in &self.cpu_nanos {
            nanos.store(0, Ordering::Relaxed);
        }
        self.watch_armed = false;
        self.panic_next = false;
        self.overstretched.store(false, Ordering::Relaxed);
    }

    /// Heap memory of the spring tables.
    pub fn heap_bytes(&self) -> usize {
        self.tables
            .iter()
            .map(SpringTable::heap_bytes)
            .sum::<usize>()
            + self.mesh_scratch.heap_bytes()
            + self.membrane_table.capacity() * size_of::<[glam::Vec3; 3]>()
    }

    /// One table per work item, each long enough for a block and the springs before it.
    fn size_tables(&mut self, grid: Grid, chunk: usize) {
        let n = grid.len();
        if self.tabulated.is_empty() || self.tables_for == (n, chunk) {
            return;
        }
        let longest = chunk.min(BLOCK)
            + self
                .kinds
                .iter()
                .map(|&k| grid.offset(k))
                .max()
                .unwrap_or(0);
        let mut table = SpringTable::default();
        for &kind in &self.kinds {
            table.kinds[kind.index()] = Vec3s::zeros(longest);
        }
        self.tables = vec![table; n.div_ceil(chunk)];
        self.tables_for = (n, chunk);
    }

    /// Writes the total force on every particle into `out` and returns the evaluation's wall
    /// time, which it also books into `profile` split among the forces as the CPU time each
    /// measured (a fused pass's time split among its forces as the arrays each reads).
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
        let panic_now = std::mem::take(&mut self.panic_next);
        let watch = if std::mem::take(&mut self.watch_armed) {
            self.stretch_limit
        } else {
            None
        };
        let Self {
            forces,
            groups,
            tabulated,
            tables,
            cpu_nanos,
            overstretched,
            mesh_scratch,
            membrane_table,
            ..
        } = self;
        let clocked = |work: &mut dyn FnMut()| {
            let clock = Instant::now();
            work();
            clock.elapsed().as_nanos() as u64
        };
        let book = |f: usize, nanos: u64| cpu_nanos[f].fetch_add(nanos, Ordering::Relaxed);
        let sweep = |(c, (mut f, table)): (usize, (Vec3SliceMut, &mut SpringTable))| {
            let range = c * chunk..c * chunk + f.len();
            if panic_now && c == 0 {
                panic!("injected panic (a test of the panic guard)");
            }
            let mut block_start = range.start;
            while block_start < range.end {
                let block = block_start..(block_start + BLOCK).min(range.end);
                // Each force's kinds (consecutive in `tabulated`), timed together.
                for run in tabulated.chunk_by(|a, b| a.0 == b.0) {
                    let f = run[0].0;
                    let Force::Springs { k, c: damping, .. } = forces[f] else {
                        unreachable!("only springs tabulate")
                    };
                    let nanos = clocked(&mut || {
                        for &(_, kind) in run {
                            let lo = block.start.saturating_sub(grid.offset(kind));
                            table.origin[kind.index()] = lo;
                            let mut slots = table.kinds[kind.index()].slices_mut(0..block.end - lo);
                            let spring = springs::SpringLaw { k, c: damping };
                            if spring.tabulate(state, kind, lo..block.end, &mut slots, watch) {
                                overstretched.store(true, Ordering::Relaxed);
                            }
                        }
                    });
                    book(f, nanos);
                }
                let mut f_block = f.sub_mut(block.start - range.start..block.end - range.start);
                for (g, group) in groups.iter().enumerate() {
                    let members = &forces[group.clone()];
                    let nanos = clocked(&mut || {
                        fused::accumulate(
                            state,
                            table,
                            members,
                            g == 0,
                            block.clone(),
                            &mut f_block,
                        )
                    });
                    // Split among the group's forces as the arrays each reads.
                    let streams = members.iter().map(Force::streams).sum::<usize>();
                    for (f, force) in group.clone().zip(members) {
                        book(f, nanos * force.streams() as u64 / streams.max(1) as u64);
                    }
                }
                block_start = block.end;
            }
        };
        if groups.is_empty() {
            out.fill(Vec3::ZERO);
        } else if tabulated.is_empty() {
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

        // The sweep's time is split among its forces; the mesh's springs are booked apart.
        let swept = start.elapsed();
        if let Some(mesh) = state.mesh {
            let clock = Instant::now();
            let over = mesh.add_spring_forces(
                crate::simd::isa(),
                (state.pos, state.vel),
                mesh.sewing(self.time),
                out,
                mesh_scratch,
                chunk,
                watch,
            );
            if over {
                overstretched.store(true, Ordering::Relaxed);
            }
            profile.add(MESH_SPRINGS, clock.elapsed());
            if let Some(membrane) = &mesh.membrane {
                let clock = Instant::now();
                let active = &mesh.springs.active;
                membrane.add_forces(state.pos, active, out, membrane_table, chunk);
                profile.add(MESH_MEMBRANE, clock.elapsed());
            }
        }
        let wall = start.elapsed();
        profile.force_time += wall;
        let cpu_total = cpu_nanos
            .iter()
            .map(|n| n.load(Ordering::Relaxed))
            .sum::<u64>();
        for (force, nanos) in forces.iter().zip(cpu_nanos.iter()) {
            let share = nanos.swap(0, Ordering::Relaxed) as f64 / cpu_total.max(1) as f64;
            profile.add(force.name(), swept.mul_f64(share));
        }
        wall
    }
}
