//! Scaffolding shared by the Rust integration tests.
#![allow(dead_code)]

use std::hash::{Hash, Hasher};

use glam::Vec3;
use rustcloth::scene::{ClothSpec, Plane};
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
/// whose side it is on for a cut vertex) and its place on the cloth at rest, in m along the
/// grid (`(i dx, j dy)`, a cut vertex where its edge was crossed).
pub struct Drawn {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub owner: Vec<usize>,
    pub rest: Vec<glam::Vec2>,
    /// The number of particles: vertices from here on are cut vertices.
    pub particles: usize,
}

impl Drawn {
    pub fn of(sim: &mut Simulation) -> Drawn {
        let grid = sim.grid();
        let size = sim.scene().cloth.size;
        let spacing = glam::Vec2::new(
            (size[0] / (grid.nx - 1) as f64) as f32,
            (size[1] / (grid.ny - 1) as f64) as f32,
        );
        let at_rest = |p: usize| {
            let (i, j) = grid.coords(p);
            glam::Vec2::new(i as f32, j as f32) * spacing
        };
        let n = grid.len();
        let mut owner: Vec<usize> = (0..n).collect();
        let mut rest: Vec<glam::Vec2> = (0..n).map(at_rest).collect();
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
