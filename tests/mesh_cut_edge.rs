//! The drawn edge of a cut through a mesh cloth runs where the stroke crossed the mesh's edges,
//! as the grid's does: the triangles on a severed edge are clipped there, each side with its
//! own cut vertices. Checked against the stroke's geometry, computed here apart from the
//! renderer: the cut vertices lie on the stroke, no drawn triangle reaches across it, and the
//! drawn area on each side of it is the mesh's own area on that side (each triangle clipped by
//! the stroke's half-plane, Sutherland-Hodgman).

use crate::common;

use common::Drawn;
use glam::{DVec2, Vec3};
use rustcloth::mesh_cloth::jittered_square;
use rustcloth::scene::{PinBox, PinSpec};
use rustcloth::{IntegratorKind, Scene, Simulation};

/// The mesh's spacing: a 1 m square of `N` x `N` points.
const N: usize = 16;
const H: f64 = 1.0 / (N - 1) as f64;

/// A hanging 1 m square of jittered points in the xy plane, centre at y = 1, held by its top.
fn hanging() -> Scene {
    let (vertices, triangles) = jittered_square(N, 1.0, [0.0, 1.0, 0.0], 0.3, 7);
    let top = PinSpec::Region(PinBox {
        corners: [[-0.6, 1.49, -0.1], [0.6, 1.6, 0.1]],
    });
    let mut scene = common::mesh_cloth_scene(vertices, triangles, vec![top]);
    scene.dt = 0.7 * scene.stable_dt(IntegratorKind::SymplecticEuler).unwrap();
    scene
}

/// Rays along -z through the line from `a` to `b` (x, y), `samples` of them: the surface they
/// sweep is that segment extruded along z.
fn stroke(a: [f32; 2], b: [f32; 2], samples: usize) -> Vec<(Vec3, Vec3)> {
    (0..samples)
        .map(|k| {
            let s = k as f32 / (samples - 1) as f32;
            let (x, y) = (a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]));
            (Vec3::new(x, y, 2.0), Vec3::NEG_Z)
        })
        .collect()
}

/// The stroke's line in the xy plane: the signed distance of a point from it (m), and the
/// distance from its segment.
struct Line {
    a: DVec2,
    b: DVec2,
}

impl Line {
    fn of(rays: &[(Vec3, Vec3)]) -> Line {
        let at = |r: &(Vec3, Vec3)| r.0.truncate().as_dvec2();
        Line {
            a: at(&rays[0]),
            b: at(&rays[rays.len() - 1]),
        }
    }

    fn side(&self, x: DVec2) -> f64 {
        (self.b - self.a).perp_dot(x - self.a) / (self.b - self.a).length()
    }

    fn distance(&self, x: DVec2) -> f64 {
        let d = self.b - self.a;
        let t = ((x - self.a).dot(d) / d.length_squared()).clamp(0.0, 1.0);
        x.distance(self.a + t * d)
    }
}

fn xy(x: Vec3) -> DVec2 {
    x.truncate().as_dvec2()
}

/// Area of the polygon `points` (shoelace).
fn area(points: &[DVec2]) -> f64 {
    let n = points.len();
    0.5 * (0..n)
        .map(|k| points[k].perp_dot(points[(k + 1) % n]))
        .sum::<f64>()
        .abs()
}

/// The part of triangle `tri` where `side` is positive (Sutherland-Hodgman on one plane).
fn clipped(tri: [DVec2; 3], side: impl Fn(DVec2) -> f64) -> Vec<DVec2> {
    let mut out = Vec::new();
    for k in 0..3 {
        let (p, q) = (tri[k], tri[(k + 1) % 3]);
        let (dp, dq) = (side(p), side(q));
        if dp >= 0.0 {
            out.push(p);
        }
        if (dp >= 0.0) != (dq >= 0.0) {
            out.push(p + dp / (dp - dq) * (q - p));
        }
    }
    out
}

/// The mesh's area on the positive side of `line` and on the negative side, from its own
/// triangles at the particles' positions now.
fn mesh_area_by_side(sim: &Simulation, line: &Line) -> [f64; 2] {
    let mesh = sim.model().mesh().expect("a mesh cloth");
    let pos = sim.positions();
    let mut sides = [0.0; 2];
    for tri in &mesh.triangles {
        let corners = tri.map(|v| xy(pos.get(v as usize)));
        sides[0] += area(&clipped(corners, |x| line.side(x)));
        sides[1] += area(&clipped(corners, |x| -line.side(x)));
    }
    sides
}

/// The drawn area on each side of `line` (a triangle's side is its centroid's), and the most
/// any drawn triangle reaches across it: the smaller of its corners' furthest on each side.
fn drawn_area_by_side(drawn: &Drawn, line: &Line) -> ([f64; 2], f64) {
    let (mut sides, mut across) = ([0.0; 2], 0.0f64);
    for tri in &drawn.triangles {
        let corners = tri.map(|v| xy(drawn.positions[v as usize]));
        let d = corners.map(|x| line.side(x));
        let (lo, hi) = (
            d.iter().copied().fold(0.0, f64::min),
            d.iter().copied().fold(0.0, f64::max),
        );
        across = across.max(hi.min(-lo));
        let centroid = (corners[0] + corners[1] + corners[2]) / 3.0;
        sides[usize::from(line.side(centroid) < 0.0)] += area(&corners);
    }
    (sides, across)
}

/// The furthest a cut vertex is from the stroke's segment (m).
fn worst_cut_vertex(drawn: &Drawn, line: &Line) -> f64 {
    (drawn.positions[drawn.particles..].iter())
        .map(|&x| line.distance(xy(x)))
        .fold(0.0, f64::max)
}

/// The sheet at rest cut by a stroke from `a` to `b` into `pieces`, its line and drawn mesh.
fn cut_at_rest(a: [f32; 2], b: [f32; 2], pieces: usize) -> (Simulation, Line, Drawn) {
    let mut sim = Simulation::new(hanging()).unwrap();
    let rays = stroke(a, b, 5);
    assert!(sim.sever_stroke(&rays).unwrap() > 0);
    assert_eq!(sim.pieces(), pieces);
    let drawn = Drawn::of(&mut sim);
    assert!(drawn.positions.len() > drawn.particles, "no cut vertex");
    (sim, Line::of(&rays), drawn)
}

/// A cut across a flat mesh at rest: every crossing is where the stroke met the edge, so the
/// drawn mesh is the mesh cut exactly along the stroke. Before, the triangles on a severed
/// edge went, leaving a strip about a spacing wide undrawn and no cut vertex.
#[test]
fn the_drawn_edge_of_a_mesh_cut_is_clipped_at_the_stroke() {
    let (sim, line, drawn) = cut_at_rest([-0.8, 0.8], [0.8, 1.15], 2);
    let worst = worst_cut_vertex(&drawn, &line);
    assert!(worst < 1e-5, "a cut vertex is {worst} m from the stroke");
    let (sides, across) = drawn_area_by_side(&drawn, &line);
    assert!(
        across < 1e-5,
        "a drawn triangle reaches {across} m across the cut"
    );
    let expected = mesh_area_by_side(&sim, &line);
    for k in 0..2 {
        let gap = (sides[k] - expected[k]).abs() / expected[k];
        assert!(
            gap < 1e-5,
            "side {k}: drawn {} m^2, the mesh's {} m^2",
            sides[k],
            expected[k]
        );
    }
    drawn.assert_pieces_share_no_vertex(&sim.piece_labels());
}

/// A cut across the sheet once it sags (no longer flat in its plane, the strain uneven) and
/// then as its pieces part: each side's edge stays near the stroke where it was cut, goes with
/// its own piece, and no drawn edge is torn open.
#[test]
fn a_mesh_cuts_drawn_edge_follows_its_pieces_as_they_part() {
    let mut sim = Simulation::new(hanging()).unwrap();
    sim.step(200).unwrap();
    let rays = stroke([-0.8, 0.9], [0.8, 1.1], 9);
    let line = Line::of(&rays);
    assert!(sim.sever_stroke(&rays).unwrap() > 0);
    let drawn = Drawn::of(&mut sim);
    assert!(drawn.positions.len() > drawn.particles, "no cut vertex");
    let worst = worst_cut_vertex(&drawn, &line);
    assert!(
        worst < 0.02 * H,
        "a cut vertex is {} spacings from the stroke",
        worst / H
    );
    let (_, across) = drawn_area_by_side(&drawn, &line);
    assert!(
        across < 0.02 * H,
        "a triangle reaches {} spacings across",
        across / H
    );
    sim.step(150).unwrap();
    let after = Drawn::of(&mut sim);
    after.assert_pieces_share_no_vertex(&sim.piece_labels());
    let stretch = after.max_edge_stretch((0.05 * H) as f32);
    assert!(
        stretch < 1.5,
        "a drawn edge is stretched {stretch} times its rest length"
    );
}

/// A stroke that stops inside the sheet leaves a slit: the triangles at its end have one
/// severed edge and are split to the opposite corner, so the drawn area is the whole mesh's.
#[test]
fn a_mesh_slit_keeps_the_whole_drawn_area() {
    let (sim, line, drawn) = cut_at_rest([-0.8, 1.03], [0.05, 1.03], 1);
    assert!(worst_cut_vertex(&drawn, &line) < 1e-5);
    let (sides, _) = drawn_area_by_side(&drawn, &line);
    let whole = mesh_area_by_side(&sim, &line).iter().sum::<f64>();
    let drawn_area = sides.iter().sum::<f64>();
    assert!(
        (drawn_area - whole).abs() < 1e-5 * whole,
        "drawn {drawn_area}, mesh {whole}"
    );
}
