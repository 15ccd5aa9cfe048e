//! Plane and mesh colliders and poses set between steps, against physics: a box mesh holds a
//! cloth where the analytic box does, an open sheet pushes from its front only, nothing tunnels
//! a mesh at 300 m/s, a box moved by `set_collider_pose` carries the cloth resting on it at its
//! speed, bad meshes and bad poses are refused naming the parameter and change nothing, and
//! the same bits come out on any thread count and through a snapshot.

use crate::common;

use common::*;
use glam::{DVec3, Vec3};
use rustcloth::scene::{ColliderSpec, ShapeKind};
use rustcloth::{Error, Scene, Simulation};

/// A call that should be refused, returning its error.
type BadCall<'a> = &'a dyn Fn(&mut Simulation) -> Error;
/// A change to a good mesh's vertices and triangles.
type MeshChange<'a> = &'a dyn Fn(&mut Vec<[f64; 3]>, &mut Vec<[i64; 3]>);

fn mesh_box(half: [f64; 3]) -> ColliderSpec {
    let (vertices, triangles) = box_mesh(half);
    ColliderSpec {
        shape: ShapeKind::Mesh,
        vertices: Some(vertices),
        triangles: Some(triangles),
        center: [0.0; 3],
        ..ColliderSpec::default()
    }
}

/// A free 16 x 16 cloth, 0.6 m across, falling from 0.05 m above y = `top`.
fn falling_cloth(top: f64, colliders: Vec<ColliderSpec>) -> Simulation {
    cloth_over(16, 0.6, top + 0.05, colliders)
}

/// A closed sphere mesh of `radius` centred on the origin: `rings` bands of latitude between
/// two poles, `segments` around, wound counter-clockwise seen from outside.
fn uv_sphere(rings: usize, segments: usize, radius: f64) -> (Vec<[f64; 3]>, Vec<[i64; 3]>) {
    use std::f64::consts::PI;
    let mut vertices = vec![[0.0, radius, 0.0]];
    for r in 1..rings {
        let (s, c) = (PI * r as f64 / rings as f64).sin_cos();
        vertices.extend((0..segments).map(|k| {
            let a = 2.0 * PI * k as f64 / segments as f64;
            [radius * s * a.cos(), radius * c, -radius * s * a.sin()]
        }));
    }
    vertices.push([0.0, -radius, 0.0]);
    let ring = |r: usize, k: usize| (1 + (r - 1) * segments + k % segments) as i64;
    let south = vertices.len() as i64 - 1;
    let mut triangles = Vec::new();
    for k in 0..segments {
        triangles.push([0, ring(1, k), ring(1, k + 1)]);
        for r in 1..rings - 1 {
            let (a, b, c, d) = (
                ring(r, k),
                ring(r + 1, k),
                ring(r + 1, k + 1),
                ring(r, k + 1),
            );
            triangles.extend([[a, b, c], [a, c, d]]);
        }
        triangles.push([ring(rings - 1, k), south, ring(rings - 1, k + 1)]);
    }
    (vertices, triangles)
}

/// The regression test of the mesh grid (`collisions::mesh`), which answers a resting cloth's
/// nearest-point queries in place of parry's BVH: a cloth draped over a 7 936-triangle sphere
/// stays `thickness` outside every triangle, judged by a brute-force nearest point written apart
/// from both, and rests where the analytic sphere holds it, less the facets' sag.
#[test]
fn a_cloth_draped_on_a_fine_sphere_mesh_stays_thickness_outside_every_triangle() {
    let (vertices, triangles) = uv_sphere(63, 64, 0.15);
    assert_eq!(triangles.len(), 7936);
    let thickness = 0.002;
    let mesh = ColliderSpec {
        shape: ShapeKind::Mesh,
        vertices: Some(vertices.clone()),
        triangles: Some(triangles.clone()),
        center: [0.0; 3],
        thickness,
        ..ColliderSpec::default()
    };
    let mut sim = falling_cloth(0.15, vec![mesh]);
    let corner = |t: &[i64; 3], k: usize| DVec3::from(vertices[t[k] as usize]);
    let mut touching = 0;
    for _ in 0..6 {
        sim.step(100).unwrap();
        for i in 0..sim.positions().len() {
            let p = sim.positions().get(i).as_dvec3();
            let d = triangles
                .iter()
                .map(|t| {
                    (p - closest_on_triangle(p, corner(t, 0), corner(t, 1), corner(t, 2))).length()
                })
                .fold(f64::INFINITY, f64::min);
            // Outside the polyhedron (it is convex; its faces are within sag of the sphere).
            assert!(p.length() > 0.149, "particle {i} inside the mesh at {p}");
            assert!(
                d > 0.99 * thickness,
                "particle {i} {d} m from the mesh at {p}"
            );
            touching += usize::from(d < 1.5 * thickness);
        }
    }
    assert!(
        touching > 100,
        "{touching} resting contacts: the cloth never lay on the mesh"
    );
    // A particle by the pole rests at the radius plus thickness, less the facets' sag there.
    let top = sim.positions().get(8 * 16 + 8).as_dvec3();
    assert!((top.length() - 0.152).abs() < 5e-4, "{top}");
}

#[test]
fn a_box_mesh_holds_the_cloth_where_the_analytic_box_does() {
    let half = [0.2, 0.1, 0.2];
    let analytic = ColliderSpec {
        shape: ShapeKind::Box,
        half_extents: Some(half),
        center: [0.0; 3],
        ..ColliderSpec::default()
    };
    let mut a = falling_cloth(0.1, vec![analytic]);
    let mut m = falling_cloth(0.1, vec![mesh_box(half)]);
    a.step(400).unwrap();
    m.step(400).unwrap();
    // The particles resting on the top face: at 0.1 + thickness in both, to float32 rounding.
    let middle = 8 * 16 + 8;
    let (pa, pm) = (a.positions().get(middle), m.positions().get(middle));
    assert!((pa.y - 0.102).abs() < 1e-4, "analytic box: {pa}");
    assert!((pm.y - pa.y).abs() < 1e-5, "mesh {pm} against box {pa}");
}

#[test]
fn an_open_sheet_pushes_from_its_front_only() {
    // One quad facing +y (counter-clockwise seen from above). A particle falling onto it from
    // above at 20 m/s (2 cm a step) stops on it; one rising through it from below at 20 m/s
    // passes as if it were not there (free flight under gravity, v t - g t^2 / 2).
    let sheet = ColliderSpec {
        shape: ShapeKind::Mesh,
        vertices: Some(vec![
            [-1.0, 0.0, -1.0],
            [1.0, 0.0, -1.0],
            [1.0, 0.0, 1.0],
            [-1.0, 0.0, 1.0],
        ]),
        triangles: Some(vec![[0, 2, 1], [0, 3, 2]]),
        center: [0.0; 3],
        friction: 0.0,
        ..ColliderSpec::default()
    };
    let mut scene = scene_under_gravity(2, 2);
    scene.colliders = vec![sheet.clone()];
    let mut down = lone_particle(scene.clone(), Vec3::new(0.1, 0.5, 0.2), -20.0 * Vec3::Y);
    down.step(200).unwrap();
    let p = down.positions().get(0);
    assert!(
        (p.y as f64 - sheet.thickness).abs() < 1e-5,
        "from above it rests on the sheet: {p}"
    );
    let mut up = lone_particle(scene, Vec3::new(0.1, -0.5, 0.2), 20.0 * Vec3::Y);
    up.step(100).unwrap();
    let t = up.time();
    let expected = -0.5 + 20.0 * t - 0.5 * 9.81 * t * t;
    let y = up.positions().get(0).y as f64;
    assert!(
        (y - expected).abs() < 2e-3,
        "from below it passes: at {y}, free flight at {expected}"
    );
}

#[test]
fn a_particle_at_300_m_s_does_not_tunnel_through_a_thin_mesh() {
    // 30 cm a step against a 2 cm slab, straight and tilted: stopped on the face it came to.
    for rotation in [[0.0, 0.0, 0.0], [0.4, 0.1, 0.3]] {
        let collider = ColliderSpec {
            rotation,
            ..mesh_box([1.0, 0.01, 1.0])
        };
        let mut scene = scene_under_gravity(2, 2);
        scene.colliders = vec![collider.clone()];
        let mut sim = lone_particle(scene, Vec3::new(0.0, 1.0, 0.0), -300.0 * Vec3::Y);
        let up = glam::DQuat::from_scaled_axis(DVec3::from(rotation)) * DVec3::Y;
        for _ in 0..20 {
            sim.step(1).unwrap();
            let p = sim.positions().get(0).as_dvec3();
            let q = glam::DQuat::from_scaled_axis(DVec3::from(rotation)).inverse() * p;
            let d = convex_mesh_distance(
                q,
                collider.vertices.as_ref().unwrap(),
                collider.triangles.as_ref().unwrap(),
            );
            assert!(
                p.dot(up) > 0.0 && d >= collider.thickness - 1e-5,
                "{rotation:?}: at {p}, {d} m from the surface"
            );
        }
    }
}

#[test]
fn a_particle_on_a_tilted_plane_slides_iff_the_slope_beats_friction() {
    // A plane through the origin tilted about z; the particle starts on it at the origin.
    let normal = |sim: &Simulation| {
        let angle = sim.scene().colliders[0].rotation[2];
        DVec3::new(-angle.sin(), angle.cos(), 0.0)
    };
    check_slides_iff_the_slope_beats_friction(
        |angle, mu| {
            let plane = ColliderSpec {
                shape: ShapeKind::Plane,
                center: [0.0; 3],
                rotation: [0.0, 0.0, angle],
                friction: mu,
                thickness: 0.0,
                ..ColliderSpec::default()
            };
            let mut scene = scene_under_gravity(2, 2);
            scene.colliders = vec![plane];
            (lone_particle(scene, Vec3::ZERO, Vec3::ZERO), Vec3::ZERO)
        },
        |sim| sim.positions().get(0).as_dvec3().dot(normal(sim)),
    );
}

#[test]
fn the_floor_and_a_plane_at_its_height_stop_a_cloth_at_the_same_height() {
    let mut with_floor = falling_cloth(0.0, vec![]);
    let mut scene = with_floor.scene().clone();
    scene.floor = Some(Default::default());
    with_floor = Simulation::new(scene).unwrap();
    let plane = ColliderSpec {
        shape: ShapeKind::Plane,
        center: [0.0; 3],
        ..ColliderSpec::default()
    };
    let mut with_plane = falling_cloth(0.0, vec![plane]);
    with_floor.step(300).unwrap();
    with_plane.step(300).unwrap();
    for p in [0, 100, 255] {
        let (a, b) = (with_floor.positions().get(p), with_plane.positions().get(p));
        assert!(
            (a.y - 0.002).abs() < 1e-6 && (b.y - 0.002).abs() < 1e-6,
            "{a} {b}"
        );
    }
}

/// A 12 x 12 cloth at rest on a 2 m box (friction 0.8), the box then moved by
/// `set_collider_pose` at `v` m/s along x for `steps` steps; returns the simulation.
fn carried(v: f64, steps: u64) -> Simulation {
    let collider = ColliderSpec {
        shape: ShapeKind::Box,
        half_extents: Some([1.0, 0.1, 1.0]),
        center: [0.0; 3],
        friction: 0.8,
        ..ColliderSpec::default()
    };
    let top = 0.1 + collider.thickness + 1e-4;
    let mut sim = cloth_over(12, 0.5, top, vec![collider]);
    for _ in 0..steps {
        let x = v * (sim.time() + sim.dt());
        sim.set_collider_pose(0, [x, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0])
            .unwrap();
        sim.step(1).unwrap();
    }
    sim
}

#[test]
fn a_box_moved_each_step_by_set_collider_pose_carries_the_cloth_at_its_speed() {
    // The pose's change over each step is the box's velocity, which friction sees: the cloth
    // is dragged up to the box's 0.5 m/s and stays on it. Without it the box would slide out
    // from under a cloth left behind.
    let v = 0.5;
    let sim = carried(v, 1000);
    let mean_vx = mean_velocity_x(&sim);
    assert!(
        (mean_vx - v).abs() < 0.03 * v,
        "the cloth moves at {mean_vx} m/s, the box at {v}"
    );
    let middle = sim.positions().get(6 * 12 + 6).as_dvec3();
    assert!(
        (middle.x - v * sim.time()).abs() < 0.05,
        "left behind at {middle}"
    );
    let pose = sim.collider_poses()[0];
    assert!((pose.position.x - v * sim.time()).abs() < 1e-9, "{pose:?}");
}

#[test]
fn a_pose_set_once_is_reached_over_one_step_and_then_held() {
    let mut sim = carried(0.0, 0);
    let q = glam::DQuat::from_rotation_y(0.3);
    sim.set_collider_pose(0, [0.1, 0.0, 0.0], q.to_array())
        .unwrap();
    // Not moved yet: it gets there by the end of the next step.
    assert_eq!(sim.collider_poses()[0].position, DVec3::ZERO);
    sim.step(1).unwrap();
    let pose = sim.collider_poses()[0];
    assert_eq!(pose.position, DVec3::new(0.1, 0.0, 0.0));
    assert!(pose.rotation.abs_diff_eq(q, 1e-12), "{pose:?}");
    sim.step(10).unwrap();
    assert_eq!(sim.collider_poses()[0].position, DVec3::new(0.1, 0.0, 0.0));
}

#[test]
fn bad_poses_are_refused_naming_the_parameter_and_change_nothing() {
    let run = |bad: BadCall| {
        let mut sim = carried(0.2, 5);
        let err = bad(&mut sim);
        sim.step(20).unwrap();
        (err, state_hash(&sim), sim.collider_poses()[0])
    };
    let mut good = carried(0.2, 5);
    good.step(20).unwrap();
    let reference = (state_hash(&good), good.collider_poses()[0]);
    let unit = [0.0, 0.0, 0.0, 1.0];
    let cases: [(&str, BadCall); 5] = [
        ("index", &|s| {
            s.set_collider_pose(1, [0.0; 3], unit).unwrap_err()
        }),
        ("index", &|s| {
            s.set_collider_pose(-1, [0.0; 3], unit).unwrap_err()
        }),
        ("rotation", &|s| {
            s.set_collider_pose(0, [0.0; 3], [0.0, 0.0, 0.0, 1.1])
                .unwrap_err()
        }),
        ("rotation", &|s| {
            s.set_collider_pose(0, [0.0; 3], [f64::NAN, 0.0, 0.0, 1.0])
                .unwrap_err()
        }),
        ("position", &|s| {
            s.set_collider_pose(0, [0.0, f64::INFINITY, 0.0], unit)
                .unwrap_err()
        }),
    ];
    for (name, bad) in cases {
        let (err, hash, pose) = run(bad);
        assert!(err.to_string().starts_with(name), "{err}");
        assert_eq!(
            (hash, pose),
            reference,
            "{name}: the refused call changed the run"
        );
    }
    let index = carried(0.0, 0)
        .set_collider_pose(3, [0.0; 3], unit)
        .unwrap_err();
    assert!(
        matches!(index, Error::IndexOutOfRange { len: 1, .. }),
        "{index}"
    );
}

#[test]
fn bad_meshes_are_refused_naming_the_parameter() {
    let (vertices, triangles) = box_mesh([0.5, 0.5, 0.5]);
    let with = |f: MeshChange| {
        let (mut v, mut t) = (vertices.clone(), triangles.clone());
        f(&mut v, &mut t);
        let scene = Scene {
            colliders: vec![ColliderSpec {
                vertices: Some(v),
                triangles: Some(t),
                ..mesh_box([0.5; 3])
            }],
            ..Scene::default()
        };
        scene.validate().unwrap_err().to_string()
    };
    let cases: [(&str, MeshChange); 9] = [
        ("colliders[0].vertices[3][1]", &|v, _| v[3][1] = f64::NAN),
        ("colliders[0].vertices[0][2]", &|v, _| {
            v[0][2] = f64::INFINITY
        }),
        ("colliders[0].vertices", &|v, t| {
            v.truncate(2);
            t.clear()
        }),
        ("colliders[0].triangles", &|_, t| t.clear()),
        ("colliders[0].triangles[4]", &|_, t| t[4] = [0, 1, 8]),
        ("colliders[0].triangles[2]", &|_, t| t[2] = [0, -1, 2]),
        ("colliders[0].triangles[5]", &|_, t| t[5] = [0, 1, 1]),
        // Collinear corners: vertices 0, 1 and their midpoint.
        ("colliders[0].triangles[0]", &|v, t| {
            v.push([0.0, -0.5, -0.5]);
            t[0] = [0, 8, 1]
        }),
        // Every triangle reversed: a closed mesh inside out.
        ("colliders[0].triangles", &|_, t| {
            t.iter_mut().for_each(|tri| tri.swap(1, 2))
        }),
    ];
    for (name, change) in cases {
        let err = with(change);
        assert!(err.starts_with(&format!("{name}:")), "{name}: {err}");
    }
    // One triangle flipped in a closed mesh: wound inconsistently.
    let err = with(&|_, t| t[3].swap(1, 2));
    assert!(err.contains("inconsistently"), "{err}");
    // Keys of other shapes are refused, and a mesh needs both arrays.
    let err = Scene::from_toml_str(
        "[[colliders]]\nshape = \"box\"\nhalf_extents = [1, 1, 1]\nvertices = [[0, 0, 0]]",
    )
    .unwrap_err()
    .to_string();
    assert!(err.starts_with("colliders[0].vertices"), "{err}");
    let err = Scene::from_toml_str("[[colliders]]\nshape = \"mesh\"\nvertices = [[0, 0, 0]]")
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("colliders[0].triangles"), "{err}");
    let err = Scene::from_toml_str("[[colliders]]\nshape = \"plane\"\nradius = 1")
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("colliders[0].radius"), "{err}");
}

/// A cloth dropped on a tilted mesh box over a plane, the box turned by `set_collider_pose`.
fn mixed_run() -> u64 {
    let mut plane = ColliderSpec {
        shape: ShapeKind::Plane,
        center: [0.0, -0.2, 0.0],
        rotation: [0.1, 0.0, 0.0],
        ..ColliderSpec::default()
    };
    plane.friction = 0.5;
    let mesh = ColliderSpec {
        rotation: [0.2, 0.0, 0.3],
        ..mesh_box([0.2, 0.1, 0.2])
    };
    let mut sim = falling_cloth(0.15, vec![plane, mesh]);
    for k in 0..200 {
        let q = glam::DQuat::from_rotation_y(0.01 * k as f64);
        sim.set_collider_pose(1, [0.0, 0.0, 0.0], q.to_array())
            .unwrap();
        sim.step(1).unwrap();
    }
    state_hash(&sim)
}

#[test]
fn plane_and_mesh_colliders_give_the_same_bits_on_any_thread_count() {
    let one = with_threads(1, mixed_run);
    assert_eq!(one, with_threads(2, mixed_run));
    assert_eq!(one, with_threads(5, mixed_run));
}

#[test]
fn a_snapshot_keeps_the_pose_set_between_steps() {
    let mut sim = carried(0.3, 10);
    sim.set_collider_pose(0, [0.5, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0])
        .unwrap();
    let mut copy = Simulation::restore(sim.snapshot()).unwrap();
    sim.step(30).unwrap();
    copy.step(30).unwrap();
    assert_eq!(state_hash(&sim), state_hash(&copy));
    assert_eq!(sim.collider_poses(), copy.collider_poses());
    // A reset forgets it: back to the scene's own (static) pose.
    sim.reset().unwrap();
    assert_eq!(sim.collider_poses()[0].position, DVec3::ZERO);
}
