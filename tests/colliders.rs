//! The `[[colliders]]` of any shape, static and moving, against physics: nothing ends inside a
//! shape (judged by signed-distance formulas written here, apart from parry), Coulomb friction
//! on a slope, a moving surface carrying what rests on it, and determinism across threads.

use crate::common;

use common::*;
use glam::{DQuat, DVec3, Vec3};
use rustcloth::scene::{ColliderSpec, ShapeKind};
use rustcloth::{Scene, Simulation};

/// Signed distance (m) from `p` to the collider's surface at time `t`, negative inside: the
/// textbook formulas for each shape in its local frame (Quilez's box and cylinder), posed as
/// the scene documents (`center + velocity t`, a turn of `angular_velocity t` after
/// `rotation`).
fn signed_distance(c: &ColliderSpec, p: Vec3, t: f64) -> f64 {
    let center = DVec3::from(c.center) + DVec3::from(c.velocity) * t;
    let rotation = DQuat::from_scaled_axis(DVec3::from(c.angular_velocity) * t)
        * DQuat::from_scaled_axis(DVec3::from(c.rotation));
    let q = rotation.inverse() * (p.as_dvec3() - center);
    match c.shape {
        ShapeKind::Sphere => q.length() - c.radius.unwrap(),
        ShapeKind::Box => {
            let d = q.abs() - DVec3::from(c.half_extents.unwrap());
            d.max(DVec3::ZERO).length() + d.max_element().min(0.0)
        }
        ShapeKind::Capsule => {
            let hh = c.half_height.unwrap();
            (q - DVec3::new(0.0, q.y.clamp(-hh, hh), 0.0)).length() - c.radius.unwrap()
        }
        ShapeKind::Cylinder => {
            let radial = q.x.hypot(q.z) - c.radius.unwrap();
            let axial = q.y.abs() - c.half_height.unwrap();
            radial.max(axial).min(0.0) + radial.max(0.0).hypot(axial.max(0.0))
        }
        ShapeKind::Plane => q.y,
        ShapeKind::Mesh => convex_mesh_distance(
            q,
            c.vertices.as_ref().unwrap(),
            c.triangles.as_ref().unwrap(),
        ),
    }
}

fn shape(shape: ShapeKind) -> ColliderSpec {
    let mut c = ColliderSpec {
        shape,
        center: [0.0; 3],
        ..ColliderSpec::default()
    };
    match shape {
        ShapeKind::Sphere => c.radius = Some(0.25),
        ShapeKind::Box => c.half_extents = Some([0.2, 0.15, 0.25]),
        ShapeKind::Capsule | ShapeKind::Cylinder => {
            c.radius = Some(0.15);
            c.half_height = Some(0.1);
        }
        ShapeKind::Plane => {}
        ShapeKind::Mesh => {
            // The box above, as 12 triangles.
            let (vertices, triangles) = box_mesh([0.2, 0.15, 0.25]);
            c.vertices = Some(vertices);
            c.triangles = Some(triangles);
        }
    }
    c
}

/// Height of the shape's top above its centre, unrotated.
fn top(c: &ColliderSpec) -> f64 {
    match c.shape {
        ShapeKind::Sphere => c.radius.unwrap(),
        ShapeKind::Box => c.half_extents.unwrap()[1],
        ShapeKind::Capsule => c.half_height.unwrap() + c.radius.unwrap(),
        ShapeKind::Cylinder => c.half_height.unwrap(),
        ShapeKind::Plane => 0.0,
        ShapeKind::Mesh => c
            .vertices
            .iter()
            .flatten()
            .map(|v| v[1])
            .fold(f64::MIN, f64::max),
    }
}

/// A free 24 x 24 cloth, 0.8 m across, falling from 0.1 m above `collider`'s top.
fn drop_onto(collider: ColliderSpec) -> Simulation {
    cloth_over(24, 0.8, top(&collider) + 0.1, vec![collider])
}

fn least_distance(sim: &Simulation, c: &ColliderSpec) -> f64 {
    let pos = sim.positions();
    (0..pos.len())
        .map(|p| signed_distance(c, pos.get(p), sim.time()))
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn every_shape_stops_a_falling_cloth() {
    let tilted = ColliderSpec {
        rotation: [0.3, 0.0, 0.2],
        ..shape(ShapeKind::Box)
    };
    for collider in [
        shape(ShapeKind::Sphere),
        shape(ShapeKind::Box),
        tilted,
        shape(ShapeKind::Capsule),
        shape(ShapeKind::Cylinder),
        shape(ShapeKind::Plane),
        ColliderSpec {
            rotation: [0.2, 0.0, -0.1],
            ..shape(ShapeKind::Plane)
        },
        shape(ShapeKind::Mesh),
        ColliderSpec {
            rotation: [0.3, 0.0, 0.2],
            ..shape(ShapeKind::Mesh)
        },
    ] {
        let mut sim = drop_onto(collider.clone());
        assert!(sim.effects().contains(&"colliders"));
        let mut least = f64::INFINITY;
        for _ in 0..800 {
            sim.step(1).unwrap();
            least = least.min(least_distance(&sim, &collider));
        }
        // Every step ends with every particle at least `thickness` out (less a float32
        // rounding of the frame change).
        assert!(
            least >= collider.thickness - 1e-6,
            "{:?}: a particle came within {least} m of the surface",
            collider.shape
        );
        // And the shape held the cloth: the middle particle rests on top, not fallen past (a
        // tilted plane lets it slide downhill, below its centre).
        let middle = sim.positions().get(12 * 24 + 12);
        let d = signed_distance(&collider, middle, sim.time());
        let above = middle.y > 0.0 || collider.shape == ShapeKind::Plane;
        assert!(
            d < collider.thickness + 0.01 && above,
            "{:?}: the middle of the cloth is {d} m off the shape, at {middle}",
            collider.shape
        );
    }
}

/// One free particle (a 2 x 2 grid with three particles cut) at `start`, at rest, under
/// gravity, with `collider`.
fn particle_on(collider: ColliderSpec, start: Vec3, v0: Vec3) -> Simulation {
    let mut scene = scene_under_gravity(2, 2);
    scene.colliders = vec![collider];
    lone_particle(scene, start, v0)
}

#[test]
fn a_particle_on_a_tilted_box_slides_iff_the_slope_beats_friction() {
    // A box tilted about z; the particle starts at rest on the middle of its top face.
    check_slides_iff_the_slope_beats_friction(
        |angle, mu| {
            let collider = ColliderSpec {
                shape: ShapeKind::Box,
                half_extents: Some([2.0, 0.1, 2.0]),
                center: [0.0; 3],
                rotation: [0.0, 0.0, angle],
                friction: mu,
                thickness: 0.0,
                ..ColliderSpec::default()
            };
            let (s, c) = (angle.sin() as f32, angle.cos() as f32);
            let start = Vec3::new(-0.1 * s, 0.1 * c, 0.0);
            (particle_on(collider, start, Vec3::ZERO), start)
        },
        |sim| {
            signed_distance(
                &sim.scene().colliders[0],
                sim.positions().get(0),
                sim.time(),
            )
        },
    );
}

#[test]
fn a_moving_box_carries_the_cloth_resting_on_it() {
    // A cloth lying on a box that moves sideways at 0.5 m/s: friction against the moving
    // surface (not against zero) drags the cloth along until it moves with the box. Without
    // the surface's velocity the box would slide out from under a cloth that stays behind.
    let v = 0.5f64;
    let collider = ColliderSpec {
        shape: ShapeKind::Box,
        half_extents: Some([1.0, 0.1, 1.0]),
        center: [0.0; 3],
        velocity: [v, 0.0, 0.0],
        friction: 0.8,
        ..ColliderSpec::default()
    };
    let top = 0.1 + collider.thickness + 1e-4;
    let mut sim = cloth_over(12, 0.5, top, vec![collider.clone()]);
    sim.step(1000).unwrap();
    let mean_vx = mean_velocity_x(&sim);
    assert!(
        (mean_vx - v).abs() < 0.02 * v,
        "after 1 s the cloth moves at {mean_vx} m/s, the box at {v}"
    );
    // It moved with the box: the middle is still over the box's middle.
    let middle = sim.positions().get(6 * 12 + 6).as_dvec3();
    let box_x = v * sim.time();
    assert!(
        (middle.x - box_x).abs() < 0.05,
        "cloth at x = {}, box at {box_x}",
        middle.x
    );
    assert!(least_distance(&sim, &collider) >= collider.thickness - 1e-6);
}

#[test]
fn a_box_sliding_under_a_particle_drags_it_up_to_speed_by_kinetic_friction() {
    // A particle set at rest on a box moving sideways at 2 m/s: the surface slips under it, and
    // kinetic friction accelerates it at mu g (`v = mu g t`, `x = mu g t^2 / 2`) until it moves
    // with the box, after v / (mu g) = 0.51 s at mu = 0.4; then static friction holds it there,
    // v^2 / (2 mu g) = 0.51 m behind its starting point on the box. Friction against the
    // surface's velocity, not against zero, and at its full coefficient.
    let (v, mu, g) = (2.0f64, 0.4f64, 9.81f64);
    let collider = ColliderSpec {
        shape: ShapeKind::Box,
        half_extents: Some([2.0, 0.1, 2.0]),
        center: [0.0; 3],
        velocity: [v, 0.0, 0.0],
        friction: mu,
        thickness: 0.0,
        ..ColliderSpec::default()
    };
    let mut sim = particle_on(collider, Vec3::new(0.0, 0.1, 0.0), Vec3::ZERO);
    sim.step(250).unwrap();
    let t = sim.time();
    let (p, u) = (sim.positions().get(0).as_dvec3(), sim.velocities().get(0));
    let (speed, moved) = (mu * g * t, 0.5 * mu * g * t * t);
    assert!(
        (u.x as f64 - speed).abs() < 0.02 * speed && (p.x - moved).abs() < 0.02 * moved,
        "at {t} s: at x = {}, moving at {}; kinetic friction says {moved}, {speed}",
        p.x,
        u.x
    );
    sim.step(750).unwrap();
    let (t, p, u) = (
        sim.time(),
        sim.positions().get(0).as_dvec3(),
        sim.velocities().get(0),
    );
    let behind = v * t - p.x;
    let slip = v * v / (2.0 * mu * g);
    assert!(
        (u.x as f64 - v).abs() < 1e-3 * v && (behind - slip).abs() < 0.02 * slip,
        "at {t} s: moving at {}, {behind} m behind its start on the box (slip {slip})",
        u.x
    );
    assert!((p.y - 0.1).abs() < 1e-4, "off the top: {p}");
}

#[test]
fn a_turning_disc_carries_a_particle_around() {
    // A particle set at rest on a cylinder turning about its axis (y) at 2 rad/s, 0.3 m out:
    // the disc slips under it until kinetic friction (mu g) has brought it to the disc's
    // 0.6 m/s, after v / (mu g); then static friction turns it with the disc (the centripetal
    // 1.2 m/s^2 is below mu g). It ends behind its starting point on the disc by the slip,
    // v^2 / (2 mu g) of arc.
    let w = 2.0f64;
    let collider = ColliderSpec {
        shape: ShapeKind::Cylinder,
        radius: Some(1.0),
        half_height: Some(0.05),
        center: [0.0; 3],
        angular_velocity: [0.0, w, 0.0],
        friction: 0.8,
        thickness: 0.0,
        ..ColliderSpec::default()
    };
    let mut sim = particle_on(collider, Vec3::new(0.3, 0.05, 0.0), Vec3::ZERO);
    sim.step(500).unwrap();
    let p = sim.positions().get(0).as_dvec3();
    let (v, mu_g) = (w * 0.3, 0.8 * 9.81);
    let angle = w * sim.time() - v * v / (2.0 * mu_g) / 0.3;
    let expected = DVec3::new(0.3 * angle.cos(), 0.05, -0.3 * angle.sin());
    assert!(
        (p - expected).length() < 0.003,
        "at {p}, expected {expected}"
    );
    let speed = sim.velocities().get(0).as_dvec3().length();
    assert!(
        (speed - v).abs() < 1e-3 * v,
        "moving at {speed}, the disc at {v}"
    );
}

#[test]
fn a_particle_at_300_m_s_does_not_tunnel_through_a_thin_box() {
    // 300 m/s is 0.3 m per step, fifteen times the box's 2 cm: the swept test stops it at
    // the face it came through, whatever the shape's orientation.
    for rotation in [[0.0, 0.0, 0.0], [0.4, 0.1, 0.3]] {
        let collider = ColliderSpec {
            shape: ShapeKind::Box,
            half_extents: Some([1.0, 0.01, 1.0]),
            center: [0.0; 3],
            rotation,
            ..ColliderSpec::default()
        };
        let mut sim = particle_on(collider.clone(), Vec3::new(0.0, 1.0, 0.0), -300.0 * Vec3::Y);
        // The side it came from: above the plane through the middle of the box.
        let up = DQuat::from_scaled_axis(DVec3::from(rotation)) * DVec3::Y;
        for _ in 0..20 {
            sim.step(1).unwrap();
            let p = sim.positions().get(0);
            let d = signed_distance(&collider, p, sim.time());
            assert!(
                p.as_dvec3().dot(up) > 0.0 && d >= collider.thickness - 1e-5,
                "{rotation:?}: at {p}, {d} m from the surface"
            );
        }
    }
}

#[test]
fn a_fast_box_pushes_a_particle_ahead_of_it_not_through_it() {
    // A 2 cm thick box moving at 60 m/s (6 cm per step) into a free particle: the particle
    // stays ahead of the front face and leaves with the box's speed (a frictionless push),
    // rather than ending behind it.
    let v = 60.0f64;
    let collider = ColliderSpec {
        shape: ShapeKind::Box,
        half_extents: Some([0.01, 0.5, 0.5]),
        center: [-0.5, 0.0, 0.0],
        velocity: [v, 0.0, 0.0],
        friction: 0.0,
        ..ColliderSpec::default()
    };
    let mut scene = bare_scene(2, 2);
    scene.colliders = vec![collider.clone()];
    let mut sim = Simulation::new(scene).unwrap();
    for p in 1..4 {
        sim.cut(p).unwrap();
    }
    let mut pos = sim.positions().clone();
    pos.set(0, Vec3::ZERO);
    sim.set_positions(&pos).unwrap();
    for _ in 0..30 {
        sim.step(1).unwrap();
        let p = sim.positions().get(0);
        let front = -0.5 + v * sim.time() + 0.01;
        assert!(
            p.x as f64 >= front + collider.thickness - 1e-4,
            "at t = {}: particle at x = {}, the box's front at {front}",
            sim.time(),
            p.x
        );
    }
    let vx = sim.velocities().get(0).x as f64;
    assert!((vx - v).abs() < 1e-3 * v, "leaves at {vx} m/s");
}

#[test]
fn colliders_give_the_same_bits_on_any_thread_count() {
    let mut collider = shape(ShapeKind::Capsule);
    collider.rotation = [0.0, 0.0, 1.2];
    collider.velocity = [0.1, 0.0, 0.0];
    collider.angular_velocity = [0.0, 1.0, 0.0];
    let run = |threads| {
        with_threads(threads, || {
            let mut sim = drop_onto(collider.clone());
            sim.step(300).unwrap();
            state_hash(&sim)
        })
    };
    let one = run(1);
    assert_eq!(one, run(2));
    assert_eq!(one, run(5));
}

#[test]
fn bad_colliders_are_refused_naming_the_parameter() {
    let cases = [
        ("shape = \"box\"", "colliders[0].half_extents"),
        (
            "shape = \"box\"\nhalf_extents = [1, 0, 1]",
            "colliders[0].half_extents[1]",
        ),
        ("shape = \"sphere\"\nradius = nan", "colliders[0].radius"),
        (
            "shape = \"sphere\"\nradius = 1\nhalf_height = 1",
            "colliders[0].half_height",
        ),
        (
            "shape = \"capsule\"\nradius = 1",
            "colliders[0].half_height",
        ),
        (
            "shape = \"sphere\"\nradius = 1\nfriction = -1",
            "colliders[0].friction",
        ),
        (
            "shape = \"sphere\"\nradius = 1\nthickness = -1",
            "colliders[0].thickness",
        ),
        (
            "shape = \"sphere\"\nradius = 1\nvelocity = [1, inf, 0]",
            "colliders[0].velocity[1]",
        ),
        ("shape = \"sphere\"\nradius = 1e30", "colliders[0].radius"),
        ("shape = \"cone\"", "colliders[0].shape"),
        ("shape = \"sphere\"\nradius = 1\nmass = 1", "colliders[0]"),
    ];
    for (body, name) in cases {
        let text = format!("[[colliders]]\nshape = \"sphere\"\nradius = 1\n[[colliders]]\n{body}");
        let err = Scene::from_toml_str(&text).unwrap_err().to_string();
        let name = name.replace("colliders[0]", "colliders[1]");
        assert!(err.starts_with(&name), "{body:?}: {err}");
    }
    let err = Scene::from_toml_str("colliders = [1]")
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("colliders[0]"), "{err}");
}

#[test]
fn a_scene_without_colliders_has_no_collider_pass_and_round_trips() {
    let scene = Scene::default();
    assert!(!Simulation::new(scene.clone())
        .unwrap()
        .effects()
        .contains(&"colliders"));
    let with = Scene {
        colliders: vec![shape(ShapeKind::Cylinder)],
        ..Scene::default()
    };
    assert_eq!(Scene::from_toml_str(&with.to_toml_string()).unwrap(), with);
}

#[test]
fn the_drape_box_scene_keeps_the_cloth_out_of_the_turning_box() {
    let scene = Scene::builtin("drape_box").unwrap();
    let collider = scene.colliders[0].clone();
    let mut sim = Simulation::new(scene).unwrap();
    for _ in 0..150 {
        sim.step(10).unwrap();
        let least = least_distance(&sim, &collider);
        assert!(
            least >= collider.thickness - 1e-5,
            "at t = {}: {least} m",
            sim.time()
        );
    }
    // The top turned with the box: the particle over its middle-right edge has been carried
    // round (half a radian a second for 1.5 s), not left where it fell.
    let p = sim.positions().get(24 * 48 + 40).as_dvec3();
    assert!(p.z < -0.1, "the cloth did not turn with the box: {p}");
}

#[test]
fn the_tablecloth_mannequin_and_spinner_scenes_run_stably() {
    // 400 steps (0.4 s: the cloth has landed and is draping): every value finite and within
    // the scene, no particle inside any collider by more than 1 mm (where two colliders meet,
    // the later one has the last word, and may leave a particle within the other's thickness).
    for name in ["tablecloth", "mannequin", "spinner"] {
        let scene = Scene::builtin(name).unwrap();
        let colliders = scene.colliders.clone();
        let mut sim = Simulation::new(scene).unwrap();
        for _ in 0..40 {
            sim.step(10).unwrap();
            let pos = sim.positions();
            for p in 0..pos.len() {
                let x = pos.get(p);
                assert!(x.is_finite() && x.abs().max_element() < 5.0, "{name}: {x}");
                for (c, collider) in colliders.iter().enumerate() {
                    let d = signed_distance(collider, x, sim.time());
                    assert!(
                        d > -1e-3,
                        "{name}: particle {p} is {d} m inside collider {c}"
                    );
                }
            }
        }
        // The cloth came to rest on the colliders, not on the floor beneath them.
        let middle = sim.grid().index(sim.grid().nx / 2, sim.grid().ny / 2);
        assert!(
            sim.positions().get(middle).y > 0.5,
            "{name}: the cloth fell through"
        );
    }
}
