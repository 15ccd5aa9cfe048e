//! Cuts that sever springs along a stroke: the pieces separate, mass is conserved to
//! the bit, the mesh follows the cut, and picking, dragging, the solvers and determinism keep
//! working across cuts.

use crate::common;

use common::{state_hash, with_threads, Drawn};
use glam::Vec3;
use rustcloth::grid::SpringKind;
use rustcloth::picking::{pick_triangle_brute_force, Ray};
use rustcloth::scene::{ClothSpec, FloorSpec, PinSpec, Plane, StrainLimitSpec};
use rustcloth::{IntegratorKind, Scene, Simulation};

const G: f32 = 9.81;
const N: u32 = 20;

/// An `n` x `n` cloth, 1 m square, in `plane` centred at `center`, pinned by the named set
/// `pins`: light (1 g a particle) and soft, as the cloth a user cuts in the demo.
fn sheet(n: u32, plane: Plane, center: [f64; 3], pins: &str) -> Scene {
    Scene {
        dt: 0.001,
        // Two substeps, as the built-in hanging scene: one is past symplectic Euler's limit.
        substeps: 2,
        gravity: [0.0, -G as f64, 0.0],
        cloth: ClothSpec {
            nx: n,
            ny: n,
            size: [1.0, 1.0],
            center,
            plane,
            particle_mass: Some(0.001),
            k_structural: 800.0,
            k_shear: 200.0,
            k_bend: 20.0,
            damping: 0.01,
            pins: vec![PinSpec::Named(pins.into())],
            ..ClothSpec::default()
        },
        ..Scene::default()
    }
}

/// A vertical 20 x 20 cloth, 1 m square, in the xy plane centred at (0, 1.5, 0), pinned along
/// its top row (j = ny - 1, y = 2).
fn curtain(integrator: IntegratorKind) -> Scene {
    Scene {
        integrator,
        ..sheet(N, Plane::Xy, [0.0, 1.5, 0.0], "top_edge")
    }
}

/// The height of the cut: halfway between rows 9 and 10 of the curtain.
fn cut_height() -> f32 {
    let dy = 1.0 / (N - 1) as f32;
    1.0 + 9.5 * dy
}

/// A stroke of `k` rays from the front (z = 2, looking along -z) across the whole width at
/// height `y`.
fn across(y: f32, k: usize) -> Vec<(Vec3, Vec3)> {
    (0..k)
        .map(|s| {
            let x = -0.8 + 1.6 * s as f32 / (k - 1) as f32;
            (Vec3::new(x, y, 2.0), Vec3::NEG_Z)
        })
        .collect()
}

fn live_mass(sim: &Simulation) -> f64 {
    let p = sim.particles();
    // Summed in index order in f64: any change of a mass or of a live flag shows.
    (0..p.len())
        .filter(|&q| p.alive[q])
        .map(|q| p.mass[q] as f64)
        .sum()
}

fn mean_velocity_y(sim: &Simulation, members: &[usize]) -> f32 {
    members
        .iter()
        .map(|&p| sim.velocities().get(p).y)
        .sum::<f32>()
        / members.len() as f32
}

#[test]
fn a_straight_cut_leaves_two_pieces_the_lower_falls_at_g_the_upper_stays() {
    let mut sim = Simulation::new(curtain(IntegratorKind::SymplecticEuler)).unwrap();
    let mass = live_mass(&sim);
    let version = sim.topology_version();
    let severed = sim.sever_stroke(&across(cut_height(), 2)).unwrap();
    // Per column: the structural j spring (rows 9-10), two shear springs per cell (19 cells),
    // and the bending springs 8-10 and 9-11.
    let nx = N as usize;
    assert_eq!(severed, nx + 2 * (nx - 1) + 2 * nx);
    assert_eq!(sim.pieces(), 2);
    assert_eq!(sim.topology_version(), version + 1);
    assert_eq!(live_mass(&sim).to_bits(), mass.to_bits());

    let labels = sim.piece_labels();
    let grid = sim.grid();
    let (lower, upper): (Vec<usize>, Vec<usize>) =
        (0..grid.len()).partition(|&p| grid.coords(p).1 <= 9);
    assert!(lower.iter().all(|&p| labels[p] == labels[lower[0]]));
    assert!(upper.iter().all(|&p| labels[p] == labels[upper[0]]));
    assert_ne!(labels[lower[0]], labels[upper[0]]);

    let upper_top_before: f32 = upper.iter().map(|&p| sim.positions().get(p).y).sum();
    let steps = 100;
    sim.step(steps).unwrap();
    let t = steps as f32 * 0.001;
    // The lower piece is free: its springs pull its particles on each other in pairs, so its
    // mean velocity is what gravity alone gives (to float32 rounding).
    let v = mean_velocity_y(&sim, &lower);
    assert!(
        (v + G * t).abs() < 1e-3 * G * t,
        "lower piece: {v} m/s, g t = {}",
        G * t
    );
    // The upper piece hangs from its pins: it sags by millimetres, not by g t^2 / 2 = 49 mm.
    let upper_top_after: f32 = upper.iter().map(|&p| sim.positions().get(p).y).sum();
    let sag = (upper_top_before - upper_top_after) / upper.len() as f32;
    assert!(
        sag.is_finite() && (-0.005..0.01).contains(&sag),
        "upper sag {sag} m"
    );
}

#[test]
fn no_drawn_triangle_spans_the_cut() {
    let mut sim = Simulation::new(curtain(IntegratorKind::SymplecticEuler)).unwrap();
    let full = sim.triangles().len();
    sim.sever_stroke(&across(cut_height(), 5)).unwrap();
    let y = cut_height();
    let triangles = sim.triangles().to_vec();
    // Exactly the row of cells the cut crosses is gone: one cell high, the full width.
    assert_eq!(triangles.len(), full - 2 * (N as usize - 1));
    let labels = sim.piece_labels();
    let pos = sim.positions().clone();
    for tri in &triangles {
        let above = tri.iter().filter(|&&q| pos.get(q as usize).y > y).count();
        assert!(above == 0 || above == 3, "triangle {tri:?} spans the cut");
        assert!(tri
            .iter()
            .all(|&q| labels[q as usize] == labels[tri[0] as usize]));
    }
    // The rendered edge is the row next to the cut on each side: within one grid spacing.
    let dy = 1.0 / (N - 1) as f32;
    let edge_gap = triangles
        .iter()
        .flatten()
        .map(|&q| (pos.get(q as usize).y - y).abs())
        .fold(f32::INFINITY, f32::min);
    assert!(
        edge_gap <= 0.5 * dy + 1e-6,
        "edge {edge_gap} m from the stroke"
    );
    // The normals cache follows: still unit and finite.
    let normals = sim.normals().clone();
    assert!((0..normals.len()).all(|p| (normals.get(p).length() - 1.0).abs() < 1e-4));
}

#[test]
fn triangle_picking_sees_the_mesh_after_a_cut() {
    let mut sim = Simulation::new(curtain(IntegratorKind::SymplecticEuler)).unwrap();
    sim.sever_stroke(&across(cut_height(), 3)).unwrap();
    sim.step(20).unwrap();
    let triangles = sim.triangles().to_vec();
    for k in 0..60 {
        let x = -0.55 + 1.1 * (k % 10) as f32 / 9.0;
        let y = 0.95 + 1.1 * (k / 10) as f32 / 5.0;
        let ray = Ray::new(Vec3::new(x, y, 2.0), Vec3::NEG_Z).unwrap();
        let want = pick_triangle_brute_force(&ray, sim.positions(), &triangles);
        let got = sim.pick_triangle(ray.origin, ray.dir).unwrap();
        assert_eq!(
            got.map(|h| h.index),
            want.map(|h| h.index),
            "ray at ({x}, {y})"
        );
    }
}

#[test]
fn mass_is_conserved_to_the_bit_over_any_sequence_of_cuts() {
    let mut sim = Simulation::new(curtain(IntegratorKind::SymplecticEuler)).unwrap();
    let mass = live_mass(&sim);
    let mut rng = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng >> 40) as f32 / (1u64 << 24) as f32
    };
    for _ in 0..20 {
        let rays: Vec<(Vec3, Vec3)> = (0..4)
            .map(|_| {
                let o = Vec3::new(next() * 1.6 - 0.8, 0.9 + next() * 1.2, 2.0);
                (o, Vec3::new(next() - 0.5, next() - 0.5, -1.0))
            })
            .collect();
        sim.sever_stroke(&rays).unwrap();
        sim.step(5).unwrap();
        assert_eq!(live_mass(&sim).to_bits(), mass.to_bits());
    }
    assert!(sim.pieces() > 1);
}

#[test]
fn strokes_that_sever_nothing_change_nothing() {
    let mut sim = Simulation::new(curtain(IntegratorKind::SymplecticEuler)).unwrap();
    sim.step(10).unwrap();
    let (hash, version) = (state_hash(&sim), sim.topology_version());
    let still = (Vec3::new(0.0, cut_height(), 2.0), Vec3::NEG_Z);
    // One ray (a click), a stroke of zero length, a stroke that misses the cloth.
    assert_eq!(sim.sever_stroke(&[still]).unwrap(), 0);
    assert_eq!(sim.sever_stroke(&[still, still, still]).unwrap(), 0);
    assert_eq!(sim.sever_stroke(&across(5.0, 4)).unwrap(), 0);
    assert_eq!(sim.sever_stroke(&[]).unwrap(), 0);
    assert_eq!(sim.topology_version(), version);
    assert_eq!(state_hash(&sim), hash);
    // Cutting the same line again: the piece is already separate there.
    assert!(sim.sever_stroke(&across(cut_height(), 2)).unwrap() > 0);
    let version = sim.topology_version();
    assert_eq!(sim.sever_stroke(&across(cut_height(), 2)).unwrap(), 0);
    assert_eq!(sim.topology_version(), version);
}

#[test]
fn a_bad_ray_is_named_and_changes_nothing() {
    let mut sim = Simulation::new(curtain(IntegratorKind::SymplecticEuler)).unwrap();
    let (hash, version, triangles) = (
        state_hash(&sim),
        sim.topology_version(),
        sim.triangles().len(),
    );
    let mut rays = across(cut_height(), 4);
    rays[2].0.x = f32::NAN;
    let err = sim.sever_stroke(&rays).unwrap_err();
    assert!(err.to_string().contains("rays[2].origin"), "{err}");
    rays[2].0.x = 0.0;
    rays[3].1 = Vec3::ZERO;
    let err = sim.sever_stroke(&rays).unwrap_err();
    assert!(err.to_string().contains("rays[3].direction"), "{err}");
    assert_eq!(
        (
            state_hash(&sim),
            sim.topology_version(),
            sim.triangles().len()
        ),
        (hash, version, triangles)
    );
    assert!(sim.spring_live(SpringKind::StructuralJ, 9 * N as usize));
}

#[test]
fn a_cut_during_a_drag_keeps_the_drag() {
    let mut sim = Simulation::new(curtain(IntegratorKind::SymplecticEuler)).unwrap();
    let p = 2 * N as usize + 10; // row 2: on the lower piece
    sim.grab(p as i64).unwrap();
    let target = sim.positions().get(p) + Vec3::new(0.0, 0.0, 0.05);
    sim.drag_to(target).unwrap();
    sim.step(10).unwrap();
    sim.sever_stroke(&across(cut_height(), 2)).unwrap();
    assert_eq!(sim.grabbed(), Some(p));
    sim.step(300).unwrap();
    assert!((sim.positions().get(p) - target).length() < 1e-5);
    // The lower piece hangs from the grabbed particle now, below it.
    let lowest = (0..N as usize)
        .map(|i| sim.positions().get(i).y)
        .fold(f32::MAX, f32::min);
    assert!(lowest < target.y);
    sim.release();
    assert_eq!(sim.grabbed(), None);
}

/// A horizontal 24 x 24 sheet 0.3 m above a floor, pinned at its corners, with a square loop
/// cut out of its middle: the fragment falls, lands and rests on the floor.
#[test]
fn an_isolated_fragment_falls_lands_and_rests() {
    let mut scene = Scene {
        floor: Some(FloorSpec::default()),
        ..sheet(24, Plane::Xz, [0.0, 0.3, 0.0], "corners")
    };
    scene.floor.as_mut().unwrap().height = 0.0;
    let mut sim = Simulation::new(scene).unwrap();
    // A loop from above (rays along -y) around the square |x|, |z| < 0.2.
    let corners = [
        (-0.2, -0.2),
        (0.2, -0.2),
        (0.2, 0.2),
        (-0.2, 0.2),
        (-0.2, -0.2),
    ];
    let mut rays = Vec::new();
    for w in corners.windows(2) {
        for s in 0..8 {
            let f = s as f32 / 8.0;
            let (x, z) = (
                w[0].0 + f * (w[1].0 - w[0].0),
                w[0].1 + f * (w[1].1 - w[0].1),
            );
            rays.push((Vec3::new(x, 2.0, z), Vec3::NEG_Y));
        }
    }
    rays.push(rays[0]);
    let mass = live_mass(&sim);
    sim.sever_stroke(&rays).unwrap();
    assert_eq!(sim.pieces(), 2);
    assert_eq!(live_mass(&sim).to_bits(), mass.to_bits());
    let labels = sim.piece_labels();
    let fragment: Vec<usize> = (0..labels.len())
        .filter(|&p| labels[p] != labels[0])
        .collect();
    let inside = |p: usize| {
        let x = sim.positions().get(p);
        x.x.abs() < 0.2 && x.z.abs() < 0.2
    };
    assert!(fragment.iter().all(|&p| inside(p)));
    assert_eq!(
        fragment.len(),
        (0..labels.len()).filter(|&p| inside(p)).count()
    );
    // Free fall from 0.3 m: 2.4 m/s at the floor. Nothing may move much faster than that.
    for _ in 0..100 {
        sim.step(10).unwrap();
        for p in 0..labels.len() {
            let v = sim.velocities().get(p);
            assert!(v.is_finite() && v.length() < 4.0, "particle {p} at {v} m/s");
        }
    }
    // One second later the fragment lies on the floor, at rest.
    for &p in &fragment {
        let (x, v) = (sim.positions().get(p), sim.velocities().get(p));
        assert!(
            (-1e-3..0.05).contains(&x.y),
            "particle {p} at height {}",
            x.y
        );
        assert!(
            x.x.abs() < 0.3 && x.z.abs() < 0.3,
            "particle {p} drifted to {x}"
        );
        assert!(v.length() < 0.05, "particle {p} still moves at {v}");
    }
}

/// In the demo a cut that deleted particles left a thin strip, which flew
/// about a metre toward the camera and lay there. Here two cuts one grid spacing apart cut a
/// strip off a hanging cloth; the strip falls (at g, within rounding) and nothing in the
/// cloth moves faster than free fall allows.
#[test]
fn a_strip_cut_off_falls_instead_of_flying() {
    let mut sim = Simulation::new(curtain(IntegratorKind::SymplecticEuler)).unwrap();
    let dy = 1.0 / (N - 1) as f32;
    sim.sever_stroke(&across(cut_height(), 6)).unwrap();
    sim.sever_stroke(&across(cut_height() - dy, 6)).unwrap();
    assert_eq!(sim.pieces(), 3);
    let strip: Vec<usize> = (9 * N as usize..10 * N as usize).collect();
    let labels = sim.piece_labels();
    assert!(strip.iter().all(|&p| labels[p] == labels[strip[0]]));
    for step in 1..=300u32 {
        sim.step(1).unwrap();
        let bound = G * step as f32 * 0.001 * 1.05 + 0.05;
        for p in 0..labels.len() {
            let v = sim.velocities().get(p);
            assert!(
                v.is_finite() && v.length() < bound,
                "step {step}: particle {p} at {v}"
            );
        }
    }
    let v = mean_velocity_y(&sim, &strip);
    assert!((v + G * 0.3).abs() < 1e-3 * G * 0.3, "strip at {v} m/s");
}

#[test]
fn every_integrator_and_strain_limiting_step_a_cut_cloth() {
    // Explicit Euler is unstable for any undamped spring (it diverges on the uncut cloth too).
    let stable = IntegratorKind::ALL
        .into_iter()
        .filter(|&k| k != IntegratorKind::ExplicitEuler);
    for integrator in stable {
        for limit in [None, Some(StrainLimitSpec::default())] {
            let mut scene = curtain(integrator);
            scene.strain_limit = limit.clone();
            // The watchdog reads the live flags too: a severed spring is never "overstretched".
            scene.watchdog.max_stretch = Some(1.5);
            let mut sim = Simulation::new(scene).unwrap();
            let ok = |r: rustcloth::Result<()>| r.unwrap_or_else(|e| panic!("{integrator:?}: {e}"));
            ok(sim.step(20));
            sim.sever_stroke(&across(cut_height(), 4)).unwrap();
            let before = sim.positions().get(0).y;
            ok(sim.step(200));
            // The lower piece fell (0.2 s: about 0.2 m); the upper one still hangs.
            let fell = before - sim.positions().get(0).y;
            assert!(
                fell.is_finite() && (0.15..0.25).contains(&fell),
                "{integrator:?} {limit:?}: fell {fell} m"
            );
            let top = sim.positions().get((N * N - 1) as usize).y;
            assert!((top - 2.0).abs() < 1e-6);
        }
    }
}

#[test]
fn cuts_are_deterministic_for_any_thread_count() {
    let run = |threads| {
        with_threads(threads, || {
            let mut scene = curtain(IntegratorKind::ImplicitEuler);
            scene.cloth.nx = 64;
            scene.cloth.ny = 64;
            let mut sim = Simulation::new(scene).unwrap();
            sim.step(10).unwrap();
            let rays: Vec<(Vec3, Vec3)> = (0..9)
                .map(|k| {
                    (
                        Vec3::new(-0.6 + 0.15 * k as f32, 1.3 + 0.05 * (k % 3) as f32, 2.0),
                        Vec3::NEG_Z,
                    )
                })
                .collect();
            let severed = sim.sever_stroke(&rays).unwrap();
            sim.step(30).unwrap();
            let drawn = Drawn::of(&mut sim);
            let bits: Vec<[u32; 3]> = drawn
                .positions
                .iter()
                .map(|x| x.to_array().map(f32::to_bits))
                .collect();
            (
                severed,
                sim.pieces(),
                state_hash(&sim),
                sim.triangles().to_vec(),
                (drawn.triangles, bits),
            )
        })
    };
    let one = run(1);
    assert!(one.0 > 0 && one.1 == 2);
    for threads in [2, 3, 7] {
        assert!(run(threads) == one, "{threads} threads differ");
    }
}

/// The culling in `springs_crossing_stroke` (particles' codes against the swept triangles'
/// planes) against testing every live spring, on a crumpled cloth and random strokes.
#[test]
fn the_culled_stroke_test_finds_what_testing_every_spring_finds() {
    use rustcloth::cutting::{far_distance, segment_crosses_triangle, springs_crossing_stroke};
    let mut sim = Simulation::new(curtain(IntegratorKind::ImplicitEuler)).unwrap();
    sim.grab(3).unwrap();
    sim.drag_to(Vec3::new(0.3, 1.6, 0.4)).unwrap();
    sim.step(300).unwrap();
    let mut rng = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng >> 40) as f32 / (1u64 << 24) as f32
    };
    let grid = sim.grid();
    let mut found = 0;
    for _ in 0..30 {
        let rays: Vec<Ray> = (0..3)
            .map(|_| {
                let o = Vec3::new(next() * 2.0 - 1.0, 0.8 + next() * 1.4, 1.0 + next());
                Ray::new(o, Vec3::new(next() - 0.5, next() - 0.5, -1.0)).unwrap()
            })
            .collect();
        let (springs, alive, pos) = (sim.springs(), &sim.particles().alive, sim.positions());
        let crossings = springs_crossing_stroke(grid, springs, alive, pos, &rays);
        let mut got: Vec<_> = crossings.iter().map(|&(slot, _)| slot).collect();
        got.sort_by_key(|&(kind, a)| (kind.index(), a));
        got.dedup();
        // Each crossing is where the spring's segment meets the surface.
        for &((kind, a), t) in &crossings {
            let b = a + grid.offset(kind);
            let x = pos.get(a).lerp(pos.get(b), t);
            assert!((0.0..=1.0).contains(&t), "{kind:?} {a}: t = {t}");
            assert!(x.is_finite());
        }
        let far = far_distance(pos, alive, &rays).unwrap();
        let mut want = Vec::new();
        for kind in SpringKind::ALL {
            springs.for_each(grid, kind, |a, b, _| {
                let (pa, pb) = (pos.get(a).as_dvec3(), pos.get(b).as_dvec3());
                let crosses = rays.windows(2).any(|w| {
                    let (o0, d0) = (w[0].origin.as_dvec3(), w[0].dir.as_dvec3());
                    let (o1, d1) = (w[1].origin.as_dvec3(), w[1].dir.as_dvec3());
                    let q = [o0, o1, o1 + far * d1, o0 + far * d0];
                    segment_crosses_triangle(pa, pb, [q[0], q[1], q[2]])
                        || segment_crosses_triangle(pa, pb, [q[0], q[2], q[3]])
                });
                if crosses {
                    want.push((kind, a));
                }
            });
        }
        assert_eq!(got, want);
        found += want.len();
    }
    assert!(found > 100, "the strokes crossed only {found} springs");
}

#[test]
fn a_severed_cloth_is_saved_and_restored_bit_for_bit() {
    let mut sim = Simulation::new(curtain(IntegratorKind::SymplecticEuler)).unwrap();
    sim.step(10).unwrap();
    sim.sever_stroke(&across(cut_height(), 3)).unwrap();
    sim.step(10).unwrap();
    let mut copy = Simulation::restore(sim.snapshot()).unwrap();
    assert_eq!(copy.pieces(), 2);
    assert_eq!(copy.topology_version(), sim.topology_version());
    sim.step(50).unwrap();
    copy.step(50).unwrap();
    assert_eq!(state_hash(&copy), state_hash(&sim));
    assert_eq!(copy.triangles(), sim.triangles());
}

/// Self-collision keeps working across a cut: the pieces part as without it. (That
/// it keeps apart exactly the drawn triangles is checked in `src/self_collision/mod.rs`.)
#[test]
fn self_collision_sees_the_cut_surface() {
    let mut scene = curtain(IntegratorKind::SymplecticEuler);
    scene.self_collision = Some(rustcloth::scene::SelfCollisionSpec::default());
    let mut sim = Simulation::new(scene).unwrap();
    sim.step(5).unwrap();
    sim.sever_stroke(&across(cut_height(), 2)).unwrap();
    let grid = sim.grid();
    let lower: Vec<usize> = (0..grid.len()).filter(|&p| grid.coords(p).1 <= 9).collect();
    let v0 = mean_velocity_y(&sim, &lower);
    sim.step(100).unwrap();
    let t = 100.0 * 0.001;
    // Nothing holds the lower piece: the pass's pushes come in equal and opposite pairs.
    let v = mean_velocity_y(&sim, &lower) - v0;
    assert!((v + G * t).abs() < 1e-3 * G * t, "lower piece: {v} m/s");
    let stats = sim.self_collision_stats().unwrap();
    assert!(stats.substeps > 0 && stats.min_distance > 0.0, "{stats:?}");
    let drawn = sim.triangles().len();
    assert!(
        drawn < 2 * (N as usize - 1).pow(2),
        "the cut left every triangle drawn"
    );
}

// ----- the drawn mesh follows the cut --------------------------------------------------------

/// Distance in the xy plane from `x` to the polyline through the stroke's ray origins: the
/// surface that rays along -z sweep is that polyline extruded along z.
fn distance_to_stroke(x: Vec3, stroke: &[(Vec3, Vec3)]) -> f32 {
    let p = x.truncate();
    stroke
        .windows(2)
        .map(|w| {
            let (a, b) = (w[0].0.truncate(), w[1].0.truncate());
            let t = ((p - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
            p.distance(a + t * (b - a))
        })
        .fold(f32::INFINITY, f32::min)
}

const DY: f32 = 1.0 / (N - 1) as f32;

/// The largest distance of a cut vertex from the nearest of `strokes`.
fn worst_cut_vertex(drawn: &Drawn, strokes: &[&[(Vec3, Vec3)]]) -> f32 {
    drawn.positions[drawn.particles..]
        .iter()
        .map(|&x| {
            strokes
                .iter()
                .map(|s| distance_to_stroke(x, s))
                .fold(f32::INFINITY, f32::min)
        })
        .fold(0.0, f32::max)
}

/// Panics if a drawn triangle has a vertex more than `tol` m above the line through `stroke`
/// (a straight one) and another more than `tol` below it.
fn assert_no_triangle_straddles(drawn: &Drawn, stroke: &[(Vec3, Vec3)], tol: f32) {
    let (a, b) = (
        stroke[0].0.truncate(),
        stroke[stroke.len() - 1].0.truncate(),
    );
    let side = |x: Vec3| (b - a).perp_dot(x.truncate() - a) / (b - a).length();
    for tri in &drawn.triangles {
        let d = tri.map(|v| side(drawn.positions[v as usize]));
        let (lo, hi) = (
            d.iter().copied().fold(f32::INFINITY, f32::min),
            d.iter().copied().fold(f32::NEG_INFINITY, f32::max),
        );
        assert!(
            !(lo < -tol && hi > tol),
            "triangle {tri:?} straddles the cut: {d:?}"
        );
    }
}

/// Cuts a sagging curtain along each stroke, then checks the drawn mesh at the cut (every cut
/// vertex on a stroke to within `on_stroke` spacings, the pieces sharing no vertex) and after
/// the pieces part for `steps` steps (no drawn edge stretched past 1.5 times its rest length).
/// Returns the simulation and the cut vertices' worst distance, in spacings.
fn cut_and_part(strokes: &[&[(Vec3, Vec3)]], steps: u64, on_stroke: f32) -> (Simulation, f32) {
    let mut sim = Simulation::new(curtain(IntegratorKind::SymplecticEuler)).unwrap();
    sim.step(200).unwrap(); // sagging: the grid is no longer a flat, even lattice
    for stroke in strokes {
        assert!(sim.sever_stroke(stroke).unwrap() > 0);
    }
    let drawn = Drawn::of(&mut sim);
    assert!(drawn.positions.len() > drawn.particles, "no cut vertex");
    let worst = worst_cut_vertex(&drawn, strokes) / DY;
    assert!(
        worst < on_stroke,
        "a cut vertex is {worst} spacings from the stroke"
    );
    drawn.assert_pieces_share_no_vertex(&sim.piece_labels());
    sim.step(steps).unwrap();
    let after = Drawn::of(&mut sim);
    after.assert_pieces_share_no_vertex(&sim.piece_labels());
    let stretch = after.max_edge_stretch(0.05 * DY);
    assert!(
        stretch < 1.5,
        "a drawn edge is stretched {stretch} times its rest length"
    );
    (sim, worst)
}

/// The drawn edge of a cut ran along the particles next to it (a staircase up to a
/// grid spacing from the stroke, with a gap). Now it runs through the points where the stroke
/// crossed the springs, each side's edge with its own vertices, and goes with its piece.
#[test]
fn the_drawn_edge_follows_a_straight_cut() {
    let stroke = across(cut_height(), 2);
    let (mut sim, worst) = cut_and_part(&[&stroke], 150, 0.02);
    // The lower piece fell some 0.11 m: its edge went with it and the upper's stayed.
    let drawn = Drawn::of(&mut sim);
    let lower = |v: usize| sim.grid().coords(drawn.owner[v]).1 <= 9;
    let cut: Vec<usize> = (drawn.particles..drawn.positions.len()).collect();
    let lowest_upper = cut
        .iter()
        .filter(|&&v| !lower(v))
        .map(|&v| drawn.positions[v].y);
    let highest_lower = cut
        .iter()
        .filter(|&&v| lower(v))
        .map(|&v| drawn.positions[v].y);
    let gap = lowest_upper.fold(f32::INFINITY, f32::min)
        - highest_lower.fold(f32::NEG_INFINITY, f32::max);
    assert!(gap > 1.5 * DY, "the two edges are {gap} m apart");
    assert!(worst < 0.02, "{worst}");
    // At the cut, nothing straddles it: the particles are at least a third of a spacing
    // from it, the cut vertices on it.
    let mut fresh = Simulation::new(curtain(IntegratorKind::SymplecticEuler)).unwrap();
    fresh.step(200).unwrap();
    fresh.sever_stroke(&stroke).unwrap();
    assert_no_triangle_straddles(&Drawn::of(&mut fresh), &stroke, 0.02 * DY);
}

#[test]
fn the_drawn_edge_follows_oblique_and_curved_strokes() {
    let oblique: Vec<(Vec3, Vec3)> = (0..2)
        .map(|s| {
            (
                Vec3::new(-0.8 + 1.6 * s as f32, 1.25 + 0.5 * s as f32, 2.0),
                Vec3::NEG_Z,
            )
        })
        .collect();
    let (mut sim, _) = cut_and_part(&[&oblique], 150, 0.05);
    assert_eq!(sim.pieces(), 2);
    let mut fresh = Simulation::new(curtain(IntegratorKind::SymplecticEuler)).unwrap();
    fresh.step(200).unwrap();
    fresh.sever_stroke(&oblique).unwrap();
    assert_no_triangle_straddles(&Drawn::of(&mut fresh), &oblique, 0.05 * DY);
    let _ = Drawn::of(&mut sim);

    let curved: Vec<(Vec3, Vec3)> = (0..25)
        .map(|s| {
            let x = -0.8 + 1.6 * s as f32 / 24.0;
            (Vec3::new(x, 1.5 + 0.15 * (5.0 * x).sin(), 2.0), Vec3::NEG_Z)
        })
        .collect();
    let (sim, _) = cut_and_part(&[&curved], 150, 0.05);
    assert_eq!(sim.pieces(), 2);
}

/// Two strokes across each other: the cells at the crossing are cut twice (triangles with
/// three severed edges), and the four pieces still share no vertex.
#[test]
fn two_crossing_cuts_leave_four_pieces_with_clean_edges() {
    let down: Vec<(Vec3, Vec3)> = (0..2)
        .map(|s| (Vec3::new(0.013, 0.8 + 1.4 * s as f32, 2.0), Vec3::NEG_Z))
        .collect();
    let stroke = across(cut_height() + 0.01, 2);
    let (sim, _) = cut_and_part(&[&stroke, &down], 150, 0.05);
    assert_eq!(sim.pieces(), 4);
}

#[test]
fn querying_the_drawn_mesh_changes_no_physics() {
    let run = |query: bool| {
        let mut sim = Simulation::new(curtain(IntegratorKind::SymplecticEuler)).unwrap();
        sim.step(20).unwrap();
        sim.sever_stroke(&across(cut_height(), 3)).unwrap();
        for _ in 0..50 {
            sim.step(1).unwrap();
            if query {
                Drawn::of(&mut sim);
            }
        }
        (
            state_hash(&sim),
            live_mass(&sim).to_bits(),
            sim.grid().len(),
        )
    };
    assert_eq!(run(true), run(false));
}

#[test]
fn the_drawn_topology_changes_only_with_the_topology_version() {
    let mut sim = Simulation::new(curtain(IntegratorKind::SymplecticEuler)).unwrap();
    let whole = sim.render_triangles().to_vec();
    assert_eq!(
        whole,
        sim.triangles().to_vec(),
        "an uncut cloth draws the grid"
    );
    assert!(sim.render_cut_vertices().is_empty());
    sim.step(5).unwrap();
    assert_eq!(sim.render_triangles(), whole);
    let version = sim.topology_version();
    sim.sever_stroke(&across(cut_height(), 3)).unwrap();
    assert_eq!(sim.topology_version(), version + 1);
    let cut = sim.render_triangles().to_vec();
    // Each of the row's 19 cells: two triangles of two severed edges, each in three pieces.
    assert_eq!(cut.len(), whole.len() + 4 * (N as usize - 1));
    // Two cut vertices on each severed edge: 20 structural and 19 diagonal.
    assert_eq!(
        sim.render_cut_vertices().len(),
        2 * (N as usize + N as usize - 1)
    );
    let before = Drawn::of(&mut sim).positions;
    sim.step(5).unwrap();
    assert_eq!(sim.render_triangles(), cut);
    assert_ne!(
        Drawn::of(&mut sim).positions,
        before,
        "the positions follow the state"
    );
    // Severing nothing moves nothing.
    assert_eq!(sim.sever_stroke(&across(cut_height(), 3)).unwrap(), 0);
    assert_eq!(sim.topology_version(), version + 1);
    assert_eq!(sim.render_triangles(), cut);
}

/// The seed's cut removes a particle: its triangles go (its mass with it), and no cut vertex
/// appears, as nothing crossed a spring between two live particles.
#[test]
fn a_removed_particle_is_a_hole_without_cut_vertices() {
    let mut sim = Simulation::new(curtain(IntegratorKind::SymplecticEuler)).unwrap();
    let p = sim.grid().index(5, 5);
    sim.cut(p as i64).unwrap();
    assert!(sim.render_cut_vertices().is_empty());
    assert!(sim
        .render_triangles()
        .iter()
        .flatten()
        .all(|&v| v as usize != p));
    let physics = sim.triangles().to_vec();
    assert_eq!(sim.render_triangles(), physics);
}

/// The live stroke of two frames across the curtain at the cut's height, the cloth moved down
/// by `drop` rows between them (the first springs cut, the cloth below sags): the first frame
/// from off the left edge to `x_mid`, the second on to `x_end`. Returns the springs severed.
fn live_stroke_over_two_frames(sim: &mut Simulation, x_mid: f32, x_end: f32, drop: f32) -> usize {
    let ray = |x: f32| (Vec3::new(x, cut_height(), 2.0), Vec3::NEG_Z);
    let frame = |from: f32, to: f32| -> Vec<(Vec3, Vec3)> {
        (0..=16)
            .map(|s| ray(from + (to - from) * s as f32 / 16.0))
            .collect()
    };
    let mut severed = sim.sever_live_stroke(&frame(-0.8, x_mid)).unwrap();
    let dy = 1.0 / (N - 1) as f32;
    let pos = sim.positions();
    let moved = rustcloth::soa::Vec3s::from_fn(pos.len(), |p| pos.get(p) - Vec3::Y * drop * dy);
    sim.set_positions(&moved).unwrap();
    severed += sim.sever_live_stroke(&frame(x_mid, x_end)).unwrap();
    sim.end_live_stroke();
    severed
}

#[test]
fn a_live_stroke_continues_through_the_material_where_the_last_frame_left_off() {
    // The cloth drops 1.5 rows between the frames: the second frame's rays meet material 1.5
    // rows above where the first frame's ended. Cut against the cloth as it is in each frame,
    // the two halves would be 1.5 rows apart with the cloth whole between them.
    let mut sim = Simulation::new(curtain(IntegratorKind::SymplecticEuler)).unwrap();
    let mass = live_mass(&sim);
    assert!(live_stroke_over_two_frames(&mut sim, 0.0, 0.8, 1.5) > 0);
    assert_eq!(sim.pieces(), 2);
    assert_eq!(live_mass(&sim).to_bits(), mass.to_bits());
}

#[test]
fn a_live_stroke_that_stays_inside_the_cloth_makes_a_slit() {
    let mut sim = Simulation::new(curtain(IntegratorKind::SymplecticEuler)).unwrap();
    let mut severed = 0;
    for frame in [[-0.3f32, 0.0], [0.0, 0.3]] {
        let rays: Vec<_> = (0..=8)
            .map(|s| frame[0] + (frame[1] - frame[0]) * s as f32 / 8.0)
            .map(|x| (Vec3::new(x, cut_height(), 2.0), Vec3::NEG_Z))
            .collect();
        severed += sim.sever_live_stroke(&rays).unwrap();
    }
    assert!(severed > 0);
    assert_eq!(sim.pieces(), 1);
}
