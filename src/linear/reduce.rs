//! Dot products that give the same bits for any number of threads and any instruction set.
//!
//! A parallel sum is split into partial sums over fixed chunks of [`REDUCE_CHUNK`] nodes, each
//! computed the same way whichever thread runs it, then added in chunk order.

use rayon::prelude::*;

use crate::soa::{Vec3Slice, Vec3s};

/// Nodes per partial sum: fixed, so that sums do not depend on the number of threads.
pub const REDUCE_CHUNK: usize = 1024;

/// Partial sums for `n` nodes.
pub fn partials(n: usize) -> Vec<f64> {
    vec![0.0; n.div_ceil(REDUCE_CHUNK)]
}

/// `a . b`: sixteen independent float32 lanes (so the loop vectorises without reordering any
/// sum, and every instruction set gives the same bits), added up in f64 at the end.
#[inline(always)]
pub fn dot(a: &[f32], b: &[f32]) -> f64 {
    const LANES: usize = 16;
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut lanes = [0.0f32; LANES];
    let whole = n / LANES * LANES;
    for (x, y) in a[..whole]
        .chunks_exact(LANES)
        .zip(b[..whole].chunks_exact(LANES))
    {
        for l in 0..LANES {
            lanes[l] += x[l] * y[l];
        }
    }
    let tail: f64 = a[whole..]
        .iter()
        .zip(&b[whole..])
        .map(|(x, y)| (x * y) as f64)
        .sum();
    lanes.iter().map(|&l| l as f64).sum::<f64>() + tail
}

/// `a . b` over the three components of one chunk.
#[inline(always)]
pub fn dot3(a: Vec3Slice, b: Vec3Slice) -> f64 {
    dot(a.x, b.x) + dot(a.y, b.y) + dot(a.z, b.z)
}

/// `a . b` over all nodes, in parallel, deterministic.
pub fn par_dot(a: &Vec3s, b: &Vec3s, partials: &mut [f64]) -> f64 {
    partials.par_iter_mut().enumerate().for_each(|(c, out)| {
        let range = c * REDUCE_CHUNK..((c + 1) * REDUCE_CHUNK).min(a.len());
        *out = crate::simd::dispatch!(dot3(a.slices(range.clone()), b.slices(range.clone())));
    });
    partials.iter().sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dot_matches_a_plain_f64_sum_closely() {
        let a: Vec<f32> = (0..1000).map(|i| (i as f32 * 0.37).sin()).collect();
        let b: Vec<f32> = (0..1000).map(|i| (i as f32 * 0.11).cos()).collect();
        let exact: f64 = a.iter().zip(&b).map(|(x, y)| *x as f64 * *y as f64).sum();
        assert!(
            (dot(&a, &b) - exact).abs() < 1e-4,
            "{} vs {exact}",
            dot(&a, &b)
        );
    }
}
