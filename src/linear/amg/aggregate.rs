//! One coarsening step of smoothed aggregation (Vanek, Mandel and Brezina 1996; PyAMG's
//! `standard_aggregation` and `jacobi_prolongation_smoother`), on a reference matrix.
//!
//! - **Strength.** Node `j` is a strong neighbour of `i` when the norm of their block is at
//!   least [`STRENGTH`] times the largest off-diagonal block norm of either row. On cloth this
//!   keeps the stretch springs and drops the bending springs, which are an order of magnitude
//!   softer and reach two rings out (aggregating along them would make aggregates too large).
//! - **Aggregates**, greedily in a local order of the nodes: a node whose strong neighbours are
//!   all free starts an aggregate with them; a node left over joins the aggregate of its first
//!   strong neighbour aggregated by then; what is still left starts an aggregate with its free
//!   strong neighbours. A held node (zero diagonal) is in no aggregate; a free node without
//!   strong neighbours is an aggregate of its own. Greedy aggregation packs its aggregates
//!   tightly when its visits sweep the mesh as a front, which the numbering's order does only
//!   where the numbering is local (row by row); a mesh numbered at random grew ragged
//!   aggregates and took a third more CG iterations. So the visits follow the numbering where
//!   it is local and a breadth-first order of the strong connections where it is scattered
//!   (measured in docs/notes/mesh_cloth.md, "Speed, as first measured, and vertex order"); the
//!   aggregates are numbered in that order, so the coarse levels are numbered locally too.
//! - **Tentative prolongator** `T`: the indicator of each aggregate (one column per aggregate,
//!   standing for a 3 x 3 identity block: the three translations are the near-null space).
//! - **Smoothed prolongator** `P = (I - omega D^-1 A) T`, `omega = 4/3 / rho(D^-1 A)`, with
//!   `A`'s blocks taken by their mean eigenvalue (trace / 3; the reference is isotropic, so
//!   this is exact there) and `rho` from [`POWER_ITERATIONS`] power iterations. The smoothing
//!   uses every connection, the bending springs too: smoothing with the strong ones only (the
//!   weak lumped onto the diagonal, PyAMG's filtered smoother) makes sparser prolongators but
//!   took CG from 12.1 to 16.9 iterations a solve on the 4k stiff drape.

use super::csr::{BlockRows, Transfer};
use super::order::{local_order, places};
use crate::linear::Sym3;

/// Strength threshold, relative to the row's strongest connection (0 to 1): lower aggregates
/// along softer springs (bigger aggregates, fewer levels, slower convergence); 0.25 is the
/// classical value, and on cloth it separates stretch (weight 1) from bending (about 0.1).
pub const STRENGTH: f32 = 0.25;

/// Power iterations for `rho(D^-1 A)`: an estimate low by a few percent only makes the
/// prolongator's smoothing a little stronger than 4/3 / rho.
pub const POWER_ITERATIONS: usize = 15;

fn norm(b: &Sym3) -> f32 {
    let b = &b.0;
    (b[0] * b[0] + b[1] * b[1] + b[2] * b[2] + 2.0 * (b[3] * b[3] + b[4] * b[4] + b[5] * b[5]))
        .sqrt()
}

fn scalar(b: &Sym3) -> f64 {
    (b.0[0] as f64 + b.0[1] as f64 + b.0[2] as f64) / 3.0
}

/// Each node's aggregate (`u32::MAX` for a held node) and the number of aggregates.
pub fn aggregate<A: BlockRows>(a: &A, numbering: Option<&[u32]>) -> (Vec<u32>, usize) {
    let n = a.rows();
    let free: Vec<bool> = (0..n).map(|v| scalar(&a.diagonal(v)) > 0.0).collect();
    let mut largest = vec![0.0f32; n];
    for (v, l) in largest.iter_mut().enumerate() {
        a.for_each_entry(v, |c, b| {
            if c != v {
                *l = l.max(norm(b));
            }
        });
    }
    // Strong neighbours in compressed rows, each listed once, in row order.
    let mut offsets = vec![0usize];
    let mut strong: Vec<u32> = Vec::new();
    for v in 0..n {
        let start = strong.len();
        if free[v] {
            a.for_each_entry(v, |c, b| {
                let s = norm(b);
                if c != v
                    && free[c]
                    && s > 0.0
                    && (s >= STRENGTH * largest[v] || s >= STRENGTH * largest[c])
                    && !strong[start..].contains(&(c as u32))
                {
                    strong.push(c as u32);
                }
            });
        }
        offsets.push(strong.len());
    }
    let neighbours = |v: usize| &strong[offsets[v]..offsets[v + 1]];
    let order = match numbering {
        Some(vertices) => renumbered_order(&free, (&offsets, &strong), vertices),
        None => local_order(&free, &offsets, &strong),
    };
    const NONE: u32 = u32::MAX;
    let mut agg = vec![NONE; n];
    let mut count = 0u32;
    for v in order.iter().map(|&v| v as usize) {
        if agg[v] == NONE && neighbours(v).iter().all(|&c| agg[c as usize] == NONE) {
            agg[v] = count;
            for &c in neighbours(v) {
                agg[c as usize] = count;
            }
            count += 1;
        }
    }
    let first = agg.clone();
    for v in order.iter().map(|&v| v as usize) {
        if agg[v] == NONE {
            if let Some(&c) = neighbours(v).iter().find(|&&c| first[c as usize] != NONE) {
                agg[v] = first[c as usize];
            }
        }
    }
    for v in order.iter().map(|&v| v as usize) {
        if agg[v] == NONE {
            agg[v] = count;
            for &c in neighbours(v) {
                if agg[c as usize] == NONE {
                    agg[c as usize] = count;
                }
            }
            count += 1;
        }
    }
    (agg, count as usize)
}

/// `rho(D^-1 A)` over the free nodes, by power iteration from a fixed start.
pub fn spectral_radius<A: BlockRows>(a: &A) -> f64 {
    let n = a.rows();
    let d: Vec<f64> = (0..n).map(|v| scalar(&a.diagonal(v))).collect();
    let mut x: Vec<f64> = (0..n)
        .map(|v| {
            if d[v] > 0.0 {
                1.0 + (v % 7) as f64 / 7.0
            } else {
                0.0
            }
        })
        .collect();
    let mut y = vec![0.0; n];
    let mut rho = 0.0;
    for _ in 0..POWER_ITERATIONS {
        for (v, yv) in y.iter_mut().enumerate() {
            let mut s = 0.0;
            if d[v] > 0.0 {
                a.for_each_entry(v, |c, b| s += scalar(b) * x[c]);
                s /= d[v];
            }
            *yv = s;
        }
        let norm = y.iter().map(|v| v * v).sum::<f64>().sqrt();
        let before = x.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !(norm > 0.0 && before > 0.0) {
            return 1.0;
        }
        rho = norm / before;
        for (x, y) in x.iter_mut().zip(&y) {
            *x = y / norm;
        }
    }
    rho
}

/// The smoothed prolongator of `a` over the aggregates `agg` (of `count` aggregates).
pub fn smoothed_prolongator<A: BlockRows>(a: &A, agg: &[u32], count: usize) -> Transfer {
    let rho = spectral_radius(a);
    let omega = 4.0 / 3.0 / rho;
    let rows: Vec<Vec<(u32, f32)>> = (0..a.rows())
        .map(|i| {
            let mut row: Vec<(u32, f64)> = Vec::new();
            let d = scalar(&a.diagonal(i));
            if agg[i] == u32::MAX || d <= 0.0 {
                return Vec::new();
            }
            a.for_each_entry(i, |j, b| {
                if agg[j] == u32::MAX {
                    return;
                }
                let w = if j == i { 1.0 } else { 0.0 } - omega * scalar(b) / d;
                match row.iter_mut().find(|e| e.0 == agg[j]) {
                    Some(e) => e.1 += w,
                    None => row.push((agg[j], w)),
                }
            });
            row.sort_by_key(|e| e.0);
            row.into_iter()
                .filter(|e| e.1 != 0.0)
                .map(|(c, w)| (c, w as f32))
                .collect()
        })
        .collect();
    Transfer::from_rows(&rows, count)
}

/// The local order ([`local_order`]) of a graph whose node `k` is node `vertices[k]` of the
/// graph as first numbered, chosen on that graph (its ties are broken and its search starts
/// by the first numbers) and given in this numbering's nodes.
fn renumbered_order(
    free: &[bool],
    (offsets, neighbours): (&[usize], &[u32]),
    vertices: &[u32],
) -> Vec<u32> {
    let n = free.len();
    let place = places(vertices, n);
    let mut first = (
        vec![false; n],
        vec![0usize],
        Vec::with_capacity(neighbours.len()),
    );
    for (v, &k) in place.iter().enumerate() {
        let k = k as usize;
        first.0[v] = free[k];
        let row = &neighbours[offsets[k]..offsets[k + 1]];
        first.2.extend(row.iter().map(|&c| vertices[c as usize]));
        first.1.push(first.2.len());
    }
    let order = local_order(&first.0, &first.1, &first.2);
    order.into_iter().map(|v| place[v as usize]).collect()
}
