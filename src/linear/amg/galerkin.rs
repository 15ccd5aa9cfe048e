//! The Galerkin coarse operator `A_c = P^T A P` of a block matrix and a scalar prolongator, in
//! two products, `AP = A P` (a row per fine node) and `A_c = P^T (AP)` (a row per coarse node).
//!
//! The sparsity of both depends only on the patterns of `A` and `P`, which a hierarchy keeps,
//! so it is worked out once ([`Galerkin::new`]) together with where each term lands; a step
//! then only adds the terms up ([`Galerkin::apply`]). Each row's terms are added in one fixed
//! order (the entries of `A`'s row, then `P`'s), and the rows are split among threads, so the
//! products are bitwise the same for any number of threads.

use super::csr::{for_each_row, BlockCsr, BlockRows, Transfer};
use crate::linear::Sym3;

/// Rows per parallel work item of both products.
const ROW_CHUNK: usize = 256;

/// The symbolic Galerkin product of one pattern of `A` and `P`, and the workspace of `AP`.
#[derive(Clone, Debug, Default)]
pub struct Galerkin {
    /// `AP` in compressed rows over the fine nodes.
    ap_offsets: Vec<u32>,
    ap: Vec<Sym3>,
    /// Per fine row, in the order `apply` visits its terms (the entries `(i, j)` of `A`, each
    /// times the entries `(j, J)` of `P`), the position of `AP[i, J]` within the row.
    ap_term_offsets: Vec<u32>,
    ap_terms: Vec<u32>,
    /// Per coarse row `I`, in visiting order (the entries `(i, I)` of `P^T`, each times the
    /// entries of `AP`'s row `i`), the position of the term within `A_c`'s row `I`.
    ac_term_offsets: Vec<u32>,
    ac_terms: Vec<u32>,
}

impl Galerkin {
    /// The plan for `A` (its pattern) and `p`, and `A_c` with that pattern and zero values.
    pub fn new<A: BlockRows>(a: &A, p: &Transfer) -> (Self, BlockCsr) {
        let (n, nc) = (a.rows(), p.coarse());
        let mut g = Galerkin {
            ap_offsets: vec![0],
            ap_term_offsets: vec![0],
            ac_term_offsets: vec![0],
            ..Galerkin::default()
        };
        // `slot[J]` is J's position in the row being built, or u32::MAX.
        let mut slot = vec![u32::MAX; nc];
        let mut ap_columns: Vec<u32> = Vec::new();
        let mut row: Vec<u32> = Vec::new();
        for i in 0..n {
            row.clear();
            a.for_each_entry(i, |j, _| {
                row.extend(p.p_row(j).map(|(c, _)| c as u32));
            });
            let start = ap_columns.len();
            ap_columns.extend(&row);
            ap_columns[start..].sort_unstable();
            dedup_tail(&mut ap_columns, start);
            for (k, &c) in ap_columns[start..].iter().enumerate() {
                slot[c as usize] = k as u32;
            }
            g.ap_terms.extend(row.iter().map(|&c| slot[c as usize]));
            for &c in &ap_columns[start..] {
                slot[c as usize] = u32::MAX;
            }
            g.ap_offsets.push(ap_columns.len() as u32);
            g.ap_term_offsets.push(g.ap_terms.len() as u32);
        }
        g.ap = vec![Sym3::ZERO; ap_columns.len()];
        let (mut ac_offsets, mut ac_columns) = (vec![0u32], Vec::new());
        for c in 0..nc {
            row.clear();
            for (i, _) in p.r_row(c) {
                let r = g.ap_offsets[i] as usize..g.ap_offsets[i + 1] as usize;
                row.extend(&ap_columns[r]);
            }
            // The diagonal first, then the rest increasing.
            let start = ac_columns.len();
            ac_columns.push(c as u32);
            ac_columns.extend(row.iter().filter(|&&j| j as usize != c));
            ac_columns[start + 1..].sort_unstable();
            dedup_tail(&mut ac_columns, start + 1);
            for (k, &j) in ac_columns[start..].iter().enumerate() {
                slot[j as usize] = k as u32;
            }
            g.ac_terms.extend(row.iter().map(|&j| slot[j as usize]));
            for &j in &ac_columns[start..] {
                slot[j as usize] = u32::MAX;
            }
            ac_offsets.push(ac_columns.len() as u32);
            g.ac_term_offsets.push(g.ac_terms.len() as u32);
        }
        (g, BlockCsr::zeros(ac_offsets, ac_columns))
    }

    /// `out = P^T a P`, `a` with the pattern and `out` as [`Galerkin::new`] made them.
    pub fn apply<A: BlockRows>(&mut self, a: &A, p: &Transfer, out: &mut BlockCsr) {
        let Galerkin {
            ap_offsets,
            ap,
            ap_term_offsets,
            ap_terms,
            ac_term_offsets,
            ac_terms,
        } = self;
        for_each_row(ap, ap_offsets, 0..a.rows(), ROW_CHUNK, &|i, out| {
            out.fill(Sym3::ZERO);
            let mut term = ap_term_offsets[i] as usize;
            a.for_each_entry(i, |j, block| {
                for (_, w) in p.p_row(j) {
                    out[ap_terms[term] as usize].add_scaled(w, block);
                    term += 1;
                }
            });
        });
        let ap = &*ap;
        let BlockCsr {
            offsets, values, ..
        } = &mut *out;
        let rows = 0..offsets.len() - 1;
        for_each_row(values, offsets, rows, ROW_CHUNK, &|c, out| {
            out.fill(Sym3::ZERO);
            let mut term = ac_term_offsets[c] as usize;
            for (i, w) in p.r_row(c) {
                for block in &ap[ap_offsets[i] as usize..ap_offsets[i + 1] as usize] {
                    out[ac_terms[term] as usize].add_scaled(w, block);
                    term += 1;
                }
            }
        });
        out.lay_out();
    }
}

/// Removes repeats from the sorted tail `v[start..]`.
fn dedup_tail(v: &mut Vec<u32>, start: usize) {
    let mut w = start;
    for r in start..v.len() {
        if w == start || v[r] != v[w - 1] {
            v[w] = v[r];
            w += 1;
        }
    }
    v.truncate(w);
}
