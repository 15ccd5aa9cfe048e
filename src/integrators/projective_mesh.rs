//! Projective dynamics on a mesh cloth: the grid's iteration ([`super::ProjectiveDynamics`])
//! with the global matrix `Q` assembled from the mesh's spring list and factored by a sparse
//! Cholesky in a nested-dissection order of the rest shape
//! ([`crate::linear::dissect_points`]), and the local step over that list: each spring's force
//! on its first end into a table, then each vertex gathers its springs in spring order (as the
//! explicit force does, [`crate::mesh_cloth::forces`]), so an iterate is bitwise the same for
//! any number of threads.

use glam::Vec3;
use rayon::prelude::*;

use super::solver::{contact_weight, depth, in_contact, live_or_zero};
use super::StepContext;
use crate::linear::reduce::{dot3, REDUCE_CHUNK};
use crate::linear::{dissect_points, SparseCholesky};
use crate::mesh_cloth::MeshCloth;
use crate::soa::Vec3s;

/// Springs per parallel work item of the per-spring pass.
const SPRING_CHUNK: usize = 4096;

/// `Q = M/h^2 + c_d/h I + sum_s (k_s + c_s/h) A_s^T A_s` (plus `w_c` on the diagonal of each
/// vertex in a predicted contact), factored over the free vertices in the rest shape's
/// nested-dissection `order` (made on the first call); sizes `spring_force`, the local step's
/// table, to the springs.
pub(super) fn factor(
    mesh: &MeshCloth,
    order: &mut Vec<usize>,
    spring_force: &mut Vec3s,
    (h, drag): (f32, f32),
    ctx: &StepContext,
) -> SparseCholesky {
    if order.is_empty() {
        *order = mesh_order(mesh);
    }
    let (mass, w) = (&ctx.particles.mass, &ctx.particles.inv_mass);
    let (h64, drag64) = (h as f64, drag as f64);
    let s = &mesh.springs;
    // Isometric bending's linear term is a zero-rest-length spring of stiffness `w`: its
    // projection is the pair itself, so it joins the constant matrix and nothing else.
    let linear = |e: usize| mesh.bending.as_ref().map_or(0.0, |b| b.linear[e] as f64);
    let weight = |e: usize| s.k[e] as f64 + linear(e) + s.c[e] as f64 / h64;
    let mut diagonal: Vec<f64> = mass
        .iter()
        .map(|&m| m as f64 / (h64 * h64) + drag64 / h64)
        .collect();
    for e in 0..s.len() {
        diagonal[s.a[e] as usize] += weight(e);
        diagonal[s.b[e] as usize] += weight(e);
    }
    for (p, &m) in mass.iter().enumerate() {
        if in_contact(ctx, p) {
            diagonal[p] += contact_weight(m, h) as f64;
        }
    }
    if spring_force.len() != s.len() {
        *spring_force = Vec3s::zeros(s.len());
    }
    let order = order.iter().copied().filter(|&p| w[p] > 0.0).collect();
    let entries = (0..s.len()).map(|e| (s.a[e] as usize, s.b[e] as usize, -weight(e)));
    SparseCholesky::factor_ordered(order, &diagonal, entries)
}

/// The local step at the iterate `x_n + x` (`y` the inertial target, both as displacements) into
/// the per-spring table `spring_force`, and the gradient into `grad`
/// `g = M/h^2 (x - y) + c_d/h (x - x_n) - f_springs(x)` (contacts' terms included, zero for held
/// vertices), as the grid's. Returns `|g|`.
pub(super) fn local_step(
    mesh: &MeshCloth,
    (x, y): (&Vec3s, &Vec3s),
    (grad, spring_force, partials): (&mut Vec3s, &mut Vec3s, &mut [f64]),
    (h, drag): (f32, f32),
    ctx: &StepContext,
) -> f64 {
    let s = &mesh.springs;
    let cur = &ctx.current.pos;
    let inv_h = 1.0 / h;
    let sewing = ctx.forces.sewing(mesh);
    let linear = mesh.bending.as_ref().map(|b| &b.linear[..]);
    spring_force
        .par_chunks_mut(SPRING_CHUNK)
        .enumerate()
        .for_each(|(ci, mut f)| {
            for i in 0..f.len() {
                let e = ci * SPRING_CHUNK + i;
                let (a, b) = (s.a[e] as usize, s.b[e] as usize);
                // The spring's change over the step, then the spring itself.
                let ext = x.get(b) - x.get(a);
                let d = (cur.get(b) - cur.get(a)) + ext;
                let l = d.length();
                let inv_l = if l > 0.0 { 1.0 / l } else { 0.0 };
                let u = d * inv_l;
                // A zero-length spring has no direction and exerts no force; a seam takes its
                // rest length from the clock, and a slack one exerts nothing.
                let magnitude = match s.taut_rest(e, l, sewing) {
                    Some(rest) => {
                        s.k[e] * (l - rest) * (l > 0.0) as u32 as f32 + s.c[e] * inv_h * u.dot(ext)
                    }
                    None => 0.0,
                };
                let force = magnitude * u;
                f.set(i, linear.map_or(force, |w| force + w[e] * d));
            }
        });
    let table = &*spring_force;
    let (mass, inv_mass) = (&ctx.particles.mass, &ctx.particles.inv_mass);
    let contacts = ctx.contacts.filter(|c| c.count > 0);
    let (inv_h2, drag_h) = (inv_h * inv_h, drag * inv_h);
    grad.par_chunks_mut(REDUCE_CHUNK)
        .zip(partials.par_iter_mut())
        .enumerate()
        .for_each(|(ci, (mut g, partial))| {
            let start = ci * REDUCE_CHUNK;
            for i in 0..g.len() {
                let p = start + i;
                let xs = x.get(p);
                let mut gp = mass[p] * inv_h2 * (xs - y.get(p)) + drag_h * xs;
                for &e in &mesh.incident[mesh.offsets[p] as usize..mesh.offsets[p + 1] as usize] {
                    // The table holds the force on the first end: its gradient takes -F, the
                    // second end's +F.
                    let f = table.get((e >> 1) as usize);
                    gp = if e & 1 == 0 { gp - f } else { gp + f };
                }
                if let Some(contacts) = contacts {
                    let normal = contacts.normal.get(p);
                    if normal != Vec3::ZERO {
                        let behind = depth(normal, contacts.offset[p], cur.get(p), xs).max(0.0);
                        gp -= contact_weight(mass[p], h) * behind * normal;
                    }
                }
                let free = inv_mass[p] > 0.0;
                g.set(
                    i,
                    Vec3::new(
                        live_or_zero(free, gp.x),
                        live_or_zero(free, gp.y),
                        live_or_zero(free, gp.z),
                    ),
                );
            }
            let gs = g.as_slices();
            *partial = dot3(gs, gs);
        });
    partials.iter().sum::<f64>().sqrt()
}

/// The nested-dissection order of a mesh's vertices by their rest positions, with the springs
/// (stretch and bend) as the graph.
fn mesh_order(mesh: &MeshCloth) -> Vec<usize> {
    let s = &mesh.springs;
    let neighbours: Vec<u32> = mesh
        .incident
        .iter()
        .map(|&e| {
            let i = (e >> 1) as usize;
            if e & 1 == 0 {
                s.b[i]
            } else {
                s.a[i]
            }
        })
        .collect();
    let offsets = &mesh.offsets;
    dissect_points(&mesh.rest, |p| {
        &neighbours[offsets[p] as usize..offsets[p + 1] as usize]
    })
}
