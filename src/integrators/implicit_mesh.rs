//! Implicit Euler on a mesh cloth: the grid's equations ([`super::ImplicitEuler`]) over the
//! mesh's spring list, assembled into a [`SpringMatrix`] (one symmetric 3 x 3 block per spring
//! and per vertex) and solved by the same preconditioned conjugate gradient.
//!
//! **Preconditioners.** `jacobi` and `block_jacobi` are the grid's. The grid's default,
//! `multigrid`, is a geometric hierarchy of the stencil; a mesh has none, so on a mesh it is
//! smoothed-aggregation algebraic multigrid ([`crate::linear::amg`]). Its aggregates and
//! prolongators are built on the matrix's isotropic part,
//!
//! ```text
//! P = M + h c_d I + sum_s (h c_s + h^2 k_s) A_s^T A_s        (one scalar for x, y and z)
//! ```
//!
//! over the free vertices, which depends only on the step, the masses, the pins, the material
//! and which springs hold: the hierarchy is rebuilt only when one of those changes (a cut or a
//! tear among them), and the last few are kept ([`HIERARCHIES_KEPT`]), so that a step split
//! into halves and back finds its own again. The coarse operators are the Galerkin products
//! of a recent step's own matrix: reusing those of `P` instead saves their products but `P`
//! overstates the out-of-plane stiffness of a slack cloth, and CG then takes about twice the
//! iterations (`reusing_the_reference_coarse_operators_costs_iterations` in the tests), while
//! those of a step a few steps back cost little ([`Reuse`]). The finest level's smoother is
//! always the step's own. Predicted contacts (`k_c n n^T` on a vertex's diagonal) are in the
//! step's matrix, so in its smoother and, refreshed every such step, its coarse operators.
//!
//! **Reuse between steps** ([`Reuse`]): the coarse operators lag behind the matrix by at most
//! [`LAG_SOLVES`] solves, and CG starts from the last accepted step's `dv`, both only where
//! the solve holds no contact and no self-contact pair. Neither changes
//! what CG converges to (any symmetric positive definite preconditioner and any start reach
//! the same tolerance), only the bits within it. A snapshot holds neither, so every decision
//! restarts at points a saved run and its restored copy share: the first step after a
//! snapshot is taken (in the run that took it, and in any run restored from it, whose system
//! is new), and after anything that changes the state or the history from outside.
//!
//! **Contacts** are held exactly by the grid's [`ContactFilter`]: the solve is the filtered
//! conjugate gradient, preconditioned by the multigrid of the matrix with `k_c n n^T` on each
//! contact's diagonal (which the filter removes from the operator, not from the
//! preconditioner).
//!
//! **The triangle membrane** (`membrane = "triangle"`) adds each element's stiffness with its
//! rotation held fixed, `h^2 K_t` ([`Membrane::stiffness`]): its diagonal blocks join the
//! vertices' diagonal blocks, its off-diagonal blocks (`K_ij`, not symmetric, `K_ji = K_ij^T`)
//! are applied per row from the triangle's own table ([`WithMembrane`]), and `h^2 K_t v` joins
//! the right-hand side. The whole stays symmetric positive definite, so CG converges. The
//! multigrid cannot hold a non-symmetric block, so it is built on a proxy of the same pattern
//! ([`build_proxy`]): on each edge the symmetric part of the elements' blocks between its ends,
//! with the skew part's norm moved onto the two ends' diagonals, which keeps it at least the
//! system (symmetric positive definite) and close to it. Its aggregates come from the
//! isotropic `P` with each stretch spring weighted as the springs membrane would weight it
//! ([`Membrane::proxy_k`]).
//!
//! **Self-contact** (`self_collision.solve_stiffness`): the pairs ahead of the step are held
//! apart by the grid's penalty ([`SelfContactTerm`]): their diagonal blocks join the
//! vertices' (the proxy's too, under the triangle membrane), their couplings join CG's product
//! ([`WithSelfContacts`]), and the step is solved again, once, holding the pairs the first
//! solve brought within `thickness` and releasing those it carried apart ([`SOLVES`]). A pair
//! rests at `thickness` or at its gap at the step's start where that is smaller
//! ([`Rest::NoCloser`]): the penalty then only ever takes energy from the cloth. With
//! colliders' contacts held the right-hand side is kept as assembled, so that the filter
//! reduces the one with the added and released pairs anew.
//!
//! **Numbering** ([`LocalSolve`]): where the mesh's own numbering is scattered (it has a
//! [`crate::mesh_cloth::MeshCloth::local`]) and its membrane is the springs, the system is
//! assembled and solved in the local numbering, so that products and smoothing sweeps gather
//! from nearby rows; the multigrid's aggregates are still chosen as the user's numbering gives
//! them ([`Amg::renumbered`]), so the preconditioner is the same, renumbered.
//!
//! Every sum has a fixed order (per spring, then per vertex over its springs in spring order;
//! the multigrid's as its module says), so a step is bitwise the same for any number of threads.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use glam::{Mat3, Vec3};
use rayon::prelude::*;

use super::contact_filter::ContactFilter;
use super::self_contact::{
    DiagonalBlocks, Rest, SelfContactTerm, SelfPairs, WithSelfContacts, SOLVES,
};
use super::solver::{live_or_zero, Preconditioner, SolverSettings, SolverStats, CONTACT_STIFFNESS};
use super::StepContext;
use crate::collisions::PredictedContacts;
use crate::linear::block_lanes::Packed;
use crate::linear::cg::BlockOperator;
use crate::linear::cg::{diagonal_blocks, ConjugateGradient, Start};
use crate::linear::stencil::SlotArrays;
use crate::linear::{Amg, SpringMatrix, Sym3};
use crate::mesh_cloth::membrane::Membrane;
use crate::mesh_cloth::MeshCloth;
use crate::scene::{gather_by, LocalNumbering};
use crate::self_collision::Pair;
use crate::soa::{Floats, Vec3SliceMut, Vec3s};

/// How many multigrid hierarchies a system keeps, the latest first: a step's and those of the
/// halves an energy-judged step is split into (down to an eighth), so that a step halved in
/// every substep (a garment held by friction at rest) rebuilds none. Each is as large as the
/// matrix.
const HIERARCHIES_KEPT: usize = 4;

/// Springs per parallel work item of the per-spring pass.
const SPRING_CHUNK: usize = 4096;

/// The most solves that use one computation of the multigrid's coarse operators, the solve
/// that computed them included (1: every solve computes them, as it always does the fine
/// level's smoother). Each solve that keeps them saves the Galerkin products and the
/// coarsest factor (about a fifth of the 16k stiff mesh's step) and costs the iterations a
/// preconditioner of an older matrix adds, which grow as the cloth moves away from it. Default
/// 8: on the 16k stiff drape 4, 8 and 16 cost at most 0.1 iteration a solve, and 8 saves
/// nearly all the setup the longer lags do.
pub(crate) const LAG_SOLVES: u32 = 8;

/// How many CG iterations above the fewest of any solve that used the coarse operators a
/// solve may take before the next one computes them anew (a cloth moving fast, whose matrix
/// changes fast). Default 1: an iteration costs about what computing them does.
pub(crate) const LAG_MARGIN: u32 = 1;

/// The mesh's system and the solver's vectors, kept between steps.
pub(super) struct MeshSystem {
    matrix: SpringMatrix,
    /// Per spring, its unfiltered block `C_s` and `K_s (v_a - v_b)`.
    blocks: Vec<Sym3>,
    kv: Vec<Vec3>,
    pub(super) rhs: Vec3s,
    pub(super) dv: Vec3s,
    cg: ConjugateGradient,
    /// The Jacobi preconditioners' inverse diagonal blocks.
    jacobi: SlotArrays,
    /// The aggregation hierarchies built on `P` and what each was built from, the one in use
    /// first.
    amg: Vec<(FactorKey, Amg)>,
    /// With the triangle membrane: its elements' blocks and the multigrid's proxy.
    membrane: Option<Elements>,
    /// The self-collision pairs held apart inside the solve.
    self_contact: SelfContactTerm,
    /// With pairs held: the right-hand side as assembled, before the contact filter reduces it.
    assembled: Vec3s,
    /// What a solve reuses from earlier ones.
    reuse: Reuse,
    /// The numbering the system is assembled and solved in where the mesh's is scattered
    /// (None: the user's).
    local: Option<LocalSolve>,
}

/// A mesh solve in the mesh's local numbering ([`crate::mesh_cloth::MeshCloth::local`]): the
/// matrix's rows and columns, the right-hand side, CG's vectors, the multigrid's levels, the
/// held contacts and self-contact pairs are all in it, so that a product's gathers and the
/// smoother's read nearby vertices; the state is gathered into it before the solve and `dv`
/// scattered back after. Each vertex sums the same springs in the same order, so the matrix
/// and right-hand side are bitwise those of the user's numbering, rows permuted; the solve's
/// sums then run in another order, which changes the result within CG's tolerance only.
/// Under the triangle membrane the solve keeps the user's numbering (its elements' products
/// read the user's triangles). The numbering itself is the mesh's ([`LocalNumbering`]); this
/// holds what the solve gathers into it.
struct LocalSolve {
    /// The step's forces, positions, velocities, inverse masses and masses, gathered into it.
    force: Vec3s,
    pos: Vec3s,
    vel: Vec3s,
    inv_mass: Vec<f32>,
    mass: Vec<f32>,
    /// The self-contact pairs ahead of the step, their vertices renumbered.
    pairs: Vec<Pair>,
    /// The solution in the user's numbering.
    dv: Vec3s,
}

impl LocalSolve {
    fn of(mesh: &MeshCloth) -> Option<Self> {
        mesh.local.as_ref().filter(|_| mesh.membrane.is_none())?;
        let n = mesh.len();
        Some(LocalSolve {
            force: Vec3s::zeros(n),
            pos: Vec3s::zeros(n),
            vel: Vec3s::zeros(n),
            inv_mass: vec![0.0; n],
            mass: vec![0.0; n],
            pairs: Vec::new(),
            dv: Vec3s::zeros(n),
        })
    }

    /// The matrix of the mesh's springs with its rows and columns in `local`, each row's
    /// springs in the order of the user's row.
    fn matrix(local: &LocalNumbering) -> SpringMatrix {
        SpringMatrix::new(&local.a, &local.b, &local.offsets, &local.incident)
    }

    /// Gathers the step's state into `local`, and the pairs ahead with their vertices
    /// renumbered.
    fn gather(&mut self, ctx: &StepContext, local: &LocalNumbering) {
        let (cur, particles) = (ctx.current, ctx.particles);
        let (f, x, v) = (&mut self.force, &mut self.pos, &mut self.vel);
        let into = [
            &mut f.x[..],
            &mut f.y[..],
            &mut f.z[..],
            &mut x.x[..],
            &mut x.y[..],
            &mut x.z[..],
            &mut v.x[..],
            &mut v.y[..],
            &mut v.z[..],
            &mut self.inv_mass[..],
            &mut self.mass[..],
        ];
        let (f, x, v) = (&*ctx.force, &cur.pos, &cur.vel);
        let from = [
            &f.x[..],
            &f.y[..],
            &f.z[..],
            &x.x[..],
            &x.y[..],
            &x.z[..],
            &v.x[..],
            &v.y[..],
            &v.z[..],
            &particles.inv_mass[..],
            &particles.mass[..],
        ];
        crate::simd::dispatch!(gather_by(into, from, &local.vertices));
        self.pairs.clear();
        if let Some(pairs) = ctx.self_pairs {
            let place = &local.place;
            self.pairs.extend(pairs.pairs.iter().map(|pair| Pair {
                verts: pair.verts.map(|v| place[v as usize]),
                ..*pair
            }));
        }
    }

    /// `dv`, in `local`, into the user's numbering.
    fn scatter(&mut self, dv: &Vec3s, local: &LocalNumbering) {
        let into = [&mut self.dv.x[..], &mut self.dv.y[..], &mut self.dv.z[..]];
        let from = [&dv.x[..], &dv.y[..], &dv.z[..]];
        crate::simd::dispatch!(gather_by(into, from, &local.place));
    }
}

/// What a solve reuses from those before it (see the module docs): every field is decided by
/// the solves since the last restart point alone, so that two runs from one such point make
/// the same decisions.
#[derive(Default)]
struct Reuse {
    /// Set from outside between steps ([`MeshSystem::restart`]): the next solve starts afresh.
    restart: AtomicBool,
    /// Whether the hierarchy in use holds the coarse operators of an earlier solve that a
    /// solve may keep: computed for that hierarchy's own key, from a matrix with no contact
    /// and no self-contact pair in it.
    coarse: bool,
    /// The solves that used the coarse operators in use, the one that computed them included.
    solves: u32,
    /// The fewest CG iterations of a solve that used them, and those of the last solve.
    fresh_iterations: u32,
    last_iterations: u32,
    /// The step `h` (bits) of the last solve, and of the last accepted step whose `dv` is in
    /// `guess` (None: CG starts from zero).
    solved_h: Option<u32>,
    guess_h: Option<u32>,
    guess: Vec3s,
}

impl Reuse {
    /// Nothing earlier is reused from here on.
    fn forget(&mut self) {
        self.coarse = false;
        self.guess_h = None;
    }

    /// Whether this solve keeps the coarse operators: the hierarchy is the one the last solve
    /// used, they hold no contact, nor does this solve's matrix, fewer than [`LAG_SOLVES`]
    /// solves used them, and the last solve took at most [`LAG_MARGIN`] iterations more than
    /// the fewest any of them took.
    fn keeps_coarse(&self, same_hierarchy: bool, held: bool) -> bool {
        self.coarse
            && same_hierarchy
            && !held
            && self.solves < LAG_SOLVES
            && self.last_iterations <= self.fresh_iterations + LAG_MARGIN
    }
}

/// How one solve numbers the vertices: `place[v]` is vertex `v`'s row and `vertices[k]` row
/// `k`'s vertex (None: the user's numbering), with each row's springs (offsets and entries as
/// [`MeshCloth::incident`]), forces, positions, velocities, inverse masses and masses, and the
/// self-contact pairs ahead, all in that numbering.
struct Numbering<'a> {
    place: Option<&'a [u32]>,
    vertices: Option<&'a [u32]>,
    incidence: (&'a [u32], &'a [u32]),
    force: &'a Vec3s,
    pos: &'a Vec3s,
    vel: &'a Vec3s,
    inv_mass: &'a [f32],
    mass: &'a [f32],
    self_pairs: Option<SelfPairs<'a>>,
}

impl<'a> Numbering<'a> {
    /// The local numbering's, where the solve has one (its state gathered for this step), else
    /// the user's.
    fn of(local: Option<&'a LocalSolve>, mesh: &'a MeshCloth, ctx: &'a StepContext) -> Self {
        let (cur, particles) = (ctx.current, ctx.particles);
        match local.zip(mesh.local.as_ref()) {
            Some((l, numbering)) => Numbering {
                place: Some(&numbering.place),
                vertices: Some(&numbering.vertices),
                incidence: (&numbering.offsets, &numbering.incident),
                force: &l.force,
                pos: &l.pos,
                vel: &l.vel,
                inv_mass: &l.inv_mass,
                mass: &l.mass,
                self_pairs: ctx.self_pairs.map(|pairs| SelfPairs {
                    pairs: &l.pairs,
                    ..pairs
                }),
            },
            None => Numbering {
                place: None,
                vertices: None,
                incidence: (&mesh.offsets, &mesh.incident),
                force: ctx.force,
                pos: &cur.pos,
                vel: &cur.vel,
                inv_mass: &particles.inv_mass,
                mass: &particles.mass,
                self_pairs: ctx.self_pairs,
            },
        }
    }
}

/// The diagonal blocks the self-contact term adds to: the system's, and the multigrid's proxy
/// under the triangle membrane.
struct Diagonals<'a> {
    matrix: &'a mut [Sym3],
    proxy: Option<&'a mut [Sym3]>,
}

impl<'a> Diagonals<'a> {
    fn of(matrix: &'a mut SpringMatrix, membrane: &'a mut Option<Elements>) -> Self {
        Diagonals {
            matrix: &mut matrix.diagonal,
            proxy: membrane.as_mut().map(|m| &mut m.proxy.diagonal[..]),
        }
    }
}

impl DiagonalBlocks for Diagonals<'_> {
    fn add(&mut self, p: usize, s: f32, block: &Sym3) {
        self.matrix.add(p, s, block);
        if let Some(proxy) = self.proxy.as_deref_mut() {
            proxy.add(p, s, block);
        }
    }
}

/// The triangle membrane's part of the system.
struct Elements {
    /// Each triangle's `h^2 K_t` (zero when it does not hold).
    blocks: Vec<[[Mat3; 3]; 3]>,
    /// The multigrid's matrix ([`build_proxy`]).
    proxy: SpringMatrix,
    /// Per spring, scratch of [`build_proxy`]: the symmetric part of the elements' blocks
    /// along it, and the norm of their skew part.
    coupling: Vec<Sym3>,
    shift: Vec<f32>,
}

/// Triangles per parallel work item of the stiffness pass.
const TRIANGLE_CHUNK: usize = 2048;

/// The system's matrix with the triangle elements' off-diagonal blocks, applied row by row:
/// vertex `v`'s row adds `K_t[i][j] x_j` over its triangles (as corner `i`) in increasing order
/// and their other corners `j`, skipping a held row or column as the springs' blocks do.
struct WithMembrane<'a> {
    matrix: &'a SpringMatrix,
    membrane: &'a Membrane,
    blocks: &'a [[[Mat3; 3]; 3]],
    inv_mass: &'a [f32],
}

impl BlockOperator for WithMembrane<'_> {
    #[inline(always)]
    fn apply_range(&self, x: &Vec3s, range: std::ops::Range<usize>, out: &mut Vec3SliceMut) {
        self.matrix.apply_range(x, range.clone(), out);
        self.add_elements(x, range, out);
    }

    fn packs(&self) -> bool {
        self.matrix.packs()
    }

    #[inline(always)]
    fn apply_range_packed(
        &self,
        (x, packed): (&Vec3s, &Packed),
        range: std::ops::Range<usize>,
        out: &mut Vec3SliceMut,
    ) {
        self.matrix
            .apply_range_packed((x, packed), range.clone(), out);
        self.add_elements(x, range, out);
    }
}

impl WithMembrane<'_> {
    /// Adds the elements' off-diagonal terms to the rows `range` of `out`.
    #[inline(always)]
    fn add_elements(&self, x: &Vec3s, range: std::ops::Range<usize>, out: &mut Vec3SliceMut) {
        let m = self.membrane;
        for (i, v) in range.enumerate() {
            if self.inv_mass[v] == 0.0 {
                continue;
            }
            let mut acc = out.get(i);
            for &e in &m.incident[m.offsets[v] as usize..m.offsets[v + 1] as usize] {
                let (t, corner) = (e as usize / 3, e as usize % 3);
                for (j, &u) in m.triangles[t].iter().enumerate() {
                    if j != corner && self.inv_mass[u as usize] != 0.0 {
                        acc += self.blocks[t][corner][j] * x.get(u as usize);
                    }
                }
            }
            out.set(i, acc);
        }
    }
}

/// The system's operator for the contact filter: the spring matrix, with the elements' blocks
/// under the triangle membrane.
enum Operator<'a> {
    Springs(&'a SpringMatrix),
    Membrane(WithMembrane<'a>),
}

impl BlockOperator for Operator<'_> {
    #[inline(always)]
    fn apply_range(&self, x: &Vec3s, range: std::ops::Range<usize>, out: &mut Vec3SliceMut) {
        match self {
            Operator::Springs(m) => m.apply_range(x, range, out),
            Operator::Membrane(a) => a.apply_range(x, range, out),
        }
    }

    fn packs(&self) -> bool {
        match self {
            Operator::Springs(m) => m.packs(),
            Operator::Membrane(a) => a.packs(),
        }
    }

    #[inline(always)]
    fn apply_range_packed(
        &self,
        operand: (&Vec3s, &Packed),
        range: std::ops::Range<usize>,
        out: &mut Vec3SliceMut,
    ) {
        match self {
            Operator::Springs(m) => m.apply_range_packed(operand, range, out),
            Operator::Membrane(a) => a.apply_range_packed(operand, range, out),
        }
    }
}

impl<'a> Operator<'a> {
    /// The spring matrix `matrix`, with the elements' `blocks` under the triangle membrane.
    fn of(
        matrix: &'a SpringMatrix,
        elements: &'a Option<Elements>,
        mesh: &'a MeshCloth,
        inv_mass: &'a [f32],
    ) -> Self {
        match (&mesh.membrane, elements) {
            (Some(membrane), Some(elements)) => Operator::Membrane(WithMembrane {
                matrix,
                membrane,
                blocks: &elements.blocks,
                inv_mass,
            }),
            _ => Operator::Springs(matrix),
        }
    }
}

/// Each holding triangle's `h^2 K_t` at `pos` into `blocks` (zero for one that does not hold).
fn element_blocks(
    membrane: &Membrane,
    active: &[bool],
    h: f32,
    pos: &Vec3s,
    blocks: &mut [[[Mat3; 3]; 3]],
) {
    let h2 = h * h;
    blocks
        .par_chunks_mut(TRIANGLE_CHUNK)
        .enumerate()
        .for_each(|(c, blocks)| {
            for (i, out) in blocks.iter_mut().enumerate() {
                let t = c * TRIANGLE_CHUNK + i;
                *out = if membrane.holds(active, t) {
                    membrane.stiffness(pos, t).map(|row| row.map(|k| k * h2))
                } else {
                    [[Mat3::ZERO; 3]; 3]
                };
            }
        });
}

/// The multigrid's proxy under the triangle membrane, in the system's pattern: on each edge
/// the spring's `-C_s` plus the symmetric part of the elements' blocks between its ends (summed
/// over its one or two triangles); on the diagonal the system's own blocks plus, for each edge
/// at the vertex, the norm of the skew part those edge blocks dropped (`|x_i^T W x_j|` is at
/// most `|W| (|x_i|^2 + |x_j|^2) / 2` for each of the pair's two terms), so the proxy is at
/// least the system: symmetric positive definite, and close to it where the skew parts are
/// small. Held rows and columns as the system's; the contacts are added after.
fn build_proxy(
    elements: &mut Elements,
    (matrix, blocks): (&SpringMatrix, &[Sym3]),
    mesh: &MeshCloth,
    membrane: &Membrane,
    w: &[f32],
) {
    let s = &mesh.springs;
    let Elements {
        blocks: element_blocks,
        proxy,
        coupling,
        shift,
    } = elements;
    // Sized once; no allocation in a step.
    coupling.clear();
    coupling.resize(s.len(), Sym3::ZERO);
    shift.clear();
    shift.resize(s.len(), 0.0);
    for (t, k) in element_blocks.iter().enumerate() {
        let corners = membrane.triangles[t];
        for (c, &e) in membrane.edges[t].iter().enumerate() {
            let e = e as usize;
            let (i, j) = if corners[c] == s.a[e] {
                (c, (c + 1) % 3)
            } else {
                ((c + 1) % 3, c)
            };
            let block = k[i][j];
            coupling[e].add_scaled(1.0, &sym(block));
            let skew = [
                block.y_axis.x - block.x_axis.y,
                block.z_axis.x - block.x_axis.z,
                block.z_axis.y - block.y_axis.z,
            ];
            shift[e] += 0.5 * (skew[0] * skew[0] + skew[1] * skew[1] + skew[2] * skew[2]).sqrt();
        }
    }
    for e in 0..s.len() {
        let (a, b) = (s.a[e] as usize, s.b[e] as usize);
        let coupled = w[a] != 0.0 && w[b] != 0.0;
        let (spring, element) = (blocks[e].0, coupling[e].0);
        proxy.off[e] = Sym3(std::array::from_fn(|x| {
            live_or_zero(coupled, element[x] - spring[x])
        }));
    }
    for (v, d) in proxy.diagonal.iter_mut().enumerate() {
        *d = matrix.diagonal[v];
        if w[v] == 0.0 {
            continue;
        }
        let around: f32 = mesh
            .springs_at(v)
            .iter()
            .map(|&e| shift[(e >> 1) as usize])
            .sum();
        d.add_scaled(around, &Sym3::outer(0.0, Vec3::ZERO, 1.0));
    }
    proxy.gather();
}

/// The symmetric part `(M + M^T) / 2` of a block (exact for a diagonal block of `K_t`, which
/// is symmetric).
fn sym(m: Mat3) -> Sym3 {
    let (c0, c1, c2) = (m.x_axis, m.y_axis, m.z_axis);
    Sym3([
        c0.x,
        c1.y,
        c2.z,
        0.5 * (c1.x + c0.y),
        0.5 * (c2.x + c0.z),
        0.5 * (c2.y + c1.z),
    ])
}

/// Everything `P` is built from (the topology is the system's own).
#[derive(PartialEq)]
struct FactorKey {
    h: u32,
    drag: u32,
    mass: Vec<f32>,
    inv_mass: Vec<f32>,
    /// Which springs hold: a cut or a tear changes `P`.
    active: Vec<bool>,
}

impl FactorKey {
    fn of(h: f32, drag: f32, ctx: &StepContext) -> Self {
        FactorKey {
            active: ctx.mesh.map_or_else(Vec::new, |m| m.springs.active.clone()),
            h: h.to_bits(),
            drag: drag.to_bits(),
            mass: ctx.particles.mass.to_vec(),
            inv_mass: ctx.particles.inv_mass.to_vec(),
        }
    }

    fn matches(&self, h: f32, drag: f32, ctx: &StepContext) -> bool {
        self.h == h.to_bits()
            && self.drag == drag.to_bits()
            && self.mass[..] == ctx.particles.mass[..]
            && self.inv_mass[..] == ctx.particles.inv_mass[..]
            && ctx
                .mesh
                .is_some_and(|m| self.active[..] == m.springs.active[..])
    }
}

impl MeshSystem {
    pub(super) fn new(mesh: &MeshCloth) -> Self {
        let n = mesh.len();
        let s = &mesh.springs;
        let local = LocalSolve::of(mesh);
        MeshSystem {
            matrix: match local.as_ref().and(mesh.local.as_ref()) {
                Some(numbering) => LocalSolve::matrix(numbering),
                None => SpringMatrix::new(&s.a, &s.b, &mesh.offsets, &mesh.incident),
            },
            blocks: vec![Sym3::ZERO; s.len()],
            kv: vec![Vec3::ZERO; s.len()],
            rhs: Vec3s::zeros(n),
            dv: Vec3s::zeros(n),
            cg: ConjugateGradient::new(n),
            jacobi: std::array::from_fn(|_| Floats::zeros(n)),
            amg: Vec::new(),
            membrane: mesh.membrane.as_ref().map(|m| Elements {
                blocks: vec![[[Mat3::ZERO; 3]; 3]; m.len()],
                proxy: SpringMatrix::new(&s.a, &s.b, &mesh.offsets, &mesh.incident),
                coupling: vec![Sym3::ZERO; s.len()],
                shift: vec![0.0; s.len()],
            }),
            self_contact: SelfContactTerm::resting(Rest::NoCloser),
            assembled: Vec3s::zeros(0),
            reuse: Reuse {
                guess: Vec3s::zeros(n),
                ..Reuse::default()
            },
            local,
        }
    }

    /// The next solve reuses nothing from earlier ones: a snapshot was taken (a run restored
    /// from it starts with a new system), or the state or history was set from outside.
    pub(super) fn restart(&self) {
        self.reuse.restart.store(true, Ordering::Relaxed);
    }

    /// The last solve's `dv` became the step's: the next step's CG starts from it.
    pub(super) fn accept(&mut self) {
        let reuse = &mut self.reuse;
        if let Some(h) = reuse.solved_h {
            reuse.guess.copy_from(&self.dv);
            reuse.guess_h = Some(h);
        }
    }

    /// Assembles the step's system, builds the preconditioner and solves for `dv` (in
    /// `self.dv`) with the predicted contacts held by `filter` and the self-collision pairs
    /// ahead (`ctx.self_pairs`) by the penalty, booking the times and the solves in `stats`.
    pub(super) fn solve(
        &mut self,
        mesh: &MeshCloth,
        (h, drag): (f32, f32),
        (settings, stats): (SolverSettings, &mut SolverStats),
        filter: &mut ContactFilter,
        ctx: &StepContext,
    ) {
        let started = Instant::now();
        if self.reuse.restart.swap(false, Ordering::Relaxed) {
            self.reuse.forget();
        }
        // The state as the solve numbers it ([`LocalSolve`]); the contact filter reads the
        // user's and places its particles by `place`.
        let mut local = self.local.take();
        if let (Some(local), Some(numbering)) = (&mut local, &mesh.local) {
            local.gather(ctx, numbering);
        }
        let numbering = Numbering::of(local.as_ref(), mesh, ctx);
        let (pos, vel, w) = (numbering.pos, numbering.vel, numbering.inv_mass);
        let self_pairs = numbering.self_pairs;
        self.build_blocks(mesh, h, ctx);
        self.matrix.gather();
        if let (Some(membrane), Some(elements)) = (&mesh.membrane, &mut self.membrane) {
            let blocks = &mut elements.blocks;
            element_blocks(membrane, &mesh.springs.active, h, &ctx.current.pos, blocks);
        }
        self.assemble_diagonal_and_rhs(mesh, (h, drag), ctx, &numbering);
        if let (Some(membrane), Some(elements)) = (&mesh.membrane, &mut self.membrane) {
            let w = &ctx.particles.inv_mass[..];
            build_proxy(elements, (&self.matrix, &self.blocks), mesh, membrane, w);
        }
        if let Some(contacts) = ctx.contacts.filter(|c| c.count > 0) {
            self.stiffen_contacts(contacts, ctx, numbering.place);
        }
        let state = (pos, vel, w);
        match self_pairs {
            Some(pairs) => {
                let term = &mut self.self_contact;
                term.gather(h, pairs, state);
                term.add_diagonal(0, &mut Diagonals::of(&mut self.matrix, &mut self.membrane));
                term.add_rhs(0, h, &mut self.rhs);
                if self.assembled.len() != self.rhs.len() {
                    self.assembled = Vec3s::zeros(self.rhs.len());
                }
                self.assembled.copy_from(&self.rhs);
            }
            None => self.self_contact.clear(),
        }
        stats.self_pairs += self.self_contact.len() as u64;
        let (cur, particles) = (ctx.current, ctx.particles);
        let mass = &particles.mass;
        let users = (&cur.pos, &cur.vel, &particles.inv_mass[..]);
        let stiffness = |p: usize| CONTACT_STIFFNESS * mass[p];
        filter.gather(h, ctx.contacts, users, stiffness, numbering.place);
        let mut setup = started;
        for solve in 1..=SOLVES {
            let start = match solve == 1 && !self.holds_contacts(ctx) {
                true => self.first_guess(h, w),
                false => Start::Zero,
            };
            self.solve_once(
                mesh,
                (h, drag),
                (settings, stats),
                (filter, &numbering),
                ctx,
                (setup, start),
            );
            let Some(pairs) = self_pairs.filter(|_| solve < SOLVES) else {
                break;
            };
            setup = Instant::now();
            let MeshSystem {
                matrix,
                membrane,
                self_contact,
                assembled,
                dv,
                ..
            } = self;
            let before = self_contact.len();
            let changed = self_contact.extend(
                h,
                pairs,
                (pos, vel, dv),
                (&mut Diagonals::of(matrix, membrane), assembled),
            );
            stats.self_pairs += self_contact.len().saturating_sub(before) as u64;
            if changed == 0 {
                break;
            }
            self.rhs.copy_from(&self.assembled);
        }
        if let (Some(local), Some(numbering)) = (&mut local, &mesh.local) {
            local.scatter(&self.dv, numbering);
        }
        self.local = local;
    }

    /// The last solve's `dv`, in the user's numbering.
    pub(super) fn solution(&self) -> &Vec3s {
        self.local.as_ref().map_or(&self.dv, |local| &local.dv)
    }

    /// Whether the solve holds predicted contacts or self-contact pairs: such a solve reuses
    /// nothing from earlier ones and leaves nothing for later ones to reuse.
    fn holds_contacts(&self, ctx: &StepContext) -> bool {
        ctx.contacts.is_some_and(|c| c.count > 0) || !self.self_contact.is_empty()
    }

    /// CG's start for the step's first solve: the last accepted step's `dv` (zero at held
    /// vertices, which a pin may have joined since) where that step had this one's `h`, in
    /// `self.dv`. Only for a solve that holds no contact and no self-contact pair: started
    /// so, the garment drag's solves (pairs and a grip held) left it gaining energy beyond
    /// its bound (`tests/garment_drag.rs`), which is not understood yet.
    fn first_guess(&mut self, h: f32, w: &[f32]) -> Start {
        let reuse = &self.reuse;
        if reuse.guess_h != Some(h.to_bits()) || reuse.guess.len() != self.dv.len() {
            return Start::Zero;
        }
        self.dv.copy_from(&reuse.guess);
        for (v, &w) in w.iter().enumerate() {
            if w == 0.0 {
                self.dv.set(v, Vec3::ZERO);
            }
        }
        Start::Guess
    }

    /// The contact filter's reduction, the preconditioner's setup and one CG solve of the
    /// assembled system into `self.dv`, from `start` (a guess in `self.dv`); `started` is
    /// when its setup began.
    fn solve_once(
        &mut self,
        mesh: &MeshCloth,
        (h, drag): (f32, f32),
        (settings, stats): (SolverSettings, &mut SolverStats),
        (filter, numbering): (&mut ContactFilter, &Numbering),
        ctx: &StepContext,
        (started, start): (Instant, Start),
    ) {
        let w = numbering.inv_mass;
        let term = (!self.self_contact.is_empty()).then_some(&self.self_contact);
        if !filter.is_empty() {
            let matrix = &Operator::of(&self.matrix, &self.membrane, mesh, w);
            let operator = WithSelfContacts { matrix, term };
            filter.reduce(&mut self.rhs, |x, y| operator.apply(x, y, ctx.chunk));
        }
        match settings.preconditioner {
            Preconditioner::Jacobi => {
                let d = &self.matrix.diagonal;
                for (c, out) in self.jacobi.iter_mut().enumerate() {
                    for (p, o) in out.iter_mut().enumerate() {
                        *o = if c < 3 && d[p].0[c] > 0.0 {
                            1.0 / d[p].0[c]
                        } else {
                            0.0
                        };
                    }
                }
            }
            Preconditioner::BlockJacobi => {
                for (p, d) in self.matrix.diagonal.iter().enumerate() {
                    for (out, v) in self.jacobi.iter_mut().zip(d.inverse_or_zero().0) {
                        out[p] = v;
                    }
                }
            }
            Preconditioner::Multigrid => {
                let found = self
                    .amg
                    .iter()
                    .position(|(key, _)| key.matches(h, drag, ctx));
                match found {
                    Some(kept) => self.amg[..=kept].rotate_right(1),
                    None => {
                        let reference = self.isotropic_matrix(mesh, h, drag, numbering);
                        let mut amg = Amg::renumbered(&reference, numbering.vertices);
                        // Isometric bending couples the second ring with the wrong sign for
                        // a sweep damped by `OMEGA` alone.
                        amg.bound_damping(mesh.bending.is_some());
                        self.amg.insert(0, (FactorKey::of(h, drag, ctx), amg));
                        self.amg.truncate(HIERARCHIES_KEPT);
                        stats.factorizations += 1;
                    }
                }
                let fine = self.membrane.as_ref().map_or(&self.matrix, |m| &m.proxy);
                let held = self.holds_contacts(ctx);
                let reuse = &mut self.reuse;
                if reuse.keeps_coarse(found == Some(0), held) {
                    self.amg[0].1.update_smoother(fine);
                    reuse.solves += 1;
                } else {
                    self.amg[0].1.update(fine);
                    reuse.coarse = !held;
                    reuse.solves = 1;
                }
            }
        }
        let solving = Instant::now();
        stats.setup_seconds += (solving - started).as_secs_f64();
        let MeshSystem {
            matrix,
            rhs,
            dv,
            cg,
            jacobi,
            amg,
            membrane,
            self_contact,
            ..
        } = self;
        let term = (!self_contact.is_empty()).then_some(&*self_contact);
        let (tolerance, most) = (settings.tolerance as f64, settings.max_iterations);
        let limits = (tolerance, most);
        let held = &*filter;
        let project = |v: &mut Vec3s| held.project(v);
        let (matrix, membrane) = (&*matrix, &*membrane);
        // The multigrid's matrix: the proxy under the triangle membrane.
        let coarse = membrane.as_ref().map_or(matrix, |m| &m.proxy);
        // Without contacts the filter projects nothing: the plain preconditioned CG.
        let a = WithSelfContacts {
            matrix: &Operator::of(matrix, membrane, mesh, w),
            term,
        };
        let (iterations, residual) = match (settings.preconditioner, amg.first_mut()) {
            (Preconditioner::Multigrid, Some((_, amg))) => {
                let precondition = |r: &Vec3s, z: &mut Vec3s| amg.apply(coarse, r, z);
                cg.solve_filtered(&a, rhs, dv, limits, precondition, project, start)
            }
            _ => {
                let precondition = |r: &Vec3s, z: &mut Vec3s| diagonal_blocks(jacobi, r, z);
                cg.solve_filtered(&a, rhs, dv, limits, precondition, project, start)
            }
        };
        let reuse = &mut self.reuse;
        if reuse.solves <= 1 || iterations < reuse.fresh_iterations {
            reuse.fresh_iterations = iterations;
        }
        reuse.last_iterations = iterations;
        reuse.solved_h = Some(h.to_bits());
        if !filter.is_empty() {
            filter.finish(dv, |x, y| a.apply(x, y, ctx.chunk));
        }
        stats.solve_seconds += solving.elapsed().as_secs_f64();
        stats.record(iterations, residual, settings.tolerance as f64);
    }

    /// Per spring, `C_s = alpha u u^T + beta I` (`alpha = h c + h^2 k (1 - g)`,
    /// `beta = h^2 k g`, `g = max(0, 1 - L / l)`), `K_s (v_a - v_b)` with
    /// `K_s = C_s - h c u u^T`, and the filtered off-diagonal block `-C_s` (zero when an end is
    /// held).
    fn build_blocks(&mut self, mesh: &MeshCloth, h: f32, ctx: &StepContext) {
        let s = &mesh.springs;
        let (pos, vel, w) = (&ctx.current.pos, &ctx.current.vel, &ctx.particles.inv_mass);
        let sewing = ctx.forces.sewing(mesh);
        let linear = mesh.bending.as_ref().map(|b| &b.linear[..]);
        self.blocks
            .par_chunks_mut(SPRING_CHUNK)
            .zip(self.kv.par_chunks_mut(SPRING_CHUNK))
            .zip(self.matrix.off.par_chunks_mut(SPRING_CHUNK))
            .enumerate()
            .for_each(|(ci, ((blocks, kv), off))| {
                for i in 0..blocks.len() {
                    let e = ci * SPRING_CHUNK + i;
                    let (a, b) = (s.a[e] as usize, s.b[e] as usize);
                    let d = pos.get(b) - pos.get(a);
                    let l = d.length();
                    // The force's own rest length: a closing seam's shrinks with the clock, and
                    // a slack seam exerts nothing (its matrix would be the seam's starting
                    // length's, missing the sewn seam's stiffness across it).
                    let (k, c, rest) = match s.taut_rest(e, l, sewing) {
                        Some(rest) => (s.k[e], s.c[e], rest),
                        None => (0.0, 0.0, 0.0),
                    };
                    let inv_l = if l > 0.0 { 1.0 / l } else { 0.0 };
                    let g = (1.0 - rest * inv_l).max(0.0) * (l > 0.0) as u32 as f32;
                    let alpha = h * c + h * h * k * (1.0 - g);
                    let beta = h * h * k * g;
                    // Isometric bending's constant Hessian, `w I` on the spring's pair.
                    let beta = linear.map_or(beta, |w| beta + h * h * w[e]);
                    let u = d * inv_l;
                    let block = Sym3::outer(alpha, u, beta);
                    let dw = vel.get(a) - vel.get(b);
                    blocks[i] = block;
                    kv[i] = (alpha - h * c) * u.dot(dw) * u + beta * dw;
                    let coupled = w[a] != 0.0 && w[b] != 0.0;
                    off[i] = Sym3(block.0.map(|x| live_or_zero(coupled, -x)));
                }
            });
    }

    /// The diagonal blocks `D_a = (m_a + h drag) I + sum_s C_s` and the right-hand side
    /// `b_a = h f_a - sum_s (+-) K_s (v_a - v_b)` (the first end takes `-`, the second `+`),
    /// zero for held vertices.
    fn assemble_diagonal_and_rhs(
        &mut self,
        mesh: &MeshCloth,
        (h, drag): (f32, f32),
        ctx: &StepContext,
        numbering: &Numbering,
    ) {
        let chunk = ctx.chunk;
        let (force, mass, w) = (numbering.force, numbering.mass, numbering.inv_mass);
        let (offsets, incident) = numbering.incidence;
        let vertices = numbering.vertices;
        let (blocks, kv) = (&self.blocks, &self.kv);
        let elements = mesh
            .membrane
            .as_ref()
            .zip(self.membrane.as_ref().map(|m| &m.blocks));
        let vel = &ctx.current.vel;
        self.matrix
            .diagonal
            .par_chunks_mut(chunk)
            .zip(self.rhs.par_chunks_mut(chunk))
            .enumerate()
            .for_each(|(ci, (d, mut b))| {
                for (i, di) in d.iter_mut().enumerate() {
                    let row = ci * chunk + i;
                    if w[row] == 0.0 {
                        *di = Sym3::ZERO;
                        b.set(i, Vec3::ZERO);
                        continue;
                    }
                    let m = mass[row] + h * drag;
                    let mut block = Sym3([m, m, m, 0.0, 0.0, 0.0]);
                    let mut r = h * force.get(row);
                    for &e in &incident[offsets[row] as usize..offsets[row + 1] as usize] {
                        let s = (e >> 1) as usize;
                        block.add_scaled(1.0, &blocks[s]);
                        r = if e & 1 == 0 { r - kv[s] } else { r + kv[s] };
                    }
                    // The elements' diagonal blocks and `- h^2 K_t v` from each triangle.
                    if let Some((m, k)) = elements {
                        let v = vertices.map_or(row, |vertices| vertices[row] as usize);
                        for &e in &m.incident[m.offsets[v] as usize..m.offsets[v + 1] as usize] {
                            let (t, corner) = (e as usize / 3, e as usize % 3);
                            block.add_scaled(1.0, &sym(k[t][corner][corner]));
                            for (j, &u) in m.triangles[t].iter().enumerate() {
                                r -= k[t][corner][j] * vel.get(u as usize);
                            }
                        }
                    }
                    *di = block;
                    b.set(i, r);
                }
            });
    }

    /// `k n n^T` (`k = CONTACT_STIFFNESS m`; `k I` for a sticking contact) on the diagonal
    /// block of each free vertex with a predicted contact, and a sliding contact's friction
    /// damper (part of the system), for the preconditioner (the grid's `stiffen_contacts`), in the proxy
    /// too under the triangle membrane.
    fn stiffen_contacts(
        &mut self,
        contacts: &PredictedContacts,
        ctx: &StepContext,
        place: Option<&[u32]>,
    ) {
        let (mass, w) = (&ctx.particles.mass, &ctx.particles.inv_mass);
        for p in 0..self.matrix.len() {
            if contacts.normal.get(p) == Vec3::ZERO || w[p] == 0.0 {
                continue;
            }
            let at = place.map_or(p, |place| place[p] as usize);
            let (s, held) = (CONTACT_STIFFNESS * mass[p], contacts.held_directions(p));
            self.matrix.diagonal[at].add_scaled(s, &held);
            if let Some(Elements { proxy, .. }) = &mut self.membrane {
                proxy.diagonal[at].add_scaled(s, &held);
            }
            if let Some(damper) = contacts.slide_block(p) {
                self.matrix.diagonal[at].add_scaled(1.0, &damper);
                if let Some(Elements { proxy, .. }) = &mut self.membrane {
                    proxy.diagonal[at].add_scaled(1.0, &damper);
                }
            }
        }
    }

    /// The isotropic part `P` as a matrix of the system's pattern: `w_s I` blocks
    /// (`w_s = h c_s + h^2 k_s`), zero rows and columns at held vertices.
    fn isotropic_matrix(
        &self,
        mesh: &MeshCloth,
        h: f32,
        drag: f32,
        numbering: &Numbering,
    ) -> SpringMatrix {
        let s = &mesh.springs;
        let (mass, w) = (numbering.mass, numbering.inv_mass);
        let at = |v: u32| numbering.place.map_or(v, |place| place[v as usize]) as usize;
        let mut p = self.matrix.clone();
        let proxy = |e: usize| mesh.membrane.as_ref().map_or(0.0, |m| m.proxy_k[e]);
        let linear = |e: usize| mesh.bending.as_ref().map_or(0.0, |b| b.linear[e]);
        let weight = |e: usize| h * s.c[e] + h * h * (s.k[e] + proxy(e) + linear(e));
        for (v, d) in p.diagonal.iter_mut().enumerate() {
            let m = mass[v] + h * drag;
            *d = Sym3([m, m, m, 0.0, 0.0, 0.0]);
        }
        for e in 0..s.len() {
            let (a, b) = (at(s.a[e]), at(s.b[e]));
            let we = weight(e);
            p.diagonal[a].add_scaled(1.0, &Sym3::outer(0.0, Vec3::ZERO, we));
            p.diagonal[b].add_scaled(1.0, &Sym3::outer(0.0, Vec3::ZERO, we));
            let coupled = w[a] != 0.0 && w[b] != 0.0;
            p.off[e] = Sym3::outer(0.0, Vec3::ZERO, live_or_zero(coupled, -we));
        }
        for (v, d) in p.diagonal.iter_mut().enumerate() {
            if w[v] == 0.0 {
                *d = Sym3::ZERO;
            }
        }
        p.gather();
        p
    }
}
