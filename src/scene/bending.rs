//! Isometric bending (`bending = "isometric"`): the quadratic bending energy of Bergou,
//! Wardetzky, Harmon, Zorin and Grinspun 2006, "A Quadratic Bending Model for Inextensible
//! Surfaces".
//!
//! Each interior edge `(x0, x1)` with its two triangles `(x0, x1, x2)` and `(x0, x1, x3)` is an
//! element with the cotangent weights
//!
//! ```text
//! K = (c03 + c04, c01 + c02, -c01 - c03, -c02 - c04)
//! ```
//!
//! (`c01`, `c02` the cotangents of the angles at `x0` in the first and second triangle, `c03`,
//! `c04` those at `x1`), and stores `E_e = B / 2 * 1 / (A0 + A1) |sum_i K_i x_i|^2`, `B` the
//! bending modulus (N m), `A0`, `A1` the triangles' rest areas. `|sum_i K_i x_i|` is the edge's
//! length times its fold angle, so this is the discrete-shells energy near the flat state.
//! Summed over the edges it approximates `B / 2 * integral |H|^2 dA` with `H` the mean
//! curvature vector (`|H| = 1 / R` on a cylinder of radius `R`), so its stiffness against a
//! curvature does not fall with the spacing as the bend springs' does. The paper writes
//! `3 / (A0 + A1)`; measured on a cylinder, that stores 2.9 to 3.5 times the continuum's
//! energy on regular, jittered and Delaunay meshes, so the factor here is 1 and `B` is the
//! continuum's modulus to within the mesh's own departure (docs/notes/mesh_cloth.md,
//! "Isometric bending, measured": 0.98 regular, 1.01 to 1.08 jittered by 0.3 of the spacing,
//! 1.16 Delaunay). The weights are those of the rest shape and the energy is exact for isometric
//! deformations of a flat rest shape, which is why a curved rest shape is refused.
//!
//! `K` sums to zero, so the energy is a sum over the element's six vertex pairs,
//! `E_e = sum_{i<j} w_ij / 2 |x_j - x_i|^2` with `w_ij = -B q_i q_j` (`q = K / sqrt(A0 + A1)`):
//! a zero-rest-length linear spring of stiffness `w_ij` (of either sign) between each pair.
//! Every pair is one of the mesh's springs (the edge and the four sides are stretch springs,
//! `(x2, x3)` is the bend spring across the edge), so the model is one constant number per
//! spring, [`IsometricBending::linear`], the sum of its elements' `w`: the force pass adds
//! `w (x_b - x_a)` to each spring's force on its first end, implicit Euler adds `h^2 w I` to
//! its block and projective dynamics `w` to its weight (the Hessian is constant).

use std::collections::HashMap;

use glam::DVec3;

use super::{EdgeKind, EdgeSprings};
use crate::error::{Error, Result};
use crate::soa::Vec3s;

/// Largest fold angle (rad) across an edge of the rest shape that still counts as flat: the
/// float32 rounding of a flat mesh's positions, well below any fold a modelling tool puts in.
const FLAT: f64 = 1e-4;

/// The isometric bending elements of a mesh cloth and the per-spring stiffness they make.
#[derive(Clone, Debug, PartialEq)]
pub struct IsometricBending {
    /// Bending modulus in N m.
    pub modulus: f64,
    /// Per element: the edge's two vertices, then the two opposite ones.
    pub corners: Vec<[u32; 4]>,
    /// Per element: `q = K / sqrt(A0 + A1)` (1/m), so that `E_e = B / 2 |sum_i q_i x_i|^2`.
    pub weights: Vec<[f64; 4]>,
    /// Per element: the springs of its pairs `(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)`.
    /// The element acts while all six hold (a cut or tear that severs its edge, a side or the
    /// bend spring across it takes it).
    pub springs: Vec<[u32; 6]>,
    /// Per spring: the linear stiffness `w` in N/m (negative for some) of the live elements on
    /// its pair; the spring's first end feels `w (x_b - x_a)`.
    pub linear: Vec<f32>,
}

/// The element's pairs, in the order of [`IsometricBending::springs`].
const PAIRS: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

impl IsometricBending {
    /// The elements of `quads` (each an interior edge's two vertices, then its two opposite
    /// ones) on the rest shape `rest`, their pairs found in `springs` (which must hold a stretch
    /// spring on every edge and a bend spring across every interior edge). Refused, naming
    /// `{at}.bending`: a rest shape folded across an edge by more than [`FLAT`].
    pub fn new(
        at: &str,
        rest: &[[f64; 3]],
        quads: &[[u32; 4]],
        springs: &EdgeSprings,
        modulus: f64,
    ) -> Result<IsometricBending> {
        let mut index: HashMap<(u32, u32, bool), u32> = HashMap::with_capacity(springs.len());
        for e in 0..springs.len() {
            let bend = match springs.kind[e] {
                EdgeKind::Stretch => false,
                EdgeKind::Bend => true,
                EdgeKind::Seam => continue,
            };
            index
                .entry((springs.a[e], springs.b[e], bend))
                .or_insert(e as u32);
        }
        let x = |k: u32| DVec3::from(rest[k as usize]);
        let cot = |a: DVec3, b: DVec3| a.dot(b) / a.cross(b).length();
        let mut weights = Vec::with_capacity(quads.len());
        let mut pair_springs = Vec::with_capacity(quads.len());
        for &[i0, i1, i2, i3] in quads {
            let (x0, x1, x2, x3) = (x(i0), x(i1), x(i2), x(i3));
            let (e0, e1, e2) = (x1 - x0, x2 - x0, x3 - x0);
            let (n0, n1) = (e0.cross(e1), e0.cross(e2));
            let fold = n0.cross(n1).length() / (n0.length() * n1.length());
            if fold > FLAT {
                return Err(Error::value(
                    format!("{at}.bending"),
                    format!(
                        "\"isometric\" needs a flat rest shape, but the mesh is folded by \
                         {:.2e} rad across the edge between vertices {i0} and {i1}: use \
                         bending = \"springs\" for a curved mesh",
                        fold.asin()
                    ),
                ));
            }
            let (c01, c02) = (cot(e0, e1), cot(e0, e2));
            let (c03, c04) = (cot(-e0, x2 - x1), cot(-e0, x3 - x1));
            let k = [c03 + c04, c01 + c02, -c01 - c03, -c02 - c04];
            let areas = 0.5 * (n0.length() + n1.length());
            let scale = areas.sqrt().recip();
            weights.push(k.map(|k| k * scale));
            let c = [i0, i1, i2, i3];
            pair_springs.push(PAIRS.map(|(i, j)| {
                let (a, b) = (c[i].min(c[j]), c[i].max(c[j]));
                let bend = (i, j) == (2, 3);
                *index.get(&(a, b, bend)).expect(
                    "a stretch spring on every edge, a bend spring across every interior edge",
                )
            }));
        }
        let mut bending = IsometricBending {
            modulus,
            corners: quads.to_vec(),
            weights,
            springs: pair_springs,
            linear: vec![0.0; springs.len()],
        };
        bending.refresh(&springs.active);
        Ok(bending)
    }

    /// Whether element `t` acts: all six of its springs hold.
    pub fn live(&self, t: usize, active: &[bool]) -> bool {
        self.springs[t].iter().all(|&e| active[e as usize])
    }

    /// Recomputes [`IsometricBending::linear`] from the live elements (after a cut or a tear),
    /// element by element in list order, so the sums are the same on every call.
    pub fn refresh(&mut self, active: &[bool]) {
        let mut linear = vec![0.0f64; self.linear.len()];
        for t in (0..self.corners.len()).filter(|&t| self.live(t, active)) {
            let q = &self.weights[t];
            for (p, &(i, j)) in PAIRS.iter().enumerate() {
                linear[self.springs[t][p] as usize] -= self.modulus * q[i] * q[j];
            }
        }
        for (w, l) in self.linear.iter_mut().zip(linear) {
            *w = l as f32;
        }
    }

    /// The bending energy at `pos` in J (f64), `B / 2 sum_e |sum_i q_i (x_i - x_0)|^2` over the
    /// live elements (`q` sums to zero, so the differences give the same sum without the
    /// cancellation of whole positions).
    pub fn energy(&self, pos: &Vec3s, active: &[bool]) -> f64 {
        let at = |k: u32| pos.get(k as usize).as_dvec3();
        (0..self.corners.len())
            .filter(|&t| self.live(t, active))
            .map(|t| {
                let c = self.corners[t];
                let q = &self.weights[t];
                let x0 = at(c[0]);
                let v = (1..4).fold(DVec3::ZERO, |v, i| v + q[i] * (at(c[i]) - x0));
                0.5 * self.modulus * v.length_squared()
            })
            .sum()
    }

    pub fn heap_bytes(&self) -> usize {
        self.corners.capacity() * 16
            + self.weights.capacity() * 32
            + self.springs.capacity() * 24
            + self.linear.capacity() * 4
    }
}
