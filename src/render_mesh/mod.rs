//! The drawn surface of the cloth: the particles plus *cut vertices*, so that the rendered and
//! exported edge of a cut runs where the stroke crossed the springs, not along the particles
//! next to it. Nothing here runs inside a step; the physics surface (what self-collision keeps
//! apart, [`Model::triangles`]) is the grid's triangles, unchanged.
//!
//! **Representation.** Vertex `p < n` is particle `p`. A triangle of the grid (see
//! [`cell_triangle`]) whose three edges are live is drawn as it is. On each severed edge
//! `p-q` the cut has two vertices at the point it crossed the spring (the parameter `t` the
//! stroke found, kept in [`Model::crossings`]; the midpoint for a tear), one belonging to
//! `p`'s side and one to `q`'s, shared by the triangles of that side on either side of the
//! edge. The triangle is then clipped: with two severed edges, a triangle at the corner they
//! share and a quad (two triangles) on the other side; with one (a stroke that ends inside),
//! a slit to the opposite corner; with three (two cuts through it), a small triangle at each
//! corner. Every drawn triangle's vertices belong to particles joined by live edges, so the
//! triangles of two pieces never share a vertex.
//!
//! **Embedding.** A cut vertex of `p`'s side moves with `p`'s side only: it lies `s` of the way
//! (the crossing's distance from `p` as a fraction of the spring) from `p` to a *ghost* of `q`,
//! where `p`'s side would have `q` if it had kept it: an affine combination
//! `x_p + alpha (x_u - x_p) + beta (x_w - x_p)` of `p` and two neighbours `u`, `w` that `p`
//! still has live structural or shear springs to, with `(alpha, beta)` the grid step from `p`
//! to `q` in the frame of the steps to `u` and `w` (the smallest such combination, so
//! interpolated where it can be). On an undeformed or uniformly strained cloth that is exactly
//! the crossing point; as the pieces part, each side's edge goes with it and no triangle
//! reaches across the gap. While the two ends of a severed edge have not moved apart (the
//! cloth is cut but its sides still touch), both sides' cut vertices go to the crossing on
//! the edge itself, `s` of the way from `p` to `q`: one point, so the cut shows as a closed
//! seam, not as two edges each extrapolated by its own side's frame, which part wherever the
//! cloth bends and let what is behind show through as specks along the cut. As the ends part
//! the vertices move over to the ghosts ([`OPEN_STRAIN`]). A particle left with one live
//! neighbour in line with the edge extrapolates along it. One with no such frame (on a strip
//! one particle wide, as a tear along a row leaves, or alone) puts its cut vertex at its rest
//! distance toward the other end ([`Frame::Toward`]): the direction is the only thing read
//! from the other side, and the edge never grows past its rest length.
//!
//! A mesh cloth's triangles are clipped by the same cases ([`clip_pieces`]); its cut vertices
//! are framed by the mesh's own neighbours (`mesh.rs`).
//!
//! **Cost.** Building the topology walks every triangle once (`O(n)`, as the grid's triangle
//! list does) when the topology version moves. A frame copies the particles' positions and
//! computes three-term sums for the cut vertices: `O(n + c)` for `c` cut vertices, no
//! allocation. The step pays nothing.

use std::collections::HashMap;

use glam::Vec3;

use crate::grid::{cell_triangle, triangle_alive, triangle_slots, Grid, SpringKind};
use crate::model::Model;
use crate::soa::Vec3s;
use crate::state::State;

mod mesh;

/// How far the ends of a severed edge must have moved apart (its strain, the length over the
/// rest length less 1) for the two sides of the cut to be drawn apart: below 0 the cut vertices
/// of both sides lie on the edge, at the crossing, one point; above this each is on its own
/// side's ghost; between, a smooth blend. 0.25: the cut opens once its sides have parted by a
/// quarter of a spacing. Lower shows a cut opening sooner but lets a bending cloth crack along
/// it (each side's ghost is an extrapolation, and they disagree where the cloth bends); higher
/// keeps the seam closed longer and stretches the drawn triangles across a widening gap.
pub const OPEN_STRAIN: f32 = 0.25;

pub use mesh::mesh_uvs;

/// A vertex on a severed edge, on one side of it: `s` of the way from particle `from` to
/// `toward`, at rest; as the cloth moves, `s` of the way from `from` to the edge's far end, or
/// to the ghost of `toward` that `frame` places once the ends have parted (see the module's
/// documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CutVertex {
    /// The particle whose side the vertex is on.
    pub from: u32,
    pub toward: u32,
    pub s: f32,
    /// The edge's rest length (m).
    pub rest: f32,
    pub frame: Frame,
}

/// How a ghost of a cut vertex's `toward` follows the side of its `from`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Frame {
    /// `w[0] x_from + w[1] x_u + w[2] x_w` for two live neighbours `u`, `w` of `from`.
    Affine {
        neighbours: [u32; 2],
        weights: [f32; 3],
    },
    /// On a strip one particle wide (a tear along a row leaves one): `along` m along the
    /// strip (toward live neighbour `neighbour`) and `across` m square to it, on the side
    /// where `toward` is. The rest offset is kept, so the edge never reaches across the gap.
    Strip {
        neighbour: u32,
        along: f32,
        across: f32,
    },
    /// `reach` m from a lone particle toward `toward`.
    Toward { reach: f32 },
}

impl CutVertex {
    /// Where the vertex is drawn while the severed edges at `toward` have parted by `apart`
    /// (0: not at all, 1: by [`OPEN_STRAIN`] or more; see [`RenderMesh::frame`]).
    pub fn position(&self, pos: &Vec3s, apart: f32) -> Vec3 {
        let (from, to) = (pos.get(self.from as usize), pos.get(self.toward as usize));
        let end = if apart > 0.0 {
            to.lerp(self.ghost(pos), apart * apart * (3.0 - 2.0 * apart))
        } else {
            to
        };
        from.lerp(end, self.s)
    }

    /// How far the edge's ends have moved apart, in units of [`OPEN_STRAIN`] (<= 0: not).
    fn parted(&self, pos: &Vec3s) -> f32 {
        let (from, to) = (pos.get(self.from as usize), pos.get(self.toward as usize));
        (from.distance(to) / self.rest - 1.0) / OPEN_STRAIN
    }

    /// Where `from`'s side would have `toward`.
    fn ghost(&self, pos: &Vec3s) -> Vec3 {
        let from = pos.get(self.from as usize);
        match self.frame {
            Frame::Affine {
                neighbours: [u, w],
                weights,
            } => {
                weights[0] * from
                    + weights[1] * pos.get(u as usize)
                    + weights[2] * pos.get(w as usize)
            }
            Frame::Strip {
                neighbour,
                along,
                across,
            } => {
                let tangent = (pos.get(neighbour as usize) - from).normalize_or_zero();
                let d = pos.get(self.toward as usize) - from;
                let square = (d - d.dot(tangent) * tangent).normalize_or_zero();
                from + along * tangent + across * square
            }
            Frame::Toward { reach } => {
                let d = (pos.get(self.toward as usize) - from).normalize_or_zero();
                from + reach * d
            }
        }
    }
}

/// The drawn mesh, rebuilt when the topology changes, its positions when the state does.
#[derive(Default)]
pub struct RenderMesh {
    /// The topology version `triangles` and `cut` were made for.
    topology_for: Option<u64>,
    triangles: Vec<[u32; 3]>,
    cut: Vec<CutVertex>,
    /// `(kind, anchor, on the anchor's side)` -> vertex index, while building.
    index: HashMap<(SpringKind, usize, bool), u32>,
    /// A mesh cloth's `(spring, on the side of its end a)` -> vertex index, while building.
    mesh_index: HashMap<(u32, bool), u32>,
    positions: Vec3s,
    /// Per particle, how far the severed edges ending there have parted (the largest,
    /// [`CutVertex::parted`], in `[0, 1]`): every cut vertex toward one particle goes over to
    /// its ghost together, so two vertices toward it on one side never sit one on the particle
    /// and one on a ghost, stretching the drawn edge between them.
    apart: Vec<f32>,
    normals: Vec3s,
    /// The `(state, topology)` versions `positions` and `normals` were made for.
    frame_for: Option<(u64, u64)>,
}

/// The grid steps a particle's frame may use: its structural and shear neighbours, in the
/// order ties are broken.
const STEPS: [(i64, i64); 8] = [
    (1, 0),
    (0, 1),
    (-1, 0),
    (0, -1),
    (1, 1),
    (-1, -1),
    (1, -1),
    (-1, 1),
];

impl RenderMesh {
    /// The drawn triangles: indices into the vertices, particles first, then
    /// [`RenderMesh::cut_vertices`].
    pub fn triangles(&mut self, model: &Model) -> &[[u32; 3]] {
        self.sync_topology(model);
        &self.triangles
    }

    /// The cut vertices, vertex `n + k` being `cut_vertices()[k]`.
    pub fn cut_vertices(&mut self, model: &Model) -> &[CutVertex] {
        self.sync_topology(model);
        &self.cut
    }

    /// The vertices' positions and unit normals: the particles' (`particle_normals`, the
    /// physics surface's vertex normals) and then the cut vertices', each with the normal of
    /// the particle whose side it is on.
    pub fn frame(
        &mut self,
        model: &Model,
        state: &State,
        particle_normals: &Vec3s,
    ) -> (&Vec3s, &Vec3s) {
        self.sync_topology(model);
        let now = (state.version, model.topology_version);
        if self.frame_for != Some(now) {
            let (pos, n) = (&state.kin.pos, model.grid.len());
            let total = n + self.cut.len();
            if self.positions.len() != total {
                self.positions = Vec3s::zeros(total);
                self.normals = Vec3s::zeros(total);
            }
            for (out, src) in [
                (&mut self.positions, pos),
                (&mut self.normals, particle_normals),
            ] {
                out.x[..n].copy_from_slice(&src.x[..n]);
                out.y[..n].copy_from_slice(&src.y[..n]);
                out.z[..n].copy_from_slice(&src.z[..n]);
            }
            self.apart.clear();
            self.apart.resize(n, 0.0);
            for v in &self.cut {
                let apart = &mut self.apart[v.toward as usize];
                *apart = apart.max(v.parted(pos).min(1.0));
            }
            for (k, v) in self.cut.iter().enumerate() {
                let apart = self.apart[v.toward as usize];
                self.positions.set(n + k, v.position(pos, apart));
                self.normals
                    .set(n + k, particle_normals.get(v.from as usize));
            }
            self.frame_for = Some(now);
        }
        (&self.positions, &self.normals)
    }

    pub fn heap_bytes(&self) -> usize {
        self.triangles.capacity() * size_of::<[u32; 3]>()
            + self.cut.capacity() * size_of::<CutVertex>()
            + self.index.capacity() * size_of::<((SpringKind, usize, bool), u32)>()
            + self.mesh_index.capacity() * size_of::<((u32, bool), u32)>()
            + self.positions.heap_bytes()
            + self.apart.capacity() * size_of::<f32>()
            + self.normals.heap_bytes()
    }

    fn sync_topology(&mut self, model: &Model) {
        if self.topology_for == Some(model.topology_version) {
            return;
        }
        self.triangles.clear();
        self.cut.clear();
        self.index.clear();
        self.mesh_index.clear();
        if let Some(topology) = model.mesh_topology() {
            self.clip_mesh(model, topology);
        } else {
            let (grid, alive) = (model.grid, &model.particles.alive);
            for id in 0..triangle_slots(grid) {
                if triangle_alive(grid, alive, id) {
                    self.clip(model, cell_triangle(grid, id));
                }
            }
        }
        self.topology_for = Some(model.topology_version);
        self.frame_for = None;
    }

    /// Appends the pieces of grid triangle `tri` (counter-clockwise) the cuts leave.
    fn clip(&mut self, model: &Model, tri: [usize; 3]) {
        let grid = model.grid;
        let severed: [bool; 3] = std::array::from_fn(|e| {
            let (kind, anchor) = grid
                .spring_between(tri[e], tri[(e + 1) % 3])
                .expect("a triangle's edges are springs");
            model.springs.active[kind.index()][anchor] == 0.0
        });
        let p = tri.map(|q| q as u32);
        let (pieces, count) = clip_pieces(p, severed, |e, end| {
            self.cut_vertex(model, tri[(e + end) % 3], tri[(e + 1 - end) % 3])
        });
        self.triangles.extend_from_slice(&pieces[..count]);
    }

    /// The index of the cut vertex on the severed edge `from`-`to`, on `from`'s side.
    fn cut_vertex(&mut self, model: &Model, from: usize, to: usize) -> u32 {
        let grid = model.grid;
        let (kind, anchor) = grid.spring_between(from, to).expect("an edge");
        let key = (kind, anchor, from == anchor);
        let n = grid.len() as u32;
        if let Some(&v) = self.index.get(&key) {
            return v;
        }
        let t = model.crossings.get(&(kind, anchor)).copied().unwrap_or(0.5);
        let s = if from == anchor { t } else { 1.0 - t };
        let vertex = embed(model, from, to, s);
        let v = n + self.cut.len() as u32;
        self.cut.push(vertex);
        self.index.insert(key, v);
        v
    }
}

/// The pieces (one to three triangles, counter-clockwise) triangle `p` leaves when its edges
/// `severed` (edge `e` from corner `e` to corner `e + 1`) are cut; `cut(e, end)` is the cut
/// vertex on edge `e` on the side of its end `end` (0: corner `e`, 1: corner `e + 1`).
fn clip_pieces(
    p: [u32; 3],
    severed: [bool; 3],
    mut cut: impl FnMut(usize, usize) -> u32,
) -> ([[u32; 3]; 3], usize) {
    match severed.iter().filter(|&&s| s).count() {
        0 => ([p, p, p], 1),
        1 => {
            let e = severed.iter().position(|&s| s).expect("one");
            let (a, b, v) = (p[e], p[(e + 1) % 3], p[(e + 2) % 3]);
            ([[a, cut(e, 0), v], [cut(e, 1), b, v], p], 2)
        }
        2 => {
            // The live edge m joins the two corners on one side; corner c is alone.
            let m = severed.iter().position(|&s| !s).expect("one live");
            let (a, b, c) = (p[m], p[(m + 1) % 3], p[(m + 2) % 3]);
            let (e1, e2) = ((m + 1) % 3, (m + 2) % 3);
            let (x1_c, x2_c) = (cut(e1, 1), cut(e2, 0));
            let (x1_b, x2_a) = (cut(e1, 0), cut(e2, 1));
            ([[x1_c, c, x2_c], [a, b, x1_b], [a, x1_b, x2_a]], 3)
        }
        _ => (
            std::array::from_fn(|k| [cut((k + 2) % 3, 1), p[k], cut(k, 0)]),
            3,
        ),
    }
}

/// The cut vertex at fraction `s` of the way from `from` to the ghost of `to` that `from`'s
/// live neighbours frame (see the module's documentation).
fn embed(model: &Model, from: usize, to: usize, s: f32) -> CutVertex {
    let grid = model.grid;
    let step = |q: usize| {
        let ((i0, j0), (i1, j1)) = (grid.coords(from), grid.coords(q));
        (i1 as i64 - i0 as i64, j1 as i64 - j0 as i64)
    };
    let g = step(to);
    // Rest offsets in m: the grid steps scaled by the spacing.
    let size = model.scene.cloth.size;
    let h = glam::DVec2::new(
        size[0] / (grid.nx - 1) as f64,
        size[1] / (grid.ny - 1) as f64,
    );
    let offset = glam::DVec2::new(g.0 as f64, g.1 as f64) * h;
    let mut live = [(0usize, (0i64, 0i64)); STEPS.len()];
    let mut count = 0;
    for d in STEPS {
        if let Some(q) = live_neighbour(model, from, d) {
            live[count] = (q, d);
            count += 1;
        }
    }
    let live = &live[..count];
    // The frame with the smallest |alpha| + |beta| (interpolating where it can).
    let mut best: Option<(f64, [usize; 2], [f64; 2])> = None;
    for (k, &(u, du)) in live.iter().enumerate() {
        for &(w, dw) in &live[k + 1..] {
            let det = (du.0 * dw.1 - du.1 * dw.0) as f64;
            if det == 0.0 {
                continue;
            }
            let alpha = (g.0 * dw.1 - g.1 * dw.0) as f64 / det;
            let beta = (du.0 * g.1 - du.1 * g.0) as f64 / det;
            let cost = alpha.abs() + beta.abs();
            if best.is_none_or(|b| cost < b.0) {
                best = Some((cost, [u, w], [alpha, beta]));
            }
        }
    }
    // Else one neighbour in line with the edge.
    let collinear = || {
        live.iter()
            .find(|(_, d)| d.0 * g.1 == d.1 * g.0)
            .map(|&(u, d)| {
                let alpha = if d.0 != 0 {
                    g.0 as f64 / d.0 as f64
                } else {
                    g.1 as f64 / d.1 as f64
                };
                ([u, from], [alpha, 0.0])
            })
    };
    let frame = match best.map(|b| (b.1, b.2)).or_else(collinear) {
        Some((frame, [wu, ww])) => Frame::Affine {
            neighbours: frame.map(|q| q as u32),
            weights: [(1.0 - wu - ww) as f32, wu as f32, ww as f32],
        },
        None => match live.first() {
            Some(&(u, du)) => {
                let tangent = (glam::DVec2::new(du.0 as f64, du.1 as f64) * h).normalize();
                let along = offset.dot(tangent);
                Frame::Strip {
                    neighbour: u as u32,
                    along: along as f32,
                    across: (offset - along * tangent).length() as f32,
                }
            }
            None => Frame::Toward {
                reach: offset.length() as f32,
            },
        },
    };
    CutVertex {
        from: from as u32,
        toward: to as u32,
        s,
        rest: offset.length() as f32,
        frame,
    }
}

/// The particle one grid step `d` from `p`, if a live spring joins them.
fn live_neighbour(model: &Model, p: usize, d: (i64, i64)) -> Option<usize> {
    let grid: Grid = model.grid;
    let (i, j) = grid.coords(p);
    let (qi, qj) = (i as i64 + d.0, j as i64 + d.1);
    if !((0..grid.nx as i64).contains(&qi) && (0..grid.ny as i64).contains(&qj)) {
        return None;
    }
    let q = grid.index(qi as usize, qj as usize);
    let (kind, anchor) = grid.spring_between(p, q)?;
    let live = model.springs.active[kind.index()][anchor] != 0.0 && model.particles.alive[q];
    live.then_some(q)
}

/// Texture coordinates of the drawn mesh's vertices: particle `(i, j)` at
/// `(i / (nx - 1), j / (ny - 1))`, a cut vertex where its edge was crossed.
pub fn uvs(grid: Grid, cut: &[CutVertex]) -> Vec<[f32; 2]> {
    let uv = |p: usize| {
        let (i, j) = grid.coords(p);
        glam::Vec2::new(
            i as f32 / (grid.nx - 1) as f32,
            j as f32 / (grid.ny - 1) as f32,
        )
    };
    (0..grid.len())
        .map(uv)
        .chain(
            cut.iter()
                .map(|v| uv(v.from as usize).lerp(uv(v.toward as usize), v.s)),
        )
        .map(|x| x.to_array())
        .collect()
}

/// The particle each vertex of the drawn mesh shows the values of (its colour in a strain or
/// speed view): a particle itself, a cut vertex the particle whose side it is on.
pub fn sources(grid: Grid, cut: &[CutVertex]) -> Vec<u32> {
    (0..grid.len() as u32)
        .chain(cut.iter().map(|v| v.from))
        .collect()
}
