//! Sparse Cholesky factorisation of scalar grid and mesh matrices, with a nested-dissection
//! ordering.
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
//! `O(N^1.5)` operations, against `O(N^2)` for the grid's natural (banded) order. A mesh
//! cloth's nodes are dissected the same way by their rest positions ([`dissect_points`]): split
//! at the median along the longest side of their bounding box, the separator being the nodes of
//! the first half with a neighbour in the second.
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

/// The nested-dissection order of the nodes `points` of a graph (`neighbours(p)` the nodes
/// joined to `p`), by their positions: a set of more than `LEAF` nodes is split at the median
/// along the longest side of its bounding box, the nodes of the first half that have a
/// neighbour in the second are its separator, and the two halves less the separator are ordered
/// first, recursively, the separator last. Deterministic (ties broken by node index). Every node
/// of `points` appears once.
pub fn dissect_points<'a, N>(positions: &[[f64; 3]], neighbours: N) -> Vec<usize>
where
    N: Fn(usize) -> &'a [u32] + Copy,
{
    const LEAF: usize = 32;
    let n = positions.len();
    let mut out = Vec::with_capacity(n);
    // 0: not in the set being split, 1: first half, 2: second half.
    let mut side = vec![0u8; n];
    let mut stack: Vec<(Vec<usize>, bool)> = vec![((0..n).collect(), false)];
    // Depth first, emitting a set's separator after both of its halves: each entry is a set to
    // split, or (`true`) a separator to emit when popped.
    while let Some((mut set, emit)) = stack.pop() {
        if emit || set.len() <= LEAF {
            out.extend_from_slice(&set);
            continue;
        }
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for &p in &set {
            for c in 0..3 {
                lo[c] = lo[c].min(positions[p][c]);
                hi[c] = hi[c].max(positions[p][c]);
            }
        }
        let axis = (0..3)
            .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
            .unwrap_or(0);
        set.sort_unstable_by(|&a, &b| {
            positions[a][axis]
                .total_cmp(&positions[b][axis])
                .then(a.cmp(&b))
        });
        let second = set.split_off(set.len() / 2);
        for &p in &set {
            side[p] = 1;
        }
        for &p in &second {
            side[p] = 2;
        }
        let (first, separator): (Vec<usize>, Vec<usize>) = set
            .iter()
            .partition(|&&p| !neighbours(p).iter().any(|&q| side[q as usize] == 2));
        for &p in first.iter().chain(&second).chain(&separator) {
            side[p] = 0;
        }
        // Popped in reverse: the first half, the second, then the separator.
        stack.push((separator, true));
        stack.push((second, false));
        stack.push((first, false));
    }
    out
}

/// `A = L L^T` of a [`ScalarStencil`] restricted to its free nodes.
#[derive(Clone, Debug, Default)]
pub struct SparseCholesky {
    /// Elimination position -> grid node.
    order: Vec<u32>,
    /// Column pointers of the strictly lower part of `L` (CSC), its rows and values.
    colptr: Vec<usize>,
    rows: Vec<u32>,
    values: Vec<f64>,
    diag: Vec<f64>,
    work: Vec<[f64; 3]>,
}

impl SparseCholesky {
    /// Factors `a` over the nodes with `free[p]`. Entries that are exactly zero (cut springs)
    /// are left out of the pattern. A pivot that is not positive (a matrix that is not positive
    /// definite: a bug upstream) is replaced by 1, decoupling that unknown.
    pub fn factor(a: &ScalarStencil, free: &[bool]) -> Self {
        let n_grid = a.len();
        let mut order = Vec::with_capacity(n_grid);
        dissect(a.nx, (0, a.nx), (0, a.ny), &mut order);
        order.retain(|&p| free[p]);
        let entries = (0..n_grid).flat_map(|p| {
            (1..SLOTS).filter_map(move |s| {
                if a.values[s].is_empty() || a.values[s][p] == 0.0 {
                    return None;
                }
                a.partner(p, s).map(|q| (p, q, a.values[s][p]))
            })
        });
        Self::factor_ordered(order, &a.values[0], entries)
    }

    /// Factors the symmetric matrix with diagonal `diagonal` (one value per node) and the
    /// off-diagonal `entries` `(p, q, value)` (each pair once, either way round; repeated pairs
    /// add up), over the nodes of `order`, eliminated in that order: a fill-reducing order of
    /// the free nodes. Entries touching a node not in `order` are left out.
    pub fn factor_ordered(
        order: Vec<usize>,
        diagonal_of: &[f64],
        entries: impl Iterator<Item = (usize, usize, f64)>,
    ) -> Self {
        let n_grid = diagonal_of.len();
        let n = order.len();
        let mut position = vec![u32::MAX; n_grid];
        for (k, &p) in order.iter().enumerate() {
            position[p] = k as u32;
        }
        // Upper-triangular pattern and values by column: entries (i, k) with i < k.
        let mut upper: Vec<Vec<(u32, f64)>> = vec![Vec::new(); n];
        let mut diagonal = vec![0.0; n];
        for (k, &p) in order.iter().enumerate() {
            diagonal[k] = diagonal_of[p];
        }
        for (p, q, value) in entries {
            let (kp, kq) = (position[p], position[q]);
            if kp == u32::MAX || kq == u32::MAX {
                continue;
            }
            let (lo, hi) = (kp.min(kq), kp.max(kq));
            upper[hi as usize].push((lo, value));
        }
        for col in &mut upper {
            col.sort_unstable_by_key(|e| e.0);
            // Two springs joining the same pair (a mesh's edge and a bend across a tiny mesh)
            // are one entry.
            col.dedup_by(|later, first| {
                let same = later.0 == first.0;
                if same {
                    first.1 += later.1;
                }
                same
            });
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
        SparseCholesky {
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
        let mut chol = SparseCholesky::factor(&a, &free);
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

    /// The neighbours of each node of an `nx` x `ny` grid within the stencil, as a mesh
    /// would list them.
    fn stencil_neighbours(nx: usize, ny: usize) -> Vec<Vec<u32>> {
        let a = grid_matrix(nx, ny);
        let mut out = vec![Vec::new(); nx * ny];
        for p in 0..nx * ny {
            for s in 1..SLOTS {
                if let Some(q) = a.partner(p, s).filter(|_| !a.values[s].is_empty()) {
                    out[p].push(q as u32);
                    out[q].push(p as u32);
                }
            }
        }
        out
    }

    #[test]
    fn dissection_by_position_orders_every_node_once_and_keeps_the_fill_low() {
        let (nx, ny) = (48, 48);
        let n = nx * ny;
        let neighbours = stencil_neighbours(nx, ny);
        // Shuffled numbering: the order must come from the positions, not the indices.
        let positions: Vec<[f64; 3]> = (0..n)
            .map(|p| {
                [
                    (p % nx) as f64,
                    (p / nx) as f64 + 0.01 * (p % 7) as f64,
                    0.0,
                ]
            })
            .collect();
        let order = dissect_points(&positions, |p| &neighbours[p]);
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..n).collect::<Vec<_>>());
        let a = grid_matrix(nx, ny);
        let entries = (0..n).flat_map(|p| {
            let a = &a;
            (1..SLOTS).filter_map(move |s| {
                (!a.values[s].is_empty())
                    .then(|| a.partner(p, s).map(|q| (p, q, a.values[s][p])))
                    .flatten()
            })
        });
        let mut chol = SparseCholesky::factor_ordered(order, &a.values[0], entries);
        let grid = SparseCholesky::factor(&a, &vec![true; n]);
        // Within a small factor of the grid's own dissection, far below the band's 2 nx.
        assert!(
            chol.nnz() < 2 * grid.nnz(),
            "{} against {}",
            chol.nnz(),
            grid.nnz()
        );
        let want = Vec3s::from_fn(n, |p| Vec3::new((p as f32 * 0.1).cos(), 2.0, 0.5));
        let mut b = Vec3s::zeros(n);
        a.apply(&want, &mut b);
        let mut x = Vec3s::zeros(n);
        chol.solve(&b, &mut x);
        for p in 0..n {
            assert!((x.get(p) - want.get(p)).length() < 1e-4, "node {p}");
        }
    }

    #[test]
    fn nested_dissection_keeps_the_fill_far_below_the_banded_orders() {
        let (nx, ny) = (48, 48);
        let n = nx * ny;
        let chol = SparseCholesky::factor(&grid_matrix(nx, ny), &vec![true; n]);
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
