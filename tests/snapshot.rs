//! A snapshot continues bit for bit (simulations cross process
//! boundaries): a run saved and restored at any point goes on exactly as the original, with
//! every integrator, substeps, the watchdog's retries and hold, strain limiting, kinematic
//! pins, a grab, cuts and `advance`'s remainder.

use crate::common;

use common::{builtin_scene, state_hash};
use glam::Vec3;
use rustcloth::scene::{FloorSpec, OnTrouble, SphereSpec, StrainLimitSpec};
use rustcloth::IntegratorKind;
use rustcloth::{Error, Scene, Simulation};

fn busy_scene(integrator: IntegratorKind) -> Scene {
    let mut scene = builtin_scene("hanging", integrator, 20, 16);
    scene.cloth.k_structural = 20000.0;
    scene.dt = 1.0 / 200.0;
    scene.substeps = 2;
    scene.floor = Some(FloorSpec {
        height: 0.9,
        ..FloorSpec::default()
    });
    scene.spheres = vec![SphereSpec {
        center: [0.0, 1.2, 0.0],
        ..SphereSpec::default()
    }];
    scene.strain_limit = Some(StrainLimitSpec::default());
    scene.watchdog.max_stretch = Some(1.3);
    scene.watchdog.on_trouble = OnTrouble::Substep;
    scene.watchdog.hold_steps = 7;
    if integrator == IntegratorKind::ExplicitEuler {
        scene.cloth.damping = 0.1;
    }
    scene
}

/// Drives `sim` through steps, drags, a cut and part-steps of `advance`.
fn drive(sim: &mut Simulation, phase: u32) -> String {
    let mut log = String::new();
    for k in 0..4 {
        let r = match (phase + k) % 4 {
            0 => sim.step(7).map(|()| 7),
            1 => sim.advance(0.0123),
            2 => sim
                .drag_to(Vec3::new(-0.24, 1.45 + 0.01 * k as f32, -0.5))
                .and_then(|()| sim.step(3).map(|()| 3)),
            _ => sim.cut(25 + k as i64).and_then(|()| sim.advance(0.004)),
        };
        log += &format!("{r:?};");
    }
    log
}

#[test]
fn a_restored_snapshot_continues_bit_for_bit() {
    let mut retried = 0;
    for integrator in IntegratorKind::ALL {
        let mut a = Simulation::new(busy_scene(integrator)).unwrap();
        a.grab(5).unwrap();
        let at = a.positions().get(300);
        a.pin(300, Some(at + Vec3::new(0.0, 0.01, 0.0))).unwrap();
        a.set_pick_radius(0.03).unwrap();
        drive(&mut a, 0);
        let mut b = Simulation::restore(a.snapshot()).unwrap();
        assert_eq!(
            b.snapshot(),
            a.snapshot(),
            "{integrator}: restore(snapshot) differs"
        );
        let (log_a, log_b) = (drive(&mut a, 1), drive(&mut b, 1));
        assert_eq!(log_a, log_b, "{integrator}");
        assert_eq!(state_hash(&a), state_hash(&b), "{integrator}");
        assert_eq!(a.time().to_bits(), b.time().to_bits());
        assert_eq!(a.watchdog_stats(), b.watchdog_stats());
        assert_eq!(a.grabbed(), b.grabbed());
        retried += a.watchdog_stats().retried;
    }
    // The scene is stiff enough that the watchdog's retries and hold are part of the test.
    assert!(retried > 0);
}

/// A change that makes a snapshot invalid.
type Spoil = Box<dyn Fn(&mut rustcloth::snapshot::Snapshot)>;

#[test]
fn a_bad_snapshot_is_refused_naming_the_part() {
    let sim = Simulation::new(busy_scene(IntegratorKind::Verlet)).unwrap();
    let cases: Vec<(&str, Spoil)> = vec![
        ("positions", Box::new(|s| s.positions.x[3] = f32::NAN)),
        (
            "velocities",
            Box::new(|s| s.velocities = rustcloth::soa::Vec3s::zeros(3)),
        ),
        ("masses[2]", Box::new(|s| s.masses[2] = -1.0)),
        ("alive", Box::new(|s| s.alive.pop().map(|_| ()).unwrap())),
        ("springs[0]", Box::new(|s| s.springs[0][19] = true)),
        ("targets", Box::new(|s| s.targets.push((7, Vec3::ONE)))),
        ("grab", Box::new(|s| s.grab = Some((10_000, false, None)))),
        ("accumulator", Box::new(|s| s.accumulator = -1.0)),
        // A cascade's hold longer than the scene's hold_steps (7).
        (
            "watchdog.cascade_hold",
            Box::new(|s| s.watchdog.cascade_hold = 8),
        ),
        ("dt", Box::new(|s| s.scene.dt = 0.0)),
    ];
    for (name, spoil) in cases {
        let mut snapshot = sim.snapshot();
        spoil(&mut snapshot);
        match Simulation::restore(snapshot) {
            Err(Error::InvalidValue { name: got, .. }) => assert_eq!(got, name),
            other => panic!("{name}: {:?}", other.map(|_| ())),
        }
    }
}
