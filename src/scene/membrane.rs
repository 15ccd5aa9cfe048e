//! The rest state of the triangle membrane's elements (`cloth.mesh.membrane = "triangle"`),
//! compiled with the scene; the model, its forces and its stiffness are in
//! `src/mesh_cloth/membrane.rs`.

use glam::DVec3;

use super::{EdgeKind, EdgeSprings};
use crate::incidence::Corners;

/// The elements of a mesh cloth's triangles (see `src/mesh_cloth/membrane.rs` for the model).
#[derive(Clone, Debug, PartialEq)]
pub struct Membrane {
    /// Lame parameters in N/m.
    pub mu: f32,
    pub lambda: f32,
    /// The triangles' corners, as the mesh lists them.
    pub triangles: Vec<[u32; 3]>,
    /// Rest area of each triangle in m^2.
    pub area: Vec<f32>,
    /// Each triangle's `B = D_m^-1`, row-major `[b00, b01, b10, b11]` (1/m).
    pub inv_rest: Vec<[f32; 4]>,
    /// Each triangle's three stretch springs (edge `k` from corner `k` to `k + 1`): the
    /// element acts while all three are active.
    pub edges: Vec<[u32; 3]>,
    /// The table entries (`3 t + corner`) at vertex `v` are
    /// `incident[offsets[v]..offsets[v + 1]]`, in increasing order.
    pub offsets: Vec<u32>,
    pub incident: Vec<u32>,
    /// Per spring, the stiffness (N/m) the springs membrane would give it, `Y A_e / L^2` on
    /// a stretch spring, 0 on the others: implicit Euler's multigrid grows its aggregates from
    /// it.
    pub proxy_k: Vec<f32>,
}

impl Membrane {
    /// The elements of `triangles` at rest in `rest`, with Young's-like modulus `stretch` (N/m)
    /// and Poisson's ratio `poisson`; `springs` must hold a stretch spring on every edge.
    pub fn new(
        rest: &[[f64; 3]],
        triangles: &[[u32; 3]],
        springs: &EdgeSprings,
        stretch: f64,
        poisson: f64,
    ) -> Membrane {
        let at = |k: u32| DVec3::from(rest[k as usize]);
        let mut area = Vec::with_capacity(triangles.len());
        let mut inv_rest = Vec::with_capacity(triangles.len());
        for t in triangles {
            let (d1, d2) = (at(t[1]) - at(t[0]), at(t[2]) - at(t[0]));
            let e1 = d1.normalize();
            let e2 = d1.cross(d2).cross(d1).normalize();
            let (m00, m01, m11) = (d1.length(), d2.dot(e1), d2.dot(e2));
            // The inverse of the upper triangular [[m00, m01], [0, m11]].
            inv_rest.push([1.0 / m00, -m01 / (m00 * m11), 0.0, 1.0 / m11].map(|x| x as f32));
            area.push((0.5 * d1.cross(d2).length()) as f32);
        }
        let stretch_spring: std::collections::HashMap<(u32, u32), u32> = (0..springs.len())
            .filter(|&e| springs.kind[e] == EdgeKind::Stretch)
            .map(|e| ((springs.a[e], springs.b[e]), e as u32))
            .collect();
        let edges: Vec<[u32; 3]> = triangles
            .iter()
            .map(|t| {
                std::array::from_fn(|k| {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    stretch_spring[&(a.min(b), a.max(b))]
                })
            })
            .collect();
        let Corners {
            offsets,
            corners: incident,
        } = Corners::new(triangles, rest.len());
        let mut proxy_k = vec![0.0f64; springs.len()];
        for (t, e) in edges.iter().enumerate() {
            for &e in e {
                let l = springs.rest[e as usize] as f64;
                proxy_k[e as usize] += stretch * area[t] as f64 / 3.0 / (l * l);
            }
        }
        Membrane {
            proxy_k: proxy_k.into_iter().map(|k| k as f32).collect(),
            mu: (stretch * (1.0 - poisson) / (4.0 * (1.0 + poisson))) as f32,
            lambda: (stretch * poisson / (2.0 * (1.0 + poisson))) as f32,
            triangles: triangles.to_vec(),
            area,
            inv_rest,
            edges,
            offsets,
            incident,
        }
    }

    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Whether triangle `t`'s element acts: its three stretch springs hold.
    #[inline(always)]
    pub fn holds(&self, active: &[bool], t: usize) -> bool {
        self.edges[t].iter().all(|&e| active[e as usize])
    }

    pub fn heap_bytes(&self) -> usize {
        self.triangles.capacity() * 12
            + self.area.capacity() * 4
            + self.inv_rest.capacity() * 16
            + self.edges.capacity() * 12
            + (self.offsets.capacity() + self.incident.capacity() + self.proxy_k.capacity()) * 4
    }
}
