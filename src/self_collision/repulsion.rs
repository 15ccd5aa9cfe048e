//! The repulsion (soft, what keeps the gap). For each pair (a vertex and a triangle without
//! it, or two edges with no shared vertex), the closest points at `x0` (`geometry.rs`) give
//! weights `c_i` with `sum c_i = 0` and a unit normal `n`, and the gap `g = (sum c_i x_i) . n`.
//! `iterations` Gauss-Seidel sweeps in pair order push every pair with `g < thickness` apart
//! along `n`, shared by inverse mass, `dx_i = w_i c_i (thickness - g) n / sum_j w_j c_j^2`
//! (the sum raised where a vertex would be given more than `LEVER` times the pair's change,
//! see `pair::inverse_mass`).
//! Then, in as many sweeps, each such pair loses its approaching normal velocity (an inelastic
//! impulse of the same shape) and, in the first sweep, by Coulomb friction up to `friction`
//! times that of its tangential relative velocity. Every correction is applied to both sides
//! with weights summing to zero, so momentum is conserved.

use glam::DVec3;

use super::pair::inverse_mass;
use super::SelfCollision;
use crate::state::Kinematics;

impl SelfCollision {
    /// The repulsion sweeps and the inelastic, frictional velocity impulses; returns whether
    /// the velocities it wrote are finite. Leaves in `pushed_most` the most it moved a vertex,
    /// summed over its corrections, each with `eps` for its round-off (m).
    ///
    /// Gauss-Seidel in pair order: each pair is corrected with the positions its predecessors
    /// left, so a vertex in many contacts is not under-corrected as a Jacobi average would (a
    /// vertex lying on a layer touches a dozen triangles and edges). Sequential, so the same for
    /// any thread count; each correction keeps momentum on its own.
    pub(super) fn repel(&mut self, next: &mut Kinematics, inv_mass: &[f32], eps: f64) -> bool {
        let thickness = self.thickness as f64;
        self.pushed.resize(next.pos.len(), 0.0);
        self.near.clear();
        // Pairs beyond twice the gap are out of the sweeps' reach (each moves a vertex by at
        // most the gap's shortfall). An ordered parallel filter: the same for any thread count.
        let pos = &next.pos;
        let near = |k: usize, pair: &super::pair::Pair| {
            (pair.n != DVec3::ZERO && pair.gap(pos) < 2.0 * thickness).then_some((k as u32, false))
        };
        self.near_parts
            .filter_map_into(&self.pairs, 1024, near, &mut self.near);
        for sweep in 0..self.iterations {
            let mut any = false;
            for slot in &mut self.near {
                let pair = &self.pairs[slot.0 as usize];
                let g = pair.gap(&next.pos);
                if g >= thickness {
                    continue;
                }
                any = true;
                if sweep == 0 {
                    self.stats.contacts += 1;
                }
                slot.1 = true;
                if let Some(w) = inverse_mass(pair, inv_mass) {
                    let lambda = (thickness - g) / w;
                    for k in 0..4 {
                        let v = pair.verts[k] as usize;
                        let dx = inv_mass[v] as f64 * pair.c[k] * lambda * pair.n;
                        if dx != DVec3::ZERO {
                            next.pos.set(v, (next.pos.get(v).as_dvec3() + dx).as_vec3());
                            self.pushed[v] += dx.length() + eps;
                        }
                    }
                }
            }
            if !any {
                break;
            }
        }
        // Only the vertices of the pairs corrected moved; they are left at zero for the next.
        self.pushed_most = 0.0;
        for &(k, touched) in &self.near {
            if touched {
                for &v in &self.pairs[k as usize].verts {
                    let p = std::mem::take(&mut self.pushed[v as usize]);
                    self.pushed_most = self.pushed_most.max(p);
                }
            }
        }
        let mut finite = true;
        let mu = self.friction as f64;
        for sweep in 0..self.iterations {
            for &(k, touched) in &self.near {
                if !touched {
                    continue;
                }
                let pair = &self.pairs[k as usize];
                let Some(w) = inverse_mass(pair, inv_mass) else {
                    continue;
                };
                let mut rel = DVec3::ZERO;
                for k in 0..4 {
                    rel += pair.c[k] * next.vel.get(pair.verts[k] as usize).as_dvec3();
                }
                let vn = rel.dot(pair.n);
                if vn >= 0.0 {
                    continue; // already separating
                }
                // Relative velocity change: -vn along n, and (in the first sweep) up to
                // mu |vn| against the sliding.
                let mut dv = -vn * pair.n;
                let tangential = rel - vn * pair.n;
                let speed = tangential.length();
                if sweep == 0 && speed > 0.0 {
                    dv -= tangential * (mu * -vn / speed).min(1.0);
                }
                for k in 0..4 {
                    let v = pair.verts[k] as usize;
                    let du = inv_mass[v] as f64 * pair.c[k] / w * dv;
                    if du != DVec3::ZERO {
                        let u = (next.vel.get(v).as_dvec3() + du).as_vec3();
                        next.vel.set(v, u);
                        finite &= u.is_finite();
                    }
                }
            }
        }
        finite
    }
}
