//! Self-collision turned on and off at run time (`Simulation::set_self_collision`, the demo's
//! C key): the state carries over bit for bit, a simulation toggled at its start steps exactly
//! as one built from the scene with or without `[self_collision]`, and settings the scene would
//! refuse change nothing.

use crate::common;

use common::{at_1ms, bare_scene, state_hash};
use rustcloth::scene::SelfCollisionSpec;
use rustcloth::{Error, Scene, Simulation};

fn pile() -> Scene {
    at_1ms("pile")
}

fn stepped(scene: Scene, steps: u64) -> Simulation {
    let mut sim = Simulation::new(scene).unwrap();
    sim.step(steps).unwrap();
    sim
}

#[test]
fn turning_self_collision_off_steps_as_the_scene_without_it() {
    let mut without = pile();
    without.self_collision = None;
    let mut toggled = Simulation::new(pile()).unwrap();
    toggled.set_self_collision(None).unwrap();
    assert!(!toggled.effects().contains(&"self_collision"));
    assert_eq!(toggled.scene().self_collision, None);
    toggled.step(400).unwrap();
    assert_eq!(state_hash(&toggled), state_hash(&stepped(without, 400)));
}

#[test]
fn turning_self_collision_on_steps_as_the_scene_with_it() {
    let spec = pile().self_collision.unwrap();
    let mut without = pile();
    without.self_collision = None;
    let mut toggled = Simulation::new(without).unwrap();
    toggled.set_self_collision(Some(spec.clone())).unwrap();
    assert!(toggled.effects().contains(&"self_collision"));
    assert_eq!(toggled.scene().self_collision, Some(spec));
    toggled.step(400).unwrap();
    let with = stepped(pile(), 400);
    assert_eq!(state_hash(&toggled), state_hash(&with));
    // And the pass did something: the same steps without it end elsewhere.
    let mut off = pile();
    off.self_collision = None;
    assert_ne!(state_hash(&with), state_hash(&stepped(off, 400)));
}

#[test]
fn off_and_on_again_mid_run_continues_bit_for_bit() {
    // Mid-fall, with a grip held and a tear's worth of topology: everything carries over.
    let mut toggled = stepped(pile(), 300);
    let mut untouched = stepped(pile(), 300);
    for sim in [&mut toggled, &mut untouched] {
        sim.grab(5).unwrap();
        sim.step(20).unwrap();
    }
    let spec = toggled.scene().self_collision.clone();
    toggled.set_self_collision(None).unwrap();
    toggled.set_self_collision(spec).unwrap();
    assert_eq!(toggled.gripped(), untouched.gripped());
    assert_eq!(toggled.steps(), untouched.steps());
    for sim in [&mut toggled, &mut untouched] {
        sim.step(200).unwrap();
    }
    assert_eq!(state_hash(&toggled), state_hash(&untouched));
}

#[test]
fn settings_the_scene_would_refuse_change_nothing() {
    let mut sim = stepped(pile(), 100);
    let (hash, effects) = (state_hash(&sim), sim.effects());
    let before = sim.scene().self_collision.clone();
    // Half the grid spacing is 1 / 31 / 2 m: a thicker gap would start in contact.
    for (bad, key) in [
        (0.1, "self_collision.thickness"),
        (-1.0, "self_collision.thickness"),
        (f64::NAN, "self_collision.thickness"),
    ] {
        let spec = SelfCollisionSpec {
            thickness: bad,
            ..SelfCollisionSpec::default()
        };
        let err = sim.set_self_collision(Some(spec)).unwrap_err();
        assert!(matches!(err, Error::InvalidValue { .. }), "{err:?}");
        assert!(err.to_string().starts_with(key), "{err}");
    }
    let spec = SelfCollisionSpec {
        iterations: 0,
        ..SelfCollisionSpec::default()
    };
    let err = sim.set_self_collision(Some(spec)).unwrap_err();
    assert!(
        err.to_string().starts_with("self_collision.iterations"),
        "{err}"
    );
    assert_eq!(state_hash(&sim), hash);
    assert_eq!(sim.effects(), effects);
    assert_eq!(sim.scene().self_collision, before);
    assert_eq!(sim.steps(), 100);
}

#[test]
fn a_cloth_without_self_collision_takes_the_defaults_when_they_fit() {
    let mut sim = Simulation::new(bare_scene(8, 8)).unwrap();
    sim.set_self_collision(Some(SelfCollisionSpec::default()))
        .unwrap();
    assert!(sim.effects().contains(&"self_collision"));
    sim.step(10).unwrap();
    assert!(sim.self_collision_stats().is_some());
}
