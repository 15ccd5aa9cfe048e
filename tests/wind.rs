//! Wind (`[wind]`, src/wind.rs): drag and lift of the air on each triangle, applied after the
//! integrator as an implicit change of velocity.

use crate::common;

use common::{state_hash, with_threads};
use rustcloth::scene::WindSpec;
use rustcloth::{IntegratorKind, Scene, Simulation};

/// A 0.8 m x 0.8 m curtain hung along its top edge in the xy plane, 0.5 kg/m^2.
fn curtain(wind: Option<WindSpec>) -> Scene {
    let mut scene = Scene::from_toml_str(
        r#"
        dt = 0.001
        substeps = 2
        [cloth]
        nx = 16
        ny = 16
        size = [0.8, 0.8]
        center = [0.0, 1.0, 0.0]
        plane = "xy"
        mass = 0.32
        k_structural = 300.0
        k_shear = 60.0
        k_bend = 5.0
        damping = 0.02
        pins = ["top_edge"]
        "#,
    )
    .unwrap();
    scene.wind = wind;
    scene
}

/// A steady wind along `velocity`, without gusts or turbulence.
fn steady(velocity: [f64; 3]) -> WindSpec {
    WindSpec {
        velocity,
        gust: 0.0,
        turbulence: 0.0,
        ..WindSpec::default()
    }
}

fn mean_z(sim: &Simulation) -> f64 {
    let z = &sim.positions().z;
    z.iter().map(|&v| v as f64).sum::<f64>() / z.len() as f64
}

#[test]
fn wind_deflects_a_hanging_cloth_downwind_and_a_stronger_wind_more() {
    let mut deflection = Vec::new();
    for speed in [0.0, 2.0, 4.0] {
        let mut sim = Simulation::new(curtain(Some(steady([0.0, 0.0, speed])))).unwrap();
        sim.step(1500).unwrap();
        deflection.push(mean_z(&sim));
    }
    let [still, breeze, wind] = deflection[..] else {
        unreachable!()
    };
    assert!(still.abs() < 1e-6, "still air moved the curtain {still} m");
    assert!(
        breeze > 0.02,
        "a 2 m/s breeze moved it only {breeze} m downwind"
    );
    // Drag grows with the square of the speed: twice the wind, well over twice the push
    // (the deflection less, as the curtain lifts towards the flow and shows it less area).
    assert!(wind > 1.5 * breeze, "4 m/s: {wind} m, 2 m/s: {breeze} m");
}

#[test]
fn a_steady_wind_carries_a_free_cloth_up_to_its_speed_and_never_faster() {
    // A horizontal cloth without springs or gravity, broadside to an upward wind: each particle
    // must approach the wind's speed from below, at any step, under every integrator (the drag
    // is taken implicitly).
    for integrator in IntegratorKind::ALL {
        for dt in [0.001, 1.0 / 60.0] {
            let mut scene = common::bare_scene(6, 6);
            (scene.integrator, scene.dt) = (integrator, dt);
            let cloth = &mut scene.cloth;
            (cloth.k_structural, cloth.k_shear, cloth.k_bend) = (0.0, 0.0, 0.0);
            scene.wind = Some(steady([0.0, 4.0, 0.0]));
            let mut sim = Simulation::new(scene).unwrap();
            let mut fastest = 0.0f32;
            for _ in 0..(3.0 / dt) as usize {
                sim.step(1).unwrap();
                let vy = &sim.velocities().y;
                fastest = vy.iter().fold(fastest, |m, &v| m.max(v));
            }
            // Without springs the particles drift apart and tilt their triangles edge-on to
            // the flow, which then stops pushing them: the mean, not every particle, arrives.
            let vy = &sim.velocities().y;
            let mean = vy.iter().sum::<f32>() / vy.len() as f32;
            assert!(
                fastest <= 4.0 * (1.0 + 1e-5),
                "{integrator:?} at dt {dt}: {fastest} m/s in a 4 m/s wind"
            );
            assert!(
                mean > 3.8,
                "{integrator:?} at dt {dt}: only {mean} m/s on average after 3 s in a 4 m/s wind"
            );
        }
    }
}

#[test]
fn still_air_leaves_a_resting_cloth_bitwise_alone() {
    // The pass runs, but a cloth at rest in air at rest feels no force.
    let weightless = |wind| Scene {
        gravity: [0.0; 3],
        ..curtain(wind)
    };
    let mut without = Simulation::new(weightless(None)).unwrap();
    let mut still = Simulation::new(weightless(Some(steady([0.0; 3])))).unwrap();
    assert!(still.effects().contains(&"wind"));
    assert!(!without.effects().contains(&"wind"));
    without.step(50).unwrap();
    still.step(50).unwrap();
    assert_eq!(state_hash(&without), state_hash(&still));
}

/// The textbook force on a flat plate of 1 m^2 with normal +y moving at `v` through still air:
/// F = 1/2 rho A |u|^2 (C_d |cos| u_hat + C_l alpha n), `u = -v` the air relative to the plate
/// and alpha the angle of attack.
fn plate_force(wind: &WindSpec, v: glam::Vec3) -> glam::DVec3 {
    let u = -v.as_dvec3();
    let (speed, normal) = (u.length(), glam::DVec3::Y);
    let (q, area) = (0.5 * wind.air_density * speed * speed, 1.0);
    let alpha = (u.dot(normal) / speed).asin();
    q * area * (wind.drag * (u.dot(normal) / speed).abs() * u / speed + wind.lift * alpha * normal)
}

/// `plate` (a weightless flat cloth of 1 m^2 in the xz plane, normal +-y) moving uniformly
/// through still air, down and sideways at 2 m/s at `degrees` to its plane, for one short
/// step: the momentum it loses is the plate's force. Returns the measured and the textbook
/// force (N).
fn plate_in_still_air(mut plate: Scene, degrees: f32) -> (glam::DVec3, glam::DVec3) {
    plate.dt = 1e-5;
    plate.wind = Some(steady([0.0; 3]));
    let wind = plate.wind.clone().unwrap();
    let mut sim = Simulation::new(plate).unwrap();
    let a = degrees.to_radians();
    let v = glam::Vec3::new(a.cos(), -a.sin(), 0.0) * 2.0;
    let n = sim.velocities().len();
    sim.set_velocities(&rustcloth::soa::Vec3s::from_fn(n, |_| v))
        .unwrap();
    let masses: Vec<f64> = sim.particles().mass.iter().map(|&m| m as f64).collect();
    sim.step(1).unwrap();
    let vel = sim.velocities();
    let momentum = (0..n)
        .map(|p| masses[p] * (vel.get(p).as_dvec3() - v.as_dvec3()))
        .sum::<glam::DVec3>();
    (momentum / 1e-5, plate_force(&wind, v))
}

#[test]
fn a_flat_plate_feels_the_textbook_drag_and_lift() {
    // Broadside (alpha = 90 degrees) and at 30 degrees.
    for degrees in [90.0f32, 30.0] {
        let (force, expected) = plate_in_still_air(common::bare_scene(8, 8), degrees);
        assert!(
            (force - expected).length() < 0.01 * expected.length(),
            "at {degrees} degrees: force {force:?} N, a plate's {expected:?} N"
        );
    }
}

#[test]
fn the_gusty_flag_is_the_same_on_one_and_two_threads() {
    let run = |threads| {
        with_threads(threads, || {
            let mut sim = Simulation::new(Scene::builtin("flag").unwrap()).unwrap();
            sim.step(300).unwrap();
            state_hash(&sim)
        })
    };
    assert_eq!(run(1), run(2));
}

#[test]
fn the_flag_streams_out_downwind_and_keeps_moving() {
    let mut sim = Simulation::new(Scene::builtin("flag").unwrap()).unwrap();
    sim.step(4000).unwrap();
    let x = &sim.positions().x;
    let tip = x.iter().fold(f32::MIN, |m, &v| m.max(v));
    // Hung from a pole at x = 0 with a 1.2 m fly: in a 5 m/s breeze it stands out from the
    // pole instead of hanging down it.
    assert!(tip > 0.8, "the flag's far edge reached only x = {tip} m");
    // Gusts and eddies keep it moving: it never settles.
    let speed = sim
        .velocities()
        .y
        .iter()
        .map(|v| v.abs())
        .fold(0.0f32, f32::max);
    assert!(
        speed > 0.05,
        "the flag is still: fastest vertical speed {speed} m/s"
    );
}

#[test]
fn bad_wind_settings_are_named() {
    for (key, value) in [
        ("gust", "1.5"),
        ("gust_period", "0.0"),
        ("turbulence", "-1.0"),
        ("turbulence_scale", "0.0"),
        ("drag", "-0.1"),
        ("air_density", "0.0"),
        ("velocity", "[1e9, 0.0, 0.0]"),
    ] {
        let text = format!("[cloth]\nnx = 4\nny = 4\n[wind]\n{key} = {value}\n");
        let error = Scene::from_toml_str(&text).unwrap_err().to_string();
        assert!(
            error.contains(&format!("wind.{key}")),
            "{key} = {value}: {error}"
        );
    }
}

#[test]
fn wind_after_a_cut_pushes_on_the_cloth_as_cut() {
    // The pass keeps its list of triangles between substeps: after a cut it must push on the
    // cloth as it is now, as a simulation restored from that moment (with a fresh pass) does.
    let mut sim = Simulation::new(curtain(Some(WindSpec::default()))).unwrap();
    sim.step(100).unwrap();
    for p in [100, 101, 102, 117, 118] {
        sim.cut(p).unwrap();
    }
    let mut restored = Simulation::restore(sim.snapshot()).unwrap();
    sim.step(100).unwrap();
    restored.step(100).unwrap();
    assert_eq!(state_hash(&sim), state_hash(&restored));
}

/// The flat plate of [`a_flat_plate_feels_the_textbook_drag_and_lift`] as an irregular mesh
/// cloth (jittered points, triangles of every shape and size, vertices of unequal mass): the
/// wind pushes on each of the mesh's triangles, so the plate's force is the textbook one
/// whatever its triangulation.
#[test]
fn an_irregular_mesh_plate_feels_the_textbook_drag_and_lift() {
    let (vertices, triangles) = rustcloth::mesh_cloth::jittered_square(9, 1.0, [0.0; 3], 0.4, 3);
    // In the xz plane, normal +y, wound counter-clockwise seen from +y.
    let vertices: Vec<[f64; 3]> = vertices.iter().map(|v| [v[0], 0.5, -v[1]]).collect();
    for degrees in [90.0f32, 30.0] {
        let mut plate = common::mesh_cloth_scene(vertices.clone(), triangles.clone(), vec![]);
        (plate.gravity, plate.air_drag) = ([0.0; 3], 0.0);
        let (force, expected) = plate_in_still_air(plate, degrees);
        assert!(
            (force - expected).length() < 0.01 * expected.length(),
            "at {degrees} degrees: force {force:?} N, a plate's {expected:?} N"
        );
    }
}

/// A mesh curtain (an irregular mesh hung by its top row) in a steady breeze leans downwind as
/// far as the grid curtain of the same size, mass and moduli (5 % apart when written), and
/// twice the wind leans it more.
#[test]
fn a_mesh_curtain_leans_downwind_as_the_grid_curtain_does() {
    use rustcloth::mesh_cloth::jittered_square;
    use rustcloth::scene::{ClothSpec, MeshSpec, PinBox, PinSpec};
    let mesh_curtain = |speed: f64| {
        let grid = curtain(None);
        let (vertices, triangles) = jittered_square(16, 0.8, [0.0, 1.0, 0.0], 0.3, 7);
        let c = &grid.cloth;
        let mut scene = Scene {
            cloth: ClothSpec {
                mesh: Some(MeshSpec {
                    vertices,
                    triangles,
                    density: 0.5,
                    stretch: 2.0 * (c.k_structural + 2.0 * c.k_shear),
                    bend: 8.0 * c.k_bend,
                    // The grid's moduli from its springs (docs/mesh_cloth.md): every grid
                    // spring has damping `c.damping`, so its damping modulus is 2 (c + 2 c).
                    damping: 6.0 * c.damping,
                    ..MeshSpec::default()
                }),
                pins: vec![PinSpec::Region(PinBox {
                    corners: [[-1.0, 1.4 - 1e-9, -1.0], [1.0, 1.5, 1.0]],
                })],
                ..ClothSpec::default()
            },
            wind: Some(steady([0.0, 0.0, speed])),
            ..grid
        };
        scene.dt = scene
            .dt
            .min(0.7 * scene.stable_dt(IntegratorKind::SymplecticEuler).unwrap());
        let mut sim = Simulation::new(scene).unwrap();
        sim.advance(3.0).unwrap();
        mean_z(&sim)
    };
    let grid_curtain = |speed: f64| {
        let mut sim = Simulation::new(curtain(Some(steady([0.0, 0.0, speed])))).unwrap();
        sim.advance(3.0).unwrap();
        mean_z(&sim)
    };
    let (mesh, grid) = (mesh_curtain(2.0), grid_curtain(2.0));
    eprintln!("lean in a 2 m/s breeze: mesh {mesh} m, grid {grid} m");
    assert!(
        mesh > 0.02,
        "a 2 m/s breeze moved the mesh only {mesh} m downwind"
    );
    assert!(
        (mesh / grid - 1.0).abs() < 0.25,
        "mesh {mesh} m, grid {grid} m"
    );
    // Four times the push; the lean grows less, as the curtain turns its face from the flow.
    let stronger = mesh_curtain(4.0);
    assert!(
        stronger > 1.2 * mesh,
        "4 m/s: {stronger} m, 2 m/s: {mesh} m"
    );
}
