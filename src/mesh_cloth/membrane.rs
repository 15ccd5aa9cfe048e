//! The triangle membrane (`cloth.mesh.membrane = "triangle"`): a co-rotational linear
//! constant-strain element on every triangle, for stretch and shear.
//!
//! Per triangle, at rest: a 2-D frame in its plane, the rest edge matrix
//! `D_m = [x1 - x0, x2 - x0]` in that frame and its inverse `B = D_m^-1`, and its area `A`.
//! At `x`: the deformation gradient `F = [x1 - x0, x2 - x0] B` (3 x 2), its rotation `R`
//! (3 x 2, orthonormal columns) from the polar decomposition `F = R S` (`S` symmetric 2 x 2),
//! found in the triangle's current plane (a QR of `F` gives the plane's frame and an upper
//! triangular 2 x 2, whose polar rotation is closed-form), the strain `E = S - I` and
//!
//! ```text
//! Psi = mu |E|^2 + lambda / 2 tr(E)^2,        P = dPsi/dF = R (2 mu E + lambda tr(E) I)
//! f_1, f_2 = columns of -A P B^T,               f_0 = -(f_1 + f_2)
//! ```
//!
//! `P` is the exact gradient of `Psi(F)` (with `|E|^2 = |F - R|^2` and `tr S` the sum of
//! `F`'s singular values), so the forces conserve the energy `A Psi`; they sum to zero by
//! construction and vanish under a rigid motion. Holding `R` fixed, the energy is a quadratic
//! in the corners, whose Hessian blocks `K_ij` (3 x 3, `K_ji = K_ij^T`, the 9 x 9 whole
//! positive semidefinite) are implicit Euler's stiffness ([`Membrane::stiffness`]).
//!
//! With `Y` = `stretch` and `nu` = `poisson`, `mu = Y (1 - nu) / (4 (1 + nu))` and
//! `lambda = Y nu / (2 (1 + nu))`: a uniform strain `e` in every direction stores `Y e^2 / 2`
//! per m^2, as the edge springs do, and `nu = 1/3` (`mu = lambda = Y / 8`) is the continuum
//! an isotropic spread of those springs tends to.
//!
//! A triangle acts while its three stretch springs hold: a cut or a tear that severs an edge
//! takes the element of each triangle on it.

use glam::{Mat3, Vec3};
use rayon::prelude::*;

pub use crate::scene::Membrane;
use crate::soa::{Vec3SliceMut, Vec3s};

/// Triangles per parallel work item of the per-triangle pass.
const TRIANGLE_CHUNK: usize = 2048;

/// The gradients of `F`'s two columns with respect to each corner: `g[i][j] = dF_j / dx_i`
/// (a scalar times the identity).
#[inline(always)]
fn column_gradients(b: &[f32; 4]) -> [[f32; 2]; 3] {
    [[-(b[0] + b[2]), -(b[1] + b[3])], [b[0], b[1]], [b[2], b[3]]]
}

/// `v / |v|`, or `fallback` where `v` is zero; written as selects, not branches, so that a
/// loop of them vectorises.
#[inline(always)]
fn unit_or(v: Vec3, fallback: Vec3) -> Vec3 {
    let l = v.length();
    let nonzero = l > 0.0;
    let inv = 1.0 / if nonzero { l } else { 1.0 };
    Vec3::new(
        if nonzero { v.x * inv } else { fallback.x },
        if nonzero { v.y * inv } else { fallback.y },
        if nonzero { v.z * inv } else { fallback.z },
    )
}

/// `F`'s columns and its rotation `R`'s columns, from the edges `d1 = x1 - x0`,
/// `d2 = x2 - x0`. Without a branch, so that a block of triangles vectorises.
#[inline(always)]
fn rotation(d1: Vec3, d2: Vec3, b: &[f32; 4]) -> ([Vec3; 2], [Vec3; 2]) {
    let f = [d1 * b[0] + d2 * b[2], d1 * b[1] + d2 * b[3]];
    // QR: the frame of the plane of F's columns, F = [e1 e2] [[a, c], [0, d]], d >= 0. A
    // degenerate triangle (a column of zero length, or both along one line) gets any frame:
    // its energy does not depend on which.
    let a = f[0].length();
    let e1 = unit_or(f[0], Vec3::X);
    let c = f[1].dot(e1);
    let rest = f[1] - c * e1;
    let d = rest.length();
    let across = if e1.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    let e2 = unit_or(rest, unit_or(e1.cross(across), Vec3::Y));
    // The polar rotation of [[a, c], [0, d]]: the angle of (a + d, -c).
    let (cos, sin) = (a + d, -c);
    let r = (cos * cos + sin * sin).sqrt();
    let turn = r > 0.0;
    let inv = 1.0 / if turn { r } else { 1.0 };
    let (cos, sin) = (if turn { cos * inv } else { 1.0 }, sin * inv);
    (f, [cos * e1 + sin * e2, cos * e2 - sin * e1])
}

/// Triangles per block of [`Membrane::element_forces`]: the block's gathered edges and
/// forces stay in the first-level cache.
const BLOCK: usize = 128;

impl Membrane {
    /// Triangle `t`'s edges `x1 - x0`, `x2 - x0` at `pos`.
    #[inline(always)]
    fn edges_at(&self, pos: &Vec3s, t: usize) -> (Vec3, Vec3) {
        let [x0, x1, x2] = self.triangles[t].map(|v| pos.get(v as usize));
        (x1 - x0, x2 - x0)
    }

    /// The forces on the corners of triangles `first..first + out.len()` at `pos` into `out`
    /// (zero for one that does not hold). Block by block, the edges are gathered into
    /// contiguous arrays first, so that the arithmetic runs as one loop without a branch,
    /// which each instruction set's build vectorises; every build gives the same bits (no
    /// fused multiply-add; square roots and divisions are exact).
    #[inline(always)]
    fn element_forces(&self, pos: &Vec3s, active: &[bool], first: usize, out: &mut [[Vec3; 3]]) {
        for (k, out) in out.chunks_mut(BLOCK).enumerate() {
            let start = first + k * BLOCK;
            let n = out.len();
            let mut edges = [[Vec3::ZERO; BLOCK]; 2];
            let mut holds = [0.0f32; BLOCK];
            for i in 0..n {
                (edges[0][i], edges[1][i]) = self.edges_at(pos, start + i);
                holds[i] = self.holds(active, start + i) as u32 as f32;
            }
            let inv_rest = &self.inv_rest[start..start + n];
            let area = &self.area[start..start + n];
            for i in 0..n {
                let [f1, f2] = self.corner_forces(edges[0][i], edges[1][i], &inv_rest[i], area[i]);
                let (f1, f2) = (f1 * holds[i], f2 * holds[i]);
                out[i] = [-(f1 + f2), f1, f2];
            }
        }
    }

    /// The forces on corners 1 and 2 of a triangle with edges `d1`, `d2`, inverse rest matrix
    /// `b` and rest area `area` (corner 0 takes minus their sum).
    #[inline(always)]
    fn corner_forces(&self, d1: Vec3, d2: Vec3, b: &[f32; 4], area: f32) -> [Vec3; 2] {
        let (f, r) = rotation(d1, d2, b);
        // S = R^T F, symmetric up to round-off; its symmetric part is the strain's.
        let s01 = 0.5 * (r[0].dot(f[1]) + r[1].dot(f[0]));
        let e = [r[0].dot(f[0]) - 1.0, r[1].dot(f[1]) - 1.0];
        let trace = self.lambda * (e[0] + e[1]);
        let two_mu = 2.0 * self.mu;
        let sigma = [
            [two_mu * e[0] + trace, two_mu * s01],
            [two_mu * s01, two_mu * e[1] + trace],
        ];
        let p = [
            r[0] * sigma[0][0] + r[1] * sigma[1][0],
            r[0] * sigma[0][1] + r[1] * sigma[1][1],
        ];
        [
            -area * (p[0] * b[0] + p[1] * b[1]),
            -area * (p[0] * b[2] + p[1] * b[3]),
        ]
    }

    /// Adds every holding element's forces at `pos` into `out`, using `table` (three entries
    /// per triangle, resized here) as scratch: per-triangle forces in parallel, then each vertex
    /// sums its triangles' entries in increasing order, so the result is bitwise the same for
    /// any number of threads.
    pub fn add_forces(
        &self,
        pos: &Vec3s,
        active: &[bool],
        out: &mut Vec3s,
        table: &mut Vec<[Vec3; 3]>,
        chunk: usize,
    ) {
        table.resize(self.len(), [Vec3::ZERO; 3]);
        table
            .par_chunks_mut(TRIANGLE_CHUNK)
            .enumerate()
            .for_each(|(c, forces)| {
                let first = c * TRIANGLE_CHUNK;
                crate::simd::dispatch!(self.element_forces(pos, active, first, forces))
            });
        let table = &*table;
        out.par_chunks_mut(chunk)
            .enumerate()
            .for_each(|(c, mut f): (usize, Vec3SliceMut)| {
                for i in 0..f.len() {
                    let v = c * chunk + i;
                    let mut sum = f.get(i);
                    for &e in &self.incident[self.offsets[v] as usize..self.offsets[v + 1] as usize]
                    {
                        sum += table[e as usize / 3][e as usize % 3];
                    }
                    f.set(i, sum);
                }
            });
    }

    /// Elastic energy `sum_t A_t Psi(F_t)` of the holding elements at `pos`, in J (f64).
    pub fn energy(&self, pos: &Vec3s, active: &[bool]) -> f64 {
        (0..self.len())
            .filter(|&t| self.holds(active, t))
            .map(|t| {
                let (d1, d2) = self.edges_at(pos, t);
                let (f, r) = rotation(d1, d2, &self.inv_rest[t]);
                let dot = |u: Vec3, w: Vec3| u.as_dvec3().dot(w.as_dvec3());
                let (e0, e1) = (dot(r[0], f[0]) - 1.0, dot(r[1], f[1]) - 1.0);
                let s01 = 0.5 * (dot(r[0], f[1]) + dot(r[1], f[0]));
                let (mu, lambda) = (self.mu as f64, self.lambda as f64);
                let psi =
                    mu * (e0 * e0 + e1 * e1 + 2.0 * s01 * s01) + 0.5 * lambda * (e0 + e1).powi(2);
                self.area[t] as f64 * psi
            })
            .sum()
    }

    /// Triangle `t`'s stiffness at `pos` with its rotation held fixed: `K[i][j]`, the 3 x 3
    /// block of `d^2 (A Psi) / dx_i dx_j` (`K[j][i] = K[i][j]^T`, the whole positive
    /// semidefinite).
    pub fn stiffness(&self, pos: &Vec3s, t: usize) -> [[Mat3; 3]; 3] {
        let b = &self.inv_rest[t];
        let (d1, d2) = self.edges_at(pos, t);
        let (_, r) = rotation(d1, d2, b);
        let g = column_gradients(b);
        // Per corner, the gradients of E_00, E_11 and E_01 (3-vectors).
        let de: [[Vec3; 3]; 3] =
            g.map(|g| [g[0] * r[0], g[1] * r[1], 0.5 * (g[1] * r[0] + g[0] * r[1])]);
        let (a, mu, lambda) = (self.area[t], self.mu, self.lambda);
        std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                let (p, q) = (&de[i], &de[j]);
                let outer = |u: Vec3, w: Vec3| Mat3::from_cols(u * w.x, u * w.y, u * w.z);
                (outer(p[0], q[0]) * (2.0 * mu)
                    + outer(p[1], q[1]) * (2.0 * mu)
                    + outer(p[2], q[2]) * (4.0 * mu)
                    + outer(p[0] + p[1], q[0] + q[1]) * lambda)
                    * a
            })
        })
    }

    /// Per vertex, the largest row sum of `|K|` over its triangles at rest (N/m): with the
    /// lumped mass, a Gershgorin bound on the elements' squared frequencies.
    pub fn row_sums(&self, rest: &Vec3s) -> Vec<f32> {
        let mut rows = vec![Vec3::ZERO; rest.len()];
        for t in 0..self.len() {
            let k = self.stiffness(rest, t);
            for (i, &v) in self.triangles[t].iter().enumerate() {
                for block in &k[i] {
                    let abs = block.abs();
                    // Row c of the block is (x_axis[c], y_axis[c], z_axis[c]).
                    rows[v as usize] += abs.x_axis + abs.y_axis + abs.z_axis;
                }
            }
        }
        rows.iter().map(|r| r.max_element()).collect()
    }
}
