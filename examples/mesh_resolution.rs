//! Resolution independence of the mesh cloth's material: the same 1 m square, as irregular
//! meshes of several sizes and as the grid cloth of the same material, hung by the first and
//! last `CLAMP` m of its top edge (the same clamp at every resolution: the top edge's vertices
//! lie on it exactly), settled under air drag, then measured: the sag (how far its centre of
//! mass dropped), the drop of its lowest point, and the largest stretch `l / L - 1` (over all
//! springs, and away from the clamps).
//!
//! `cargo run --release --example mesh_resolution -- [SIZES] [SECONDS] [CLOTHS] [TOP] [SEEDS] [BEND] [CLAMP]`,
//! SIZES points per side (default `17,33`, about 300 and 1k vertices: seconds), SECONDS
//! simulated (default 3), CLOTHS which to hang (default `springs,grid`; `triangle` is the mesh
//! with `membrane = "triangle"`, `isometric` the springs membrane with `bending =
//! "isometric"`, `triangle-isometric` both), TOP `jittered` (default: the top edge's vertices slide along
//! it as the interior's move, so a clamp's end moves by up to 0.3 spacing from one mesh to the
//! next), `even` (the top row evenly spaced: every mesh holds exactly the same clamps) or
//! `graded` (`graded_square`: SIZES squared vertices, spacing graded toward the clamps' inner
//! ends and the top corners, where the strain is singular, a vertex exactly at each clamp end;
//! GRADING below), SEEDS
//! the meshes' seeds (default `1`; `1,2` hangs two triangulations of each size), BEND the bend
//! springs' modulus (N/m, default 0.8; the isometric cloths take `bend_modulus` 5e-5 N m), CLAMP
//! each clamp's length along the top edge from its corner (m, default 0.125; 0.5 clamps the whole
//! edge, which leaves no clamp end inside the edge where the membrane's strain is singular),
//! GRADING the graded meshes' `radius,exponent,floor` (default `0.3,1,0.15`; see `Grading`),
//! STEP `symplectic` (default: symplectic Euler at 0.7 of its stable step, which a graded
//! mesh's smallest triangles lower by up to the floor) or `implicit:DT` (implicit Euler at `DT`
//! s, for the graded 16k mesh whose explicit step would take hours; the settled shape is the
//! same equilibrium, and the example prints the kinetic energy left to show it settled).
//! docs/mesh_cloth.md quotes `-- 33,65,129 4` (1k, 4k and 16k vertices; about ten minutes on
//! two shared cores, most of it the 16k mesh) and the membrane's runs.

use std::time::Instant;

use rustcloth::mesh_cloth::{graded_square, jittered_square, Grading};
use rustcloth::scene::{BendingKind, ClothSpec, MembraneKind, MeshSpec, PinBox, PinSpec, Plane};
use rustcloth::{IntegratorKind, Scene, Simulation};

/// Length of each clamp along the top edge from a corner, m (the default; see CLAMP above).
const CLAMP: f64 = 0.125;
/// Areal density (kg/m^2) and stretch modulus (N/m): a soft cloth, so that it sags visibly.
const DENSITY: f64 = 0.2;
const STRETCH: f64 = 60.0;
/// Air drag per unit mass, 1/s: settles the cloth without changing where it settles.
const DRAG_RATE: f64 = 4.0;

fn pins(clamp: f64) -> Vec<PinSpec> {
    [[-0.5, -0.5 + clamp], [0.5 - clamp, 0.5]]
        .map(|[x0, x1]| {
            PinSpec::Region(PinBox {
                corners: [[x0, 1.5 - 1e-9, -0.1], [x1, 1.5, 0.1]],
            })
        })
        .to_vec()
}

/// Bending modulus of the `isometric` cloths, N m: the mesh cloth's default.
const BEND_MODULUS: f64 = 5e-5;

/// How the mesh's top edge meets the clamps (TOP above).
#[derive(Clone, Copy, PartialEq)]
enum Top {
    Jittered,
    Even,
    Graded(Grading),
}

fn mesh_scene(
    n: usize,
    (membrane, bending): (MembraneKind, BendingKind),
    top: Top,
    seed: u64,
    bend: f64,
    clamp: f64,
) -> Scene {
    let (vertices, triangles) = match top {
        Top::Graded(grading) => graded_square(n * n, 1.0, [0.0, 1.0, 0.0], clamp, grading, seed),
        Top::Jittered | Top::Even => {
            let (mut vertices, triangles) = jittered_square(n, 1.0, [0.0, 1.0, 0.0], 0.3, seed);
            if top == Top::Even {
                for (i, v) in vertices[n * (n - 1)..].iter_mut().enumerate() {
                    v[0] = i as f64 / (n - 1) as f64 - 0.5;
                }
            }
            (vertices, triangles)
        }
    };
    let mut scene = Scene {
        // The same drag per unit mass on average, whatever the vertex count.
        air_drag: DRAG_RATE * DENSITY / vertices.len() as f64,
        cloth: ClothSpec {
            mesh: Some(MeshSpec {
                vertices,
                triangles,
                density: DENSITY,
                stretch: STRETCH,
                bend,
                damping: 0.01,
                membrane,
                bending,
                bend_modulus: match bending {
                    BendingKind::Springs => MeshSpec::default().bend_modulus,
                    BendingKind::Isometric => BEND_MODULUS,
                },
                ..MeshSpec::default()
            }),
            pins: pins(clamp),
            ..ClothSpec::default()
        },
        ..Scene::default()
    };
    scene.dt = 0.7 * scene.stable_dt(IntegratorKind::SymplecticEuler).unwrap();
    scene
}

/// The grid cloth of the same material: `Y = 2 (k_structural + 2 k_shear)` with the grid's
/// usual 4 : 1, bend `8 k_bend`, the same mass.
fn grid_scene(n: u32, clamp: f64) -> Scene {
    let k_structural = STRETCH / 2.0 / 1.5;
    let mut scene = Scene {
        air_drag: DRAG_RATE * DENSITY / (n * n) as f64,
        cloth: ClothSpec {
            nx: n,
            ny: n,
            size: [1.0, 1.0],
            center: [0.0, 1.0, 0.0],
            plane: Plane::Xy,
            mass: Some(DENSITY),
            k_structural,
            k_shear: k_structural / 4.0,
            k_bend: 0.1,
            damping: 0.001,
            pins: pins(clamp),
            ..ClothSpec::default()
        },
        ..Scene::default()
    };
    scene.dt = 0.7 * scene.stable_dt(IntegratorKind::SymplecticEuler).unwrap();
    scene
}

/// Length below a clamp's inner end over which `measure` takes the mean stretch, m: a fixed
/// physical size, so that the number converges with the mesh where the strain at the end
/// itself (singular) cannot.
const SPAN: f64 = 0.05;

/// The mean stretch of the cloth's material line from each clamp's inner end `SPAN` straight
/// down (the rest point's deformed position by the barycentric coordinates of the rest
/// triangle holding it), the larger of the two; `None` for the grid.
fn stretch_below_clamp_ends(scene: &Scene, sim: &Simulation, clamp: f64) -> Option<f64> {
    let mesh = scene.cloth.mesh.as_ref()?;
    let pos = sim.positions();
    let at = |p: usize| [pos.x[p] as f64, pos.y[p] as f64, pos.z[p] as f64];
    // The deformed position of the rest point `q` (in the square's plane).
    let deformed = |q: [f64; 2]| {
        mesh.triangles.iter().find_map(|t| {
            let [a, b, c] = t.map(|k| mesh.vertices[k as usize]);
            let det = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
            let u = ((q[0] - a[0]) * (c[1] - a[1]) - (q[1] - a[1]) * (c[0] - a[0])) / det;
            let v = ((b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0])) / det;
            let inside = u >= -1e-12 && v >= -1e-12 && u + v <= 1.0 + 1e-12;
            inside.then(|| {
                let [pa, pb, pc] = t.map(|k| at(k as usize));
                [0, 1, 2].map(|i| pa[i] + u * (pb[i] - pa[i]) + v * (pc[i] - pa[i]))
            })
        })
    };
    [-0.5 + clamp, 0.5 - clamp]
        .iter()
        .map(|&x| {
            let top = deformed([x, 1.5])?;
            let below = deformed([x, 1.5 - SPAN])?;
            let d = (0..3).map(|i| (top[i] - below[i]).powi(2)).sum::<f64>();
            Some(d.sqrt() / SPAN - 1.0)
        })
        .try_fold(f64::MIN, |m, s| s.map(|s| m.max(s)))
}

fn measure(label: &str, scene: Scene, seconds: f64, clamp: f64) {
    let mut sim = Simulation::new(scene.clone()).unwrap();
    if let Some(mesh) = &scene.cloth.mesh {
        // The barycentric measure below needs particle `p` to be vertex `p`.
        let pos = sim.positions();
        assert!(mesh
            .vertices
            .iter()
            .enumerate()
            .all(|(p, v)| (pos.x[p] as f64 - v[0]).abs() < 1e-6
                && (pos.y[p] as f64 - v[1]).abs() < 1e-6));
    }
    let start = Instant::now();
    sim.advance(seconds).unwrap();
    let wall = start.elapsed().as_secs_f64();
    let (pos, m) = (sim.positions(), &sim.particles().mass);
    let mass: f64 = m.iter().map(|&m| m as f64).sum();
    let centroid = (0..m.len())
        .map(|p| m[p] as f64 * pos.y[p] as f64)
        .sum::<f64>()
        / mass;
    let lowest = pos.y.iter().fold(f32::MAX, |a, &b| a.min(b)) as f64;
    let strain = sim.spring_strain();
    // Away from the clamps, whose ends concentrate strain more as the mesh refines.
    let away = (0..m.len())
        .filter(|&p| pos.y[p] < 1.5 - 2.0 * clamp.min(CLAMP) as f32)
        .map(|p| strain[p])
        .fold(0.0f32, f32::max);
    let e = sim.energy();
    let span = stretch_below_clamp_ends(&scene, &sim, clamp)
        .map_or("-".to_string(), |s| format!("{s:.5}"));
    println!(
        "{label:>22} {:>6} particles  sag {:.5} m  lowest drop {:.5} m  max stretch {:.5}  \
         away from pins {:.5}  over {SPAN} m below a clamp end {span}  kinetic {:.2e} J  \
         dt {:.2e} s  {wall:.1} s wall",
        m.len(),
        1.0 - centroid,
        0.5 - lowest,
        sim.max_stretch(),
        away,
        e.kinetic,
        sim.dt(),
    );
}

/// A comma-separated argument (or `default` where it is absent), each item parsed; `what`
/// names the argument in the message of a bad item.
fn list<T: std::str::FromStr>(arg: Option<&String>, default: &str, what: &str) -> Vec<T> {
    arg.map_or(default, String::as_str)
        .split(',')
        .map(|s| s.parse().unwrap_or_else(|_| panic!("{what}: {s}")))
        .collect()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let sizes: Vec<usize> = list(
        args.get(1),
        "17,33",
        "SIZES: points per side, comma separated",
    );
    let seconds: f64 = args.get(2).map_or(3.0, |s| s.parse().expect("SECONDS"));
    let cloths: Vec<&str> = args
        .get(3)
        .map_or("springs,grid", String::as_str)
        .split(',')
        .collect();
    let top_name = args.get(4).map_or("jittered", String::as_str);
    let seeds: Vec<u64> = list(args.get(5), "1", "SEEDS: comma separated");
    let bend: f64 = args.get(6).map_or(0.8, |s| s.parse().expect("BEND: N/m"));
    let clamp: f64 = args.get(7).map_or(CLAMP, |s| s.parse().expect("CLAMP: m"));
    let grading: Vec<f64> = list(args.get(8), "0.3,1,0.15", "GRADING: radius,exponent,floor");
    let implicit_dt: Option<f64> = match args.get(9).map_or("symplectic", String::as_str) {
        "symplectic" => None,
        other => Some(
            other
                .strip_prefix("implicit:")
                .and_then(|dt| dt.parse().ok())
                .expect("STEP: symplectic or implicit:DT"),
        ),
    };
    let top = match top_name {
        "jittered" => Top::Jittered,
        "even" => Top::Even,
        "graded" => Top::Graded(Grading {
            radius: grading[0],
            exponent: grading[1],
            floor: grading[2],
        }),
        other => panic!("TOP: jittered, even or graded, got {other}"),
    };
    println!(
        "density {DENSITY} kg/m^2, stretch {STRETCH} N/m, clamps {clamp} m, {seconds} s, \
         top edge {top_name}{}",
        if let Top::Graded(g) = top {
            format!(
                " (radius {}, exponent {}, floor {})",
                g.radius, g.exponent, g.floor
            )
        } else {
            String::new()
        }
    );
    for cloth in cloths {
        let model = match cloth {
            "springs" => (MembraneKind::Springs, BendingKind::Springs),
            "triangle" => (MembraneKind::Triangle, BendingKind::Springs),
            "isometric" => (MembraneKind::Springs, BendingKind::Isometric),
            "triangle-isometric" => (MembraneKind::Triangle, BendingKind::Isometric),
            "grid" => {
                for &n in &sizes {
                    measure(
                        &format!("grid {n}x{n}"),
                        grid_scene(n as u32, clamp),
                        seconds,
                        clamp,
                    );
                }
                continue;
            }
            other => panic!(
                "CLOTHS: springs, triangle, isometric, triangle-isometric or grid, got {other}"
            ),
        };
        for &n in &sizes {
            for &seed in &seeds {
                let mut scene = mesh_scene(n, model, top, seed, bend, clamp);
                if let Some(dt) = implicit_dt {
                    scene.integrator = IntegratorKind::ImplicitEuler;
                    scene.dt = dt;
                }
                measure(&format!("{cloth} {n}x{n} #{seed}"), scene, seconds, clamp);
            }
        }
    }
}
