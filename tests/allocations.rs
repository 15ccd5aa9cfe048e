//! Stepping never allocates: every buffer a step needs is made when the simulation (or its
//! integrator, or the strain-limiting pass) is built or on its first step. A counting global
//! allocator checks it, counting only on the threads of the test's rayon pool: the test
//! harness's own thread allocates at times of its choosing (about one run in thirty, its table
//! of running tests).
//!
//! rayon's work stealing allocates too, rarely and not in our code: crossbeam-epoch, which its
//! deques use, moves a full bag of deferred frees to a global queue once in a long while, more
//! often when a loaded machine makes threads steal. So each check builds, warms up and measures
//! a fresh simulation three times and takes the fewest allocations: an allocation in a step
//! (even a one-time one, such as a first retry's buffer) happens in every run, the epoch's
//! rarely in all three.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

use common::{builtin_scene, with_threads};
use glam::Vec3;
use rustcloth::grid::Grid;
use rustcloth::model::Particles;
use rustcloth::scene::{
    ColliderSpec, FloorSpec, OnTrouble, ShapeKind, StrainLimitSpec, WatchdogSpec,
};
use rustcloth::soa::Vec3s;
use rustcloth::springs::Springs;
use rustcloth::state::Kinematics;
use rustcloth::strain_limit::StrainLimit;
use rustcloth::IntegratorKind;
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
        for integrator in IntegratorKind::ALL {
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
                let mut scene = builtin_scene("drape", integrator, 64, 64);
                scene.dt = 0.0002;
                scene.floor = Some(FloorSpec::default());
                scene.watchdog = watchdog;
                scene.strain_limit = strain_limit;
                check_stepping(integrator, scene);
            }
        }
    });
}

/// Allocations on the watched threads while `f` runs.
fn counted<R>(f: impl FnOnce() -> R) -> (usize, R) {
    ALLOCATIONS.store(0, Ordering::Relaxed);
    COUNTING.store(true, Ordering::Relaxed);
    let out = f();
    COUNTING.store(false, Ordering::Relaxed);
    (ALLOCATIONS.load(Ordering::Relaxed), out)
}

/// The fewest allocations `run` reports in three tries (see the module documentation).
fn fewest(mut run: impl FnMut() -> usize) -> usize {
    (0..3).map(|_| run()).min().unwrap()
}

/// Steps `scene` a while, then asserts that further steps allocate nothing.
fn check_stepping(integrator: IntegratorKind, scene: Scene) {
    let effects = Simulation::new(scene.clone()).unwrap().effects().join(", ");
    let allocations = fewest(|| {
        let mut sim = Simulation::new(scene.clone()).unwrap();
        sim.pin(0, Some(glam::Vec3::new(0.0, 2.0, 0.0))).unwrap();
        sim.step(3).unwrap(); // first steps may size scratch buffers
        let (allocations, ()) = counted(|| {
            sim.step(20).unwrap();
            sim.advance(0.003).unwrap();
        });
        allocations
    });
    assert_eq!(allocations, 0, "{integrator} allocated ({effects})");
    // The counter itself works: a call that does allocate is seen.
    let sim = Simulation::new(scene).unwrap();
    let (allocations, strain) = counted(|| sim.spring_strain());
    assert!(allocations > 0 && !strain.is_empty());
}

/// A substep on a kept pair list that finds no pair near enough allocates nothing: the list's
/// filter and each vertex's stray from the cloth's common motion work in buffers sized when the
/// list is built. A flat cloth at rest, its cells (7.7 mm) close enough to its `thickness`
/// (3 mm) that the list holds its neighbours, built on the first substep and then kept.
#[test]
fn a_quiet_substep_on_a_kept_pair_list_allocates_nothing() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    with_threads(2, || {
        rayon::broadcast(|_| WATCHED.with(|w| w.set(true)));
        let mut scene = common::at_1ms("twist");
        (scene.cloth.nx, scene.cloth.ny, scene.cloth.size) = (40, 40, [0.3, 0.3]);
        let allocations = fewest(|| {
            let mut sim = Simulation::new(scene.clone()).unwrap();
            sim.step(3).unwrap();
            let before = sim.self_collision_stats().unwrap();
            let (allocations, ()) = counted(|| sim.step(20).unwrap());
            let after = sim.self_collision_stats().unwrap();
            assert_eq!(before.rebuilds, 1, "the list is built once");
            assert!(
                before.effort.candidates > 0,
                "the list holds no pair to filter"
            );
            assert_eq!(
                (after.rebuilds, after.pairs),
                (1, 0),
                "the substeps were not quiet"
            );
            assert_eq!(after.substeps, before.substeps + 20);
            allocations
        });
        assert_eq!(allocations, 0, "a quiet substep allocated");
    });
}

/// A step of a cloth in self-contact, its pairs held inside implicit Euler's solve, allocates
/// nothing once its buffers have grown to what the step needs: the searches, the filters of
/// their candidates and pairs, the repulsion and the cap keep their buffers from step to step
/// (grown afresh at every step, the 128 x 128 twist's were megabytes the kernel zeroed page by
/// page). The built-in `pile` as it lands on itself; the same steps are run four times from
/// one state, restored into the same simulation (which keeps its buffers), and the last two
/// counted, whose steps start as the second's did in every respect (the fewer of the two: see
/// the module documentation on rayon's own rare allocations).
#[test]
fn a_step_holding_self_contact_allocates_nothing_once_its_buffers_have_grown() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    with_threads(2, || {
        rayon::broadcast(|_| WATCHED.with(|w| w.set(true)));
        let scene = Scene::builtin("pile").unwrap();
        let mut sim = Simulation::new(scene).unwrap();
        sim.step(96).unwrap(); // 0.8 s: the folds are landing on each other
        let from = sim.snapshot();
        let before = sim.self_collision_stats().unwrap();
        let mut counts = Vec::new();
        for _ in 0..4 {
            sim = sim.continuing(from.clone()).unwrap();
            let (allocations, ()) = counted(|| sim.step(12).unwrap());
            counts.push(allocations);
        }
        let after = sim.self_collision_stats().unwrap();
        assert!(
            after.pairs > before.pairs && after.swept_substeps > before.swept_substeps,
            "the steps held no pair or took no swept search"
        );
        let fewest = counts[2].min(counts[3]);
        assert_eq!(fewest, 0, "steps in self-contact allocated: {counts:?}");
    });
}

#[test]
fn the_watchdog_retry_path_does_not_allocate() {
    // The allocation test armed the watchdog with a limit that never tripped, so the retry
    // path was never measured; read, it allocated the retry's start state on the first retry
    // and the step's start on the first held multi-substep step. A scene that trips the limit
    // now retries and holds inside the counted window, and allocates nothing.
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    with_threads(2, || {
        rayon::broadcast(|_| WATCHED.with(|w| w.set(true)));
        for integrator in IntegratorKind::ALL {
            let mut scene = builtin_scene("hanging", integrator, 48, 48);
            scene.cloth.k_structural = 20000.0;
            scene.substeps = 1;
            scene.dt = 0.002;
            scene.watchdog = WatchdogSpec {
                max_stretch: Some(1.2),
                on_trouble: OnTrouble::Substep,
                max_substeps: 256,
                hold_steps: 3,
            };
            if integrator == IntegratorKind::ExplicitEuler {
                scene.cloth.damping = 0.2;
            }
            let allocations = fewest(|| {
                let mut sim = Simulation::new(scene.clone()).unwrap();
                sim.step(1).ok(); // sizes the force tables
                let before = sim.watchdog_stats();
                let (allocations, outcome) = counted(|| sim.step(30));
                let after = sim.watchdog_stats();
                if [
                    IntegratorKind::SymplecticEuler,
                    IntegratorKind::Verlet,
                    IntegratorKind::Rk4,
                ]
                .contains(&integrator)
                {
                    // These need the retries here and are saved by them (implicit Euler needs
                    // none, explicit Euler is beyond saving): both paths ran in the window.
                    assert!(
                        after.retried > before.retried && after.held_steps > before.held_steps,
                        "{integrator}: {before:?} -> {after:?} ({outcome:?})"
                    );
                }
                allocations
            });
            assert_eq!(allocations, 0, "{integrator} allocated while retrying");
        }
    });
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

        let allocations = fewest(|| {
            counted(|| {
                for _ in 0..10 {
                    for start in [&within, &stretched] {
                        state.copy_from(start);
                        limit.apply(grid, &springs, &particles, &mut state, 1000);
                    }
                }
            })
            .0
        });
        assert_eq!(allocations, 0);
        // The stretched calls did run their sweeps.
        assert_ne!(state, within);
        // The counter itself works: a call that does allocate is seen.
        let (allocations, copy) = counted(|| state.clone());
        assert!(allocations > 0 && copy == state);
    });
}

#[test]
fn moving_colliders_allocate_nothing_while_stepping() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    with_threads(2, || {
        rayon::broadcast(|_| WATCHED.with(|w| w.set(true)));
        for integrator in [
            IntegratorKind::SymplecticEuler,
            IntegratorKind::ImplicitEuler,
        ] {
            let mut scene = Scene::builtin("drape_box").unwrap();
            scene.integrator = integrator;
            scene.colliders[0].velocity = [0.1, 0.0, 0.0];
            check_stepping(integrator, scene);
        }
    });
}

#[test]
fn mesh_and_plane_colliders_and_set_poses_allocate_nothing_while_stepping() {
    // An icosahedron mesh (parry's BVH queries keep their stacks on the stack) and a plane,
    // with the mesh's pose set before every step.
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    with_threads(2, || {
        rayon::broadcast(|_| WATCHED.with(|w| w.set(true)));
        let mut scene = Scene::builtin("drape_box").unwrap();
        let t = (1.0 + 5f64.sqrt()) / 2.0;
        let s = 0.3 / (1.0 + t * t).sqrt();
        let vertices: Vec<[f64; 3]> = [
            [-1.0, t, 0.0],
            [1.0, t, 0.0],
            [-1.0, -t, 0.0],
            [1.0, -t, 0.0],
            [0.0, -1.0, t],
            [0.0, 1.0, t],
            [0.0, -1.0, -t],
            [0.0, 1.0, -t],
            [t, 0.0, -1.0],
            [t, 0.0, 1.0],
            [-t, 0.0, -1.0],
            [-t, 0.0, 1.0],
        ]
        .iter()
        .map(|v| v.map(|x| x * s))
        .collect();
        let triangles = vec![
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ];
        scene.colliders = vec![
            ColliderSpec {
                shape: ShapeKind::Mesh,
                vertices: Some(vertices),
                triangles: Some(triangles),
                center: [0.0, 0.68, 0.0],
                ..ColliderSpec::default()
            },
            ColliderSpec {
                shape: ShapeKind::Plane,
                center: [0.0, 0.1, 0.0],
                ..ColliderSpec::default()
            },
        ];
        // The icosahedron's top 2 cm under the cloth: in contact after the first 100 steps.
        let mut sim = Simulation::new(scene).unwrap();
        sim.step(100).unwrap();
        let before = sim.positions().clone();
        let allocations = fewest(|| {
            counted(|| {
                for k in 0..5 {
                    let x = 0.001 * k as f64;
                    sim.set_collider_pose(0, [x, 0.68, 0.0], [0.0, 0.0, 0.0, 1.0])
                        .unwrap();
                    sim.step(1).unwrap();
                }
            })
            .0
        });
        assert_eq!(allocations, 0, "steps with a mesh collider allocated");
        // The mesh held the cloth up: the middle rests on its top edge (y = 0.68 + 0.3 t /
        // sqrt(1 + t^2) = 0.935), not fallen past it.
        let middle = 24 * 48 + 24;
        let y = sim.positions().get(middle).y;
        assert!(y > 0.935, "at {y}, from {}", before.get(middle));
    });
}

#[test]
fn a_mesh_cloth_allocates_nothing_while_stepping() {
    // A 12 x 12 square of triangles under both membranes: the springs' force pass, the
    // triangle elements' and their implicit blocks and multigrid proxy.
    use rustcloth::scene::{MembraneKind, MeshSpec};
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let n = 12usize;
    let vertices: Vec<[f64; 3]> = (0..n * n)
        .map(|k| [(k % n) as f64 / n as f64, 1.0, (k / n) as f64 / n as f64])
        .collect();
    let triangles: Vec<[i64; 3]> = (0..n - 1)
        .flat_map(|j| (0..n - 1).map(move |i| (j * n + i) as i64))
        .flat_map(|a| {
            [
                [a, a + n as i64, a + 1],
                [a + 1, a + n as i64, a + n as i64 + 1],
            ]
        })
        .collect();
    with_threads(2, || {
        rayon::broadcast(|_| WATCHED.with(|w| w.set(true)));
        for (membrane, integrators) in [
            (MembraneKind::Springs, &IntegratorKind::ALL[..]),
            (
                MembraneKind::Triangle,
                &[
                    IntegratorKind::SymplecticEuler,
                    IntegratorKind::ImplicitEuler,
                ][..],
            ),
        ] {
            for &integrator in integrators {
                let mut scene = Scene {
                    integrator,
                    dt: if integrator == IntegratorKind::ImplicitEuler {
                        1.0 / 120.0
                    } else {
                        1e-4
                    },
                    ..Scene::default()
                };
                scene.cloth.pins = vec![];
                scene.cloth.mesh = Some(MeshSpec {
                    vertices: vertices.clone(),
                    triangles: triangles.clone(),
                    membrane,
                    ..MeshSpec::default()
                });
                check_stepping(integrator, scene);
            }
        }
    });
}
