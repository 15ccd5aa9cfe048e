//! How the passes split their work over rayon's threads: chunks of particles sized by the pool,
//! never so small that scheduling dominates, and one entry into the pool per run of steps.

/// Fewest particles per parallel work item: below this, scheduling costs more than it saves.
pub const MIN_CHUNK: usize = 2048;

/// Particles per parallel work item for `n` particles: about four items per thread, so the
/// load balances, but never so small that scheduling dominates. Results never depend on it.
pub fn chunk_len(n: usize) -> usize {
    let per_thread = n.div_ceil(4 * rayon::current_num_threads());
    per_thread.max(MIN_CHUNK)
}

/// Runs `f` on a thread of rayon's pool, so that the parallel loops of every pass inside it
/// fork from a worker (cheap) instead of each being injected into the pool from outside (a
/// cross-thread wake-up per pass, which dominates the step of a small cloth).
pub fn on_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    rayon::scope(|_| f())
}
