//! Golden states: digests of the state after fixed runs of every integrator, with and without
//! colliders, strain limiting, the watchdog, picking, dragging and cuts, checked against
//! `tests/golden/state_digests.txt`.
//!
//! The digests pin the solver's behaviour to the bit. A refactor must leave every one unchanged;
//! a change that is meant to alter behaviour updates the file in the same commit and says
//! which digests moved and why. Regenerate with
//! `GOLDEN_UPDATE=1 cargo test --release --test integration golden::`.

use crate::common;

use std::fmt::Write as _;

use common::{bare_scene, builtin_scene, with_threads};
use glam::Vec3;
use rustcloth::scene::{FloorSpec, OnTrouble, PinSpec, Plane, SphereSpec, StrainLimitSpec};
use rustcloth::IntegratorKind;
use rustcloth::{Scene, Simulation};

const GOLDEN: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/golden/state_digests.txt"
);

/// FNV-1a over 64 bits: stable across Rust versions, unlike `DefaultHasher`.
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
}

/// Every bit of the state a user can observe: positions, velocities, step count, which
/// particles are alive and pinned, and how the run ended.
fn digest(sim: &Simulation, outcome: &rustcloth::Result<()>) -> String {
    let mut h = Fnv::new();
    for v in [sim.positions(), sim.velocities()] {
        for c in [&v.x, &v.y, &v.z] {
            for x in c.iter() {
                h.bytes(&x.to_bits().to_le_bytes());
            }
        }
    }
    h.bytes(&sim.steps().to_le_bytes());
    let particles = sim.particles();
    for p in 0..particles.len() {
        h.bytes(&[particles.alive[p] as u8, particles.pinned[p] as u8]);
    }
    match outcome {
        Ok(()) => h.bytes(b"ok"),
        Err(e) => h.bytes(e.to_string().as_bytes()),
    }
    format!("{:016x}", h.0)
}

/// A 24 x 20 horizontal cloth hung by two corners, with drag.
fn hanging(integrator: IntegratorKind) -> Scene {
    let mut scene = builtin_scene("hanging", integrator, 24, 20);
    scene.air_drag = 0.0005;
    // Explicit Euler survives only with enough damping and a short step.
    if integrator == IntegratorKind::ExplicitEuler {
        scene.cloth.damping = 0.05;
        scene.substeps = 4;
    }
    scene
}

/// A cloth dropped onto a sphere that stands on the floor.
fn drape(integrator: IntegratorKind) -> Scene {
    let mut scene = builtin_scene("drape", integrator, 24, 24);
    if integrator == IntegratorKind::ExplicitEuler {
        scene.cloth.damping = 0.05;
        scene.substeps = 4;
    }
    scene
}

fn run(mut sim: Simulation, steps: u64) -> String {
    let outcome = sim.step(steps);
    digest(&sim, &outcome)
}

type Case = (String, Box<dyn Fn() -> String>);

fn cases() -> Vec<Case> {
    let mut out: Vec<Case> = Vec::new();
    for integrator in IntegratorKind::ALL {
        let name = |what: &str| format!("{what}/{integrator}");
        out.push((
            name("hanging"),
            Box::new(move || run(Simulation::new(hanging(integrator)).unwrap(), 300)),
        ));
        out.push((
            name("drape_floor_sphere"),
            Box::new(move || run(Simulation::new(drape(integrator)).unwrap(), 600)),
        ));
        out.push((
            name("substeps_3"),
            Box::new(move || {
                let mut scene = hanging(integrator);
                scene.substeps *= 3;
                run(Simulation::new(scene).unwrap(), 100)
            }),
        ));
        out.push((
            name("strain_limit"),
            Box::new(move || {
                let mut scene = drape(integrator);
                scene.strain_limit = Some(StrainLimitSpec {
                    max_strain: 0.05,
                    iterations: 3,
                });
                run(Simulation::new(scene).unwrap(), 400)
            }),
        ));
        out.push((
            name("watchdog_substep_retries"),
            Box::new(move || {
                // Too stiff for the step: the watchdog retries with more substeps.
                let mut scene = bare_scene(12, 12);
                scene.integrator = integrator;
                scene.gravity = [0.0, -9.81, 0.0];
                scene.cloth.k_structural = 4000.0;
                scene.cloth.damping = 0.05;
                scene.cloth.pins = vec![PinSpec::Named("top_edge".into())];
                scene.cloth.plane = Plane::Xy;
                scene.dt = 1.0 / 240.0;
                scene.watchdog.max_stretch = Some(1.5);
                scene.watchdog.on_trouble = OnTrouble::Substep;
                scene.watchdog.max_substeps = 256;
                scene.watchdog.hold_steps = 5;
                let mut sim = Simulation::new(scene).unwrap();
                let outcome = sim.step(60);
                format!(
                    "{} retried={}",
                    digest(&sim, &outcome),
                    sim.watchdog_stats().retried
                )
            }),
        ));
        out.push((
            name("pick_drag_cut"),
            Box::new(move || {
                let mut sim = Simulation::new(hanging(integrator)).unwrap();
                let mut outcome = sim.step(50);
                // Grab what a ray from the front hits, drag it, let go, cut a stroke. A grip of
                // radius 0 holds the one particle, as a grab did before grips, and a drag time
                // of 0 lands it on each target in the next substep, as a drag did before
                // glides: bitwise the same.
                let hit = sim.pick(Vec3::new(0.05, 3.0, 0.1), Vec3::NEG_Y).unwrap();
                let p = hit.expect("the ray hits the cloth").index;
                sim.set_grip_radius(0.0).unwrap();
                sim.set_drag_time(0.0).unwrap();
                sim.grab(p as i64).unwrap();
                for k in 0..20 {
                    sim.drag_to(Vec3::new(0.05 + 0.01 * k as f32, 1.2, 0.3))
                        .unwrap();
                    outcome = outcome.and(sim.step(5));
                }
                sim.release();
                let rays: Vec<(Vec3, Vec3)> = (0..12)
                    .map(|k| (Vec3::new(-0.3 + 0.05 * k as f32, 3.0, -0.2), Vec3::NEG_Y))
                    .collect();
                sim.cut_stroke(&rays).unwrap();
                sim.cut(7).unwrap();
                outcome = outcome.and(sim.step(100));
                digest(&sim, &outcome)
            }),
        ));
        out.push((
            name("many_chunks_3_threads"),
            Box::new(move || {
                // 100 x 64 particles: several parallel chunks, on three threads.
                let mut scene = drape(integrator);
                scene.cloth.nx = 100;
                scene.cloth.ny = 64;
                scene.cloth.particle_mass = Some(0.0005);
                scene.floor = Some(FloorSpec::default());
                scene.spheres = vec![SphereSpec::default()];
                with_threads(3, || run(Simulation::new(scene).unwrap(), 80))
            }),
        ));
    }
    out
}

#[test]
fn golden_states_are_unchanged() {
    let mut report = String::new();
    for (name, case) in cases() {
        writeln!(report, "{name} {}", case()).unwrap();
    }
    if std::env::var_os("GOLDEN_UPDATE").is_some() {
        std::fs::write(GOLDEN, &report).unwrap();
        return;
    }
    let expected = std::fs::read_to_string(GOLDEN).expect("tests/golden/state_digests.txt");
    let changed: Vec<String> = expected
        .lines()
        .zip(report.lines())
        .filter(|(a, b)| a != b)
        .map(|(a, b)| format!("  expected {a}\n  got      {b}"))
        .collect();
    assert!(
        changed.is_empty() && expected.lines().count() == report.lines().count(),
        "{} golden state(s) changed:\n{}",
        changed.len(),
        changed.join("\n")
    );
}
