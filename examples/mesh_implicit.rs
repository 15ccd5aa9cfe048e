//! The implicit solvers on a mesh cloth against the grid: a stiff 1 m square (`k h^2 / m` in the
//! thousands at 1/60 s) held by its two far corners, falling from flat, stepped at 1/60 s by
//! implicit Euler (each preconditioner) and projective dynamics, as an irregular mesh of `n` x `n`
//! jittered points and as the `g` x `g` grid of the same material. Prints the time per step (the best of a few runs of `STEPS` steps, after a warm-up
//! that pays for the factorisations) and the iterations per solve. The time is this process's
//! CPU time where Linux reports it per thread (steady on a shared machine when run with
//! `RAYON_NUM_THREADS=1`), wall time elsewhere.
//!
//! `cargo run --release --example mesh_implicit -- [N] [G] [STEPS] [PRECONDITIONERS]`, defaults
//! `129 128 20 all` (16,641 mesh vertices against 16,384 grid particles; about a minute on two
//! shared cores); `PRECONDITIONERS` a comma-separated list (`multigrid` alone takes seconds) or
//! `all`, and projective dynamics runs only with `all`.
//! Only the ratios measured in one run mean anything on a shared machine.

use std::time::Instant;

use rustcloth::mesh_cloth::{jittered_square, MeshCloth};
use rustcloth::scene::{ClothSpec, MeshSpec, PinSpec, Plane, Preconditioner};
use rustcloth::{IntegratorKind, Scene, Simulation};

/// The grid's stiff drape (`tests/stiff.rs`): 0.5 kg, `k_structural` 500, `k_shear` 125,
/// `k_bend` 25 N/m.
const MASS: f64 = 0.5;
const K_STRUCTURAL: f64 = 500.0;
const K_SHEAR: f64 = 125.0;
const K_BEND: f64 = 25.0;

fn grid_scene(g: u32) -> Scene {
    Scene {
        dt: 1.0 / 60.0,
        cloth: ClothSpec {
            nx: g,
            ny: g,
            size: [1.0, 1.0],
            center: [0.0, 1.5, 0.0],
            plane: Plane::Xz,
            particle_mass: Some(MASS / (g * g) as f64),
            k_structural: K_STRUCTURAL,
            k_shear: K_SHEAR,
            k_bend: K_BEND,
            damping: 0.01,
            pins: vec![PinSpec::Named("top_corners".into())],
            ..ClothSpec::default()
        },
        ..Scene::default()
    }
}

/// The same material as a mesh: `Y = 2 (k_structural + 2 k_shear)`, bend `8 k_bend`
/// (docs/mesh_cloth.md), the same mass, lying in the same plane, held by the same corners.
fn mesh_scene(n: usize) -> Scene {
    let (vertices, triangles) = jittered_square(n, 1.0, [0.0, 0.0, 0.0], 0.3, 7);
    let vertices = vertices.iter().map(|v| [v[0], 1.5, v[1]]).collect();
    let corners = [n * (n - 1), n * n - 1].map(|p| PinSpec::Index(p as i64));
    Scene {
        dt: 1.0 / 60.0,
        cloth: ClothSpec {
            mesh: Some(MeshSpec {
                vertices,
                triangles,
                density: MASS,
                stretch: 2.0 * (K_STRUCTURAL + 2.0 * K_SHEAR),
                bend: 8.0 * K_BEND,
                damping: 0.02,
                ..MeshSpec::default()
            }),
            pins: corners.to_vec(),
            ..ClothSpec::default()
        },
        ..Scene::default()
    }
}

/// The stiffest spring's `k h^2 / m` (m the lighter end's mass).
fn stiffness_ratio(scene: &Scene) -> f64 {
    let mesh = MeshCloth::new(scene.cloth.mesh.as_ref().unwrap()).unwrap();
    let s = &mesh.springs;
    (0..s.len())
        .map(|e| {
            let m = mesh.masses[s.a[e] as usize].min(mesh.masses[s.b[e] as usize]);
            s.k[e] as f64 * scene.dt * scene.dt / m
        })
        .fold(0.0, f64::max)
}

/// Seconds of CPU time of all this process's threads (`/proc/self/task/*/schedstat`), or of
/// wall time where that is not available.
fn clock() -> f64 {
    let cpu = std::fs::read_dir("/proc/self/task").ok().map(|tasks| {
        tasks
            .flatten()
            .filter_map(|t| std::fs::read_to_string(t.path().join("schedstat")).ok())
            .filter_map(|s| s.split_whitespace().next()?.parse::<u64>().ok())
            .sum::<u64>() as f64
            * 1e-9
    });
    cpu.unwrap_or_else(|| {
        static START: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
        START.get_or_init(Instant::now).elapsed().as_secs_f64()
    })
}

fn measure(label: &str, scene: Scene, steps: usize) {
    let mut sim = Simulation::new(scene).unwrap();
    // Warm-up: the first steps pay for allocations and factorisations, and the cloth leaves
    // its flat start.
    sim.step(5).unwrap();
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let start = clock();
        sim.step(steps as u64).unwrap();
        best = best.min((clock() - start) / steps as f64);
    }
    let stats = sim.solver_stats().unwrap();
    println!(
        "{label:>34}  {:>6} particles  {:>7.2} ms/step  {:>6.1} iterations/solve (most {:>4})  \
         {} factorisations  not converged {}  max stretch {:.3}  setup {:.0} %",
        sim.particles().mass.len(),
        best * 1e3,
        stats.iterations as f64 / stats.solves as f64,
        stats.most_iterations,
        stats.factorizations,
        stats.not_converged,
        sim.max_stretch(),
        100.0 * stats.setup_seconds / (stats.setup_seconds + stats.solve_seconds),
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize, default: usize| args.get(i).map_or(default, |s| s.parse().unwrap());
    let (n, g, steps) = (arg(1, 129), arg(2, 128) as u32, arg(3, 20));
    let chosen = args.get(4).map_or("all", String::as_str);
    let wanted = |name: &str| chosen == "all" || chosen.split(',').any(|c| c == name);
    println!(
        "mesh {n} x {n}, grid {g} x {g}, 1/60 s, mesh stiffest k h^2/m = {:.0}",
        stiffness_ratio(&mesh_scene(n))
    );
    for preconditioner in Preconditioner::ALL
        .into_iter()
        .filter(|p| wanted(&p.to_string()))
    {
        for (label, mut scene) in [("grid", grid_scene(g)), ("mesh", mesh_scene(n))] {
            scene.integrator = IntegratorKind::ImplicitEuler;
            scene.preconditioner = preconditioner;
            scene.cg_max_iterations = 2000;
            measure(
                &format!("{label} implicit_euler {preconditioner}"),
                scene,
                steps,
            );
        }
    }
    if chosen != "all" {
        return;
    }
    for (label, mut scene) in [("grid", grid_scene(g)), ("mesh", mesh_scene(n))] {
        scene.integrator = IntegratorKind::ProjectiveDynamics;
        measure(&format!("{label} projective_dynamics"), scene, steps);
    }
}
