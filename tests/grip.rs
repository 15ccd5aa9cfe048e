//! The grip: `grab` holds the patch of cloth within `grip_radius` of the particle hit (joined to
//! it by live springs), `drag_to` moves the patch rigidly, `release` restores each particle's
//! pin state, and snapshots carry the grip.
//!
//! The story: a grab used to hold one particle. Dragging a lower corner of the `tear` scene
//! put the whole pull on that particle's 12 springs, which tore first and plucked it out of
//! the sheet (a pinhole, "2 pieces") while the sheet barely moved.

use crate::common;

use common::{bare_scene, builtin_scene, state_hash};
use glam::Vec3;
use rustcloth::integrators::IntegratorKind;
use rustcloth::{Scene, Simulation};

/// A flat 21 x 21 sheet, 1 m square, spacing 0.05 m, with no gravity (nothing moves unless
/// dragged).
fn sheet() -> Simulation {
    let mut scene = bare_scene(21, 21);
    scene.cloth.size = [1.0, 1.0];
    Simulation::new(scene).unwrap()
}

/// The live particles within `radius` of particle `p`, found by brute force (an intact flat
/// sheet is convex, so every one of them is joined to `p` inside the ball).
fn within(sim: &Simulation, p: usize, radius: f32) -> Vec<usize> {
    let centre = sim.positions().get(p);
    let mut out: Vec<usize> = (0..sim.grid().len())
        .filter(|&q| (sim.positions().get(q) - centre).length() <= radius)
        .collect();
    out.sort_unstable();
    out
}

fn sorted(mut v: Vec<usize>) -> Vec<usize> {
    v.sort_unstable();
    v
}

#[test]
fn the_default_grip_holds_the_particles_within_a_few_spacings() {
    let mut sim = sheet();
    let centre = 10 * 21 + 10;
    let radius = sim.grip_radius();
    assert!((radius - 2.5 * 0.05).abs() < 1e-6, "{radius}");
    sim.grab(centre as i64).unwrap();
    let held = sim.gripped();
    assert_eq!(held[0], centre, "the particle hit comes first");
    assert_eq!(sim.grabbed(), Some(centre));
    assert_eq!(sorted(held.clone()), within(&sim, centre, radius));
    // A disc of radius 2.5 spacings on a square lattice: the 21 points with i^2 + j^2 <= 6.25.
    assert_eq!(held.len(), 21);
    assert!(held.iter().all(|&p| sim.particles().pinned[p]));
    // A corner's grip is the quarter disc.
    sim.grab(0).unwrap();
    assert_eq!(sorted(sim.gripped()), within(&sim, 0, radius));
    assert_eq!(sim.gripped().len(), 8);
    assert!(
        !sim.particles().pinned[centre],
        "grabbing again let go of the first grip"
    );
}

#[test]
fn a_zero_radius_grabs_the_one_particle_hit() {
    let mut sim = sheet();
    sim.set_grip_radius(0.0).unwrap();
    sim.grab(5).unwrap();
    assert_eq!(sim.gripped(), vec![5]);
    for bad in [-0.1, -1e-50, f64::NAN, f64::INFINITY, 1e300] {
        let err = sim.set_grip_radius(bad).unwrap_err().to_string();
        assert!(err.contains("grip_radius"), "{err}");
    }
    assert_eq!(sim.grip_radius(), 0.0, "a refused radius changes nothing");
}

#[test]
fn a_grip_does_not_reach_across_a_cut() {
    // Sever the sheet between columns 10 and 11 along its whole height; a grip at column 10
    // holds nothing of the far side, though it lies within the radius.
    let mut sim = sheet();
    let x = sim.positions().get(10).x + 0.025;
    let rays: Vec<(Vec3, Vec3)> = (0..=40)
        .map(|k| {
            let z = -0.6 + 1.2 * k as f32 / 40.0;
            (Vec3::new(x, 1.0, z), Vec3::new(0.0, -1.0, 0.0))
        })
        .collect();
    assert!(sim.sever_stroke(&rays).unwrap() > 0);
    let centre = 10 * 21 + 10;
    sim.grab(centre as i64).unwrap();
    let held = sim.gripped();
    assert!(!held.is_empty());
    let columns: Vec<usize> = held.iter().map(|&p| p % 21).collect();
    assert!(columns.iter().all(|&i| i <= 10), "{columns:?}");
    let near_side: Vec<usize> = within(&sim, centre, sim.grip_radius())
        .into_iter()
        .filter(|&p| p % 21 <= 10)
        .collect();
    assert_eq!(sorted(held), near_side);
}

#[test]
fn a_drag_moves_the_patch_rigidly_and_a_release_restores_each_pin() {
    let mut sim = sheet();
    let centre = 10 * 21 + 10;
    let (pinned, kinematic) = (centre + 1, centre - 21);
    sim.pin(pinned as i64, None).unwrap();
    let kept = sim.positions().get(kinematic) + Vec3::new(0.0, 0.01, 0.0);
    sim.pin(kinematic as i64, Some(kept)).unwrap();
    sim.step(1).unwrap();
    let start: Vec<(usize, Vec3)> = {
        sim.grab(centre as i64).unwrap();
        sim.gripped()
            .into_iter()
            .map(|p| (p, sim.positions().get(p)))
            .collect()
    };
    let moved = Vec3::new(0.1, 0.2, -0.05);
    sim.drag_to(start[0].1 + moved).unwrap();
    // Once the grip's glide is over (a drag time), every held particle is on its target.
    sim.advance(sim.drag_time()).unwrap();
    sim.step(1).unwrap();
    for &(p, x) in &start {
        assert_eq!(sim.positions().get(p), x + moved, "particle {p}");
    }
    // The cloth around the patch follows it.
    let outside = centre + 4;
    assert!(sim.positions().get(outside).y > 0.0);
    sim.release();
    assert_eq!(sim.grabbed(), None);
    assert!(sim.gripped().is_empty());
    let particles = sim.particles();
    for &(p, _) in &start {
        let pinned_before = p == pinned || p == kinematic;
        assert_eq!(particles.pinned[p], pinned_before, "particle {p}");
    }
    assert_eq!(sim.snapshot().targets, vec![(kinematic, kept)]);
}

#[test]
fn a_drag_back_to_the_start_puts_every_held_particle_exactly_where_it_was() {
    let mut sim = sheet();
    let centre = 10 * 21 + 10;
    sim.grab(centre as i64).unwrap();
    let start: Vec<Vec3> = sim
        .gripped()
        .iter()
        .map(|&p| sim.positions().get(p))
        .collect();
    sim.drag_to(start[0] + Vec3::new(0.3, 0.1, 0.0)).unwrap();
    sim.step(3).unwrap();
    sim.drag_to(start[0]).unwrap();
    sim.advance(sim.drag_time()).unwrap();
    sim.step(1).unwrap();
    let now: Vec<Vec3> = sim
        .gripped()
        .iter()
        .map(|&p| sim.positions().get(p))
        .collect();
    assert_eq!(now, start);
}

/// The `hanging` scene at 24 x 20: pinned at its two top corners, no tearing.
fn hanging() -> Simulation {
    let mut sim = Simulation::new(builtin_scene(
        "hanging",
        IntegratorKind::SymplecticEuler,
        24,
        20,
    ))
    .unwrap();
    sim.advance(0.3).unwrap();
    sim
}

#[test]
fn a_drag_without_tearing_moves_the_patch_and_the_cloth_without_plucking() {
    let mut sim = hanging();
    let corner = 0;
    sim.grab(corner as i64).unwrap();
    let held = sim.gripped();
    assert!(held.len() > 1);
    let start = sim.positions().get(corner);
    let near = 2 * 24 + 4; // two rows up, four across: outside the grip
    assert!(!held.contains(&near));
    let near_start = sim.positions().get(near);
    // Half a metre down and out over half a second, as the demo's frames would.
    for f in 1..=30 {
        let to = start + Vec3::new(-0.3, -0.4, 0.0) * (f as f32 / 30.0);
        sim.drag_to(to).unwrap();
        sim.advance(1.0 / 60.0).unwrap();
    }
    assert_eq!(sim.pieces(), 1);
    let followed = sim.positions().get(near) - near_start;
    assert!(
        followed.length() > 0.25,
        "the cloth beside the grip moved only {followed}"
    );
    sim.release();
    sim.advance(0.5).unwrap();
    assert_eq!(sim.pieces(), 1);
    assert!((0..sim.grid().len()).all(|p| sim.positions().get(p).is_finite()));
}

/// The grip survives a snapshot: the restored simulation continues the drag bit for bit.
#[test]
fn a_restored_grip_continues_bit_for_bit() {
    let mut a = hanging();
    a.set_grip_radius(0.15).unwrap();
    a.grab(3).unwrap();
    let start = a.positions().get(3);
    a.drag_to(start + Vec3::new(0.0, -0.05, 0.05)).unwrap();
    a.step(20).unwrap();
    let mut b = Simulation::restore(a.snapshot()).unwrap();
    assert_eq!(b.gripped(), a.gripped());
    assert_eq!(b.grip_radius(), a.grip_radius());
    for sim in [&mut a, &mut b] {
        sim.drag_to(start + Vec3::new(0.1, -0.1, 0.0)).unwrap();
        sim.step(30).unwrap();
        sim.release();
        sim.step(30).unwrap();
        sim.grab(40).unwrap();
    }
    assert_eq!(state_hash(&a), state_hash(&b));
    assert_eq!(a.gripped(), b.gripped());
}

/// A change that makes a snapshot bad.
type Spoil = Box<dyn Fn(&mut rustcloth::snapshot::Snapshot)>;

#[test]
fn a_snapshot_with_a_bad_grip_is_refused_by_name() {
    let mut sim = hanging();
    sim.grab(3).unwrap();
    let good = sim.snapshot();
    assert!(!good.grip.is_empty());
    let n = sim.grid().len();
    let cases: Vec<(&str, Spoil)> = vec![
        ("grip[0]", Box::new(move |s| s.grip[0].0 = n)),
        ("grip[0]", Box::new(|s| s.grip[0].3 = Vec3::NAN)),
        ("grip[0]", Box::new(|s| s.grip[0].0 = 3)),
        ("grip", Box::new(|s| s.grab = None)),
        ("grip_origin", Box::new(|s| s.grip_origin = None)),
        (
            "grip_origin",
            Box::new(|s| s.grip_origin = Some(Vec3::INFINITY)),
        ),
        ("grip_radius", Box::new(|s| s.grip_radius = Some(-1.0))),
    ];
    for (name, spoil) in cases {
        let mut bad = good.clone();
        spoil(&mut bad);
        let err = Simulation::restore(bad).err().expect(name).to_string();
        assert!(err.contains(name), "{name}: {err}");
    }
}

/// The tear scene's corner, dragged as the demo drags it, comes away with at least the grip,
/// not one particle (tests/test_grip.py checks that the rip runs along the scene's
/// perforation).
#[test]
fn a_drag_of_tear_pulls_out_the_grip_not_a_pinhole() {
    let mut sim = Simulation::new(Scene::builtin("tear").unwrap()).unwrap();
    sim.advance(0.5).unwrap();
    sim.grab(0).unwrap();
    let held = sim.gripped();
    let start = sim.positions().get(0);
    for f in 1..=90 {
        let to = start + Vec3::new(-0.6, -0.6, 0.0) * (f as f32 / 90.0);
        sim.drag_to(to).unwrap();
        sim.advance(1.0 / 60.0).unwrap();
    }
    assert!(sim.pieces() >= 2, "the drag tore nothing");
    let labels = sim.piece_labels();
    let piece = labels[0];
    let size = labels.iter().filter(|&&l| l == piece).count();
    assert!(held.iter().all(|&p| labels[p] == piece));
    assert!(size >= held.len(), "{size} particles came away");
}

/// A drag glides the grip from where it is to its target over the drag time, at a constant
/// velocity and rigidly, instead of landing on it in the next substep: a demo's drags arrive
/// once a frame, and a frame's travel in one substep jerks the springs round the grip apart.
#[test]
fn a_drag_glides_the_grip_to_its_target_over_the_drag_time() {
    let mut sim = sheet();
    let centre = 10 * 21 + 10;
    sim.grab(centre as i64).unwrap();
    let held = sim.gripped();
    let start: Vec<Vec3> = held.iter().map(|&p| sim.positions().get(p)).collect();
    let dt = sim.dt();
    sim.set_drag_time(10.0 * dt).unwrap();
    let moved = Vec3::new(0.1, -0.2, 0.05);
    sim.drag_to(start[0] + moved).unwrap();
    for s in 1..=12 {
        sim.step(1).unwrap();
        let f = (s as f32 / 10.0).min(1.0);
        for (&p, &x) in held.iter().zip(&start) {
            let at = sim.positions().get(p);
            assert!(
                (at - (x + moved * f)).length() < 1e-5,
                "step {s}, particle {p}: {at}"
            );
        }
    }
    // On its target to the bit once the glide is over.
    for (&p, &x) in held.iter().zip(&start) {
        assert_eq!(sim.positions().get(p), x + moved, "particle {p}");
    }
    // A new target mid-glide: the grip turns from where it is, arriving a drag time later.
    sim.drag_to(start[0]).unwrap();
    sim.step(5).unwrap();
    let halfway = start[0] + moved * 0.5;
    assert!((sim.positions().get(held[0]) - halfway).length() < 1e-5);
    sim.drag_to(start[0] + moved).unwrap();
    sim.step(11).unwrap(); // a step past the glide's end, whatever the clock's rounding
    assert_eq!(sim.positions().get(held[0]), start[0] + moved);
    // Drag time 0: the grip lands on its target in the next step, as a pin does.
    sim.set_drag_time(0.0).unwrap();
    sim.drag_to(start[0]).unwrap();
    sim.step(1).unwrap();
    assert_eq!(sim.positions().get(held[0]), start[0]);
    for bad in [-1.0, f64::NAN, f64::INFINITY] {
        let err = sim.set_drag_time(bad).unwrap_err().to_string();
        assert!(err.contains("drag_time"), "{err}");
    }
}
