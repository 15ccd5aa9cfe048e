//! Cuts and tears on a mesh cloth: which springs a severed edge takes with it, which triangles
//! are still drawn, and which pieces the cloth is in.
//!
//! A severed spring keeps its slot in the spring list ([`EdgeSprings`]) with `active` false and
//! stiffness and damping 0, so the force pass, the implicit solvers' assembly and the energy
//! need no branch for it, the list never reallocates, and no index moves (the picking and
//! self-collision trees keep their leaves; the solvers' factors are refreshed because they key
//! on the `active` flags).
//!
//! * A bend spring belongs to the two triangles on the edge it crosses: it holds only while
//!   both are whole. Severing a stretch spring therefore severs the bend springs across every
//!   edge of the (one or two) triangles on it; severing a bend spring alone (a stroke crossing
//!   it) takes nothing else.
//! * A triangle is drawn while its three corners are alive and its three stretch springs hold
//!   ([`MeshTopology::drawn`]). A mesh built with no stretch springs (stretch modulus 0) has
//!   nothing to cut along its edges, and its triangles stay drawn.
//! * A piece is a set of live vertices joined by live springs other than seams, or by drawn
//!   triangles: a seam pulls two panels of a garment together but does not make them one piece.
//!
//! The drawn mesh clips the triangles on a severed edge where the stroke crossed it
//! ([`MeshTopology::crossings`], [`crate::render_mesh`]), as on the grid.

use std::collections::HashMap;
use std::sync::Arc;

use super::{EdgeKind, EdgeSprings, MeshCloth};

/// No spring or triangle.
pub const NONE: u32 = u32::MAX;

/// A mesh cloth with the tables its cuts read, and the triangle list shared with the picking
/// trees.
#[derive(Clone, Debug)]
pub struct MeshTopology {
    /// The cloth; its springs' `active`, `k` and `c` change as it is cut.
    pub mesh: Arc<MeshCloth>,
    /// The triangles, every one drawn or not, in the mesh's order (the stable triangle ids).
    pub triangles: Arc<[[u32; 3]]>,
    /// Per triangle, its three stretch springs (edge `k` from corner `k` to corner `k + 1`), or
    /// [`NONE`] where the mesh has none.
    edges: Vec<[u32; 3]>,
    /// Per triangle, the bend spring across each of its edges, or [`NONE`] (a boundary edge).
    bends: Vec<[u32; 3]>,
    /// Per spring, the triangles on its edge (a stretch spring's one or two), or [`NONE`].
    faces: Vec<[u32; 2]>,
    /// Where a stroke crossed each spring it severed: `t` in `[0, 1]` from the spring's end
    /// `a`. Springs severed without a stroke (a tear) have none; the drawn mesh opens them at
    /// their midpoints. Nothing in a step reads it.
    pub crossings: HashMap<u32, f32>,
}

impl MeshTopology {
    pub fn new(mesh: MeshCloth) -> MeshTopology {
        let s = &mesh.springs;
        let key = |a: u32, b: u32| (a.min(b), a.max(b));
        let mut stretch = HashMap::with_capacity(s.len());
        // A pair of opposite vertices may stand across two edges (each gets its own spring,
        // listed next to each other): each edge takes the next unclaimed one.
        let mut bend: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
        for e in 0..s.len() {
            match s.kind[e] {
                EdgeKind::Stretch => {
                    stretch.insert((s.a[e], s.b[e]), e as u32);
                }
                EdgeKind::Bend => bend.entry((s.a[e], s.b[e])).or_default().push(e as u32),
                EdgeKind::Seam => {}
            }
        }
        for list in bend.values_mut() {
            list.reverse(); // popped from the back: the lowest index first
        }
        let mut faces = vec![[NONE; 2]; s.len()];
        let edges: Vec<[u32; 3]> = (mesh.triangles.iter().enumerate())
            .map(|(t, tri)| {
                std::array::from_fn(|k| {
                    let e = *stretch.get(&key(tri[k], tri[(k + 1) % 3])).unwrap_or(&NONE);
                    if e != NONE {
                        let slot = &mut faces[e as usize];
                        slot[usize::from(slot[0] != NONE)] = t as u32;
                    }
                    e
                })
            })
            .collect();
        // The bend spring across an edge joins the corners opposite it in its two triangles,
        // visited in the order the mesh built them (edges in order of their ends).
        let mut edge_faces: Vec<((u32, u32), u32, usize)> = (mesh.triangles.iter().enumerate())
            .flat_map(|(t, tri)| (0..3).map(move |k| (key(tri[k], tri[(k + 1) % 3]), t as u32, k)))
            .collect();
        edge_faces.sort_unstable();
        let mut bends = vec![[NONE; 3]; mesh.triangles.len()];
        for run in edge_faces.chunk_by(|x, y| x.0 == y.0) {
            if let [(_, t0, k0), (_, t1, k1)] = *run {
                let opposite = |t: u32, k: usize| mesh.triangles[t as usize][(k + 2) % 3];
                let pair = key(opposite(t0, k0), opposite(t1, k1));
                if let Some(e) = bend.get_mut(&pair).and_then(Vec::pop) {
                    bends[t0 as usize][k0] = e;
                    bends[t1 as usize][k1] = e;
                }
            }
        }
        MeshTopology {
            triangles: mesh.triangles.clone().into(),
            mesh: Arc::new(mesh),
            edges,
            bends,
            faces,
            crossings: HashMap::new(),
        }
    }

    /// Triangle `t`'s stretch springs, edge `k` from corner `k` to corner `k + 1`, or [`NONE`]
    /// where the mesh has none.
    #[inline]
    pub fn edge_springs(&self, t: usize) -> [u32; 3] {
        self.edges[t]
    }

    /// The bend springs across triangle `t`'s edges (edge `k` from corner `k` to corner
    /// `k + 1`), each joining corner `k + 2` to the corner opposite the edge in the triangle
    /// beyond it; [`NONE`] on a boundary edge or where the mesh has none.
    #[inline]
    pub fn bend_springs(&self, t: usize) -> [u32; 3] {
        self.bends[t]
    }

    /// Whether triangle `t` is drawn: its corners alive and its stretch springs holding.
    #[inline]
    pub fn drawn(&self, alive: &[bool], t: usize) -> bool {
        let active = &self.mesh.springs.active;
        self.triangles[t].iter().all(|&v| alive[v as usize])
            && self.edges[t]
                .iter()
                .all(|&e| e == NONE || active[e as usize])
    }

    /// Severs `springs` (indices into the spring list) and what goes with them; returns how
    /// many of those listed were live (a spring listed twice counts once).
    pub fn sever(&mut self, springs: impl IntoIterator<Item = u32>) -> usize {
        self.sever_each(springs.into_iter().map(|e| (e, None)))
    }

    /// [`MeshTopology::sever`] for springs a stroke crossed, each with where it crossed (kept
    /// in [`MeshTopology::crossings`]); a spring listed twice keeps its first crossing.
    pub fn sever_crossing(&mut self, crossings: &[(u32, f32)]) -> usize {
        self.sever_each(crossings.iter().map(|&(e, t)| (e, Some(t))))
    }

    fn sever_each(&mut self, cuts: impl Iterator<Item = (u32, Option<f32>)>) -> usize {
        let Self {
            mesh,
            faces,
            bends,
            crossings,
            ..
        } = self;
        let s = &mut Arc::make_mut(mesh).springs;
        let mut severed = 0;
        let mut changed = Vec::new();
        for (e, t) in cuts {
            if !s.active[e as usize] {
                continue;
            }
            severed += 1;
            cut_spring(s, e, &mut changed);
            if let Some(t) = t {
                crossings.insert(e, t);
            }
            for t in faces[e as usize].into_iter().filter(|&t| t != NONE) {
                for b in bends[t as usize].into_iter().filter(|&b| b != NONE) {
                    cut_spring(s, b, &mut changed);
                }
            }
        }
        if severed > 0 {
            Arc::make_mut(mesh).refresh_cut_springs(&changed);
        }
        severed
    }

    /// Severs every spring touching vertex `v` (seams included: the vertex leaves the cloth);
    /// returns how many were live.
    pub fn sever_vertex(&mut self, v: usize) -> usize {
        let touching: Vec<u32> = (self.mesh.springs_at(v).iter()).map(|&e| e >> 1).collect();
        self.sever(touching)
    }

    /// Puts back a saved set of live springs on a cloth none of whose springs is severed yet:
    /// each spring `active[e]` false is severed alone (what went with it is listed too).
    pub fn sever_as_saved(&mut self, active: &[bool]) {
        let s = &mut Arc::make_mut(&mut self.mesh).springs;
        let mut changed = Vec::new();
        for (e, _) in active.iter().enumerate().filter(|(_, &live)| !live) {
            cut_spring(s, e as u32, &mut changed);
        }
        Arc::make_mut(&mut self.mesh).refresh_cut_springs(&changed);
    }

    /// The piece each vertex belongs to, named by the smallest vertex index in it; `u32::MAX`
    /// for a removed vertex.
    pub fn piece_labels(&self, alive: &[bool]) -> Vec<u32> {
        self.piece_labels_joined_by(alive, |_| true)
    }

    /// [`MeshTopology::piece_labels`] as if only the live springs `joins(e)` accepts (indices
    /// into the spring list) were left: the pieces a cut of the others would leave.
    pub fn piece_labels_joined_by(&self, alive: &[bool], joins: impl Fn(u32) -> bool) -> Vec<u32> {
        let n = self.mesh.len();
        let mut parent: Vec<u32> = (0..n as u32).collect();
        fn root(parent: &mut [u32], mut v: u32) -> u32 {
            while parent[v as usize] != v {
                parent[v as usize] = parent[parent[v as usize] as usize];
                v = parent[v as usize];
            }
            v
        }
        let mut join = |a: u32, b: u32| {
            let (a, b) = (root(&mut parent, a), root(&mut parent, b));
            // The smaller index as the root, so that a root is its piece's smallest vertex.
            parent[a.max(b) as usize] = a.min(b);
        };
        let s = &self.mesh.springs;
        for e in 0..s.len() {
            let (a, b) = (s.a[e], s.b[e]);
            if s.active[e]
                && joins(e as u32)
                && s.kind[e] != EdgeKind::Seam
                && alive[a as usize]
                && alive[b as usize]
            {
                join(a, b);
            }
        }
        let held = |t: usize| self.edges[t].iter().all(|&e| e == NONE || joins(e));
        for t in (0..self.triangles.len()).filter(|&t| self.drawn(alive, t) && held(t)) {
            let [a, b, c] = self.triangles[t];
            join(a, b);
            join(a, c);
        }
        (0..n as u32)
            .map(|v| match alive[v as usize] {
                true => root(&mut parent, v),
                false => u32::MAX,
            })
            .collect()
    }

    pub fn heap_bytes(&self) -> usize {
        self.mesh.heap_bytes()
            + self.triangles.len() * 12
            + (self.edges.capacity() + self.bends.capacity()) * 12
            + self.faces.capacity() * 8
            + self.crossings.capacity() * size_of::<(u32, f32)>()
    }
}

/// A severed spring holds nothing: no stiffness, no damping.
/// Severs spring `e` and lists it in `changed` (for [`MeshCloth::refresh_cut_springs`]).
fn cut_spring(s: &mut EdgeSprings, e: u32, changed: &mut Vec<u32>) {
    let i = e as usize;
    s.active[i] = false;
    s.k[i] = 0.0;
    s.c[i] = 0.0;
    changed.push(e);
}
