//! A cloth from a triangle mesh: its checks, its material's resolution independence, and its
//! physics (momentum, energy, equilibrium, determinism, snapshots) on the explicit integrators.

use crate::common;

use common::{momentum, state_hash, with_threads};
use glam::{DVec3, Vec3};
use rustcloth::mesh_cloth::{jittered_square, EdgeKind, MeshCloth};
use rustcloth::scene::{
    ClothSpec, ColliderSpec, FloorSpec, MeshSpec, PinBoundary, PinBox, PinSpec, PinTop, ShapeKind,
    TearingSpec,
};
use rustcloth::simd::Isa;
use rustcloth::soa::Vec3s;
use rustcloth::{IntegratorKind, Scene, Simulation};

/// A hanging 1 m square of `n` x `n` jittered points, centre at y = 1, held by the vertices
/// within `pin` m of its two top corners.
fn hanging_square(n: usize, pin: f64, seed: u64) -> Scene {
    let (vertices, triangles) = jittered_square(n, 1.0, [0.0, 1.0, 0.0], 0.3, seed);
    let corner = |x: f64| {
        PinSpec::Region(PinBox {
            corners: [[x - pin, 1.5 - 2.0 * pin, -0.1], [x + pin, 1.5, 0.1]],
        })
    };
    let pins = vec![corner(-0.5 + pin), corner(0.5 - pin)];
    let mut scene = common::mesh_cloth_scene(vertices, triangles, pins);
    scene.dt = 0.7 * scene.stable_dt(IntegratorKind::SymplecticEuler).unwrap();
    scene
}

/// A mesh's vertices and triangles.
type MeshArrays = (Vec<[f64; 3]>, Vec<[i64; 3]>);

/// A bad mesh and the parameter its error must name.
type Case = (Vec<[f64; 3]>, Vec<[i64; 3]>, &'static str);

fn mesh_scene(vertices: Vec<[f64; 3]>, triangles: Vec<[i64; 3]>) -> Scene {
    common::mesh_cloth_scene(vertices, triangles, vec![])
}

/// Two triangles sharing the edge 0-2: a unit square.
fn quad() -> MeshArrays {
    (
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    )
}

fn refused(scene: Scene) -> String {
    let err = scene.validate().expect_err("must be refused");
    let text = err.to_string();
    // The model refuses it too, so nothing is built from an invalid mesh.
    assert!(Simulation::new(scene).is_err());
    text
}

#[test]
fn bad_meshes_are_refused_naming_the_parameter_and_element() {
    let (v, t) = quad();
    let mut nan = v.clone();
    nan[2][1] = f64::NAN;
    let cases: Vec<Case> = vec![
        (nan, t.clone(), "cloth.mesh.vertices[2]"),
        (
            v.clone(),
            vec![[0, 1, 2], [0, 2, 4]],
            "cloth.mesh.triangles[1]",
        ),
        (
            v.clone(),
            vec![[0, 1, 2], [0, -1, 3]],
            "cloth.mesh.triangles[1]",
        ),
        // Zero area: a repeated corner, then three collinear corners.
        (
            v.clone(),
            vec![[0, 1, 2], [0, 2, 2]],
            "cloth.mesh.triangles[1]",
        ),
        (
            vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            vec![[0, 3, 1], [0, 1, 2]],
            "cloth.mesh.triangles[1]",
        ),
        // The same triangle twice, in another order.
        (
            v.clone(),
            vec![[0, 1, 2], [0, 2, 3], [2, 0, 1]],
            "cloth.mesh.triangles[2]",
        ),
        // Vertex 3 used by no triangle.
        (v.clone(), vec![[0, 1, 2]], "cloth.mesh.vertices[3]"),
        // Two triangles walking their shared edge 0-2 the same way.
        (
            v.clone(),
            vec![[0, 1, 2], [0, 3, 2]],
            "cloth.mesh.triangles[1]",
        ),
    ];
    for (vertices, triangles, name) in cases {
        let text = refused(mesh_scene(vertices, triangles.clone()));
        assert!(text.starts_with(name), "{triangles:?}: {text}");
    }
    // A non-manifold edge: 0-2 in three triangles (a fin on the square's diagonal).
    let mut fin = v.clone();
    fin.push([0.5, 0.5, 1.0]);
    let text = refused(mesh_scene(fin, vec![[0, 1, 2], [0, 2, 3], [0, 4, 2]]));
    assert!(text.starts_with("cloth.mesh.triangles[2]"), "{text}");
    assert!(text.contains("non-manifold"), "{text}");
    // Too few vertices, no triangles, bad uvs, a bad material.
    let text = refused(mesh_scene(vec![[0.0; 3]; 2], vec![]));
    assert!(text.starts_with("cloth.mesh.vertices"), "{text}");
    let text = refused(mesh_scene(v.clone(), vec![]));
    assert!(text.starts_with("cloth.mesh.triangles"), "{text}");
    let mut scene = mesh_scene(v.clone(), t.clone());
    scene.cloth.mesh.as_mut().unwrap().uvs = Some(vec![[0.0, 0.0]; 3]);
    assert!(refused(scene).starts_with("cloth.mesh.uvs"));
    let mut scene = mesh_scene(v.clone(), t.clone());
    scene.cloth.mesh.as_mut().unwrap().density = 0.0;
    assert!(refused(scene).starts_with("cloth.mesh.density"));
    // Two pieces are allowed.
    let mut two = v.clone();
    two.extend(v.iter().map(|p| [p[0] + 3.0, p[1], p[2]]));
    let scene = mesh_scene(two, vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]]);
    let sim = Simulation::new(scene).unwrap();
    assert_eq!(sim.pieces(), 2);
    assert_eq!(sim.piece_labels(), vec![0, 0, 0, 0, 4, 4, 4, 4]);
}

#[test]
fn a_mesh_cloth_refuses_grid_keys_and_names_its_pins() {
    let (v, t) = quad();
    let mut scene = mesh_scene(v.clone(), t.clone());
    scene.cloth.nx = 8;
    assert!(refused(scene).starts_with("cloth.nx"));
    let mut scene = mesh_scene(v.clone(), t.clone());
    scene.cloth.k_structural = 1.0;
    assert!(refused(scene).starts_with("cloth.k_structural"));
    // The grid's default pins name grid particles: a mesh must say which vertices.
    let mut scene = mesh_scene(v.clone(), t.clone());
    scene.cloth.pins = ClothSpec::default().pins;
    assert!(refused(scene).starts_with("cloth.pins[0]"));
    let mut scene = mesh_scene(v.clone(), t.clone());
    scene.cloth.pins = vec![PinSpec::Index(4)];
    assert!(refused(scene).starts_with("cloth.pins[0]"));
    let mut scene = mesh_scene(v.clone(), t.clone());
    scene.cloth.pins = vec![PinSpec::Region(PinBox {
        corners: [[5.0; 3], [6.0; 3]],
    })];
    let text = refused(scene);
    assert!(text.contains("holds no particle"), "{text}");
    let mut scene = mesh_scene(v.clone(), t.clone());
    scene.cloth.pins = vec![
        PinSpec::Index(1),
        PinSpec::Region(PinBox {
            corners: [[-0.1, 0.9, -0.1], [1.1, 1.1, 0.1]],
        }),
    ];
    let sim = Simulation::new(scene).unwrap();
    assert_eq!(sim.particles().pinned, vec![false, true, true, true]);
}

/// Tearing and cuts were refused on a mesh cloth while only the grid's stencil could be cut:
/// the scene with `[tearing]` and every cut call must now run, and do what it says.
#[test]
fn tearing_and_cuts_run_on_a_mesh_cloth() {
    let (v, t) = quad();
    let base = mesh_scene(v, t);
    let mut torn = base.clone();
    torn.tearing = Some(TearingSpec::default());
    let mut sim = Simulation::new(torn).unwrap();
    assert!(sim.effects().contains(&"tearing"));
    sim.step(10).unwrap();
    let mut sim = Simulation::new(base).unwrap();
    // A stroke down through the quad's middle severs the edges it crosses.
    let stroke = [
        (Vec3::new(0.5, -1.0, 1.0), -Vec3::Z),
        (Vec3::new(0.5, 2.0, 1.0), -Vec3::Z),
    ];
    assert!(sim.sever_stroke(&stroke).unwrap() > 0);
    assert!(sim.triangles().len() < 2);
    sim.cut(0).unwrap();
    assert!(!sim.particles().alive[0]);
    let cut = sim
        .cut_stroke(&[(Vec3::new(1.0, 1.0, 1.0), -Vec3::Z)])
        .unwrap();
    assert_eq!(cut.len(), 1);
    assert_eq!(sim.scene().integrator, IntegratorKind::SymplecticEuler);
}

#[test]
fn lumped_mass_is_density_times_area() {
    for n in [5, 17] {
        let scene = hanging_square(n, 0.05, 1);
        let spec = scene.cloth.mesh.as_ref().unwrap();
        let cloth = MeshCloth::new(spec).unwrap();
        let total: f64 = cloth.masses.iter().sum();
        assert!((total - spec.density).abs() < 1e-12, "{n}: {total}");
    }
}

/// The stiffness `k = Y A_e / L^2` is what makes the material independent of the mesh: a
/// uniform strain `e` stores `Y e^2 A / 2` J whatever the triangles.
#[test]
fn uniform_strain_stores_the_modulus_energy_at_any_resolution() {
    let e = 0.01;
    for (n, seed) in [(4, 3), (12, 4), (30, 5)] {
        let scene = hanging_square(n, 0.05, seed);
        let mut spec = scene.cloth.mesh.clone().unwrap();
        spec.bend = 0.0;
        let cloth = MeshCloth::new(&spec).unwrap();
        assert!(cloth.springs.kind.iter().all(|&k| k == EdgeKind::Stretch));
        let scaled = Vec3s::from_fn(cloth.len(), |v| {
            ((1.0 + e) * DVec3::from(cloth.rest[v])).as_vec3()
        });
        let energy = cloth.elastic_energy(&scaled);
        let expected = spec.stretch * e * e / 2.0 * 1.0;
        // float32 positions: the strain is known to about 1e-7 / 1e-2.
        assert!(
            (energy / expected - 1.0).abs() < 1e-3,
            "{n}: {energy} J, expected {expected}"
        );
    }
}

/// A free mesh cloth, no gravity, no drag, thrown spinning and stretched: its springs push
/// each pair of ends with bitwise opposite forces, so the momentum stays what it was.
#[test]
fn a_free_mesh_cloth_keeps_its_momentum() {
    for integrator in [
        IntegratorKind::SymplecticEuler,
        IntegratorKind::Verlet,
        IntegratorKind::Rk4,
        IntegratorKind::ExplicitEuler,
    ] {
        let mut scene = hanging_square(9, 0.05, 7);
        scene.gravity = [0.0; 3];
        scene.cloth.pins = vec![];
        scene.integrator = integrator;
        scene.dt = 2e-4;
        let mut sim = Simulation::new(scene).unwrap();
        common::throw_spinning_and_stretched(&mut sim);
        let p0 = momentum(&sim);
        sim.step(500).unwrap();
        let drift = (momentum(&sim) - p0).length();
        assert!(drift < 1e-6, "{integrator:?}: momentum moved by {drift}");
    }
}

/// Hanging under gravity with spring damping, no work done on it: its total energy never
/// rises above where it started (checked every 20 steps over 2 s).
#[test]
fn a_hanging_mesh_cloth_never_gains_energy() {
    for integrator in [IntegratorKind::SymplecticEuler, IntegratorKind::Rk4] {
        let mut scene = hanging_square(12, 0.05, 11);
        scene.integrator = integrator;
        let mut sim = Simulation::new(scene).unwrap();
        let start = sim.energy().total();
        let mut highest = f64::NEG_INFINITY;
        for _ in 0..200 {
            sim.step(20).unwrap();
            highest = highest.max(sim.energy().total());
        }
        let end = sim.energy().total();
        assert!(
            highest <= start + 1e-4 * start.abs(),
            "{integrator:?}: {start} -> {highest}"
        );
        assert!(
            end < start,
            "{integrator:?}: lost nothing, {start} -> {end}"
        );
    }
}

/// At equilibrium the springs carry the weight: on every free vertex the total force is small
/// beside its weight, and the pins hold the cloth's whole weight.
#[test]
fn a_hanging_mesh_cloth_settles_where_springs_carry_its_weight() {
    let mut scene = hanging_square(10, 0.05, 13);
    scene.air_drag = 0.005;
    let mut sim = Simulation::new(scene).unwrap();
    sim.advance(4.0).unwrap();
    let force = rustcloth::simulation::total_force(&mut sim);
    let (mass, pinned) = (&sim.particles().mass, &sim.particles().pinned);
    let weight: f64 = mass.iter().map(|&m| m as f64 * 9.81).sum();
    let (mut free_sum, mut worst) = (DVec3::ZERO, 0.0f64);
    for p in 0..mass.len() {
        if !pinned[p] {
            let f = force.get(p).as_dvec3();
            free_sum += f;
            worst = worst.max(f.length() / (mass[p] as f64 * 9.81));
        }
    }
    assert!(
        worst < 0.05,
        "a free vertex is pushed by {worst} of its weight"
    );
    // What the pinned vertices' springs pull down with (their own weight aside) is the weight
    // the free vertices hang on them: the free vertices' total force is what is left over.
    assert!(
        free_sum.length() < 0.01 * weight,
        "{free_sum:?} of {weight} N"
    );
}

#[test]
fn a_mesh_cloth_steps_bitwise_alike_on_any_thread_count_and_restores_bitwise() {
    let run = |threads| {
        with_threads(threads, || {
            let mut sim = Simulation::new(hanging_square(40, 0.05, 17)).unwrap();
            sim.step(50).unwrap();
            state_hash(&sim)
        })
    };
    assert_eq!(run(1), run(2));
    assert_eq!(run(2), run(3));

    let mut scene = hanging_square(12, 0.05, 19);
    scene.floor = Some(FloorSpec {
        height: 0.9,
        ..FloorSpec::default()
    });
    let mut sim = Simulation::new(scene).unwrap();
    sim.step(100).unwrap();
    let snapshot = sim.snapshot();
    sim.step(100).unwrap();
    let mut copy = Simulation::restore(snapshot).unwrap();
    copy.step(100).unwrap();
    assert_eq!(state_hash(&copy), state_hash(&sim));
    assert_eq!(copy.energy(), sim.energy());
}

/// The floor and colliders act on the particles, whatever joins them.
#[test]
fn a_mesh_cloth_rests_on_the_floor_above_it() {
    let (vertices, triangles) = jittered_square(12, 1.0, [0.0, 0.0, 0.0], 0.3, 23);
    // Lay it flat (x, y) -> (x, z) at 0.3 m.
    let vertices = vertices.iter().map(|v| [v[0], 0.3, v[1]]).collect();
    let mut scene = mesh_scene(vertices, triangles);
    scene.floor = Some(FloorSpec::default());
    let mut sim = Simulation::new(scene).unwrap();
    sim.advance(1.0).unwrap();
    let y = &sim.positions().y;
    assert!(
        y.iter()
            .all(|&y| y.is_finite() && (0.0019..0.01).contains(&y)),
        "{:?}",
        y.iter().fold(f32::MAX, |a, &b| a.min(b))
    );
}

/// The watchdog's stretch limit reads the mesh's springs: a cloth pulled past it is caught.
#[test]
fn the_watchdog_catches_an_overstretched_mesh_cloth() {
    let mut scene = hanging_square(8, 0.05, 29);
    scene.watchdog.max_stretch = Some(1.5);
    let mut sim = Simulation::new(scene).unwrap();
    sim.step(10).unwrap();
    let n = sim.positions().len();
    let pos = Vec3s::from_fn(n, |p| {
        let x = sim.positions().get(p);
        if p == n / 2 {
            x + Vec3::new(0.0, 0.0, 0.5)
        } else {
            x
        }
    });
    sim.set_positions(&pos).unwrap();
    let err = sim.step(1).unwrap_err().to_string();
    assert!(err.contains("stretch"), "{err}");
}

/// Sag and stretch of a 1 m square of a soft cloth (60 N/m) hung by the first and last 12.5 cm
/// of its top edge and settled under drag proportional to mass, as two different irregular
/// meshes of about 1k vertices and as a coarser one of 289. The bounds are what edge springs
/// reach, not the 2 %: two random triangulations of one resolution differ by 6 % in
/// sag (an edge-spring network is stiffer or softer as its edges happen to line up with the
/// load; a triangle element would not be), and across resolutions the sag converges as any
/// discretisation of the clamp does (the grid cloth too: 9 % from 17 to 33 points a side, then
/// 6 %). Measured in docs/mesh_cloth.md with `examples/mesh_resolution.rs`.
#[test]
fn irregular_meshes_of_the_same_square_hang_alike() {
    let settle = |n: usize, seed: u64| common::settle_clamped(hanging_square(n, 0.06, seed), n);
    let (a, b, coarse) = (settle(33, 1), settle(33, 2), settle(17, 3));
    assert!((0.03..0.2).contains(&a.0), "it hangs: sag {} m", a.0);
    assert!((b.0 / a.0 - 1.0).abs() < 0.08, "sag {} m vs {} m", a.0, b.0);
    assert!((b.1 / a.1 - 1.0).abs() < 0.10, "stretch {} vs {}", a.1, b.1);
    assert!(
        (coarse.0 / a.0 - 1.0).abs() < 0.12,
        "sag {} m vs {} m",
        coarse.0,
        a.0
    );
    eprintln!("sag and stretch: {a:?} {b:?}, coarse {coarse:?}");
}

/// A mesh cloth dropped on a box drapes over it: every step, no vertex is inside the box (the
/// collider pass works on particles, whatever joins them).
#[test]
fn a_mesh_cloth_dropped_on_a_box_never_ends_a_step_inside_it() {
    let (vertices, triangles) = jittered_square(20, 1.0, [0.0; 3], 0.3, 37);
    let vertices = vertices.iter().map(|v| [v[0], 0.6, v[1]]).collect();
    let mut scene = mesh_scene(vertices, triangles);
    scene.dt = 0.7 * scene.stable_dt(IntegratorKind::SymplecticEuler).unwrap();
    let half = [0.2, 0.25, 0.2];
    scene.colliders = vec![ColliderSpec {
        shape: ShapeKind::Box,
        half_extents: Some(half),
        center: [0.0, 0.25, 0.0],
        ..ColliderSpec::default()
    }];
    scene.floor = Some(FloorSpec::default());
    let mut sim = Simulation::new(scene).unwrap();
    for _ in 0..100 {
        sim.step(10).unwrap();
        let pos = sim.positions();
        for p in 0..pos.len() {
            let x = pos.get(p);
            let inside = x.x.abs() < half[0] as f32
                && (x.y - 0.25).abs() < half[1] as f32
                && x.z.abs() < half[2] as f32;
            assert!(!inside, "vertex {p} at {x} is inside the box");
        }
    }
    // It rests on the box's top, draped.
    let top = sim.positions().y.iter().fold(f32::MIN, |a, &b| a.max(b));
    assert!((0.5..0.55).contains(&top), "highest vertex at {top} m");
}

/// Grabbing a vertex and dragging it moves it exactly to the target (a kinematic pin), and
/// the cloth follows.
#[test]
fn a_grabbed_mesh_vertex_goes_where_it_is_dragged() {
    let mut sim = Simulation::new(hanging_square(10, 0.06, 41)).unwrap();
    let p = 45;
    sim.grab(p as i64).unwrap();
    let target = sim.positions().get(p) + Vec3::new(0.0, 0.0, 0.2);
    sim.drag_to(target).unwrap();
    sim.step(200).unwrap();
    assert_eq!(sim.positions().get(p), target);
    assert!(
        sim.positions().get(p + 1).z > 0.05,
        "its neighbour did not follow"
    );
}

/// `{ boundary = true }` pins the outline and the rims of holes: on a 9 x 9 irregular square
/// with the two triangles of one interior cell removed, the 32 vertices of the outer ring and
/// the 4 corners of the hole, found here from the grid coordinates the mesh was made from.
#[test]
fn the_boundary_selection_pins_the_outline_and_the_rims_of_holes() {
    let n = 9;
    let (vertices, triangles) = jittered_square(n, 1.0, [0.0, 0.0, 0.0], 0.3, 5);
    // Horizontal, 1 m up, so that gravity pulls the free vertices out of its plane.
    let vertices = vertices.iter().map(|v| [v[0], 1.0, -v[1]]).collect();
    let cell = 4 * (n - 1) + 4;
    let triangles: Vec<[i64; 3]> = triangles
        .into_iter()
        .enumerate()
        .filter(|&(t, _)| t / 2 != cell)
        .map(|(_, tri)| tri)
        .collect();
    let mut scene = mesh_scene(vertices, triangles);
    scene.cloth.pins = vec![PinSpec::Boundary(PinBoundary { boundary: true })];
    let mut expected: Vec<usize> = (0..n * n)
        .filter(|&p| {
            let (i, j) = (p % n, p / n);
            i == 0 || j == 0 || i == n - 1 || j == n - 1
        })
        .collect();
    let corner = 4 * n + 4;
    expected.extend([corner, corner + 1, corner + n, corner + n + 1]);
    expected.sort_unstable();
    assert_eq!(scene.cloth.pinned_indices(), expected);
    // Pinned, the sheet keeps its outline and the hole's rim; the rest sags like a drum skin.
    let sim_scene = Scene {
        dt: 0.5 * scene.stable_dt(IntegratorKind::SymplecticEuler).unwrap(),
        ..scene
    };
    let mut sim = Simulation::new(sim_scene).unwrap();
    let start: Vec<Vec3> = expected.iter().map(|&p| sim.positions().get(p)).collect();
    sim.advance(0.2).unwrap();
    for (&p, &x) in expected.iter().zip(&start) {
        assert_eq!(sim.positions().get(p), x, "vertex {p}");
    }
    let lowest = sim.positions().y.iter().fold(f32::MAX, |a, &b| a.min(b));
    assert!(lowest < 1.0 - 5e-3, "the skin sagged only to {lowest} m");
}

/// `{ top = d }` pins the vertices within `d` of the highest, whatever their numbering: the top
/// row of a hanging square whose vertices are listed in reverse, which then hangs from it.
#[test]
fn the_top_selection_pins_the_highest_row_however_the_vertices_are_numbered() {
    let n = 10;
    let (vertices, triangles) = jittered_square(n, 1.0, [0.0, 1.0, 0.0], 0.3, 8);
    let last = (n * n - 1) as i64;
    let vertices: Vec<[f64; 3]> = vertices.into_iter().rev().collect();
    let triangles = triangles.into_iter().map(|t| t.map(|k| last - k)).collect();
    let mut scene = mesh_scene(vertices, triangles);
    scene.cloth.pins = vec![PinSpec::Top(PinTop { top: 1e-9 })];
    // The top row was n*n - n .. n*n, reversed: 0 .. n.
    assert_eq!(scene.cloth.pinned_indices(), (0..n).collect::<Vec<_>>());
    // A wider band takes the jittered second row too (jitter at most 0.3 of 1/9 m).
    scene.cloth.pins = vec![PinSpec::Top(PinTop {
        top: 1.0 / 9.0 + 0.04,
    })];
    assert_eq!(scene.cloth.pinned_indices(), (0..2 * n).collect::<Vec<_>>());
    scene.cloth.pins = vec![PinSpec::Top(PinTop { top: 0.0 })];
    scene.dt = 0.5 * scene.stable_dt(IntegratorKind::SymplecticEuler).unwrap();
    let mut sim = Simulation::new(scene).unwrap();
    let top = sim.positions().get(0);
    sim.advance(0.3).unwrap();
    assert_eq!(sim.positions().get(0), top);
    let lowest = sim.positions().y.iter().fold(f32::MAX, |a, &b| a.min(b));
    assert!(
        lowest < 0.5 - 1e-3,
        "it hangs and stretches: lowest at {lowest} m"
    );
}

/// The selections read from TOML on either cloth; the grid's boundary is its four edges, its
/// top (hanging in xy) its top edge; bad values name the pin.
#[test]
fn the_selections_read_from_toml_and_bad_ones_name_the_pin() {
    let grid = |pins: &str| {
        Scene::from_toml_str(&format!(
            "[cloth]\nnx = 6\nny = 5\nplane = \"xy\"\npins = [{pins}]"
        ))
    };
    let named = |names: &[&str]| {
        let mut scene = grid("").unwrap();
        scene.cloth.pins = names.iter().map(|&n| PinSpec::Named(n.into())).collect();
        scene.cloth.pinned_indices()
    };
    let boundary = grid("{ boundary = true }").unwrap().cloth.pinned_indices();
    assert_eq!(
        boundary,
        named(&["top_edge", "bottom_edge", "left_edge", "right_edge"])
    );
    let top = grid("{ top = 0.0 }").unwrap().cloth.pinned_indices();
    assert_eq!(top, named(&["top_edge"]));
    for (pins, says) in [
        ("{ boundary = false }", "selects nothing"),
        ("{ top = -1.0 }", "top must be"),
        ("{ top = nan }", "top must be"),
    ] {
        let err = grid(&format!("3, {pins}")).unwrap_err().to_string();
        assert!(err.starts_with("cloth.pins[1]"), "{pins}: {err}");
        assert!(err.contains(says), "{pins}: {err}");
    }
}

/// Runs the built-in scene `name` for `seconds`, checking every 10 ms that every position is
/// finite and within 5 m and that `outside` holds for every vertex; returns the simulation.
fn run_builtin(name: &str, seconds: f64, outside: impl Fn(Vec3) -> bool) -> Simulation {
    let scene = Scene::builtin(name).unwrap();
    let stable = scene.stable_dt(scene.integrator).unwrap();
    let substep = scene.dt / scene.substeps as f64;
    assert!(
        substep < stable,
        "{name}: substep {substep} s, stable {stable} s"
    );
    let mut sim = Simulation::new(scene).unwrap();
    let every = (0.01 / sim.scene().dt).round() as u64;
    for _ in 0..(seconds / 0.01) as usize {
        sim.step(every).unwrap();
        let pos = sim.positions();
        for p in 0..pos.len() {
            let x = pos.get(p);
            assert!(x.is_finite() && x.abs().max_element() < 5.0, "{name}: {x}");
            assert!(outside(x), "{name}: vertex {p} at {x}");
        }
    }
    sim
}

/// The round tablecloth lands on the round table, falls over its rim all round and never
/// enters the top or the leg.
#[test]
fn the_round_tablecloth_drapes_over_its_round_table() {
    let inside_cylinder = |x: Vec3, radius: f32, y: f32, half: f32| {
        (x.x * x.x + x.z * x.z).sqrt() < radius - 1e-3 && (x.y - y).abs() < half - 1e-3
    };
    let sim = run_builtin("round_tablecloth", 1.0, |x| {
        !inside_cylinder(x, 0.5, 0.75, 0.02) && !inside_cylinder(x, 0.05, 0.365, 0.365)
    });
    let pos = sim.positions();
    // Resting on the top (0.77 m) inside the rim; hanging below it all round.
    let on_top = (0..pos.len()).filter(|&p| {
        let x = pos.get(p);
        (x.x * x.x + x.z * x.z).sqrt() < 0.4
    });
    for p in on_top {
        assert!(
            (0.77..0.8).contains(&pos.get(p).y),
            "vertex {p} at {}",
            pos.get(p)
        );
    }
    for quadrant in 0..4 {
        let angle = quadrant as f32 * std::f32::consts::FRAC_PI_2;
        let hanging = (0..pos.len()).any(|p| {
            let x = pos.get(p);
            x.y < 0.6
                && (x.z.atan2(x.x) - angle).sin().abs() < 0.5
                && x.x * angle.cos() + x.z * angle.sin() > 0.0
        });
        assert!(hanging, "nothing hangs over the rim towards {angle} rad");
    }
}

/// The flag with a hole hangs from its pinned edge by the pole, never inside the pole.
#[test]
fn the_flag_with_a_hole_hangs_from_its_pole() {
    let sim = run_builtin("flag_hole", 1.0, |x| {
        let axis = Vec3::new(0.02, x.y.clamp(0.0, 2.4), 0.0);
        (x - axis).length() > 0.025 - 1e-3
    });
    let pos = sim.positions();
    let pinned = &sim.particles().pinned;
    let scene = Scene::builtin("flag_hole").unwrap();
    let rest = &scene.cloth.mesh.as_ref().unwrap().vertices;
    assert!(pinned.iter().filter(|&&p| p).count() >= 20);
    for p in (0..pos.len()).filter(|&p| pinned[p]) {
        assert_eq!(pos.get(p), Vec3::from(rest[p].map(|x| x as f32)));
    }
    // Its free end fell: the far edge (starting 1.15 to 1.25 m out) is lower than it started.
    let far = (0..pos.len()).filter(|&p| rest[p][0] > 1.15);
    let dropped = far
        .map(|p| rest[p][1] as f32 - pos.get(p).y)
        .fold(f32::MAX, f32::min);
    eprintln!("flag_hole: far edge dropped at least {dropped} m");
    assert!(dropped > 0.05, "the far edge dropped only {dropped} m");
}

/// A mesh numbered in a scattered order (as a file may number it) gets a local numbering that
/// the force pass works in, gathering the state into it and the forces back; each vertex's
/// springs are summed in the same order, so the forces must be bitwise those of the pass in
/// the user's numbering. A mesh numbered row by row is local already and keeps its own.
#[test]
fn the_force_pass_in_a_local_numbering_gives_bitwise_the_forces_of_the_users() {
    let n = 24;
    let m = n * n;
    let (vertices, triangles) = jittered_square(n, 1.0, [0.0, 1.0, 0.0], 0.3, 3);
    // Vertex `old[k]` of the row-by-row mesh is numbered `k` (7919 is prime to 576).
    let old: Vec<usize> = (0..m).map(|k| k * 7919 % m).collect();
    let mut new = vec![0; m];
    for (k, &v) in old.iter().enumerate() {
        new[v] = k;
    }
    let spec = |vertices, triangles| MeshSpec {
        vertices,
        triangles,
        ..MeshSpec::default()
    };
    let ordered = MeshCloth::new(&spec(vertices.clone(), triangles.clone())).unwrap();
    assert!(ordered.local.is_none(), "a row-by-row mesh renumbered");
    let scattered = MeshCloth::new(&spec(
        old.iter().map(|&v| vertices[v]).collect(),
        (triangles.iter())
            .map(|t| t.map(|v| new[v as usize] as i64))
            .collect(),
    ))
    .unwrap();
    assert!(
        scattered.local.is_some(),
        "a scattered mesh kept its numbering"
    );
    let mut plain = scattered.clone();
    plain.set_local(None);
    // Stretched, rippled and moving, so that every spring pulls or pushes and damps.
    let pos = Vec3s::from_fn(m, |v| {
        let [x, y, _] = scattered.rest[v].map(|c| c as f32);
        Vec3::new(1.05 * x, y + 0.02 * (9.0 * x).sin(), 0.03 * (7.0 * y).cos())
    });
    let vel = Vec3s::from_fn(m, |v| {
        Vec3::new((v % 7) as f32 * 0.1, -0.2, (v % 3) as f32 * 0.05)
    });
    let forces = |mesh: &MeshCloth| {
        let mut out = Vec3s::from_fn(m, |v| Vec3::new(0.0, -9.81 * mesh.masses[v] as f32, 0.0));
        let mut scratch = Default::default();
        let isa = rustcloth::simd::isa();
        let over = mesh.add_spring_forces(
            isa,
            (&pos, &vel),
            0.0,
            &mut out,
            &mut scratch,
            64,
            Some(1.5),
        );
        (out, over)
    };
    let ((local, over_local), (user, over_user)) = (forces(&scattered), forces(&plain));
    assert_eq!(over_local, over_user);
    for v in 0..m {
        let bits = |f: &Vec3s| f.get(v).to_array().map(f32::to_bits);
        assert_eq!(bits(&local), bits(&user), "vertex {v}");
    }
}

/// The force pass computes each spring at both of its ends, from the lanes' copies of its
/// parameters; each vertex's sum must be bitwise that of a table of per-spring forces (the
/// force on the first end `F`, added as `+F` there and `-1 * F` at the second end, in the
/// vertex's incidence order), computed here apart: on a mesh in row order, the same mesh
/// renumbered (the local numbering), a sewn garment (seams, some slack) and isometric bending,
/// each before and after cuts, which the lanes' copies must follow; on every instruction set
/// the CPU has.
#[test]
fn computing_each_spring_at_both_ends_gives_bitwise_the_sums_of_a_per_spring_table() {
    let n = 20;
    let (vertices, triangles) = jittered_square(n, 1.0, [0.0, 1.0, 0.0], 0.3, 5);
    let m = n * n;
    let old: Vec<usize> = (0..m).map(|k| k * 7919 % m).collect();
    let mut new = vec![0; m];
    for (k, &v) in old.iter().enumerate() {
        new[v] = k;
    }
    let square = MeshSpec {
        vertices: vertices.clone(),
        triangles: triangles.clone(),
        ..MeshSpec::default()
    };
    let scattered = MeshSpec {
        vertices: old.iter().map(|&v| vertices[v]).collect(),
        triangles: (triangles.iter())
            .map(|t| t.map(|v| new[v as usize] as i64))
            .collect(),
        ..MeshSpec::default()
    };
    let bending = MeshSpec {
        bending: rustcloth::scene::BendingKind::Isometric,
        ..scattered.clone()
    };
    let shirt = Scene::builtin("shirt").unwrap().sewn().unwrap();
    let garment = shirt.cloth.mesh.unwrap();
    for (name, spec, sewing) in [
        ("row order", square, 0.0),
        ("scattered", scattered, 0.0),
        ("isometric bending", bending, 0.0),
        ("garment", garment, 0.4),
    ] {
        let mesh = MeshCloth::new(&spec).unwrap();
        let mut topology = rustcloth::mesh_cloth::MeshTopology::new(mesh);
        for cut in [false, true] {
            if cut {
                let springs = topology.mesh.springs.len() as u32;
                assert!(topology.sever((0..springs).step_by(37)) > 0);
            }
            let mesh = &topology.mesh;
            assert_spring_sums_bitwise(mesh, sewing, &format!("{name}, cut {cut}"));
        }
    }
}

/// Compares [`MeshCloth::add_spring_forces`] on every instruction set this CPU has, in one
/// process, with a per-spring table summed vertex by vertex.
fn assert_spring_sums_bitwise(mesh: &MeshCloth, sewing: f32, name: &str) {
    for isa in [Isa::Baseline, Isa::Avx2, Isa::Avx512] {
        if rustcloth::simd::has(isa) {
            assert_spring_sums_bitwise_on(isa, mesh, sewing, &format!("{name}, {isa:?}"));
        }
    }
}

fn assert_spring_sums_bitwise_on(isa: Isa, mesh: &MeshCloth, sewing: f32, name: &str) {
    let m = mesh.len();
    let pos = Vec3s::from_fn(m, |v| {
        let [x, y, z] = mesh.rest[v].map(|c| c as f32);
        Vec3::new(
            1.05 * x,
            y + 0.02 * (9.0 * x).sin(),
            z + 0.03 * (7.0 * y).cos(),
        )
    });
    let vel = Vec3s::from_fn(m, |v| {
        Vec3::new((v % 7) as f32 * 0.1, -0.2, (v % 3) as f32 * 0.05)
    });
    let start = |v: usize| Vec3::new(0.0, -9.81 * mesh.masses[v] as f32, 0.0);
    let mut out = Vec3s::from_fn(m, start);
    let over = mesh.add_spring_forces(
        isa,
        (&pos, &vel),
        sewing,
        &mut out,
        &mut Default::default(),
        64,
        Some(1.02),
    );
    let s = &mesh.springs;
    let linear = mesh.bending.as_ref().map(|b| &b.linear);
    let coordinate = |x: &Vec3s, v: u32| x.get(v as usize).to_array();
    let mut any_over = false;
    let table: Vec<[f32; 3]> = (0..s.len())
        .map(|e| {
            let (a, b) = (s.a[e], s.b[e]);
            let (xa, xb) = (coordinate(&pos, a), coordinate(&pos, b));
            let (va, vb) = (coordinate(&vel, a), coordinate(&vel, b));
            let d: [f32; 3] = std::array::from_fn(|c| xb[c] - xa[c]);
            let w: [f32; 3] = std::array::from_fn(|c| vb[c] - va[c]);
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let seam = s.kind[e] == EdgeKind::Seam;
            let rest = if seam { s.rest[e] * sewing } else { s.rest[e] };
            any_over |= !seam && s.active[e] && l > 1.02 * rest;
            let u: [f32; 3] = std::array::from_fn(|c| if l > 0.0 { d[c] / l } else { d[c] * 0.0 });
            let closing = w[0] * u[0] + w[1] * u[1] + w[2] * u[2];
            let magnitude = s.k[e] * (l - rest) + s.c[e] * closing;
            let f: [f32; 3] = match seam && l <= rest {
                true => [0.0; 3],
                false => u.map(|u| magnitude * u),
            };
            match linear {
                Some(linear) => std::array::from_fn(|c| f[c] + linear[e] * d[c]),
                None => f,
            }
        })
        .collect();
    assert_eq!(over, any_over, "{name}: the stretch watch");
    for v in 0..m {
        let mut sum = start(v).to_array();
        for &e in &mesh.incident[mesh.offsets[v] as usize..mesh.offsets[v + 1] as usize] {
            let sign = 1.0 - 2.0 * (e & 1) as f32;
            for c in 0..3 {
                sum[c] += table[(e >> 1) as usize][c] * sign;
            }
        }
        assert_eq!(
            out.get(v).to_array().map(f32::to_bits),
            sum.map(f32::to_bits),
            "{name}: vertex {v}"
        );
    }
}
