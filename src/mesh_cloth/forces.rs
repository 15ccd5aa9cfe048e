//! The springs of a mesh cloth added to the force, in two parallel passes: each spring's force
//! on its first end into a per-spring table (the grid's arithmetic, in float32), then each
//! vertex gathers `+F` or `-F` from the springs that touch it, in increasing spring order. The
//! order of every sum is fixed by the mesh, so the result is bitwise the same for any number of
//! threads, and each spring's two ends get bitwise opposite forces (momentum is conserved up to
//! the order of summation).

use rayon::prelude::*;

use super::{EdgeKind, MeshCloth};
use crate::soa::Vec3s;
use crate::springs::overstretched;

/// Springs per parallel work item of the first pass.
const SPRING_CHUNK: usize = 4096;

impl MeshCloth {
    /// Adds the force of every spring at `(pos, vel)` into `out`, using `table` (one entry per
    /// spring, resized here) as scratch, the seams' rest lengths scaled by `sewing`
    /// ([`MeshCloth::sewing`]). With a `watch` limit, also returns whether a spring other
    /// than a seam (whose rest length goes to zero) is longer than that many times its rest
    /// length (the watchdog's stretch check). A seam shorter than its rest length is slack.
    pub fn add_spring_forces(
        &self,
        (pos, vel): (&Vec3s, &Vec3s),
        sewing: f32,
        out: &mut Vec3s,
        table: &mut Vec<[f32; 3]>,
        chunk: usize,
        watch: Option<f32>,
    ) -> bool {
        let s = &self.springs;
        table.resize(s.len(), [0.0; 3]);
        let limit = watch.unwrap_or(f32::INFINITY);
        let over = table
            .par_chunks_mut(SPRING_CHUNK)
            .enumerate()
            .map(|(c, forces)| {
                let mut over = false;
                for (i, f) in forces.iter_mut().enumerate() {
                    let e = c * SPRING_CHUNK + i;
                    let (a, b) = (s.a[e] as usize, s.b[e] as usize);
                    let d = pos.get(b) - pos.get(a);
                    let l = d.length();
                    let rest = if s.kind[e] == EdgeKind::Seam {
                        s.rest[e] * sewing
                    } else {
                        // A severed spring's ends part freely.
                        over |= s.active[e] && overstretched(l, s.rest[e], 1.0, limit);
                        s.rest[e]
                    };
                    let u = if l > 0.0 { d / l } else { d * 0.0 };
                    let closing = (vel.get(b) - vel.get(a)).dot(u);
                    let magnitude = s.k[e] * (l - rest) + s.c[e] * closing;
                    // A seam is a thread: it pulls its ends together, it never pushes them
                    // apart (a pair that came closer than the seam's rest length is slack).
                    let slack = s.kind[e] == EdgeKind::Seam && l <= rest;
                    *f = if slack {
                        [0.0; 3]
                    } else {
                        (magnitude * u).to_array()
                    };
                }
                over
            })
            .reduce(|| false, |x, y| x | y);
        let table = &*table;
        out.par_chunks_mut(chunk)
            .enumerate()
            .for_each(|(c, mut f)| {
                for i in 0..f.len() {
                    let v = c * chunk + i;
                    let mut sum = f.get(i);
                    for &e in self.springs_at(v) {
                        let g = glam::Vec3::from_array(table[(e >> 1) as usize]);
                        sum = if e & 1 == 0 { sum + g } else { sum - g };
                    }
                    f.set(i, sum);
                }
            });
        watch.is_some() && over
    }

    /// Elastic energy of the springs at `pos`, `sum k (l - L)^2 / 2`, in J (f64); a seam
    /// counts at the zero rest length it holds once sewn (while it closes, its rest length is
    /// driven by the clock and the energy is not conserved).
    pub fn elastic_energy(&self, pos: &Vec3s) -> f64 {
        let s = &self.springs;
        (0..s.len())
            .map(|e| {
                let l = (pos.get(s.b[e] as usize) - pos.get(s.a[e] as usize)).length() as f64;
                let rest = if s.kind[e] == EdgeKind::Seam {
                    0.0
                } else {
                    s.rest[e] as f64
                };
                let stretch = l - rest;
                0.5 * s.k[e] as f64 * stretch * stretch
            })
            .sum()
    }

    /// The first spring (in list order) longer than `limit` times its rest length at `pos`,
    /// as `(its first end, l / L)`: the watchdog's report, over every spring as the force
    /// loop's check is.
    pub fn first_overstretched(&self, pos: &Vec3s, limit: f32) -> Option<(usize, f32)> {
        let s = &self.springs;
        (0..s.len())
            .filter(|&e| s.kind[e] != EdgeKind::Seam && s.active[e])
            .find_map(|e| {
                let (a, b) = (s.a[e] as usize, s.b[e] as usize);
                let l = (pos.get(b) - pos.get(a)).length();
                overstretched(l, s.rest[e], 1.0, limit).then(|| (a, l / s.rest[e]))
            })
    }

    /// Per vertex, the largest strain `(l - L) / L` of the live stretch springs that touch it
    /// (0 for a vertex with none).
    pub fn vertex_strain(&self, pos: &Vec3s) -> Vec<f32> {
        let s = &self.springs;
        let mut strain = vec![0.0f32; self.len()];
        for e in (0..s.len()).filter(|&e| s.kind[e] == EdgeKind::Stretch && s.active[e]) {
            let (a, b) = (s.a[e] as usize, s.b[e] as usize);
            let value = (pos.get(b) - pos.get(a)).length() / s.rest[e] - 1.0;
            strain[a] = strain[a].max(value);
            strain[b] = strain[b].max(value);
        }
        strain
    }

    /// Area-weighted vertex normals of `triangles` (the drawn ones) at `pos` (unit;
    /// `fallback` where they cancel or none touches the vertex).
    pub fn vertex_normals(
        &self,
        triangles: impl Iterator<Item = [u32; 3]>,
        pos: &Vec3s,
        fallback: glam::Vec3,
    ) -> Vec3s {
        let mut normals = Vec3s::zeros(self.len());
        for t in triangles {
            let [a, b, c] = t.map(|v| pos.get(v as usize));
            let n = (b - a).cross(c - a);
            for v in t {
                let v = v as usize;
                normals.set(v, normals.get(v) + n);
            }
        }
        for v in 0..self.len() {
            normals.set(v, normals.get(v).try_normalize().unwrap_or(fallback));
        }
        normals
    }
}
