//! The solver against analytic solutions and invariants of the model.

use crate::common;

use common::*;
use glam::{Quat, Vec3};
use rustcloth::scene::{FloorSpec, SphereSpec};
use rustcloth::simulation::total_force;
use rustcloth::soa::Vec3s;
use rustcloth::IntegratorKind;
use rustcloth::{Scene, Simulation};

#[test]
fn free_fall_matches_the_discrete_closed_form_of_each_integrator() {
    // x_n = x_0 + h^2 g n (n + 1) / 2 for symplectic Euler (the new velocity moves the
    // particle), n (n - 1) / 2 for explicit Euler (the old one does).
    for (integrator, lag) in [
        (IntegratorKind::SymplecticEuler, 1.0),
        (IntegratorKind::ExplicitEuler, -1.0),
    ] {
        let mut scene = bare_scene(8, 8);
        scene.integrator = integrator;
        scene.gravity = [0.0, -9.81, 0.0];
        let mut sim = Simulation::new(scene).unwrap();
        let y0 = position(&sim, 0).y as f64;
        let n = 500u64;
        sim.step(n).unwrap();
        let h = sim.dt();
        let expected =
            y0 - 9.81 * h * h * (n * n) as f64 / 2.0 - lag * 9.81 * h * h * n as f64 / 2.0;
        for p in 0..64 {
            let y = position(&sim, p).y as f64;
            assert!(
                (y - expected).abs() < 2e-5,
                "{integrator}: particle {p} at {y}, expected {expected}"
            );
        }
        let v = sim.velocities().get(0).y as f64;
        assert!(
            (v + 9.81 * h * n as f64).abs() < 1e-4,
            "{integrator}: v = {v}"
        );
    }
}

#[test]
fn a_two_particle_spring_oscillates_with_period_two_pi_sqrt_m_over_k() {
    let (k, m) = (50.0f64, 0.02f64);
    let expected = 2.0 * std::f64::consts::PI * (m / k).sqrt();
    for integrator in [
        IntegratorKind::SymplecticEuler,
        IntegratorKind::ExplicitEuler,
    ] {
        let mut sim = two_particle_spring(k, m, integrator, 1e-5);
        sim.pin(0, None).unwrap();
        // Stretch by 1 cm and let go.
        let mut pos = sim.positions().clone();
        pos.x[1] = 1.01;
        sim.set_positions(&pos).unwrap();
        // Time the upward zero crossings of the displacement over three periods.
        let mut crossings = Vec::new();
        let mut prev = 0.01f64;
        while crossings.len() < 4 {
            sim.step(1).unwrap();
            let d = position(&sim, 1).x as f64 - 1.0;
            if prev < 0.0 && d >= 0.0 {
                // Linear interpolation between the two samples.
                crossings.push(sim.time() - sim.dt() * d / (d - prev));
            }
            prev = d;
            assert!(sim.time() < 10.0 * expected, "{integrator}: no oscillation");
        }
        let period = (crossings[3] - crossings[0]) / 3.0;
        let error = (period - expected).abs() / expected;
        assert!(
            error < 2e-3,
            "{integrator}: period {period}, expected {expected}"
        );
    }
}

#[test]
fn springs_exert_no_force_at_rest_nor_under_rigid_motion() {
    let mut scene = bare_scene(12, 9);
    scene.cloth.damping = 0.5;
    let mut sim = Simulation::new(scene).unwrap();
    let at_rest = total_force(&mut sim);
    for p in 0..sim.grid().len() {
        assert!(
            at_rest.get(p).length() < 1e-4,
            "particle {p}: {}",
            at_rest.get(p)
        );
    }
    // A rigid rotation about an arbitrary point with a rigid angular velocity: no stretch and
    // no closing speed along any spring.
    let rotation = Quat::from_axis_angle(Vec3::new(1.0, 2.0, -0.5).normalize(), 1.1);
    let pivot = Vec3::new(0.3, -2.0, 1.0);
    let omega = Vec3::new(0.4, -1.5, 2.0);
    let pos0 = sim.positions().clone();
    let pos = Vec3s::from_fn(pos0.len(), |p| pivot + rotation * (pos0.get(p) - pivot));
    let vel = Vec3s::from_fn(pos0.len(), |p| omega.cross(pos.get(p) - pivot));
    sim.set_positions(&pos).unwrap();
    sim.set_velocities(&vel).unwrap();
    let rotated = total_force(&mut sim);
    for p in 0..sim.grid().len() {
        // k = 200 N/m: 1e-3 N is a length error of 5 micrometres, f32 rounding of ~1 m.
        assert!(
            rotated.get(p).length() < 1e-3,
            "particle {p}: {}",
            rotated.get(p)
        );
    }
}

#[test]
fn spring_forces_conserve_momentum() {
    let mut sim = Simulation::new(bare_scene(10, 10)).unwrap();
    let n = sim.grid().len();
    let vel = Vec3s::from_fn(n, |p| {
        Vec3::new(
            (p % 7) as f32 - 3.0,
            (p % 5) as f32 * 0.3,
            (p % 3) as f32 - 1.0,
        )
    });
    sim.set_velocities(&vel).unwrap();
    let momentum = |sim: &Simulation| {
        (0..n)
            .map(|p| sim.velocities().get(p).as_dvec3())
            .sum::<glam::DVec3>()
    };
    let before = momentum(&sim);
    sim.step(200).unwrap();
    let after = momentum(&sim);
    assert!((after - before).length() < 1e-3, "{before} -> {after}");
}

#[test]
fn elastic_energy_of_a_stretched_spring_is_half_k_x_squared() {
    let mut sim = two_particle_spring(80.0, 0.01, IntegratorKind::SymplecticEuler, 1e-3);
    let mut pos = sim.positions().clone();
    pos.x[1] = 1.25;
    sim.set_positions(&pos).unwrap();
    let e = sim.energy();
    assert!((e.elastic - 0.5 * 80.0 * 0.25 * 0.25).abs() < 1e-5, "{e:?}");
    assert_eq!(e.kinetic, 0.0);
}

#[test]
fn pinned_particles_stay_bitwise_put() {
    let mut sim = Simulation::new(Scene::builtin("hanging").unwrap()).unwrap();
    let pinned: Vec<usize> = (0..sim.grid().len())
        .filter(|&p| sim.particles().pinned[p])
        .collect();
    assert_eq!(pinned.len(), 2);
    let before: Vec<[u32; 3]> = pinned
        .iter()
        .map(|&p| position(&sim, p).to_array().map(f32::to_bits))
        .collect();
    sim.step(400).unwrap();
    let after: Vec<[u32; 3]> = pinned
        .iter()
        .map(|&p| position(&sim, p).to_array().map(f32::to_bits))
        .collect();
    assert_eq!(before, after);
    // The cloth itself did move.
    assert!(position(&sim, 0).y < 1.0);
}

#[test]
fn a_kinematic_pin_carries_its_particle_to_the_target() {
    let mut sim = Simulation::new(Scene::builtin("hanging").unwrap()).unwrap();
    let target = Vec3::new(0.2, 2.0, -0.1);
    sim.pin(5, Some(target)).unwrap();
    assert!(sim.effects().contains(&"kinematic_pins"));
    sim.step(3).unwrap();
    assert_eq!(position(&sim, 5), target);
    sim.unpin(5).unwrap();
    assert!(!sim.effects().contains(&"kinematic_pins"));
}

fn assert_outside_colliders(sim: &Simulation, floor: f32, sphere: Option<(Vec3, f32)>) {
    for p in 0..sim.grid().len() {
        let x = position(sim, p);
        assert!(x.is_finite());
        assert!(x.y >= floor, "particle {p} below the floor: {x}");
        if let Some((c, r)) = sphere {
            assert!((x - c).length() >= r, "particle {p} inside the sphere: {x}");
        }
    }
}

#[test]
fn fast_particles_never_end_a_step_inside_the_floor_or_a_sphere() {
    let center = Vec3::new(0.0, 0.3, 0.0);
    let mut scene = scene_under_gravity(24, 24);
    scene.cloth.center = [0.0, 1.0, 0.0];
    scene.floor = Some(FloorSpec {
        height: 0.0,
        friction: 0.3,
        thickness: 0.002,
    });
    scene.spheres = vec![SphereSpec {
        center: center.as_dvec3().to_array(),
        radius: 0.1,
        friction: 0.2,
        thickness: 0.001,
    }];
    for speed in [10.0f32, 100.0, 700.0] {
        let mut sim = Simulation::new(scene.clone()).unwrap();
        let n = sim.grid().len();
        let start = sim.positions().clone();
        sim.set_velocities(&Vec3s::from_fn(n, |_| Vec3::new(0.0, -speed, 0.0)))
            .unwrap();
        for _ in 0..40 {
            sim.step(1).unwrap();
            assert_outside_colliders(&sim, 0.002, Some((center, 0.101)));
        }
        // At 700 m/s a particle crosses the 0.2 m sphere in 0.3 ms, well inside one step: the
        // ones that fell onto its top must still be above it, not through it. (Particles that
        // hit it nearer its rim slide round it, and the cloth can pull them in underneath.)
        for p in 0..n {
            let (x, x0) = (position(&sim, p), start.get(p));
            if (x0.x - center.x).hypot(x0.z - center.z) < 0.05 {
                assert!(
                    x.y > center.y,
                    "speed {speed}: particle {p} tunnelled to {x}"
                );
            }
        }
    }
}

#[test]
fn a_sphere_the_cloth_never_reaches_changes_nothing() {
    let mut scene = Scene::builtin("hanging").unwrap();
    let plain = Simulation::new(scene.clone());
    scene.spheres = vec![SphereSpec {
        center: [50.0, 0.0, 0.0],
        radius: 1.0,
        ..SphereSpec::default()
    }];
    let mut with_sphere = Simulation::new(scene).unwrap();
    let mut plain = plain.unwrap();
    for _ in 0..20 {
        plain.step(25).unwrap();
        with_sphere.step(25).unwrap();
        assert_eq!(state_hash(&plain), state_hash(&with_sphere));
    }
    assert!(with_sphere.effects().contains(&"spheres"));
}

#[test]
fn only_requested_effects_run() {
    let mut scene = bare_scene(4, 4);
    scene.cloth.k_bend = 0.0;
    let sim = Simulation::new(scene.clone()).unwrap();
    assert_eq!(
        sim.effects(),
        ["structural_springs", "shear_springs", "symplectic_euler"]
    );
    scene.gravity = [0.0, -1.0, 0.0];
    scene.air_drag = 0.1;
    scene.cloth.k_bend = 1.0;
    scene.floor = Some(FloorSpec::default());
    scene.spheres = vec![SphereSpec::default()];
    let sim = Simulation::new(scene).unwrap();
    assert_eq!(
        sim.effects(),
        [
            "gravity",
            "air_drag",
            "structural_springs",
            "shear_springs",
            "bend_springs",
            "symplectic_euler",
            "spheres",
            "floor"
        ]
    );
}

/// One free particle (a 2 x 2 grid with three particles cut) at `start` with velocity `v0`,
/// under gravity, on the floor (`floor`) or a sphere (`sphere`), each with `friction`.
fn slider(start: Vec3, v0: Vec3, floor: Option<f64>, sphere: Option<(Vec3, f64)>) -> Simulation {
    let mut scene = scene_under_gravity(2, 2);
    if let Some(friction) = floor {
        scene.floor = Some(FloorSpec {
            height: 0.0,
            friction,
            thickness: 0.0,
        });
    }
    if let Some((center, friction)) = sphere {
        scene.spheres = vec![SphereSpec {
            center: center.as_dvec3().to_array(),
            radius: center.length() as f64,
            friction,
            thickness: 0.0,
        }];
    }
    lone_particle(scene, start, v0)
}

/// Steps until particle 0 stops (or 5 s pass); returns the time (s) and distance (m) it slid.
fn slide(sim: &mut Simulation) -> (f64, f64) {
    let start = position(sim, 0);
    for _ in 0..5000 {
        sim.step(1).unwrap();
        let v = sim.velocities().get(0);
        if v.x == 0.0 && v.z == 0.0 {
            break;
        }
    }
    let d = position(sim, 0) - start;
    (sim.time(), (d.x as f64).hypot(d.z as f64))
}

#[test]
fn a_sliding_particle_decelerates_at_mu_g_on_the_floor() {
    // Nothing tested the floor's friction coefficient: halving it broke no test. A particle
    // sliding at v0 on a level floor loses mu g of speed per second (Coulomb friction with the
    // normal force m g), so it stops after v0 / (mu g) and v0^2 / (2 mu g). One step of dt of
    // discretisation error on each.
    let (v0, g, dt) = (1.5f64, 9.81f64, 0.001f64);
    for mu in [0.15, 0.3, 0.6] {
        let mut sim = slider(Vec3::ZERO, Vec3::new(v0 as f32, 0.0, 0.0), Some(mu), None);
        let (t, d) = slide(&mut sim);
        let (t_stop, d_stop) = (v0 / (mu * g), v0 * v0 / (2.0 * mu * g));
        assert!(
            (t - t_stop).abs() <= 2.0 * dt,
            "mu {mu}: stopped at {t} s, expected {t_stop}"
        );
        assert!(
            (d - d_stop).abs() <= 2.0 * v0 * dt,
            "mu {mu}: slid {d} m, expected {d_stop}"
        );
        assert!(position(&sim, 0).y.abs() < 1e-6, "it stays on the floor");
    }
}

#[test]
fn a_sliding_particle_slows_by_coulomb_friction_on_a_sphere() {
    // A particle started at the top of a 10 m sphere, sliding: on the curved surface the
    // normal force is m (g cos theta - v^2 / R) and gravity pulls it downhill by g sin theta,
    // so along the arc s (theta = s / R) dv/dt = g sin theta - mu (g cos theta - v^2 / R).
    // The stopping time and distance of that ODE, integrated in f64, are the reference; the
    // sphere's friction coefficient must show in them.
    let (g, r) = (9.81f64, 10.0f64);
    let reference = |v0: f64, mu: f64| {
        let (mut s, mut v, mut t, h) = (0.0f64, v0, 0.0f64, 1e-6);
        while v > 0.0 {
            let theta = s / r;
            v += h * (g * theta.sin() - mu * (g * theta.cos() - v * v / r));
            s += h * v;
            t += h;
        }
        (t, s)
    };
    for (v0, mu) in [(1.0, 0.2), (1.0, 0.4), (2.0, 0.4)] {
        let center = Vec3::new(0.0, -r as f32, 0.0);
        let mut sim = slider(
            Vec3::ZERO,
            Vec3::new(0.0, 0.0, v0 as f32),
            None,
            Some((center, mu)),
        );
        let (t, d) = slide(&mut sim);
        let (t_stop, d_stop) = reference(v0, mu);
        // A few steps of the contact's first-order lag (a particle meets the surface a step
        // after it sinks into it): far below what a different friction changes.
        let dt = 0.001;
        assert!(
            (t - t_stop).abs() <= 5.0 * dt,
            "mu {mu}: stopped at {t} s, expected {t_stop}"
        );
        assert!(
            (d - d_stop).abs() <= 5.0 * v0 * dt,
            "mu {mu}: slid {d} m, expected {d_stop}"
        );
    }
}
