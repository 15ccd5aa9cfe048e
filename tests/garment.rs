//! Garments from flat panels: the panels' meshes, the seams' pairing, bad input named in the
//! error, and the built-in shirt and skirt sewn on the mannequin (checked against the body's
//! shapes by a distance test written here, apart from the solver's colliders).

use crate::common;

use common::crossings::intersecting_pairs;
use common::{state_hash, with_threads};
use glam::DVec3;
use rustcloth::garment::{Garment, GarmentSpec, PanelSpec, Placement, SeamSpec};
use rustcloth::mesh_cloth::EdgeKind;
use rustcloth::scene::{IntegratorKind, MembraneKind, ShapeKind};
use rustcloth::{Scene, Simulation};

/// A `w` x `h` rectangle with its sides named `bottom`, `right`, `top`, `left`.
fn rectangle(name: &str, w: f64, h: f64, placement: Placement) -> PanelSpec {
    PanelSpec {
        name: name.into(),
        outline: vec![[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]],
        edges: [
            ("bottom", [0, 1]),
            ("right", [1, 2]),
            ("top", [2, 3]),
            ("left", [3, 0]),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect(),
        placement,
        ..PanelSpec::default()
    }
}

fn at(origin: [f64; 3]) -> Placement {
    Placement {
        origin,
        ..Placement::default()
    }
}

fn seam(a: &str, b: &str) -> SeamSpec {
    SeamSpec {
        a: a.into(),
        b: b.into(),
        reverse: false,
    }
}

/// Two squares side by side in the plane z = 0, 5 cm apart, their facing sides sewn.
fn two_squares(width_b: f64) -> GarmentSpec {
    GarmentSpec {
        panels: vec![
            rectangle("a", 0.3, 0.3, at([0.0, 0.0, 0.0])),
            rectangle("b", width_b, 0.3, at([0.35, 0.0, 0.0])),
        ],
        seams: vec![seam("a.right", "b.left")],
        ..GarmentSpec::default()
    }
}

fn error_of(garment: GarmentSpec) -> String {
    garment.compile().expect_err("must be refused").to_string()
}

/// The area of a compiled garment's triangles, m^2.
fn area(mesh: &Garment) -> f64 {
    let v = |k: i64| DVec3::from(mesh.vertices[k as usize]);
    mesh.triangles
        .iter()
        .map(|t| 0.5 * (v(t[1]) - v(t[0])).cross(v(t[2]) - v(t[0])).length())
        .sum()
}

#[test]
fn panel_meshes_cover_the_outline_with_triangles_of_about_the_edge_length() {
    let garment = GarmentSpec {
        panels: vec![rectangle("a", 0.6, 0.4, at([0.0; 3]))],
        edge_length: 0.03,
        ..GarmentSpec::default()
    };
    let mesh = garment.compile().unwrap();
    let v = |k: i64| DVec3::from(mesh.vertices[k as usize]);
    let area = area(&mesh);
    assert!(
        (area - 0.24).abs() < 1e-9,
        "triangles cover {area} m^2, not 0.24"
    );
    // Every triangle is wound the same way (its normal along +z, the placement's).
    for t in &mesh.triangles {
        let n = (v(t[1]) - v(t[0])).cross(v(t[2]) - v(t[0]));
        assert!(n.z > 0.0, "triangle {t:?} faces {n}");
    }
    let mut edges: Vec<f64> = mesh
        .triangles
        .iter()
        .flat_map(|t| (0..3).map(move |k| (t[k], t[(k + 1) % 3])))
        .map(|(a, b)| v(a).distance(v(b)))
        .collect();
    edges.sort_by(f64::total_cmp);
    let median = edges[edges.len() / 2];
    assert!(
        (0.02..=0.04).contains(&median),
        "median edge {median} m for an edge length of 0.03 m"
    );
    assert!(edges[0] > 0.005, "an edge of {} m: a sliver", edges[0]);
    // UVs are the flat layout.
    for (p, uv) in mesh.vertices.iter().zip(&mesh.uvs) {
        assert!((p[0] - uv[0]).abs() < 1e-12 && (p[1] - uv[1]).abs() < 1e-12);
    }
}

#[test]
fn a_hole_is_left_out_of_the_mesh() {
    let mut panel = rectangle("a", 0.4, 0.4, at([0.0; 3]));
    panel.holes = vec![vec![[0.15, 0.15], [0.25, 0.15], [0.25, 0.25], [0.15, 0.25]]];
    let garment = GarmentSpec {
        panels: vec![panel],
        ..GarmentSpec::default()
    };
    let mesh = garment.compile().unwrap();
    let v = |k: i64| DVec3::from(mesh.vertices[k as usize]);
    let area = area(&mesh);
    assert!((area - 0.15).abs() < 1e-9, "area {area}, not 0.16 - 0.01");
    for t in &mesh.triangles {
        let c = (v(t[0]) + v(t[1]) + v(t[2])) / 3.0;
        assert!(
            !(0.15..0.25).contains(&c.x) || !(0.15..0.25).contains(&c.y),
            "a triangle inside the hole"
        );
    }
}

#[test]
fn seam_chains_get_the_same_points_paired_along_their_length() {
    // Sides of 0.3 m and 0.36 m: the points are paired at equal fractions of each side.
    let garment = two_squares(0.3);
    let mut tall = garment.clone();
    tall.panels[1].outline = vec![[0.0, 0.0], [0.3, 0.0], [0.3, 0.36], [0.0, 0.36]];
    for g in [garment, tall] {
        let mesh = g.compile().unwrap();
        let v = |k: i64| DVec3::from(mesh.vertices[k as usize]);
        let height_b = g.panels[1].outline[2][1];
        assert!(
            mesh.seams.len() >= 11,
            "{} pairs on a 0.3 m seam",
            mesh.seams.len()
        );
        for &[a, b] in &mesh.seams {
            let (pa, pb) = (v(a), v(b));
            let (left, right) = if pa.x < pb.x { (pa, pb) } else { (pb, pa) };
            assert!((left.x - 0.3).abs() < 1e-12 && (right.x - 0.35).abs() < 1e-12);
            let fraction = (left.y / 0.3, right.y / height_b);
            assert!((fraction.0 - fraction.1).abs() < 1e-9, "{fraction:?}");
        }
    }
}

/// The `y` of each sewn pair's two ends.
fn sewn_heights(garment: &GarmentSpec) -> Vec<(f64, f64)> {
    let mesh = garment.compile().unwrap();
    let y = |k: i64| mesh.vertices[k as usize][1];
    mesh.seams.iter().map(|&[a, b]| (y(a), y(b))).collect()
}

#[test]
fn a_seam_sews_start_to_end_as_neighbouring_panels_meet() {
    // Side by side, both facing +z: a's right side runs up, b's left side runs down, and
    // each point meets the one level with it. A twisted seam (the shirt's side seams, sewn
    // hem to armpit when the way was picked by distance) would pair the bottom with the top.
    let garment = two_squares(0.3);
    for (ya, yb) in sewn_heights(&garment) {
        assert!((ya - yb).abs() < 1e-9, "{ya} sewn to {yb}");
    }
    // `reverse` sews start to start: bottom to top.
    let mut twisted = garment.clone();
    twisted.seams[0].reverse = true;
    for (ya, yb) in sewn_heights(&twisted) {
        assert!((ya + yb - 0.3).abs() < 1e-9, "{ya} sewn to {yb}");
    }
    // An outline given clockwise runs the other way: the same pairs as the first.
    let mut clockwise = garment.clone();
    // [0, h], [w, h], [w, 0], [0, 0]: the left side, [3, 0], now walks up.
    clockwise.panels[1].outline.reverse();
    let pairs = sewn_heights(&clockwise);
    assert!(!pairs.is_empty());
    for (ya, yb) in pairs {
        assert!((ya - yb).abs() < 1e-9, "{ya} sewn to {yb}");
    }
}

#[test]
fn chains_that_start_on_each_other_are_merged_into_one_piece() {
    // b's left side lies on a's right side: the seam is closed from the start, so its points
    // become shared vertices (one piece, the cloth's springs across it) instead of springs.
    let mut garment = two_squares(0.3);
    garment.panels[1].placement.origin = [0.3, 0.0, 0.0];
    let apart = two_squares(0.3).compile().unwrap();
    let joined = garment.compile().unwrap();
    assert!(joined.seams.is_empty(), "{:?}", joined.seams);
    assert_eq!(
        joined.vertices.len(),
        apart.vertices.len() - apart.seams.len()
    );
    let scene = Scene {
        cloth: rustcloth::scene::ClothSpec {
            garment: Some(garment),
            pins: vec![],
            ..Default::default()
        },
        ..Scene::default()
    };
    // Built in code and sewn by the simulation; serialised as the mesh it compiles to.
    let sim = Simulation::new(scene.clone()).unwrap();
    let again = Scene::from_toml_str(&scene.to_toml_string()).unwrap();
    assert_eq!(&again, sim.scene());
    let labels = sim.piece_labels();
    assert!(labels.iter().all(|&l| l == 0), "more than one piece");
}

#[test]
fn bad_panels_and_seams_are_refused_naming_them() {
    let mut bow = two_squares(0.3);
    bow.panels[0].outline = vec![[0.0, 0.0], [0.3, 0.3], [0.3, 0.0], [0.0, 0.3]];
    let mut flat = two_squares(0.3);
    flat.panels[1].outline = vec![[0.0, 0.0], [0.3, 0.0], [0.6, 0.0]];
    let mut off = two_squares(0.3);
    off.panels[0].edges.insert("right".into(), [1, 7]);
    let mut long = two_squares(0.3);
    long.panels[1].outline = vec![[0.0, 0.0], [0.3, 0.0], [0.3, 0.6], [0.0, 0.6]];
    let mut unknown = two_squares(0.3);
    unknown.seams[0].b = "b.sleeve".into();
    let mut twice = two_squares(0.3);
    twice.seams.push(seam("b.left", "a.left"));
    let cases = [
        (bow, "cloth.garment.panels[0].outline", "intersects itself"),
        (flat, "cloth.garment.panels[1].outline", "zero area"),
        (
            off,
            "cloth.garment.panels[0].edges.right",
            "must run along the panel's boundary",
        ),
        (long, "cloth.garment.seams[0]", "differ too much in length"),
        (unknown, "cloth.garment.seams[0].b", "b.sleeve"),
        (twice, "cloth.garment.seams[1].a", "one seam only"),
    ];
    for (garment, name, phrase) in cases {
        let err = error_of(garment);
        assert!(err.starts_with(name) && err.contains(phrase), "{err}");
    }
    // Through the scene: a garment and a mesh together.
    let text = "[cloth]\npins = []\n[cloth.garment]\n[[cloth.garment.panels]]\nname = \"a\"\n\
                outline = [[0, 0], [1, 0], [1, 0]]\n";
    let err = Scene::from_toml_str(text).unwrap_err().to_string();
    assert!(err.starts_with("cloth.garment.panels[0].outline"), "{err}");
}

#[test]
fn seam_springs_are_their_own_kind_and_close_over_the_sewing_time() {
    let scene = Scene::builtin("skirt").unwrap();
    let sim = Simulation::new(scene).unwrap();
    let mesh = sim.model().mesh().unwrap();
    let seams = mesh
        .springs
        .kind
        .iter()
        .filter(|&&k| k == EdgeKind::Seam)
        .count();
    assert_eq!(seams, pairs(&sim).len());
    assert_eq!(mesh.sewing(0.0), 1.0);
    assert_eq!(mesh.sewing(0.1), 0.5);
    assert_eq!(mesh.sewing(5.0), 0.0);
}

/// The body's shapes as segments with radii: (a, b, r). Spheres are segments of no length.
fn body(scene: &Scene) -> Vec<(DVec3, DVec3, f64)> {
    scene
        .colliders
        .iter()
        .map(|c| {
            let centre = DVec3::from(c.center);
            let r = c.radius.expect("the mannequin's shapes have radii");
            match c.shape {
                ShapeKind::Sphere => (centre, centre, r),
                ShapeKind::Capsule => {
                    // The capsule's axis is its local y, turned by the rotation vector.
                    let turn = glam::DQuat::from_scaled_axis(DVec3::from(c.rotation));
                    let axis = turn * DVec3::Y * c.half_height.expect("a capsule's half height");
                    (centre - axis, centre + axis, r)
                }
                other => panic!("the mannequin has no {other:?}"),
            }
        })
        .collect()
}

/// How far `p` is outside the body (negative: inside), by plain point-segment distances.
fn clearance(shapes: &[(DVec3, DVec3, f64)], p: DVec3) -> f64 {
    shapes
        .iter()
        .map(|&(a, b, r)| {
            let ab = b - a;
            let t = if ab.length_squared() > 0.0 {
                ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
            } else {
                0.0
            };
            p.distance(a + t * ab) - r
        })
        .fold(f64::INFINITY, f64::min)
}

struct Measure {
    /// Largest distance between two sewn vertices, m.
    gap: f64,
    /// Smallest clearance of a cloth vertex from the body, m.
    clearance: f64,
    /// Kinetic energy, J.
    kinetic: f64,
    /// Lowest vertex, m.
    lowest: f64,
}

/// The sewn vertex pairs of a garment's simulation.
fn pairs(sim: &Simulation) -> &[[i64; 2]] {
    let mesh = sim
        .scene()
        .cloth
        .mesh
        .as_ref()
        .expect("a garment is a mesh cloth");
    &mesh.seams.as_ref().expect("a garment has seams").pairs
}

fn measure(sim: &Simulation, shapes: &[(DVec3, DVec3, f64)]) -> Measure {
    let pos = sim.positions();
    let p = |k: usize| pos.get(k).as_dvec3();
    let gap = pairs(sim)
        .iter()
        .map(|&[a, b]| p(a as usize).distance(p(b as usize)))
        .fold(0.0, f64::max);
    let n = pos.len();
    Measure {
        gap,
        clearance: (0..n)
            .map(|k| clearance(shapes, p(k)))
            .fold(f64::INFINITY, f64::min),
        kinetic: sim.energy().kinetic,
        lowest: (0..n).map(|k| p(k).y).fold(f64::INFINITY, f64::min),
    }
}

/// The kinetic energy the built-in garments must be below after 4 s on the mannequin (J): a
/// ten-thousandth of what the shirt has while it drapes (0.1 to 0.2 J), a mean speed of about
/// 1 cm/s for its 0.14 kg. The seams are held to below the self-collision thickness after 2 s.
const MAX_KINETIC: f64 = 1e-5;

/// Sews the built-in garment `name` on the mannequin for 4 s, checking at every 1/60 s frame
/// that no vertex is inside the body and that no two triangles intersect
/// (tests/common/crossings.rs); then the seams after 2 s (closer than the self-collision
/// thickness) and the motion after 4 s. Returns the lowest vertex at 4 s (m).
fn sew(name: &str) -> f64 {
    sew_scene(name, Scene::builtin(name).unwrap())
}

/// [`sew`] for `scene`, the garment `name` with other settings.
fn sew_scene(name: &str, scene: Scene) -> f64 {
    let thickness = scene
        .self_collision
        .as_ref()
        .expect("the garments collide with themselves")
        .thickness;
    let shapes = body(&scene);
    let mut sim = Simulation::new(scene).unwrap();
    let mut closest = f64::INFINITY;
    let mut two = None;
    // Sewn vertices are one point to the crossing checker: each pair's higher index is
    // taken as its lower (the chains of a seam hold no vertex twice).
    let mut same: Vec<u32> = (0..sim.positions().len() as u32).collect();
    for &[a, b] in pairs(&sim) {
        same[a.max(b) as usize] = a.min(b) as u32;
    }
    let triangles = sim.model().mesh().unwrap().triangles.clone();
    // Checked frames with intersecting triangles, and how many pairs.
    let mut crossed = Vec::new();
    for frame in 1..=240 {
        sim.advance(1.0 / 60.0).unwrap();
        let found = intersecting_pairs(&triangles, sim.positions(), |p| same[p as usize]);
        if !found.is_empty() {
            crossed.push((frame, found.len()));
        }
        let m = measure(&sim, &shapes);
        assert!(
            m.clearance.is_finite() && m.clearance > -1e-3,
            "{name}: a vertex {:.4} m inside the body at frame {frame}",
            -m.clearance
        );
        closest = closest.min(m.clearance);
        if frame == 120 {
            two = Some(m);
        }
    }
    let (two, four) = (two.unwrap(), measure(&sim, &shapes));
    // The simulation's own measure, in float32.
    let gap = sim.seam_gap().expect("a garment has seams") as f64;
    assert!((gap - four.gap).abs() < 1e-6, "{gap} and {}", four.gap);
    println!(
        "{name}: gap {:.5} m at 2 s, {:.5} m at 4 s; kinetic {:.3e} J at 4 s; lowest {:.3} m; \
         closest to the body {closest:.5} m",
        two.gap, four.gap, four.kinetic, four.lowest,
    );
    assert!(
        two.gap < thickness,
        "{name}: largest seam gap {} m after 2 s, the thickness {thickness} m",
        two.gap
    );
    assert!(
        four.kinetic < MAX_KINETIC,
        "{name}: kinetic energy {} J after 4 s",
        four.kinetic
    );
    // Sewn vertices are one point to the self-collision pass as to this checker; the panels
    // meet at their seams and nowhere else.
    assert!(
        crossed.is_empty(),
        "{name}: frames with intersecting triangles (frame, pairs): {crossed:?}"
    );
    four.lowest
}

#[test]
fn the_shirt_is_sewn_on_the_mannequin_never_intersects_and_comes_to_rest() {
    // Without self-collision its layers passed through each other while it fell over the head
    // (the checker found 4 triangle pairs at 0.6 s).
    let lowest = sew("shirt");
    // Hanging from the shoulders (they are at 1.47 m), not fallen to the floor.
    assert!(lowest > 0.5, "lowest vertex at {lowest} m");
}

#[test]
fn the_shirt_is_sewn_on_implicit_euler_at_one_step_a_frame_as_on_symplectic_euler() {
    // One implicit step of 1/60 s a frame instead of 83 substeps: the same checks, the
    // self-collision pass after each step.
    let mut scene = Scene::builtin("shirt").unwrap();
    scene.integrator = rustcloth::IntegratorKind::ImplicitEuler;
    scene.dt = 1.0 / 60.0;
    scene.substeps = 1;
    let lowest = sew_scene("shirt", scene);
    assert!(lowest > 0.5, "lowest vertex at {lowest} m");
}

#[test]
fn the_skirt_is_sewn_round_the_waist_stays_up_and_never_intersects() {
    // Its waist started at 1.25 m and its hem at 0.75 m: it has not slid down the body.
    let lowest = sew("skirt");
    assert!(
        lowest > 0.6,
        "lowest vertex at {lowest} m: the skirt slid down"
    );
}

#[test]
fn self_collision_does_not_hold_a_seam_open() {
    // With self-collision on, the edges of two panels' seamed sides are a pair the repulsion
    // kept `thickness` apart, against the seam springs pulling them shut: every seam of the
    // skirt stayed open at the thickness (2.016 mm at 2 mm). Sewn vertices are one point to the
    // pass, as they are once sewn. Two weightless squares 5 cm apart, sewn over 0.2 s.
    let mut garment = two_squares(0.3);
    garment.sew_time = 0.2;
    let thickness = 0.003;
    let scene = Scene {
        gravity: [0.0; 3],
        substeps: 6,
        cloth: rustcloth::scene::ClothSpec {
            garment: Some(garment),
            pins: vec![],
            ..Default::default()
        },
        self_collision: Some(rustcloth::scene::SelfCollisionSpec {
            thickness,
            ..Default::default()
        }),
        ..Scene::default()
    };
    let mut sim = Simulation::new(scene).unwrap();
    let start = sim.seam_gap().unwrap() as f64;
    assert!((start - 0.05).abs() < 1e-6, "{start}");
    sim.advance(0.5).unwrap();
    let gap = sim.seam_gap().unwrap() as f64;
    assert!(
        gap.is_finite() && gap < 0.1 * thickness,
        "seam gap {gap} m after the sewing time, thickness {thickness} m"
    );
    // Nothing else was near enough to touch.
    let stats = sim.self_collision_stats().unwrap();
    assert_eq!(stats.contacts, 0, "{stats:?}");
}

#[test]
fn sewing_is_bitwise_the_same_for_any_thread_count() {
    // The seams are springs of the mesh's list, gathered per vertex in a fixed order; the
    // skirt's close in its first 0.2 s.
    let run = |threads| {
        with_threads(threads, || {
            let mut sim = Simulation::new(Scene::builtin("skirt").unwrap()).unwrap();
            sim.step(300).unwrap();
            state_hash(&sim)
        })
    };
    assert_eq!(run(1), run(2));
}

/// Square `b` hanging from square `a` (its top held) by their seam alone, so the sewn seam
/// carries b's weight and holds it against swinging; stepped 1 s at 1/120 s.
fn hang_by_the_seam(garment: GarmentSpec, integrator: IntegratorKind) -> Simulation {
    use rustcloth::scene::{ClothSpec, PinBox, PinSpec};
    let scene = Scene {
        integrator,
        dt: 1.0 / 120.0,
        substeps: 1,
        cloth: ClothSpec {
            garment: Some(GarmentSpec {
                sew_time: 0.2,
                ..garment
            }),
            pins: vec![PinSpec::Region(PinBox {
                corners: [[-0.01, 0.299, -0.01], [0.301, 0.301, 0.01]],
            })],
            ..Default::default()
        },
        ..Scene::default()
    };
    let mut sim = Simulation::new(scene).unwrap();
    sim.advance(1.0).unwrap();
    sim
}

fn assert_sewn_and_still(sim: &Simulation, what: &str) {
    let gap = sim.seam_gap().unwrap();
    let kinetic = sim.energy().kinetic;
    assert!(gap < 1e-3, "{what}: seam gap {gap} m after 1 s");
    assert!(
        kinetic < MAX_KINETIC,
        "{what}: kinetic energy {kinetic} J after 1 s"
    );
}

#[test]
fn the_implicit_solvers_sew_a_hanging_panel_shut_and_hold_it_still() {
    // The implicit solvers must take the seam as the force pass does: its rest length closing
    // with the clock to zero. Taking the starting 5 cm instead, projective dynamics held the
    // seam 5 cm open, and implicit Euler's matrix lacked the sewn seam's stiffness across it:
    // at 1 s the seam was 3.5 mm open and b still moving with 1.4e-4 J.
    for integrator in [
        IntegratorKind::ImplicitEuler,
        IntegratorKind::ProjectiveDynamics,
    ] {
        let sim = hang_by_the_seam(two_squares(0.3), integrator);
        assert_sewn_and_still(&sim, &integrator.to_string());
    }
}

#[test]
fn a_garment_on_the_triangle_membrane_sews_shut_and_holds_still() {
    // The triangle elements, not edge springs, then hold the panels' stretch and shear; the
    // seams are springs under either membrane.
    let garment = GarmentSpec {
        membrane: MembraneKind::Triangle,
        poisson: 0.3,
        ..two_squares(0.3)
    };
    let scene = Scene {
        cloth: rustcloth::scene::ClothSpec {
            garment: Some(garment.clone()),
            ..Default::default()
        },
        ..Scene::default()
    };
    let mesh = scene.sewn().unwrap().cloth.mesh.unwrap();
    assert_eq!((mesh.membrane, mesh.poisson), (MembraneKind::Triangle, 0.3));
    let sim = hang_by_the_seam(garment, IntegratorKind::ImplicitEuler);
    assert_sewn_and_still(&sim, "triangle membrane");
}

#[test]
fn a_garment_material_out_of_range_is_refused_naming_the_garment_key() {
    let cases = [
        (
            GarmentSpec {
                density: -1.0,
                ..two_squares(0.3)
            },
            IntegratorKind::SymplecticEuler,
            "cloth.garment.density",
        ),
        (
            GarmentSpec {
                poisson: 0.3,
                ..two_squares(0.3)
            },
            IntegratorKind::SymplecticEuler,
            "cloth.garment.poisson",
        ),
        (
            GarmentSpec {
                membrane: MembraneKind::Triangle,
                poisson: 1.0,
                ..two_squares(0.3)
            },
            IntegratorKind::SymplecticEuler,
            "cloth.garment.poisson",
        ),
        (
            GarmentSpec {
                membrane: MembraneKind::Triangle,
                ..two_squares(0.3)
            },
            IntegratorKind::ProjectiveDynamics,
            "cloth.garment.membrane",
        ),
    ];
    for (garment, integrator, name) in cases {
        let scene = Scene {
            integrator,
            cloth: rustcloth::scene::ClothSpec {
                garment: Some(garment),
                ..Default::default()
            },
            ..Scene::default()
        };
        let err = Simulation::new(scene).err().expect("refused").to_string();
        assert!(err.starts_with(name), "{err}");
    }
    // Read from TOML, the garment is compiled as it is read.
    let text = "integrator = \"projective_dynamics\"\n[cloth]\npins = []\n[cloth.garment]\n\
                membrane = \"triangle\"\n[[cloth.garment.panels]]\nname = \"a\"\n\
                outline = [[0, 0], [1, 0], [1, 1]]\n";
    let err = Scene::from_toml_str(text).unwrap_err().to_string();
    assert!(err.starts_with("cloth.garment.membrane"), "{err}");
}
