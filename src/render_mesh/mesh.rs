//! A mesh cloth's drawn surface: its triangles clipped at their severed edges as the grid's
//! are ([`clip_pieces`]), with a cut vertex on each side of a severed edge where the stroke
//! crossed it ([`MeshTopology::crossings`]; a tear's at the midpoint).
//!
//! **Embedding.** A cut vertex of `p`'s side lies `s` (the crossing's fraction of the edge from
//! `p`) of the way from `p` to a ghost of `q` that follows `p` and two neighbours `u`, `w` that
//! live stretch springs join to `p`: `x_p + alpha (x_u - x_p) + beta (x_w - x_p)`, with
//! `(alpha, beta)` the rest edge from `p` to `q` in the frame of the rest edges to `u` and `w`
//! (least squares, exact on a flat mesh). As on the grid, a severed edge whose ends have not
//! parted puts both sides' vertices at its crossing.
//! Of the pairs, the one with the smallest `|alpha| + |beta|` plus the part of the edge out of
//! their plane (relative to its length), so interpolated where it can be and in the plane the
//! edge lies in. A vertex whose live neighbours are all in line follows the strip they make,
//! one with none reaches toward `q` ([`Frame::Strip`], [`Frame::Toward`], as on the grid).

use glam::DVec3;

use super::{clip_pieces, CutVertex, Frame, RenderMesh};
use crate::mesh_cloth::topology::{MeshTopology, NONE};
use crate::mesh_cloth::{EdgeKind, MeshCloth};
use crate::model::Model;

/// Pairs of neighbours whose rest edges make a smaller `sin^2` of their angle than this are in
/// line: no frame (a 0.06 degree angle; an accepted mesh's triangles are far from it).
const IN_LINE: f64 = 1e-6;

impl RenderMesh {
    /// Appends a mesh cloth's drawn triangles: each triangle whose corners are alive, clipped
    /// at its severed edges.
    pub(super) fn clip_mesh(&mut self, model: &Model, topology: &MeshTopology) {
        let (alive, springs) = (&model.particles.alive, &topology.mesh.springs);
        for (t, tri) in topology.triangles.iter().enumerate() {
            if !tri.iter().all(|&v| alive[v as usize]) {
                continue;
            }
            let edges = topology.edge_springs(t);
            let severed = edges.map(|e| e != NONE && !springs.active[e as usize]);
            let (pieces, count) = clip_pieces(*tri, severed, |e, end| {
                let (from, to) = (tri[(e + end) % 3], tri[(e + 1 - end) % 3]);
                self.mesh_cut_vertex(model, topology, edges[e], from, to)
            });
            self.triangles.extend_from_slice(&pieces[..count]);
        }
    }

    /// The index of the cut vertex on severed spring `e` (from `from` to `to`), on `from`'s
    /// side.
    fn mesh_cut_vertex(
        &mut self,
        model: &Model,
        topology: &MeshTopology,
        e: u32,
        from: u32,
        to: u32,
    ) -> u32 {
        let on_a = topology.mesh.springs.a[e as usize] == from;
        if let Some(&v) = self.mesh_index.get(&(e, on_a)) {
            return v;
        }
        let t = topology.crossings.get(&e).copied().unwrap_or(0.5);
        let s = if on_a { t } else { 1.0 - t };
        let v = (model.grid.len() + self.cut.len()) as u32;
        self.cut
            .push(embed(model, topology, from as usize, to as usize, s));
        self.mesh_index.insert((e, on_a), v);
        v
    }
}

/// The cut vertex at fraction `s` of the way from `from` to the ghost of `to` that `from`'s
/// live neighbours frame at rest (see the module's documentation).
fn embed(model: &Model, topology: &MeshTopology, from: usize, to: usize, s: f32) -> CutVertex {
    let mesh = &topology.mesh;
    let rest = |v: usize| DVec3::from(mesh.rest[v]);
    let origin = rest(from);
    let edge = rest(to) - origin;
    let springs = &mesh.springs;
    let alive = &model.particles.alive;
    let live: Vec<usize> = (mesh.springs_at(from).iter())
        .map(|&x| (x >> 1) as usize)
        .filter(|&k| springs.active[k] && springs.kind[k] == EdgeKind::Stretch)
        .map(|k| (springs.a[k] ^ springs.b[k] ^ from as u32) as usize)
        .filter(|&q| alive[q])
        .collect();
    let mut best: Option<(f64, [usize; 2], [f64; 2])> = None;
    for (k, &u) in live.iter().enumerate() {
        for &w in &live[k + 1..] {
            let (eu, ew) = (rest(u) - origin, rest(w) - origin);
            let (uu, uw, ww) = (eu.dot(eu), eu.dot(ew), ew.dot(ew));
            let det = uu * ww - uw * uw;
            if det <= IN_LINE * uu * ww {
                continue;
            }
            let (du, dw) = (eu.dot(edge), ew.dot(edge));
            let alpha = (du * ww - dw * uw) / det;
            let beta = (dw * uu - du * uw) / det;
            let off = (edge - alpha * eu - beta * ew).length() / edge.length();
            let cost = alpha.abs() + beta.abs() + off;
            if best.is_none_or(|b| cost < b.0) {
                best = Some((cost, [u, w], [alpha, beta]));
            }
        }
    }
    let frame = match (best, live.first()) {
        (Some((_, pair, [wu, ww])), _) => Frame::Affine {
            neighbours: pair.map(|q| q as u32),
            weights: [(1.0 - wu - ww) as f32, wu as f32, ww as f32],
        },
        (None, Some(&u)) => {
            let offset = edge;
            let tangent = (rest(u) - origin).normalize();
            let along = offset.dot(tangent);
            Frame::Strip {
                neighbour: u as u32,
                along: along as f32,
                across: (offset - along * tangent).length() as f32,
            }
        }
        (None, None) => Frame::Toward {
            reach: edge.length() as f32,
        },
    };
    CutVertex {
        from: from as u32,
        toward: to as u32,
        s,
        rest: edge.length() as f32,
        frame,
    }
}

/// Texture coordinates of a mesh cloth's drawn vertices: its vertices' ([`vertex_uvs`]), then
/// each cut vertex's where its edge was crossed.
pub fn mesh_uvs(mesh: &MeshCloth, cut: &[CutVertex]) -> Vec<[f32; 2]> {
    let mut uvs = vertex_uvs(mesh);
    let at = |v: u32| glam::Vec2::from(uvs[v as usize]);
    let cut_uvs: Vec<[f32; 2]> = (cut.iter())
        .map(|v| at(v.from).lerp(at(v.toward), v.s).to_array())
        .collect();
    uvs.extend(cut_uvs);
    uvs
}

/// Texture coordinates of a mesh cloth's vertices: the mesh's own, or without them the rest
/// shape projected onto the two axes along which it extends furthest, each scaled to `[0, 1]`.
fn vertex_uvs(mesh: &MeshCloth) -> Vec<[f32; 2]> {
    if let Some(uvs) = &mesh.uvs {
        return uvs.clone();
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for v in &mesh.rest {
        for c in 0..3 {
            lo[c] = lo[c].min(v[c]);
            hi[c] = hi[c].max(v[c]);
        }
    }
    let mut axes = [0, 1, 2];
    axes.sort_by(|&a, &b| (hi[b] - lo[b]).total_cmp(&(hi[a] - lo[a])));
    let along = |v: &[f64; 3], c: usize| {
        let extent = hi[c] - lo[c];
        (if extent > 0.0 {
            (v[c] - lo[c]) / extent
        } else {
            0.0
        }) as f32
    };
    let (u, w) = (axes[0].min(axes[1]), axes[0].max(axes[1]));
    mesh.rest
        .iter()
        .map(|v| [along(v, u), along(v, w)])
        .collect()
}
