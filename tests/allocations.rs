//! Stepping never allocates: every buffer a step needs is made when the simulation (or its
//! integrator) is built or on its first step. A counting global allocator checks it.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use common::with_threads;
use rustcloth::scene::{FloorSpec, INTEGRATORS};
use rustcloth::{Scene, Simulation};

struct Counting;

static COUNTING: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn no_integrator_allocates_while_stepping() {
    with_threads(2, || {
        for integrator in INTEGRATORS {
            let mut scene = Scene::builtin("drape").unwrap();
            scene.integrator = integrator.to_string();
            scene.cloth.nx = 64;
            scene.cloth.ny = 64;
            scene.dt = 0.0002;
            scene.floor = Some(FloorSpec::default());
            let mut sim = Simulation::new(scene).unwrap();
            sim.pin(0, Some(glam::Vec3::new(0.0, 2.0, 0.0))).unwrap();
            sim.step(3).unwrap(); // first steps may size scratch buffers
            ALLOCATIONS.store(0, Ordering::Relaxed);
            COUNTING.store(true, Ordering::Relaxed);
            sim.step(20).unwrap();
            sim.advance(0.003).unwrap();
            COUNTING.store(false, Ordering::Relaxed);
            assert_eq!(
                ALLOCATIONS.load(Ordering::Relaxed),
                0,
                "{integrator} allocated"
            );
            // The counter itself works: a call that does allocate is seen.
            COUNTING.store(true, Ordering::Relaxed);
            let strain = sim.spring_strain();
            COUNTING.store(false, Ordering::Relaxed);
            assert!(ALLOCATIONS.load(Ordering::Relaxed) > 0 && !strain.is_empty());
        }
    });
}
