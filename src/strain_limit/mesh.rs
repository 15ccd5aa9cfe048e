//! Strain limiting over a mesh cloth's stretch springs: the grid's check, sweep and velocity
//! correction ([`super::kernel`]) with the stencil's runs replaced by each vertex's list of
//! springs. Each vertex computes, from its own side, the share of every over-limit spring that
//! touches it (`d` pointing from it to the other end), so the two ends of a spring compute
//! exactly opposite moves for equal masses, and gathers them in spring order: bitwise the same
//! for any chunking or number of threads.

use glam::Vec3;
use rayon::prelude::*;

use super::kernel::{over_limit, Kernel};
use super::Check;
use crate::mesh_cloth::{EdgeKind, MeshCloth};
use crate::soa::Vec3s;
use crate::state::Kinematics;

/// The live stretch springs touching vertex `v`, each as `(spring, other end)`.
fn stretch_springs(mesh: &MeshCloth, v: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
    let s = &mesh.springs;
    mesh.incident[mesh.offsets[v] as usize..mesh.offsets[v + 1] as usize]
        .iter()
        .map(|&e| (e >> 1) as usize)
        .filter(|&e| s.kind[e] == EdgeKind::Stretch && s.active[e])
        .map(move |e| {
            let other = if s.a[e] as usize == v { s.b[e] } else { s.a[e] };
            (e, other as usize)
        })
}

impl Kernel<'_> {
    /// [`Kernel::check`] on a mesh: each spring is measured once, at its first end.
    pub(super) fn check_mesh(
        &self,
        mesh: &MeshCloth,
        pos: &Vec3s,
        count: &mut [u8],
        chunk: usize,
    ) -> Check {
        let (s, w, factor) = (&mesh.springs, self.inv_mass, self.factor);
        count
            .par_chunks_mut(chunk)
            .enumerate()
            .map(|(c, count)| {
                let mut total = Check {
                    worst_ratio2: 1.0,
                    ..Check::default()
                };
                for (i, n) in count.iter_mut().enumerate() {
                    let v = c * chunk + i;
                    *n = 0;
                    for (e, other) in stretch_springs(mesh, v) {
                        let l2 = (pos.get(other) - pos.get(v)).length_squared();
                        let is_over = over_limit(l2, s.rest[e], 1.0, factor);
                        let moves = (is_over && w[v] > 0.0) as u8;
                        *n = n.saturating_add(moves);
                        total.movable += moves as u32;
                        if s.a[e] as usize == v {
                            total.over += is_over as u32;
                            let ratio2 = l2 / (s.rest[e] * s.rest[e]);
                            if s.rest[e] > 0.0 && ratio2 <= f32::MAX {
                                total.worst_ratio2 = total.worst_ratio2.max(ratio2);
                            }
                        }
                    }
                }
                total
            })
            .reduce(
                || Check {
                    worst_ratio2: 1.0,
                    ..Check::default()
                },
                Check::merge,
            )
    }

    /// [`Kernel::sweep`] on a mesh.
    pub(super) fn sweep_mesh(
        &self,
        mesh: &MeshCloth,
        pos: &Vec3s,
        count: &[u8],
        out: &mut Vec3s,
        chunk: usize,
    ) -> bool {
        let (s, w, factor) = (&mesh.springs, self.inv_mass, self.factor);
        per_vertex(out, chunk, |v| {
            let x = pos.get(v);
            if count[v] == 0 {
                // Nothing to correct (or it cannot move): it keeps its bits.
                return (x, false);
            }
            let mut sum = Vec3::ZERO;
            for (e, other) in stretch_springs(mesh, v) {
                let d = pos.get(other) - x;
                let l2 = d.length_squared();
                if !over_limit(l2, s.rest[e], 1.0, factor) {
                    continue;
                }
                let l = l2.sqrt();
                let lim = factor * s.rest[e];
                let shared = count[v].max(count[other]) as f32;
                let share = w[v] / (w[v] + w[other]) * ((l - lim) / (l * shared));
                sum += share * d;
            }
            let new = x + sum;
            (
                new,
                new.to_array().map(f32::to_bits) != x.to_array().map(f32::to_bits),
            )
        })
    }

    /// [`Kernel::velocity_corrections`] on a mesh, `(before, after)` as there.
    pub(super) fn velocity_corrections_mesh(
        &self,
        mesh: &MeshCloth,
        (before, after): (&Kinematics, &Vec3s),
        (count, out): (&[u8], &mut Vec3s),
        chunk: usize,
    ) -> bool {
        let (s, w, factor) = (&mesh.springs, self.inv_mass, self.factor);
        per_vertex(out, chunk, |v| {
            let (mut sum, mut any) = (Vec3::ZERO, false);
            if w[v] == 0.0 {
                return (sum, any);
            }
            for (e, other) in stretch_springs(mesh, v) {
                let d0 = before.pos.get(other) - before.pos.get(v);
                if !over_limit(d0.length_squared(), s.rest[e], 1.0, factor) {
                    continue;
                }
                let d = after.get(other) - after.get(v);
                let l2 = d.length_squared();
                let apart = (before.vel.get(other) - before.vel.get(v)).dot(d);
                if !(apart > 0.0 && l2 > 0.0) {
                    continue;
                }
                let shared = count[v].max(count[other]) as f32;
                sum += w[v] / (w[v] + w[other]) * (apart / (l2 * shared)) * d;
                any = true;
            }
            (sum, any)
        })
    }
}

/// Writes `f(v)`'s vector for every vertex `v` into `out`, in parallel chunks of `chunk`
/// vertices, and returns whether any `f(v)` said true.
fn per_vertex(out: &mut Vec3s, chunk: usize, f: impl Fn(usize) -> (Vec3, bool) + Sync) -> bool {
    out.par_chunks_mut(chunk)
        .enumerate()
        .map(|(c, mut out)| {
            let mut any = false;
            for i in 0..out.len() {
                let (value, flag) = f(c * chunk + i);
                out.set(i, value);
                any |= flag;
            }
            any
        })
        .reduce(|| false, |a, b| a | b)
}
