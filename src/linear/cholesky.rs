//! Sparse Cholesky factorisation of scalar grid matrices, with a nested-dissection ordering.
//!
//! Projective dynamics solves, every iteration, a system whose matrix changes only when the
//! cloth's topology, pins, masses or step do: it is factored once and each solve is two
//! triangular sweeps. The matrix is a [`ScalarStencil`] (the same scalar acts on x, y and z), the
//! unknowns are the free nodes.
//!
//! **Ordering.** Nested dissection on the grid (George 1973): a rectangle of nodes is split
//! across its longer side by a separator two columns (or rows) wide, since the stencil reaches
//! two nodes (the bending springs), the two halves are ordered first, recursively, and the
//! separator last. The fill of `L` is then `O(N log N)` and the factorisation costs
//! `O(N^1.5)` operations, against `O(N^2)` for the grid's natural (banded) order.
//!
//! **Factorisation.** Elimination tree and row patterns by the up-looking algorithm of Davis
//! ("Direct methods for sparse linear systems", 2006, `cs_etree`, `cs_ereach`, `cs_chol`):
//! row `k` of `L` is found by a sparse triangular solve with the rows before it. Simplicial (no
//! supernodes) and serial, in f64; a supernodal code (CHOLMOD, faer) would factor several times
//! faster on large grids, the solves much less so, being memory-bound. Both are deterministic.

use crate::soa::Vec3s;

use super::stencil::{OFFSETS, SLOTS};

/// A symmetric scalar matrix on an `nx` x `ny` grid, stored like [`super::BlockStencil`] (the
/// diagonal and the upper half of the 5 x 5 neighbourhood, zero where the partner is off the
/// grid), in f64.
#[derive(Clone, Debug)]
pub struct ScalarStencil {
    pub nx: usize,
    pub ny: usize,
    values: [Vec<f64>; SLOTS],
}

impl ScalarStencil {
    /// A zero matrix storing the slots `present` (the diagonal always).
    pub fn new(nx: usize, ny: usize, present: &[usize]) -> Self {
        let n = nx * ny;
        let values = std::array::from_fn(|s| {
            if s == 0 || present.contains(&s) {
                vec![0.0; n]
            } else {
                Vec::new()
            }
        });
        ScalarStencil { nx, ny, values }
    }

    pub fn len(&self) -> usize {
        self.nx * self.ny
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn slot(&self, s: usize) -> &[f64] {
        &self.values[s]
    }

    pub fn slot_mut(&mut self, s: usize) -> &mut [f64] {
        &mut self.values[s]
    }

    /// The partner of node `p` in slot `s`, if on the grid.
    #[inline]
    fn partner(&self, p: usize, s: usize) -> Option<usize> {
        let (i, j) = ((p % self.nx) as i64, (p / self.nx) as i64);
        let (di, dj) = (OFFSETS[s].0 as i64, OFFSETS[s].1 as i64);
        let (qi, qj) = (i + di, j + dj);
        ((0..self.nx as i64).contains(&qi) && (0..self.ny as i64).contains(&qj))
            .then(|| (qj * self.nx as i64 + qi) as usize)
    }

    /// `y = A x` for the three components alike, in f32 (a residual, not a solve).
    pub fn apply(&self, x: &Vec3s, y: &mut Vec3s) {
        for p in 0..self.len() {
            y.set(p, self.values[0][p] as f32 * x.get(p));
        }
        for s in 1..SLOTS {
            if self.values[s].is_empty() {
                continue;
            }
            for p in 0..self.len() {
                let a = self.values[s][p];
                if a == 0.0 {
                    continue;
                }
                if let Some(q) = self.partner(p, s) {
                    let a = a as f32;
                    y.set(p, y.get(p) + a * x.get(q));
                    y.set(q, y.get(q) + a * x.get(p));
                }
            }
        }
    }

    pub fn heap_bytes(&self) -> usize {
        self.values.iter().map(|v| v.capacity() * 8).sum()
    }
}

/// The nested-dissection order of the rectangle `[i0, i1) x [j0, j1)` of an `nx`-wide grid.
fn dissect(nx: usize, (i0, i1): (usize, usize), (j0, j1): (usize, usize), out: &mut Vec<usize>) {
    let (w, h) = (i1 - i0, j1 - j0);
    let leaf = |out: &mut Vec<usize>| {
        for j in j0..j1 {
            for i in i0..i1 {
                out.push(j * nx + i);
            }
        }
    };
    if w.max(h) <= 4 {
        return leaf(out);
    }
    if w >= h {
        let m = i0 + (w - 2) / 2;
        dissect(nx, (i0, m), (j0, j1), out);
        dissect(nx, (m + 2, i1), (j0, j1), out);
        dissect(nx, (m, m + 2), (j0, j1), out);
    } else {
        let m = j0 + (h - 2) / 2;
        dissect(nx, (i0, i1), (j0, m), out);
        dissect(nx, (i0, i1), (m + 2, j1), out);
        dissect(nx, (i0, i1), (m, m + 2), out);
    }
}

/// `A = L L^T` of a [`ScalarStencil`] restricted to its free nodes.
#[derive(Clone, Debug, Default)]
pub struct GridCholesky {
    /// Elimination position -> grid node.
    order: Vec<u32>,
    /// Column pointers of the strictly lower part of `L` (CSC), its rows and values.
    colptr: Vec<usize>,
    rows: Vec<u32>,
    values: Vec<f64>,
    diag: Vec<f64>,
    work: Vec<[f64; 3]>,
}

impl GridCholesky {
    /// Factors `a` over the nodes with `free[p]`. Entries that are exactly zero (cut springs)
    /// are left out of the pattern. A pivot that is not positive (a matrix that is not positive
    /// definite: a bug upstream) is replaced by 1, decoupling that unknown.
    pub fn factor(a: &ScalarStencil, free: &[bool]) -> Self {
        let n_grid = a.len();
        let mut order = Vec::with_capacity(n_grid);
        dissect(a.nx, (0, a.nx), (0, a.ny), &mut order);
        order.retain(|&p| free[p]);
        let n = order.len();
        let mut position = vec![u32::MAX; n_grid];
        for (k, &p) in order.iter().enumerate() {
            position[p] = k as u32;
        }
        // Upper-triangular pattern and values by column: entries (i, k) with i < k.
        let mut upper: Vec<Vec<(u32, f64)>> = vec![Vec::new(); n];
        let mut diagonal = vec![0.0; n];
        for p in 0..n_grid {
            let kp = position[p];
            if kp == u32::MAX {
                continue;
            }
            diagonal[kp as usize] = a.values[0][p];
            for s in 1..SLOTS {
                if a.values[s].is_empty() || a.values[s][p] == 0.0 {
                    continue;
                }
                let Some(q) = a.partner(p, s) else { continue };
                let kq = position[q];
                if kq == u32::MAX {
                    continue;
                }
                let (lo, hi) = (kp.min(kq), kp.max(kq));
                upper[hi as usize].push((lo, a.values[s][p]));
            }
        }
        for col in &mut upper {
            col.sort_unstable_by_key(|e| e.0);
        }
        // Elimination tree (cs_etree).
        let none = u32::MAX;
        let mut parent = vec![none; n];
        let mut ancestor = vec![none; n];
        for (k, column) in upper.iter().enumerate() {
            for &(i, _) in column {
                let mut i = i;
                while i != none && (i as usize) < k {
                    let next = ancestor[i as usize];
                    ancestor[i as usize] = k as u32;
                    if next == none {
                        parent[i as usize] = k as u32;
                    }
                    i = next;
                }
            }
        }
        // Row patterns (cs_ereach), counted once to size L, then again while factoring.
        let mut mark = vec![none; n];
        let mut stack = vec![0u32; n];
        let mut path = vec![0u32; n];
        let ereach = |k: usize, mark: &mut [u32], stack: &mut [u32], path: &mut [u32]| -> usize {
            let mut top = n;
            mark[k] = k as u32;
            for &(i, _) in &upper[k] {
                let mut len = 0;
                let mut i = i;
                while mark[i as usize] != k as u32 {
                    path[len] = i;
                    len += 1;
                    mark[i as usize] = k as u32;
                    i = parent[i as usize];
                }
                while len > 0 {
                    len -= 1;
                    top -= 1;
                    stack[top] = path[len];
                }
            }
            top
        };
        let mut counts = vec![0usize; n];
        for k in 0..n {
            let top = ereach(k, &mut mark, &mut stack, &mut path);
            for &j in &stack[top..] {
                counts[j as usize] += 1;
            }
        }
        let mut colptr = vec![0usize; n + 1];
        for j in 0..n {
            colptr[j + 1] = colptr[j] + counts[j];
        }
        let nnz = colptr[n];
        let mut rows = vec![0u32; nnz];
        let mut values = vec![0.0f64; nnz];
        let mut diag = vec![0.0f64; n];
        let mut fill = colptr.clone();
        let mut x = vec![0.0f64; n];
        mark.fill(none);
        // Up-looking numeric factorisation (cs_chol).
        for k in 0..n {
            let top = ereach(k, &mut mark, &mut stack, &mut path);
            for &(i, v) in &upper[k] {
                x[i as usize] = v;
            }
            let mut d = diagonal[k];
            for &i in &stack[top..] {
                let i = i as usize;
                let lki = x[i] / diag[i];
                x[i] = 0.0;
                for p in colptr[i]..fill[i] {
                    x[rows[p] as usize] -= values[p] * lki;
                }
                d -= lki * lki;
                rows[fill[i]] = k as u32;
                values[fill[i]] = lki;
                fill[i] += 1;
            }
            diag[k] = if d > 0.0 && d.is_finite() {
                d.sqrt()
            } else {
                1.0
            };
        }
        GridCholesky {
            order: order.into_iter().map(|p| p as u32).collect(),
            colptr,
            rows,
            values,
            diag,
            work: vec![[0.0; 3]; n],
        }
    }

    /// Unknowns (free nodes).
    pub fn len(&self) -> usize {
        self.diag.len()
    }

    pub fn is_empty(&self) -> bool {
        self.diag.is_empty()
    }

    /// Nonzeros of `L`, diagonal included.
    pub fn nnz(&self) -> usize {
        self.values.len() + self.diag.len()
    }

    pub fn heap_bytes(&self) -> usize {
        self.values.capacity() * 8
            + self.rows.capacity() * 4
            + self.colptr.capacity() * 8
            + self.diag.capacity() * 8
            + self.order.capacity() * 4
            + self.work.capacity() * 24
    }

    /// `x = A^-1 b` on the free nodes, for the three components at once; the held nodes of `x`
    /// are left as they are.
    pub fn solve(&mut self, b: &Vec3s, x: &mut Vec3s) {
        let n = self.len();
        let w = &mut self.work;
        for (k, &p) in self.order.iter().enumerate() {
            let p = p as usize;
            w[k] = [b.x[p] as f64, b.y[p] as f64, b.z[p] as f64];
        }
        // L y = b, by columns.
        for j in 0..n {
            let d = self.diag[j];
            let yj = [w[j][0] / d, w[j][1] / d, w[j][2] / d];
            w[j] = yj;
            for p in self.colptr[j]..self.colptr[j + 1] {
                let (r, l) = (self.rows[p] as usize, self.values[p]);
                for c in 0..3 {
                    w[r][c] -= l * yj[c];
                }
            }
        }
        // L^T x = y, by columns of L (rows of L^T).
        for j in (0..n).rev() {
            let mut s = w[j];
            for p in self.colptr[j]..self.colptr[j + 1] {
                let (r, l) = (self.rows[p] as usize, self.values[p]);
                for c in 0..3 {
                    s[c] -= l * w[r][c];
                }
            }
            let d = self.diag[j];
            w[j] = [s[0] / d, s[1] / d, s[2] / d];
        }
        for (k, &p) in self.order.iter().enumerate() {
            let p = p as usize;
            x.x[p] = w[k][0] as f32;
            x.y[p] = w[k][1] as f32;
            x.z[p] = w[k][2] as f32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// A 2-D Laplacian with bending-length couplings plus a mass term.
    fn grid_matrix(nx: usize, ny: usize) -> ScalarStencil {
        let kinds = [1usize, 5, 6, 4, 2, 10];
        let mut a = ScalarStencil::new(nx, ny, &kinds);
        for p in 0..nx * ny {
            a.values[0][p] += 0.5;
            for &s in &kinds {
                if let Some(q) = a.partner(p, s) {
                    let w = 1.0 + s as f64;
                    a.values[s][p] = -w;
                    a.values[0][p] += w;
                    a.values[0][q] += w;
                }
            }
        }
        a
    }

    #[test]
    fn nested_dissection_orders_every_node_once() {
        for (nx, ny) in [(1, 1), (3, 7), (16, 16), (33, 12)] {
            let mut order = Vec::new();
            dissect(nx, (0, nx), (0, ny), &mut order);
            order.sort_unstable();
            assert_eq!(order, (0..nx * ny).collect::<Vec<_>>());
        }
    }

    #[test]
    fn the_factor_solves_the_free_system_and_leaves_held_nodes_alone() {
        let (nx, ny) = (23, 17);
        let n = nx * ny;
        let a = grid_matrix(nx, ny);
        let mut free = vec![true; n];
        for p in [0, 5, 100, n - 1] {
            free[p] = false;
        }
        let mut chol = GridCholesky::factor(&a, &free);
        assert_eq!(chol.len(), n - 4);
        // A right-hand side from a known solution (zero at held nodes, whose columns the
        // restricted system does not have).
        let want = Vec3s::from_fn(n, |p| {
            if free[p] {
                Vec3::new((p as f32 * 0.3).sin(), 1.0, p as f32 / n as f32)
            } else {
                Vec3::ZERO
            }
        });
        let mut b = Vec3s::zeros(n);
        a.apply(&want, &mut b);
        let mut x = Vec3s::from_fn(n, |_| Vec3::splat(7.0));
        chol.solve(&b, &mut x);
        for (p, &free) in free.iter().enumerate() {
            if free {
                assert!((x.get(p) - want.get(p)).length() < 1e-4, "node {p}");
            } else {
                assert_eq!(x.get(p), Vec3::splat(7.0));
            }
        }
    }

    #[test]
    fn nested_dissection_keeps_the_fill_far_below_the_banded_orders() {
        let (nx, ny) = (48, 48);
        let n = nx * ny;
        let chol = GridCholesky::factor(&grid_matrix(nx, ny), &vec![true; n]);
        // The natural order fills the whole band of half-width 2 nx; the gap widens with size
        // (N log N against N^1.5).
        assert!(
            chol.nnz() < n * 2 * nx * 6 / 10,
            "nnz {} against {}",
            chol.nnz(),
            n * 2 * nx
        );
    }
}
