//! Tearing and cuts on a mesh cloth: springs of the spring list severed (the bend springs of
//! the triangles on a severed edge with them), the triangles on them no longer drawn, the cloth
//! in pieces that move apart. Checked by physics: a released piece falls as a free body
//! (`g t^2 / 2`, whatever its springs do inside it), the elastic energy drops at a tear by the
//! energy the broken springs held, a snapshot after a tear continues bitwise, the result is
//! the same for any number of threads, and self-collision keeps the torn cloth free of
//! intersections by the independent checker of tests/common/crossings.rs.

use crate::common;

use common::crossings::intersecting_pairs;
use common::{state_hash, with_threads};
use glam::Vec3;
use rustcloth::mesh_cloth::{jittered_square, EdgeKind};
use rustcloth::scene::{PinBox, PinSpec, SelfCollisionSpec, StrainLimitSpec, TearingSpec};
use rustcloth::{IntegratorKind, Scene, Simulation};

const G: f64 = 9.81;

/// A hanging 1 m square of `n` x `n` jittered points (an irregular mesh, no grid in its
/// springs), centre at y = 1, held by its whole top edge, with `tearing` if given.
fn hanging(n: usize, tearing: Option<TearingSpec>) -> Scene {
    let (vertices, triangles) = jittered_square(n, 1.0, [0.0, 1.0, 0.0], 0.3, 7);
    let top = PinSpec::Region(PinBox {
        corners: [[-0.6, 1.49, -0.1], [0.6, 1.6, 0.1]],
    });
    let mut scene = common::mesh_cloth_scene(vertices, triangles, vec![top]);
    scene.tearing = tearing;
    scene.dt = 0.7 * scene.stable_dt(IntegratorKind::SymplecticEuler).unwrap();
    scene
}

fn pinned(sim: &Simulation) -> Vec<usize> {
    (0..sim.grid().len())
        .filter(|&p| sim.particles().pinned[p])
        .collect()
}

/// Pulls the left and the right half of the top edge apart (each half's pins moved sideways
/// at 1 m/s) for `steps` steps, calling `each` after every step. At the scene's step (0.55
/// ms) the halves part after about 1500 steps.
fn pull_apart(sim: &mut Simulation, steps: u32, mut each: impl FnMut(&mut Simulation)) {
    let pins = pinned(sim);
    let start: Vec<Vec3> = pins.iter().map(|&p| sim.positions().get(p)).collect();
    let dt = sim.dt() as f32;
    for s in 1..=steps {
        for (&p, x) in pins.iter().zip(&start) {
            let side = if x.x < 0.0 { -1.0 } else { 1.0 };
            let target = *x + Vec3::X * side * s as f32 * dt;
            sim.pin(p as i64, Some(target)).unwrap();
        }
        sim.step(1).unwrap();
        each(sim);
    }
}

/// The mass-weighted mean of `field` (positions or velocities) over the particles `of`, in f64.
fn mass_mean(sim: &Simulation, of: &[usize], field: &rustcloth::soa::Vec3s) -> glam::DVec3 {
    let mass = &sim.particles().mass;
    let total: f64 = of.iter().map(|&p| mass[p] as f64).sum();
    of.iter()
        .map(|&p| field.get(p).as_dvec3() * mass[p] as f64)
        .sum::<glam::DVec3>()
        / total
}

/// The centre of mass of the particles `of`.
fn centre(sim: &Simulation, of: &[usize]) -> glam::DVec3 {
    mass_mean(sim, of, sim.positions())
}

/// The velocity of the centre of mass of the particles `of`.
fn velocity(sim: &Simulation, of: &[usize]) -> glam::DVec3 {
    mass_mean(sim, of, sim.velocities())
}

/// The particles of the piece labelled `label`.
fn piece(sim: &Simulation, label: u32) -> Vec<usize> {
    let labels = sim.piece_labels();
    (0..labels.len()).filter(|&p| labels[p] == label).collect()
}

/// The piece holding the lowest particle.
fn lowest_piece(sim: &Simulation) -> Vec<usize> {
    let labels = sim.piece_labels();
    let y = |p: usize| sim.positions().get(p).y;
    let lowest = (0..labels.len())
        .min_by(|&a, &b| y(a).total_cmp(&y(b)))
        .unwrap();
    piece(sim, labels[lowest])
}

/// Checks that the particles `of`, free of pins and of every other piece, fall for `steps`
/// steps as one body under gravity alone: the drop of their centre of mass beyond what its
/// starting velocity carries is `g t^2 / 2` (symplectic Euler's `g h^2 n (n + 1) / 2`)
/// within `tolerance` of it.
fn falls_freely(sim: &mut Simulation, of: &[usize], steps: u64, tolerance: f64) {
    let (x0, v0) = (centre(sim, of), velocity(sim, of));
    sim.step(steps).unwrap();
    let (h, n) = (sim.dt(), steps as f64);
    let t = h * n;
    let drop = x0.y + v0.y * t - centre(sim, of).y;
    let want = G * h * h * n * (n + 1.0) / 2.0;
    assert!(
        (drop - want).abs() <= tolerance * want,
        "the piece dropped {drop} m beyond its start velocity in {t} s, free fall {want} m"
    );
    assert!((0.5 * G * t * t - want).abs() < 0.02 * want);
}

#[test]
fn a_mesh_pulled_apart_by_its_top_tears_in_two_and_the_released_piece_falls_freely() {
    let mut sim = Simulation::new(hanging(16, Some(TearingSpec::default()))).unwrap();
    assert!(sim.effects().contains(&"tearing"));
    let springs = sim.model().mesh().unwrap().springs.len();
    let mut torn_at = None;
    pull_apart(&mut sim, 2000, |sim| {
        if torn_at.is_none() && sim.pieces() > 1 {
            torn_at = Some(sim.steps());
        }
    });
    let torn_at = torn_at.expect("the cloth never tore apart");
    assert!(torn_at > 10, "tore at once, at step {torn_at}");
    let mesh = sim.model().mesh().unwrap();
    assert_eq!(
        mesh.springs.len(),
        springs,
        "the spring list never reallocates"
    );
    let severed: Vec<usize> = (0..springs).filter(|&e| !mesh.springs.active[e]).collect();
    assert!(!severed.is_empty());
    assert!(severed
        .iter()
        .all(|&e| mesh.springs.k[e] == 0.0 && mesh.springs.c[e] == 0.0));
    assert!(sim.steps() > 0);
    // Every drawn triangle has its three edges live, and one piece.
    let labels = sim.piece_labels();
    for t in sim.triangles().to_vec() {
        assert!(t
            .iter()
            .all(|&v| labels[v as usize] == labels[t[0] as usize]));
    }
    let all = sim.model().mesh().unwrap().triangles.len();
    assert!(sim.triangles().len() < all);
    // The halves went apart: the pins of the left half and of the right half are on
    // different pieces.
    let pins = pinned(&sim);
    let side = |p: usize| sim.positions().get(p).x < 0.0;
    let right: Vec<usize> = pins.iter().copied().filter(|&p| !side(p)).collect();
    let left: Vec<usize> = pins.iter().copied().filter(|&p| side(p)).collect();
    let mut sizes: Vec<(usize, u32)> = right
        .iter()
        .map(|&p| {
            (
                right.iter().filter(|&&q| labels[q] == labels[p]).count(),
                labels[p],
            )
        })
        .collect();
    sizes.sort_unstable();
    let released = sizes.last().unwrap().1;
    assert!(left.iter().all(|&p| labels[p] != released));
    // Let the right half go: it falls as a free body.
    for &p in &right {
        sim.unpin(p as i64).unwrap();
    }
    let body = piece(&sim, released);
    assert!(
        body.len() > 20,
        "the released piece has {} vertices",
        body.len()
    );
    falls_freely(&mut sim, &body, 300, 1e-3);
}

/// A stroke of rays along -z at height `y`, across the whole cloth.
fn across(y: f32) -> Vec<(Vec3, Vec3)> {
    (0..=20)
        .map(|k| (Vec3::new(-1.0 + 0.1 * k as f32, y, 2.0), -Vec3::Z))
        .collect()
}

fn a_cut_across_gives_two_pieces_and_the_lower_falls(integrator: IntegratorKind, tol: f64) {
    let mut scene = hanging(16, None);
    scene.integrator = integrator;
    let mut sim = Simulation::new(scene).unwrap();
    sim.step(20).unwrap();
    let factorizations = |sim: &Simulation| sim.solver_stats().map(|s| s.factorizations);
    let settled = factorizations(&sim);
    sim.step(1).unwrap();
    assert_eq!(
        factorizations(&sim),
        settled,
        "refactored with nothing changed"
    );
    let version = sim.topology_version();
    let severed = sim.sever_stroke(&across(1.02)).unwrap();
    assert!(severed > 0);
    sim.step(1).unwrap();
    if integrator != IntegratorKind::SymplecticEuler {
        // The factor keys on which springs hold: the step after the cut refactors.
        assert_eq!(
            factorizations(&sim),
            settled.map(|f| f + 1),
            "{integrator:?}"
        );
    }
    assert_eq!(sim.topology_version(), version + 1);
    assert_eq!(sim.pieces(), 2);
    // Cutting again along the same line finds nothing live: a no-op, the version unmoved.
    assert_eq!(sim.sever_stroke(&across(1.02)).unwrap(), 0);
    assert_eq!(sim.topology_version(), version + 1);
    let lower = lowest_piece(&sim);
    assert!(lower.iter().all(|&p| !sim.particles().pinned[p]));
    assert!(lower.len() > 50 && lower.len() < 200, "{}", lower.len());
    falls_freely(&mut sim, &lower, 100, tol);
}

#[test]
fn a_cut_across_a_hanging_mesh_gives_two_pieces_and_the_lower_falls() {
    a_cut_across_gives_two_pieces_and_the_lower_falls(IntegratorKind::SymplecticEuler, 1e-3);
}

/// The implicit solvers factor the spring list's matrix: the cut must reach the factor, or
/// the lower piece would hang on springs that no longer exist.
#[test]
fn a_cut_across_a_hanging_mesh_parts_it_under_implicit_euler_and_projective_dynamics() {
    for integrator in [
        IntegratorKind::ImplicitEuler,
        IntegratorKind::ProjectiveDynamics,
    ] {
        // Implicit Euler's step is not symplectic Euler's: its drop is g h^2 n (n + 1) / 2 to
        // within one step's g h^2 n, and its solves stop at a tolerance.
        a_cut_across_gives_two_pieces_and_the_lower_falls(integrator, 0.03);
    }
}

/// Whether the force pass's per-slot copies of the springs are what copying every slot again
/// gives: a cut or a tear refreshes only the slots of the springs it severed.
fn slots_follow_the_springs(sim: &Simulation) -> bool {
    let mesh = sim.model().mesh().unwrap();
    let mut full = mesh.slots.clone();
    full.refresh(&mesh.springs, None);
    full == mesh.slots
}

#[test]
fn the_force_pass_follows_every_spring_a_cut_or_a_tear_severs() {
    let mut sim = Simulation::new(hanging(16, Some(TearingSpec::default()))).unwrap();
    sim.cut(100).unwrap();
    // A stroke that stops in the middle: a slit, the cloth still one piece.
    let slit: Vec<(Vec3, Vec3)> = across(1.2).into_iter().take(10).collect();
    assert!(sim.sever_stroke(&slit).unwrap() > 0);
    assert!(slots_follow_the_springs(&sim));
    let mut steps_checked = 0;
    pull_apart(&mut sim, 1500, |sim| {
        assert!(slots_follow_the_springs(sim), "at step {}", sim.steps());
        steps_checked += 1;
    });
    assert!(sim.pieces() > 1, "the cloth never tore apart");
    assert_eq!(steps_checked, 1500);
}

#[test]
fn cutting_a_vertex_severs_every_spring_touching_it() {
    let mut sim = Simulation::new(hanging(8, None)).unwrap();
    let p = 27;
    let version = sim.topology_version();
    sim.cut(p as i64).unwrap();
    assert_eq!(sim.topology_version(), version + 1);
    assert!(!sim.particles().alive[p]);
    let mesh = sim.model().mesh().unwrap();
    for &e in mesh.springs_at(p) {
        assert!(!mesh.springs.active[(e >> 1) as usize]);
    }
    assert!(sim.triangles().iter().all(|t| !t.contains(&(p as u32))));
    assert_eq!(sim.piece_labels()[p], u32::MAX);
    assert_eq!(sim.pieces(), 1);
    sim.step(50).unwrap();
    assert!(sim.positions().x.iter().all(|x| x.is_finite()));
    // A second cut of the same vertex does nothing.
    sim.cut(p as i64).unwrap();
    assert_eq!(sim.topology_version(), version + 1);
}

/// The elastic energy of the springs listed, at the simulation's positions and stiffness now.
fn energy_of(sim: &Simulation, springs: &[usize]) -> f64 {
    let s = &sim.model().mesh().unwrap().springs;
    springs
        .iter()
        .map(|&e| {
            let (a, b) = (s.a[e] as usize, s.b[e] as usize);
            let l = (sim.positions().get(b) - sim.positions().get(a)).length() as f64;
            0.5 * s.k[e] as f64 * (l - s.rest[e] as f64).powi(2)
        })
        .sum()
}

#[test]
fn the_energy_at_a_tear_drops_by_what_the_broken_springs_held() {
    let tearing = TearingSpec {
        max_strain: 0.2,
        max_per_step: 16,
    };
    let stretched = |tearing| {
        let mut sim = Simulation::new(hanging(12, tearing)).unwrap();
        let mut pos = sim.positions().clone();
        for p in 0..pos.len() {
            pos.x[p] *= 1.3;
        }
        sim.set_positions(&pos).unwrap();
        sim
    };
    let (mut torn, mut whole) = (stretched(Some(tearing)), stretched(None));
    torn.step(1).unwrap();
    whole.step(1).unwrap();
    // The tear runs after the step: the positions are the same to the bit.
    assert_eq!(state_hash(&torn), state_hash(&whole));
    let (before, after) = (
        &whole.model().mesh().unwrap().springs,
        &torn.model().mesh().unwrap().springs,
    );
    let broken: Vec<usize> = (0..before.len())
        .filter(|&e| before.active[e] && !after.active[e])
        .collect();
    let stretch = broken
        .iter()
        .filter(|&&e| before.kind[e] == EdgeKind::Stretch)
        .count();
    assert_eq!(stretch, 16, "at most max_per_step stretch springs tear");
    assert!(
        broken.len() > stretch,
        "the bend springs of the torn triangles go too"
    );
    let dropped = whole.energy().elastic - torn.energy().elastic;
    let held = energy_of(&whole, &broken);
    assert!(held > 0.0);
    assert!(
        (dropped - held).abs() <= 1e-9 * whole.energy().elastic,
        "dropped {dropped} J, the broken springs held {held} J"
    );
    // The springs that broke are the most strained stretch springs.
    let strain = |e: usize| {
        let (a, b) = (before.a[e] as usize, before.b[e] as usize);
        (whole.positions().get(b) - whole.positions().get(a)).length() / before.rest[e] - 1.0
    };
    let weakest_broken = (broken.iter().copied())
        .filter(|&e| before.kind[e] == EdgeKind::Stretch)
        .map(strain)
        .fold(f32::INFINITY, f32::min);
    let strongest_kept = (0..before.len())
        .filter(|&e| after.active[e] && before.kind[e] == EdgeKind::Stretch)
        .map(strain)
        .fold(0.0f32, f32::max);
    assert!(weakest_broken >= strongest_kept);
}

/// A tear run: the pull, every 50 steps the state's hash and the live springs.
fn tear_run() -> Vec<(u64, Vec<bool>, Vec<u32>)> {
    let mut sim = Simulation::new(hanging(16, Some(TearingSpec::default()))).unwrap();
    let mut out = Vec::new();
    pull_apart(&mut sim, 600, |sim| {
        if sim.steps() % 50 == 0 {
            let active = sim.model().mesh().unwrap().springs.active.clone();
            out.push((state_hash(sim), active, sim.piece_labels()));
        }
    });
    out
}

#[test]
fn a_tear_is_the_same_for_any_number_of_threads() {
    let one = with_threads(1, tear_run);
    assert!(
        one.last().unwrap().1.iter().any(|&live| !live),
        "nothing tore"
    );
    for threads in [2, 5] {
        assert!(with_threads(threads, tear_run) == one, "{threads} threads");
    }
}

#[test]
fn a_snapshot_after_a_tear_continues_bitwise() {
    let mut sim = Simulation::new(hanging(16, Some(TearingSpec::default()))).unwrap();
    pull_apart(&mut sim, 500, |_| {});
    let active = sim.model().mesh().unwrap().springs.active.clone();
    assert!(active.iter().any(|&live| !live), "nothing tore");
    let snapshot = sim.snapshot();
    assert_eq!(snapshot.mesh_springs, active);
    let mut copy = Simulation::restore(snapshot).unwrap();
    assert_eq!(
        copy.model().mesh().unwrap().springs,
        sim.model().mesh().unwrap().springs
    );
    assert_eq!(copy.triangles(), sim.triangles());
    assert_eq!(copy.piece_labels(), sim.piece_labels());
    assert_eq!(copy.topology_version(), sim.topology_version());
    for _ in 0..5 {
        pull_apart(&mut sim, 20, |_| {});
        pull_apart(&mut copy, 20, |_| {});
        assert_eq!(state_hash(&copy), state_hash(&sim));
    }
    assert_eq!(
        copy.model().mesh().unwrap().springs,
        sim.model().mesh().unwrap().springs
    );
}

#[test]
fn a_snapshot_of_the_wrong_mesh_springs_is_refused_naming_them() {
    let sim = Simulation::new(hanging(6, None)).unwrap();
    let mut snapshot = sim.snapshot();
    snapshot.mesh_springs.pop();
    let err = Simulation::restore(snapshot).err().expect("refused");
    assert!(err.to_string().starts_with("mesh_springs"), "{err}");
}

#[test]
fn self_collision_keeps_a_tearing_mesh_free_of_intersections() {
    let mut scene = hanging(16, Some(TearingSpec::default()));
    scene.self_collision = Some(SelfCollisionSpec::default());
    let mut sim = Simulation::new(scene).unwrap();
    let mut checked = 0;
    pull_apart(&mut sim, 2000, |sim| {
        if sim.steps() % 20 == 0 {
            let tris = sim.triangles().to_vec();
            let crossings = intersecting_pairs(&tris, sim.positions(), |p| p);
            assert!(crossings.is_empty(), "step {}: {crossings:?}", sim.steps());
            checked += 1;
        }
    });
    assert!(sim.pieces() > 1, "nothing tore");
    assert_eq!(checked, 100);
}

/// The pieces of a cut fall apart, stretching their severed springs without bound: the
/// watchdog's stretch check, strain limiting and the strain view must not read them, or the
/// step would be refused, the pieces held together, or the cut's edge shown as torn.
#[test]
fn severed_springs_are_skipped_by_the_watchdog_strain_limiting_and_the_strain_view() {
    let mut scene = hanging(16, None);
    scene.watchdog.max_stretch = Some(2.0);
    scene.strain_limit = Some(StrainLimitSpec::default());
    let mut sim = Simulation::new(scene).unwrap();
    sim.step(20).unwrap();
    assert!(sim.sever_stroke(&across(1.02)).unwrap() > 0);
    let lower = lowest_piece(&sim);
    let top = centre(&sim, &lower).y;
    sim.step(600).unwrap(); // 0.33 s: the lower piece falls about 0.5 m
    assert!(top - centre(&sim, &lower).y > 0.4);
    let strain = sim.spring_strain();
    let worst = strain.iter().copied().fold(0.0f32, f32::max);
    assert!(worst < 0.2, "the strain view shows {worst}");
}
