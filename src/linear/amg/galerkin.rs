//! The Galerkin coarse operator `A_c = P^T A P` of a block matrix and a scalar prolongator, in
//! two products, `AP = A P` (a row per fine node) and `A_c = P^T (AP)` (a row per coarse node).
//!
//! The sparsity of both depends only on the patterns of `A` and `P`, which a hierarchy keeps,
//! and so do the weights (`P` is fixed), so [`Galerkin::new`] works out once, for every entry
//! of `AP` and of `A_c`, the list of its terms: which block it takes and by which weight. A
//! step ([`Galerkin::apply`]) then sums each entry's list in a register and stores it once.
//! Each entry's terms are listed in the order a row-by-row product visits them (the entries of
//! `A`'s row, then `P`'s row; for `A_c`, the rows of `P^T`, then `AP`'s row), so every sum is
//! bitwise the one that product's scattered adds give. `A_c` is symmetric, so only its entries
//! on and above the diagonal are summed, and each one below is a copy of its mirror: about
//! half of `P^T (AP)`'s terms, and an operator exactly symmetric. Summing entry by entry keeps
//! each sum in registers, where scattering each term into its row loads and stores the entry a
//! term and waits on the store before (docs/notes/mesh_cloth.md, "Speed", 2026-12-06: the
//! coarse levels' products a third shorter, the fine level's `AP` a seventh, its `P^T (AP)`
//! unchanged); the lists take 8 bytes a term (a block's id and a weight) where the scattered
//! plan took 4. The rows are split among threads, so the products are bitwise the same for
//! any number of threads.

use super::csr::{for_each_row, BlockCsr, BlockRows, Transfer};
use crate::linear::Sym3;

/// Rows per parallel work item of both products.
const ROW_CHUNK: usize = 256;

/// One term of an entry's sum: `weight` times the block `block` names.
#[derive(Clone, Copy, Debug, Default)]
struct Term {
    block: u32,
    weight: f32,
}

/// The symbolic Galerkin product of one pattern of `A` and `P`, and the workspace of `AP`.
#[derive(Clone, Debug, Default)]
pub struct Galerkin {
    /// `AP` in compressed rows over the fine nodes, columns increasing in each row.
    ap_offsets: Vec<u32>,
    ap: Vec<Sym3>,
    /// Entry `k` of `AP`, in row `i`, is `0 + ap_diagonal[k] A_ii` (zero where `P`'s row `i`
    /// has no entry in its column) plus the terms
    /// `ap_terms[ap_term_offsets[k]..ap_term_offsets[k + 1]]`, each naming an off-diagonal block
    /// of `A` ([`BlockRows::block`]) and an entry of `P`'s weight. The diagonal block is each
    /// row's first entry, so its term is each sum's first; with a zero weight it adds `+0.0`
    /// bitwise to the zero it starts from (`0 + (-0) = +0`), as leaving it out would, while
    /// the diagonal block is finite (an infinite one is a broken step either way). Kept apart
    /// so that reading `A`'s blocks by id needs no test of which array holds them.
    ap_diagonal: Vec<f32>,
    ap_term_offsets: Vec<u32>,
    ap_terms: Vec<Term>,
    /// Entry `k` of `A_c` (in its storage order) on or above the diagonal is the sum of
    /// `ac_terms[ac_term_offsets[k]..ac_term_offsets[k + 1]]`, each naming an entry of `AP` and
    /// an entry of `P^T`'s weight; an entry below it whose mirror is in the pattern has no
    /// terms and is a copy of that mirror (`ac_mirrors`).
    ac_term_offsets: Vec<u32>,
    ac_terms: Vec<Term>,
    /// `(k, m)`: entry `k` of `A_c`, at `(c, J)` with `J < c`, is entry `m`, at `(J, c)`.
    /// `A_c` is symmetric and its blocks are (every block of `A` is, and `P` is scalar), so
    /// half its sums give all of it, and the copy makes it exactly symmetric, which summing
    /// `(c, J)` and `(J, c)` in their own orders does not.
    ac_mirrors: Vec<(u32, u32)>,
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
        // The row's terms in visiting order, each with the column it adds to.
        let mut row: Vec<(u32, Term)> = Vec::new();
        for i in 0..n {
            row.clear();
            a.for_each_off_diagonal_id(i, |j, block| {
                let terms = p
                    .p_row(j)
                    .map(|(c, weight)| (c as u32, Term { block, weight }));
                row.extend(terms);
            });
            let start = ap_columns.len();
            ap_columns.extend(p.p_row(i).map(|(c, _)| c as u32));
            ap_columns.extend(row.iter().map(|&(c, _)| c));
            ap_columns[start..].sort_unstable();
            dedup_tail(&mut ap_columns, start);
            g.ap_diagonal.resize(ap_columns.len(), 0.0);
            let columns = &ap_columns[start..];
            for (c, weight) in p.p_row(i) {
                let k = columns
                    .binary_search(&(c as u32))
                    .expect("P's column in AP's row");
                g.ap_diagonal[start + k] = weight;
            }
            let lists = (&mut g.ap_term_offsets, &mut g.ap_terms);
            list_by_entry(&row, columns, &mut slot, lists);
            g.ap_offsets.push(ap_columns.len() as u32);
        }
        g.ap = vec![Sym3::ZERO; ap_columns.len()];
        let (mut ac_offsets, mut ac_columns) = (vec![0u32], Vec::new());
        for c in 0..nc {
            row.clear();
            for (i, weight) in p.r_row(c) {
                let r = g.ap_offsets[i] as usize..g.ap_offsets[i + 1] as usize;
                let terms = r.map(|k| {
                    (
                        ap_columns[k],
                        Term {
                            block: k as u32,
                            weight,
                        },
                    )
                });
                row.extend(terms);
            }
            // The diagonal first, then the rest increasing.
            let start = ac_columns.len();
            ac_columns.push(c as u32);
            ac_columns.extend(row.iter().map(|&(j, _)| j).filter(|&j| j as usize != c));
            ac_columns[start + 1..].sort_unstable();
            dedup_tail(&mut ac_columns, start + 1);
            // Below the diagonal, each entry whose mirror is in the pattern (every one, for
            // a symmetric pattern) is copied from it rather than summed.
            let mut mirrored = start + 1;
            for k in start + 1..ac_columns.len() {
                let j = ac_columns[k] as usize;
                if j >= c {
                    break;
                }
                let above = ac_offsets[j] as usize + 1..ac_offsets[j + 1] as usize;
                match ac_columns[above.clone()].binary_search(&(c as u32)) {
                    Ok(m) => g.ac_mirrors.push((k as u32, (above.start + m) as u32)),
                    Err(_) => break,
                }
                mirrored = k + 1;
            }
            let copied = &ac_columns[start + 1..mirrored];
            row.retain(|(j, _)| copied.binary_search(j).is_err());
            let lists = (&mut g.ac_term_offsets, &mut g.ac_terms);
            list_by_entry(&row, &ac_columns[start..], &mut slot, lists);
            ac_offsets.push(ac_columns.len() as u32);
        }
        (g, BlockCsr::zeros(ac_offsets, ac_columns))
    }

    /// `out = P^T a P` (`P` the prolongator of [`Galerkin::new`]), `a` with the pattern and `out`
    /// as [`Galerkin::new`] made them.
    pub fn apply<A: BlockRows>(&mut self, a: &A, out: &mut BlockCsr) {
        let Galerkin {
            ap_offsets,
            ap,
            ap_diagonal,
            ap_term_offsets,
            ap_terms,
            ac_term_offsets,
            ac_terms,
            ac_mirrors,
        } = self;
        let (ap_term_offsets, ap_terms) = (&ap_term_offsets[..], &ap_terms[..]);
        let ap_diagonal = &ap_diagonal[..];
        for_each_row(ap, ap_offsets, 0..a.rows(), ROW_CHUNK, &|i, out| {
            let (first, diagonal) = (ap_offsets[i] as usize, a.diagonal(i));
            for (k, out) in (first..).zip(out) {
                let terms = ap_term_offsets[k] as usize..ap_term_offsets[k + 1] as usize;
                let mut start = Sym3::ZERO;
                start.add_scaled(ap_diagonal[k], &diagonal);
                *out = sum(start, &ap_terms[terms], |id| a.block(id));
            }
        });
        let ap = &ap[..];
        let BlockCsr {
            offsets, values, ..
        } = &mut *out;
        let offsets = &offsets[..];
        let rows = 0..offsets.len() - 1;
        for_each_row(values, offsets, rows, ROW_CHUNK, &|c, out| {
            let first = offsets[c] as usize;
            for (k, out) in (first..).zip(out) {
                let terms = ac_term_offsets[k] as usize..ac_term_offsets[k + 1] as usize;
                *out = sum(Sym3::ZERO, &ac_terms[terms], |id| &ap[id as usize]);
            }
        });
        for &(k, m) in ac_mirrors.iter() {
            values[k as usize] = values[m as usize];
        }
        out.lay_out();
    }
}

/// `start + sum_t weight_t block_t` over `terms`, added in order (as adding each term into the
/// entry gives it).
#[inline(always)]
fn sum<'a>(start: Sym3, terms: &[Term], block: impl Fn(u32) -> &'a Sym3) -> Sym3 {
    let mut total = start;
    for term in terms {
        total.add_scaled(term.weight, block(term.block));
    }
    total
}

/// Appends the terms `row` (each with the column it adds to, in visiting order) to `terms`,
/// grouped by entry in the order of `columns` (the row's distinct columns) and in visiting
/// order within each, and each entry's end to `offsets`; `slot` is all `u32::MAX` before and
/// after.
fn list_by_entry(
    row: &[(u32, Term)],
    columns: &[u32],
    slot: &mut [u32],
    (offsets, terms): (&mut Vec<u32>, &mut Vec<Term>),
) {
    for (k, &c) in columns.iter().enumerate() {
        slot[c as usize] = k as u32;
    }
    let mut next = vec![0u32; columns.len()];
    for &(c, _) in row {
        next[slot[c as usize] as usize] += 1;
    }
    let mut end = terms.len() as u32;
    for next in next.iter_mut() {
        let count = *next;
        *next = end;
        end += count;
        offsets.push(end);
    }
    terms.resize(end as usize, Term::default());
    for &(c, term) in row {
        let next = &mut next[slot[c as usize] as usize];
        terms[*next as usize] = term;
        *next += 1;
    }
    for &c in columns {
        slot[c as usize] = u32::MAX;
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
