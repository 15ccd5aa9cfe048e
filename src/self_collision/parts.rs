//! Buffers for the searches' and the pass's ordered parallel filters, kept from call to call.
//! rayon's `par_extend` of a filter gathers each task's output in a vector of its own, grown
//! from nothing at every call: the 128 x 128 twist's filters find megabytes a step, and
//! buffers that large come fresh from the kernel, zeroed page by page.

use rayon::prelude::*;

/// A parallel filter into one vector: the input is cut into a fixed number of runs a thread,
/// each filtered into its own buffer, kept for the next call, and the buffers are appended in
/// the input's order, so the output is the sequential filter's whatever the thread count.
pub(crate) struct Parts<T> {
    runs: Vec<Vec<T>>,
}

impl<T> Default for Parts<T> {
    fn default() -> Self {
        Parts { runs: Vec::new() }
    }
}

impl<T: Send> Parts<T> {
    /// Appends to `out`, in order, `keep(k, item)` of each `k`-th of `items` where it is
    /// Some; a run holds at least `min_len` items.
    pub(crate) fn filter_map_into<S: Sync>(
        &mut self,
        items: &[S],
        min_len: usize,
        keep: impl Fn(usize, &S) -> Option<T> + Sync,
        out: &mut Vec<T>,
    ) {
        // Eight runs a thread, as rayon's adaptive splits would about give: a run's filter can
        // cost several times another's where the cloth is folded.
        let run = items
            .len()
            .div_ceil(8 * rayon::current_num_threads())
            .max(min_len.max(1));
        let n = items.len().div_ceil(run);
        if self.runs.len() < n {
            self.runs.resize_with(n, Vec::new);
        }
        items
            .par_chunks(run)
            .zip(self.runs[..n].par_iter_mut())
            .enumerate()
            .for_each(|(r, (items, found))| {
                found.clear();
                let first = r * run;
                let kept = items.iter().enumerate();
                found.extend(kept.filter_map(|(k, item)| keep(first + k, item)));
            });
        out.reserve(self.runs[..n].iter().map(Vec::len).sum());
        for found in &mut self.runs[..n] {
            out.append(found);
        }
    }

    pub(crate) fn heap_bytes(&self) -> usize {
        self.runs.iter().map(Vec::capacity).sum::<usize>() * size_of::<T>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The ordered filter gives what the sequential filter gives, whatever the thread count
    /// and however the runs it keeps were sized by an earlier, larger call.
    #[test]
    fn the_kept_runs_filter_as_the_sequential_filter_does_for_any_thread_count() {
        let items: Vec<u64> = (0..10_000u64)
            .map(|k| k.wrapping_mul(2_654_435_761) % 997)
            .collect();
        let keep = |k: usize, &v: &u64| (v % 3 == 0).then_some((k, v));
        let want: Vec<(usize, u64)> = items
            .iter()
            .enumerate()
            .filter_map(|(k, v)| keep(k, v))
            .collect();
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let mut parts = Parts::default();
                for len in [10_000, 37, 0, 5_000, 10_000] {
                    let mut out = vec![(0, 0)];
                    parts.filter_map_into(&items[..len], 64, keep, &mut out);
                    let expect: Vec<_> = want.iter().copied().filter(|&(k, _)| k < len).collect();
                    assert_eq!(out[1..], expect[..], "{threads} threads, {len} items");
                }
            });
        }
    }
}
