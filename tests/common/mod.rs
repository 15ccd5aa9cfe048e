//! Scaffolding shared by the Rust integration tests.
#![allow(dead_code)]

pub mod crossings;

use std::hash::{Hash, Hasher};

use glam::Vec3;
use rustcloth::scene::{
    ClothSpec, ColliderSpec, FloorSpec, MeshSpec, PinSpec, Plane, SphereSpec, StrainLimitSpec,
};
use rustcloth::soa::Vec3s;
use rustcloth::IntegratorKind;
use rustcloth::{Scene, Simulation};

/// A cloth with no pins, no gravity and no colliders: add what a test needs.
pub fn bare_scene(nx: u32, ny: u32) -> Scene {
    Scene {
        gravity: [0.0; 3],
        cloth: ClothSpec {
            nx,
            ny,
            pins: vec![],
            ..ClothSpec::default()
        },
        ..Scene::default()
    }
}

/// The default scene (under gravity, no colliders) with a mesh cloth of the default material
/// held by `pins`: change `scene.cloth.mesh` for another.
pub fn mesh_cloth_scene(
    vertices: Vec<[f64; 3]>,
    triangles: Vec<[i64; 3]>,
    pins: Vec<PinSpec>,
) -> Scene {
    Scene {
        cloth: ClothSpec {
            mesh: Some(MeshSpec {
                vertices,
                triangles,
                ..MeshSpec::default()
            }),
            pins,
            ..ClothSpec::default()
        },
        ..Scene::default()
    }
}

/// [`bare_scene`] under gravity (9.81 m/s^2 along -y).
pub fn scene_under_gravity(nx: u32, ny: u32) -> Scene {
    let mut scene = bare_scene(nx, ny);
    scene.gravity = [0.0, -9.81, 0.0];
    scene
}

/// The built-in scene `name` with `integrator`, on an `nx` x `ny` grid.
pub fn builtin_scene(name: &str, integrator: IntegratorKind, nx: u32, ny: u32) -> Scene {
    let mut scene = Scene::builtin(name).unwrap();
    scene.integrator = integrator;
    scene.cloth.nx = nx;
    scene.cloth.ny = ny;
    scene
}

/// The built-in `pile` or `twist` as it was tuned, and as the tests on it were built: symplectic
/// Euler at 1 ms steps (the pile in two substeps), spring damping 0.01 N s/m and no
/// self-contact term in a solve. The scenes themselves run implicit Euler at display-frame
/// steps (docs/contact.md, "The scenes at display-frame steps"); these tests count steps and
/// substeps of the explicit run, or compare runs of it bit for bit.
pub fn at_1ms(name: &str) -> Scene {
    let mut scene = Scene::builtin(name).unwrap();
    scene.integrator = IntegratorKind::SymplecticEuler;
    scene.dt = 0.001;
    scene.substeps = if name == "pile" { 2 } else { 1 };
    scene.cloth.damping = 0.01;
    if let Some(spec) = scene.self_collision.as_mut() {
        spec.solve_stiffness = 0.0;
    }
    scene
}

/// The built-in `pile`'s square dropped edge first instead of lowered on its sinking ball:
/// upright (`xy`), its lower edge 15 cm above the floor, beside a 4 cm ball that tips it out of
/// its plane, with stiffer bending (10 N/m) and a less grippy floor (0.5): the hard landing the
/// contact and self-collision tests were built on, with no collider doing work on the cloth.
pub fn edge_first_pile() -> Scene {
    let mut scene = at_1ms("pile");
    scene.cloth.plane = Plane::Xy;
    scene.cloth.center = [0.0, 0.65, 0.0];
    scene.cloth.k_bend = 10.0;
    scene.colliders.clear();
    scene.spheres = vec![SphereSpec {
        center: [0.1, 0.04, 0.03],
        radius: 0.04,
        friction: 0.3,
        thickness: 0.003,
    }];
    if let Some(floor) = scene.floor.as_mut() {
        floor.friction = 0.5;
    }
    scene
}

/// The built-in drape (with its own integrator) on an `n` x `n` grid, hung by the two corners
/// of its top edge instead of falling free.
pub fn hung_drape(n: u32) -> Scene {
    let mut scene = Scene::builtin("drape").unwrap();
    scene.cloth.nx = n;
    scene.cloth.ny = n;
    scene.cloth.pins = vec![PinSpec::Named("top_corners".into())];
    scene
}

/// Where the optional passes of [`every_pass_scene`] act.
pub struct Passes {
    /// The floor's height (m).
    pub floor: f64,
    /// The sphere's centre (m) and radius (m).
    pub sphere: ([f64; 3], f64),
    /// The named pin set.
    pub pins: &'static str,
    /// The watchdog's `max_stretch`.
    pub max_stretch: f64,
}

/// A vertical cloth of `nx` x `ny` in the xy plane with every optional pass the scene can ask
/// for: drag, a floor and a sphere it touches, strain limiting, the watchdog's stretch check.
/// Explicit Euler gets the damping it needs to survive.
pub fn every_pass_scene(nx: u32, ny: u32, integrator: IntegratorKind, passes: Passes) -> Scene {
    let (center, radius) = passes.sphere;
    let mut scene = Scene {
        integrator,
        air_drag: 0.001,
        floor: Some(FloorSpec {
            height: passes.floor,
            ..FloorSpec::default()
        }),
        spheres: vec![SphereSpec {
            center,
            radius,
            ..SphereSpec::default()
        }],
        strain_limit: Some(StrainLimitSpec::default()),
        ..Scene::default()
    };
    scene.cloth.nx = nx;
    scene.cloth.ny = ny;
    scene.cloth.plane = Plane::Xy;
    scene.cloth.pins = vec![PinSpec::Named(passes.pins.into())];
    scene.watchdog.max_stretch = Some(passes.max_stretch);
    if integrator == IntegratorKind::ExplicitEuler {
        scene.cloth.damping = 0.05;
    }
    scene
}

/// A free, level `n` x `n` cloth `size` m across, under gravity, starting at height `y` (m)
/// above `colliders`.
pub fn cloth_over(n: u32, size: f64, y: f64, colliders: Vec<ColliderSpec>) -> Simulation {
    let mut scene = scene_under_gravity(n, n);
    scene.cloth.size = [size, size];
    scene.cloth.center = [0.0, y, 0.0];
    scene.colliders = colliders;
    Simulation::new(scene).unwrap()
}

/// The mean x velocity of the cloth (m/s), summed in f64.
pub fn mean_velocity_x(sim: &Simulation) -> f64 {
    let n = sim.velocities().len();
    (0..n)
        .map(|p| sim.velocities().get(p).x as f64)
        .sum::<f64>()
        / n as f64
}

/// `scene`'s 2 x 2 cloth with three particles cut: one free particle (index 0) at `start`
/// with velocity `v0`, for contact and friction tests against an analytic trajectory.
pub fn lone_particle(scene: Scene, start: Vec3, v0: Vec3) -> Simulation {
    assert_eq!((scene.cloth.nx, scene.cloth.ny), (2, 2));
    let mut sim = Simulation::new(scene).unwrap();
    for p in 1..4 {
        sim.cut(p).unwrap();
    }
    let mut pos = sim.positions().clone();
    pos.set(0, start);
    sim.set_positions(&pos).unwrap();
    let mut vel = Vec3s::zeros(4);
    vel.set(0, v0);
    sim.set_velocities(&vel).unwrap();
    sim
}

/// Two particles joined by one structural spring of rest length 1 m: a 2 x 2 grid in the
/// xy plane with its top row cut away. Particle 0 is at the origin, particle 1 at x = 1.
pub fn two_particle_spring(k: f64, mass: f64, integrator: IntegratorKind, dt: f64) -> Simulation {
    let scene = Scene {
        integrator,
        dt,
        cloth: ClothSpec {
            nx: 2,
            ny: 2,
            size: [1.0, 1.0],
            center: [0.5, 0.5, 0.0],
            plane: Plane::Xy,
            particle_mass: Some(mass),
            k_structural: k,
            k_shear: 0.0,
            k_bend: 0.0,
            damping: 0.0,
            pins: vec![],
            ..ClothSpec::default()
        },
        ..bare_scene(2, 2)
    };
    let mut sim = Simulation::new(scene).unwrap();
    sim.cut(2).unwrap();
    sim.cut(3).unwrap();
    sim
}

/// A hash of every bit of the state, for bitwise comparisons.
pub fn state_hash(sim: &Simulation) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for v in [sim.positions(), sim.velocities()] {
        for c in [&v.x, &v.y, &v.z] {
            for x in c.iter() {
                x.to_bits().hash(&mut h);
            }
        }
    }
    h.finish()
}

pub fn position(sim: &Simulation, p: usize) -> Vec3 {
    sim.positions().get(p)
}

/// Asserts that `run` (a fresh simulation, stepped, hashed with [`state_hash`]) gives the same
/// hash on 1, 2 and 3 threads; `label` names the case in the message.
pub fn assert_bitwise_on_1_2_3_threads(label: &str, run: impl Fn() -> u64 + Sync) {
    let hashes: Vec<u64> = [1, 2, 3]
        .into_iter()
        .map(|threads| with_threads(threads, &run))
        .collect();
    assert!(
        hashes.windows(2).all(|w| w[0] == w[1]),
        "{label}: {hashes:?}"
    );
}

/// Stretches `sim`'s cloth by 5 % about the origin and throws it: drifting at (0.3, -0.2, 0.1)
/// m/s and spinning about z at 2 rad/s.
pub fn throw_spinning_and_stretched(sim: &mut Simulation) {
    let n = sim.positions().len();
    let pos = Vec3s::from_fn(n, |p| sim.positions().get(p) * 1.05);
    let vel = Vec3s::from_fn(n, |p| {
        let x = sim.positions().get(p);
        Vec3::new(0.3, -0.2, 0.1) + Vec3::Z.cross(x) * 2.0
    });
    sim.set_positions(&pos).unwrap();
    sim.set_velocities(&vel).unwrap();
}

/// `sum m v` over the live particles, in kg m/s.
pub fn momentum(sim: &Simulation) -> glam::DVec3 {
    let (vel, particles) = (sim.velocities(), sim.particles());
    (0..vel.len())
        .filter(|&p| particles.alive[p])
        .map(|p| vel.get(p).as_dvec3() * particles.mass[p] as f64)
        .sum()
}

/// Runs `f` on a rayon pool of `threads` threads.
pub fn with_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

/// A proptest config: `cases` cases unless `PROPTEST_CASES` says otherwise, the fixed `seed`
/// unless `PROPTEST_RNG_SEED` does, no failure persistence (a failure prints its seed and its
/// shrunk input; each bug found becomes a named regression test instead).
pub fn proptest_config(cases: u32, seed: u64) -> proptest::test_runner::Config {
    use proptest::test_runner::{Config, FileFailurePersistence, RngAlgorithm, RngSeed};
    let env = |name: &str| std::env::var(name).ok();
    Config {
        cases: env("PROPTEST_CASES").map_or(cases, |v| v.parse().expect("PROPTEST_CASES")),
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(
            env("PROPTEST_RNG_SEED").map_or(seed, |v| v.parse().expect("PROPTEST_RNG_SEED")),
        ),
        failure_persistence: Some(Box::new(FileFailurePersistence::Off)),
        ..Config::default()
    }
}

/// The drawn mesh of a simulation ([`rustcloth::render_mesh`]) as plain arrays, with what the
/// tests of the cut edge need: each vertex's particle (itself for a particle, the particle
/// whose side it is on for a cut vertex) and its place on the cloth at rest, in m (a grid's
/// particle at `(i dx, j dy, 0)`, a mesh's vertex where the mesh puts it, a cut vertex where
/// its edge was crossed).
pub struct Drawn {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub owner: Vec<usize>,
    pub rest: Vec<Vec3>,
    /// The number of particles: vertices from here on are cut vertices.
    pub particles: usize,
}

impl Drawn {
    pub fn of(sim: &mut Simulation) -> Drawn {
        let grid = sim.grid();
        let size = sim.scene().cloth.size;
        let spacing = Vec3::new(
            (size[0] / (grid.nx - 1).max(1) as f64) as f32,
            (size[1] / (grid.ny - 1).max(1) as f64) as f32,
            0.0,
        );
        let mesh_rest: Option<Vec<Vec3>> = (sim.model().mesh()).map(|mesh| {
            mesh.rest
                .iter()
                .map(|&v| glam::DVec3::from(v).as_vec3())
                .collect()
        });
        let at_rest = |p: usize| match &mesh_rest {
            Some(rest) => rest[p],
            None => {
                let (i, j) = grid.coords(p);
                Vec3::new(i as f32, j as f32, 0.0) * spacing
            }
        };
        let n = grid.len();
        let mut owner: Vec<usize> = (0..n).collect();
        let mut rest: Vec<Vec3> = (0..n).map(at_rest).collect();
        for v in sim.render_cut_vertices() {
            let from = v.from as usize;
            owner.push(from);
            rest.push(at_rest(from).lerp(at_rest(v.toward as usize), v.s));
        }
        let triangles = sim.render_triangles().to_vec();
        let pos = sim.render_frame().0;
        let positions = (0..pos.len()).map(|v| pos.get(v)).collect();
        Drawn {
            positions,
            triangles,
            owner,
            rest,
            particles: n,
        }
    }

    /// The largest ratio of a drawn edge's length to its length at rest, over the edges longer
    /// than `floor` m at rest (a cut vertex next to its particle makes a vanishing edge).
    pub fn max_edge_stretch(&self, floor: f32) -> f32 {
        let mut worst = 0.0f32;
        for tri in &self.triangles {
            for e in 0..3 {
                let (a, b) = (tri[e] as usize, tri[(e + 1) % 3] as usize);
                let rest = self.rest[a].distance(self.rest[b]);
                if rest > floor {
                    worst = worst.max(self.positions[a].distance(self.positions[b]) / rest);
                }
            }
        }
        worst
    }

    /// Panics unless every drawn triangle's vertices are on one piece (`labels`, from
    /// `Simulation::piece_labels`), and unless no vertex is drawn by two pieces.
    pub fn assert_pieces_share_no_vertex(&self, labels: &[u32]) {
        let mut piece_of = vec![u32::MAX; self.positions.len()];
        for tri in &self.triangles {
            let piece = labels[self.owner[tri[0] as usize]];
            for &v in tri {
                let v = v as usize;
                assert_eq!(
                    labels[self.owner[v]], piece,
                    "triangle {tri:?} spans two pieces"
                );
                assert!(
                    piece_of[v] == u32::MAX || piece_of[v] == piece,
                    "vertex {v} is drawn by pieces {} and {piece}",
                    piece_of[v]
                );
                piece_of[v] = piece;
            }
        }
    }
}

/// A closed box mesh of half extents `h` centred on the origin: 8 vertices, 12 triangles wound
/// counter-clockwise seen from outside.
pub fn box_mesh(h: [f64; 3]) -> (Vec<[f64; 3]>, Vec<[i64; 3]>) {
    let vertices = (0..8)
        .map(|k| {
            let s = |bit: usize| if k & (1 << bit) != 0 { 1.0 } else { -1.0 };
            [s(0) * h[0], s(1) * h[1], s(2) * h[2]]
        })
        .collect();
    // Each face as a quad (a, b, c, d) counter-clockwise from outside; vertex k has x from
    // bit 0, y from bit 1, z from bit 2.
    let quads = [
        [0, 2, 3, 1], // z-
        [4, 5, 7, 6], // z+
        [0, 4, 6, 2], // x-
        [1, 3, 7, 5], // x+
        [0, 1, 5, 4], // y-
        [2, 6, 7, 3], // y+
    ];
    let triangles = quads
        .iter()
        .flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]])
        .collect();
    (vertices, triangles)
}

/// The point of triangle `(a, b, c)` nearest `p` (Ericson, Real-Time Collision Detection,
/// 5.1.5): written here apart from parry, to judge it.
pub fn closest_on_triangle(
    p: glam::DVec3,
    a: glam::DVec3,
    b: glam::DVec3,
    c: glam::DVec3,
) -> glam::DVec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

/// Signed distance (m) from the local point `q` to a convex closed mesh (negative inside):
/// inside, the largest distance to a face's plane; outside, the distance to the nearest
/// triangle. Exact for convex polyhedra, which is what the tests build.
pub fn convex_mesh_distance(q: glam::DVec3, vertices: &[[f64; 3]], triangles: &[[i64; 3]]) -> f64 {
    let corners = |t: &[i64; 3]| t.map(|k| glam::DVec3::from(vertices[k as usize]));
    let plane = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = corners(t);
            (q - a).dot((b - a).cross(c - a).normalize())
        })
        .fold(f64::NEG_INFINITY, f64::max);
    if plane <= 0.0 {
        return plane;
    }
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = corners(t);
            (q - closest_on_triangle(q, a, b, c)).length()
        })
        .fold(f64::INFINITY, f64::min)
}

/// Coulomb on a surface tilted by `angle` about z: a particle set at rest on it stays put while
/// `tan(angle) <= mu`, else slides down the slope at `a = g (sin - mu cos)`, `a t^2 / 2` in `t`.
/// For `mu` 0.2 and 0.5 and slopes 0.8 and 1.25 times `mu`, `setup(angle, mu)` builds the
/// simulation (particle 0 at rest on the surface) and returns it with the particle's start;
/// after 0.5 s the slide must match to 2 % and `off_surface(sim)` (m) stay below 0.1 mm.
pub fn check_slides_iff_the_slope_beats_friction(
    setup: impl Fn(f64, f64) -> (Simulation, Vec3),
    off_surface: impl Fn(&Simulation) -> f64,
) {
    let (g, t) = (9.81f64, 0.5f64);
    for mu in [0.2f64, 0.5] {
        for ratio in [0.8, 1.25] {
            let angle = (ratio * mu).atan();
            let (mut sim, start) = setup(angle, mu);
            sim.step((t / sim.dt()).round() as u64).unwrap();
            let moved = (sim.positions().get(0) - start).as_dvec3();
            let a = g * (angle.sin() - mu * angle.cos());
            let expected = if a > 0.0 { 0.5 * a * t * t } else { 0.0 };
            let downhill = -glam::DVec3::new(angle.cos(), angle.sin(), 0.0);
            let along = moved.dot(downhill);
            assert!(
                (along - expected).abs() <= 0.02 * expected + 1e-5,
                "mu {mu}, tan {}: slid {along} m, expected {expected}",
                angle.tan()
            );
            let d = off_surface(&sim);
            assert!(d.abs() < 1e-4, "mu {mu}: it left the surface by {d} m");
        }
    }
}

/// A 1 m mesh square (`scene`, `n` x `n` vertices, hanging in xy with its top edge at y = 1.5)
/// hung by the first and last 12.5 cm of its top edge, `stretch` 60 N/m, `bend` 0.8 N/m,
/// `damping` 0.01 N s/m, settled 3 s under drag proportional to mass at 0.7 of symplectic
/// Euler's stable step: its sag (m, how far the centre of mass dropped from y = 1) and its
/// largest edge strain below y = 1.25 (away from the clamps' singular ends).
pub fn settle_clamped(scene: Scene, n: usize) -> (f64, f64) {
    settle_clamped_over(scene, n, 0.125)
}

/// [`settle_clamped`] with clamps `clamp` m long from each top corner (0.5: the whole edge).
pub fn settle_clamped_over(mut scene: Scene, n: usize, clamp: f64) -> (f64, f64) {
    hang_by_clamps(&mut scene, clamp, n * n);
    scene.dt = 0.7 * scene.stable_dt(IntegratorKind::SymplecticEuler).unwrap();
    let sim = settled(scene, 3.0);
    let y = &sim.positions().y;
    let strain = sim.spring_strain();
    let away = (0..y.len())
        .filter(|&p| y[p] < 1.25)
        .map(|p| strain[p])
        .fold(0.0f32, f32::max);
    (centroid_drop(&sim), away as f64)
}

/// The sag (m) of `scene`'s mesh, of `vertices` vertices, hung by two 12.5 cm clamps as
/// [`settle_clamped`] hangs it, settled 4 s under the scene's own integrator and step.
pub fn settle_clamped_implicit(mut scene: Scene, vertices: usize) -> f64 {
    hang_by_clamps(&mut scene, 0.125, vertices);
    centroid_drop(&settled(scene, 4.0))
}

/// Pins the first and last `clamp` m of the top edge (y = 1.5) of a 1 m mesh square of
/// `vertices` vertices, with the material and the drag (proportional to mass) of
/// [`settle_clamped`].
fn hang_by_clamps(scene: &mut Scene, clamp: f64, vertices: usize) {
    scene.cloth.pins = [[-0.5, -0.5 + clamp], [0.5 - clamp, 0.5]]
        .map(|[x0, x1]| {
            PinSpec::Region(rustcloth::scene::PinBox {
                corners: [[x0, 1.5 - 1e-9, -0.1], [x1, 1.5, 0.1]],
            })
        })
        .to_vec();
    let spec = scene.cloth.mesh.as_mut().unwrap();
    (spec.stretch, spec.bend, spec.damping) = (60.0, 0.8, 0.01);
    scene.air_drag = 4.0 * 0.2 / vertices as f64;
}

/// `scene` stepped for `seconds`, asserting it has come to rest.
fn settled(scene: Scene, seconds: f64) -> Simulation {
    let mut sim = Simulation::new(scene).unwrap();
    sim.advance(seconds).unwrap();
    let kinetic = sim.energy().kinetic;
    assert!(kinetic < 1e-5, "not settled: kinetic energy {kinetic} J");
    sim
}

/// How far the centre of mass lies below y = 1 (the hung square's rest centre), m.
fn centroid_drop(sim: &Simulation) -> f64 {
    let (y, m) = (&sim.positions().y, &sim.particles().mass);
    let centroid: f64 = (0..m.len()).map(|p| m[p] as f64 * y[p] as f64).sum::<f64>()
        / m.iter().map(|&m| m as f64).sum::<f64>();
    1.0 - centroid
}

/// Steps `sim` one step a frame for `frames` frames, asserting that its total energy never
/// rises from one frame to the next (beyond 1e-6 of where it started) and that it ends below
/// where it started; `label` names the case.
pub fn assert_energy_never_rises(sim: &mut Simulation, frames: u32, label: &str) {
    let mut last = sim.energy().total();
    let start = last;
    for frame in 0..frames {
        sim.step(1).unwrap();
        let e = sim.energy().total();
        assert!(
            e <= last + 1e-6 * start.abs().max(1e-3),
            "{label}: frame {frame} rose {last} -> {e}"
        );
        last = e;
    }
    assert!(last < start, "{label}: nothing dissipated");
}
