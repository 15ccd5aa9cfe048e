//! Stepping never allocates: every buffer a step needs is made when the simulation (or its
//! integrator, or the strain-limiting pass) is built or on its first step. A counting global allocator checks it, counting
//! only on the threads of the test's rayon pool: the test harness's own thread allocates at
//! times of its choosing (about one run in thirty, its table of running tests).

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

use common::with_threads;
use glam::Vec3;
use rustcloth::forces::Springs;
use rustcloth::grid::Grid;
use rustcloth::scene::{FloorSpec, OnTrouble, StrainLimitSpec, WatchdogSpec, INTEGRATORS};
use rustcloth::soa::Vec3s;
use rustcloth::state::{Kinematics, Particles};
use rustcloth::strain_limit::StrainLimit;
use rustcloth::{Scene, Simulation};

struct Counting;

static COUNTING: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

/// The counter is global: the tests take turns.
static SERIAL: Mutex<()> = Mutex::new(());

thread_local! {
    /// Set on the threads whose allocations count.
    static WATCHED: Cell<bool> = const { Cell::new(false) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) && WATCHED.try_with(Cell::get).unwrap_or(false) {
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
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    with_threads(2, || {
        // Every thread of the pool (the test runs on one of them); this also returns only
        // once every worker has started, which allocates.
        rayon::broadcast(|_| WATCHED.with(|w| w.set(true)));
        for integrator in INTEGRATORS {
            for (watchdog, strain_limit) in [
                (WatchdogSpec::default(), None),
                (
                    WatchdogSpec {
                        max_stretch: Some(1e3),
                        on_trouble: OnTrouble::Substep,
                        ..WatchdogSpec::default()
                    },
                    Some(StrainLimitSpec::default()),
                ),
            ] {
                let mut scene = Scene::builtin("drape").unwrap();
                scene.integrator = integrator.to_string();
                scene.cloth.nx = 64;
                scene.cloth.ny = 64;
                scene.dt = 0.0002;
                scene.floor = Some(FloorSpec::default());
                scene.watchdog = watchdog;
                scene.strain_limit = strain_limit;
                check_stepping(integrator, scene);
            }
        }
    });
}

/// Steps `scene` a while, then asserts that further steps allocate nothing.
fn check_stepping(integrator: &str, scene: Scene) {
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
        "{integrator} allocated ({:?})",
        sim.effects()
    );
    // The counter itself works: a call that does allocate is seen.
    COUNTING.store(true, Ordering::Relaxed);
    let strain = sim.spring_strain();
    COUNTING.store(false, Ordering::Relaxed);
    assert!(ALLOCATIONS.load(Ordering::Relaxed) > 0 && !strain.is_empty());
}

#[test]
fn strain_limiting_allocates_only_on_its_first_call() {
    // Its buffers are sized on the first call and reused, whether it finds nothing to do or
    // runs every sweep.
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    with_threads(2, || {
        let grid = Grid { nx: 64, ny: 64 };
        let rest = Vec3s::from_fn(grid.len(), |p| {
            let (i, j) = grid.coords(p);
            Vec3::new(i as f32, 0.0, j as f32) * 0.01
        });
        let springs = Springs::new(grid, &rest);
        let particles = Particles::new(grid.len(), 0.001);
        let within = Kinematics {
            pos: rest.clone(),
            vel: Vec3s::zeros(grid.len()),
        };
        let stretched = Kinematics {
            pos: Vec3s::from_fn(grid.len(), |p| rest.get(p) * 1.5),
            vel: Vec3s::zeros(grid.len()),
        };
        let mut limit = StrainLimit::new(0.1, 4);
        let mut state = within.clone();
        limit.apply(grid, &springs, &particles, &mut state, 1000);
        assert_eq!(limit.heap_bytes(), 26 * grid.len());
        // Every thread of the pool (the test itself runs on one of them); this also returns
        // only once every worker has started, which allocates.
        rayon::broadcast(|_| WATCHED.with(|w| w.set(true)));
        for _ in 0..3 {
            state.copy_from(&stretched);
            limit.apply(grid, &springs, &particles, &mut state, 1000);
        }

        ALLOCATIONS.store(0, Ordering::Relaxed);
        COUNTING.store(true, Ordering::Relaxed);
        for _ in 0..10 {
            for start in [&within, &stretched] {
                state.copy_from(start);
                limit.apply(grid, &springs, &particles, &mut state, 1000);
            }
        }
        COUNTING.store(false, Ordering::Relaxed);
        assert_eq!(ALLOCATIONS.load(Ordering::Relaxed), 0);
        // The stretched calls did run their sweeps.
        assert_ne!(state, within);
        // The counter itself works: a call that does allocate is seen.
        COUNTING.store(true, Ordering::Relaxed);
        let copy = state.clone();
        COUNTING.store(false, Ordering::Relaxed);
        assert!(ALLOCATIONS.load(Ordering::Relaxed) > 0 && copy == state);
    });
}
