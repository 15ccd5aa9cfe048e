//! How one simulation is shared by Python threads, and the last line of defence against panics.
//!
//! **The model.** Every call on a `Simulation` takes its lock for the whole call; calls from
//! other threads wait their turn, without holding the GIL, so a thread reading `positions`
//! while another steps gets the state at a call boundary, never a half-written one. The lock is
//! fair (parking_lot's `FairMutex`: each unlock hands it to the longest waiter), so a thread
//! stepping in a loop cannot starve a reader: the reader runs after at most the call in
//! progress. A long call (`step(10**6)`) holds the others back for its length; step in pieces
//! (`advance` per frame) when another thread must stay responsive.
//!
//! A call that comes from the thread already inside a call on the same simulation (a signal
//! handler or a warning filter that runs while `step` waits on Ctrl-C checks) cannot wait for
//! itself: it raises `SimulationBusy` instead of deadlocking.
//!
//! **Panics.** A panic is a bug, but it must not reach Python as pyo3's `PanicException` (a
//! `BaseException` that `except Exception` misses) nor leave a half-changed simulation. The
//! core rolls a step that panics back to its start itself; here every call runs under
//! `catch_unwind` as a last resort, and a panic caught here becomes `InternalError` after
//! [`Simulation::after_panic`] drops every cache the call may have left half-built.

use std::cell::Cell;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicU64, Ordering};

use parking_lot::FairMutex;
use pyo3::prelude::*;
use pyo3::{import_exception, PyErr};

use super::errors::to_py;
use crate::{Error, Simulation};

import_exception!(rustcloth.errors, SimulationBusy);

/// What the lock guards: the simulation and the binding's own per-simulation memory.
pub(crate) struct Held {
    pub sim: Simulation,
    /// Whether the one warning about an unconverged linear solve was given.
    pub warned_not_converged: bool,
}

/// A simulation behind a fair lock that knows which thread holds it.
pub(crate) struct Shared {
    held: FairMutex<Held>,
    /// [`thread_id`] of the thread inside a call, 0 when none.
    owner: AtomicU64,
}

thread_local! {
    static THREAD_ID: Cell<u64> = const { Cell::new(0) };
}

/// A number for the calling thread, never 0, unique for the process's life.
fn thread_id() -> u64 {
    static NEXT: AtomicU64 = AtomicU64::new(1);
    THREAD_ID.with(|id| {
        if id.get() == 0 {
            id.set(NEXT.fetch_add(1, Ordering::Relaxed));
        }
        id.get()
    })
}

impl Shared {
    pub fn new(sim: Simulation) -> Self {
        Shared {
            held: FairMutex::new(Held {
                sim,
                warned_not_converged: false,
            }),
            owner: AtomicU64::new(0),
        }
    }

    /// Runs `f` on the simulation, alone: waits (detached from the interpreter) while another
    /// thread's call is in progress. A panic in `f` becomes `InternalError`.
    pub fn with<R>(&self, py: Python<'_>, f: impl FnOnce(&mut Held) -> PyResult<R>) -> PyResult<R> {
        let me = thread_id();
        let mut guard = match self.held.try_lock() {
            Some(guard) => guard,
            None if self.owner.load(Ordering::Acquire) == me => {
                return Err(SimulationBusy::new_err(
                    "this thread is already inside a call on this Simulation (a signal handler \
                     or warning filter calling back during a step?); it cannot wait for itself",
                ));
            }
            None => py.detach(|| self.held.lock()),
        };
        self.owner.store(me, Ordering::Release);
        let outcome = catch_unwind(AssertUnwindSafe(|| f(&mut guard)));
        let result = outcome.unwrap_or_else(|payload| {
            guard.sim.after_panic();
            Err(internal_error(payload.as_ref()))
        });
        self.owner.store(0, Ordering::Release);
        drop(guard);
        result
    }
}

/// `InternalError` for a caught panic.
fn internal_error(payload: &(dyn std::any::Any + Send)) -> PyErr {
    let message = payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a Rust panic".into());
    to_py(Error::Internal { message })
}
