//! The V-cycle on the systems implicit Euler builds for a stiff mesh cloth: a jittered square
//! of the example's material (`examples/mesh_implicit.rs`) held by two corners, stretched 5 %
//! one way and rippled out of its plane, so that some springs pull and some are slack.

use glam::Vec3;

use super::*;
use crate::linear::ConjugateGradient;
use crate::mesh_cloth::{jittered_square, MeshCloth};
use crate::scene::MeshSpec;

const H: f32 = 1.0 / 60.0;

/// The step's matrix (`M + sum C_s`, filtered at the held corners) and its isotropic part.
fn stiff_system(n: usize) -> (SpringMatrix, SpringMatrix) {
    let (vertices, triangles) = jittered_square(n, 1.0, [0.0, 0.0, 0.0], 0.3, 7);
    let spec = MeshSpec {
        vertices: vertices.iter().map(|v| [v[0], 0.0, v[1]]).collect(),
        triangles,
        density: 0.5,
        stretch: 1500.0,
        bend: 200.0,
        damping: 0.02,
        ..MeshSpec::default()
    };
    let mesh = MeshCloth::new(&spec).unwrap();
    let s = &mesh.springs;
    let held = |v: usize| v == n * (n - 1) || v == n * n - 1;
    let pos: Vec<Vec3> = mesh
        .rest
        .iter()
        .map(|r| {
            let (x, z) = (r[0] as f32, r[2] as f32);
            Vec3::new(1.05 * x, 0.05 * (9.0 * x).sin() * (7.0 * z).cos(), z)
        })
        .collect();
    let new = || SpringMatrix::new(&s.a, &s.b, &mesh.offsets, &mesh.incident);
    let (mut step, mut reference) = (new(), new());
    for v in 0..mesh.len() {
        let m = mesh.masses[v] as f32;
        step.diagonal[v] = Sym3([m, m, m, 0.0, 0.0, 0.0]);
        reference.diagonal[v] = step.diagonal[v];
    }
    for e in 0..s.len() {
        let (a, b) = (s.a[e] as usize, s.b[e] as usize);
        let (k, c) = (s.k[e], s.c[e]);
        let d = pos[b] - pos[a];
        let g = (1.0 - s.rest[e] / d.length()).max(0.0);
        let block = Sym3::outer(H * c + H * H * k * (1.0 - g), d.normalize(), H * H * k * g);
        let iso = Sym3::outer(0.0, Vec3::ZERO, H * c + H * H * k);
        for (matrix, block) in [(&mut step, block), (&mut reference, iso)] {
            matrix.diagonal[a].add_scaled(1.0, &block);
            matrix.diagonal[b].add_scaled(1.0, &block);
            let live = !held(a) && !held(b);
            matrix.off[e] = Sym3(block.0.map(|x| if live { -x } else { 0.0 }));
        }
    }
    for matrix in [&mut step, &mut reference] {
        for v in (0..mesh.len()).filter(|&v| held(v)) {
            matrix.diagonal[v] = Sym3::ZERO;
        }
        matrix.gather();
    }
    (step, reference)
}

/// A fixed pseudo-random vector, zero at the held vertices (zero diagonal).
fn random(matrix: &SpringMatrix, seed: u64) -> Vec3s {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32 - 0.5
    };
    Vec3s::from_fn(matrix.len(), |v| {
        let r = Vec3::new(next(), next(), next());
        if matrix.diagonal[v] == Sym3::ZERO {
            Vec3::ZERO
        } else {
            r
        }
    })
}

fn dot(a: &Vec3s, b: &Vec3s) -> f64 {
    (0..a.len()).map(|v| a.get(v).dot(b.get(v)) as f64).sum()
}

/// CG iterations to the solver's default tolerance (1e-4) on `step dv = b`, `b` random.
fn iterations(amg: &mut Amg, step: &SpringMatrix) -> u32 {
    let b = random(step, 3);
    let mut x = Vec3s::zeros(step.len());
    let mut cg = ConjugateGradient::new(step.len());
    let (iterations, residual) =
        cg.solve(step, &b, &mut x, 1e-4, 500, |r, z| amg.apply(step, r, z));
    assert!(
        residual <= 1e-4,
        "not converged: {residual} after {iterations}"
    );
    iterations
}

#[test]
fn the_v_cycle_is_a_symmetric_positive_definite_preconditioner() {
    let (step, reference) = stiff_system(33);
    let mut amg = Amg::new(&reference);
    assert!(amg.sizes().len() >= 3, "levels {:?}", amg.sizes());
    amg.update(&step);
    for seed in 0..4 {
        let (x, y) = (random(&step, 2 * seed + 1), random(&step, 2 * seed + 2));
        let (mut mx, mut my) = (Vec3s::zeros(step.len()), Vec3s::zeros(step.len()));
        amg.apply(&step, &x, &mut mx);
        amg.apply(&step, &y, &mut my);
        let (xmy, ymx, xmx, ymy) = (dot(&x, &my), dot(&y, &mx), dot(&x, &mx), dot(&y, &my));
        assert!(xmx > 0.0 && ymy > 0.0, "x M x {xmx}, y M y {ymy}");
        assert!(
            (xmy - ymx).abs() <= 1e-5 * (xmx * ymy).sqrt(),
            "x M y {xmy} against y M x {ymx}"
        );
        for v in (0..step.len()).filter(|&v| step.diagonal[v] == Sym3::ZERO) {
            assert_eq!(mx.get(v), Vec3::ZERO, "held vertex {v} moved");
        }
    }
}

#[test]
fn cg_iterations_grow_little_from_1k_to_16k_vertices() {
    let counts: Vec<u32> = [33, 129]
        .map(|n| {
            let (step, reference) = stiff_system(n);
            let mut amg = Amg::new(&reference);
            amg.update(&step);
            iterations(&mut amg, &step)
        })
        .to_vec();
    eprintln!("CG iterations at 1k and 16k vertices: {counts:?}");
    // Block Jacobi alone takes over a hundred at 1k and four hundred at 16k.
    assert!(counts.iter().all(|&c| c <= 25), "iterations {counts:?}");
    assert!(counts[1] <= counts[0] + 8, "iterations {counts:?}");
}

#[test]
fn reusing_the_reference_coarse_operators_costs_iterations() {
    let (step, reference) = stiff_system(65);
    let mut rebuilt = Amg::new(&reference);
    rebuilt.update(&step);
    let mut reused = Amg::new(&reference);
    reused.update_smoother(&step);
    let (rebuilt, reused) = (
        iterations(&mut rebuilt, &step),
        iterations(&mut reused, &step),
    );
    eprintln!("CG iterations at 4k vertices: rebuilt {rebuilt}, reused {reused}");
    assert!(rebuilt < reused, "rebuilt {rebuilt}, reused {reused}");
}
