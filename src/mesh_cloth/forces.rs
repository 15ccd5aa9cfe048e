//! The springs of a mesh cloth added to the force, in two parallel passes: each spring's force
//! on its first end into a per-spring table (the grid's arithmetic, in float32), then each
//! vertex gathers `+F` or `-F` from the springs that touch it, in increasing spring order. The
//! order of every sum is fixed by the mesh, so the result is bitwise the same for any number of
//! threads, and each spring's two ends get bitwise opposite forces (momentum is conserved up to
//! the order of summation). Both passes are written for the vector unit: the first gathers a
//! block's differences before its arithmetic, the second sums a group of vertices at once
//! ([`IncidenceLanes`]); neither reorders any operation, so every instruction set gives the
//! same bits. A mesh whose numbering is scattered is worked on in its own local numbering
//! ([`crate::scene::MeshCloth::local`]): the state is gathered into it, the passes run there,
//! the forces are scattered back, each vertex's sum the same.

use rayon::prelude::*;

use super::{EdgeKind, EdgeSprings, MeshCloth};
use crate::scene::{IncidenceLanes, LANES};
use crate::soa::{Vec3SliceMut, Vec3s};
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
        let limit = watch.unwrap_or(f32::INFINITY);
        // Whole groups of vertices per work item; each vertex's sum is the same in any split.
        let per_item = chunk.next_multiple_of(LANES);
        let Some(local) = &self.local else {
            // One entry per spring, and the lanes' padding entry.
            table.resize(s.len() + 1, [0.0; 3]);
            let coordinates = [&pos.x, &pos.y, &pos.z, &vel.x, &vel.y, &vel.z].map(|x| &x[..]);
            let ends = (&s.a[..], &s.b[..]);
            let linear = self.bending.as_ref().map(|b| &b.linear[..]);
            let over =
                spring_pass::<1>(s, linear, ends, coordinates, sewing, limit, &mut table[..]);
            let (table, lanes) = (&*table, &self.lanes);
            out.par_chunks_mut(per_item).enumerate().for_each(|(c, f)| {
                let first = c * per_item / LANES;
                crate::simd::dispatch!(gather_forces(lanes, first, table, f))
            });
            return watch.is_some() && over;
        };
        // In the local numbering: the table, then the positions, velocities and forces
        // gathered into it.
        let n = self.len();
        table.resize(s.len() + 1 + 3 * n, [0.0; 3]);
        let (forces, state) = table.split_at_mut(s.len() + 1);
        let (x, state) = state.split_at_mut(n);
        let (v, f) = state.split_at_mut(n);
        let (vertices, now) = (&local.vertices, &*out);
        (x.par_chunks_mut(per_item).zip(v.par_chunks_mut(per_item)))
            .zip(f.par_chunks_mut(per_item))
            .enumerate()
            .for_each(|(c, ((x, v), f))| {
                let from = &vertices[c * per_item..c * per_item + x.len()];
                for (k, &i) in from.iter().enumerate() {
                    let i = i as usize;
                    x[k] = [pos.x[i], pos.y[i], pos.z[i]];
                    v[k] = [vel.x[i], vel.y[i], vel.z[i]];
                    f[k] = [now.x[i], now.y[i], now.z[i]];
                }
            });
        let (x, v) = (x.as_flattened(), v.as_flattened());
        let coordinates = [x, &x[1..], &x[2..], v, &v[1..], &v[2..]];
        let ends = (&local.a[..], &local.b[..]);
        let linear = self.bending.as_ref().map(|b| &b.linear[..]);
        let over = spring_pass::<3>(s, linear, ends, coordinates, sewing, limit, forces);
        let (forces, lanes) = (&*forces, &local.lanes);
        f.par_chunks_mut(per_item).enumerate().for_each(|(c, f)| {
            let first = c * per_item / LANES;
            crate::simd::dispatch!(gather_local_forces(lanes, first, forces, f))
        });
        let (f, place) = (&*f, &local.place);
        out.par_chunks_mut(per_item)
            .enumerate()
            .for_each(|(c, out)| {
                for k in 0..out.x.len() {
                    let [x, y, z] = f[place[c * per_item + k] as usize];
                    (out.x[k], out.y[k], out.z[k]) = (x, y, z);
                }
            });
        watch.is_some() && over
    }

    /// Elastic energy of the springs at `pos`, `sum k (l - L)^2 / 2`, and of the triangle
    /// membrane's and the isometric bending's elements where the cloth has them, in J (f64); a
    /// seam
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
            .sum::<f64>()
            + (self.membrane.as_ref()).map_or(0.0, |m| m.energy(pos, &s.active))
            + (self.bending.as_ref()).map_or(0.0, |b| b.energy(pos, &s.active))
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

/// Fills `table` (one entry per spring, then the lanes' padding entry `-0.0`; any more entries
/// are left as they are) with the force on the first end of each spring, its ends `ends`
/// indexing `coordinates` (x, y, z of the position, then of the velocity) `STRIDE` apart, plus
/// `linear[e] (x_b - x_a)` where the cloth has isometric bending; whether one other than a
/// seam is longer than `limit` times its rest length.
fn spring_pass<const STRIDE: usize>(
    s: &EdgeSprings,
    linear: Option<&[f32]>,
    ends: (&[u32], &[u32]),
    coordinates: [&[f32]; 6],
    sewing: f32,
    limit: f32,
    table: &mut [[f32; 3]],
) -> bool {
    let over = table[..s.len()]
        .par_chunks_mut(SPRING_CHUNK)
        .enumerate()
        .map(|(c, forces)| {
            let first = c * SPRING_CHUNK;
            // Two builds of the loop: without bending's term it is exactly the springs' own.
            match linear {
                None => crate::simd::dispatch!(spring_forces::<STRIDE, false>(
                    s,
                    (ends, &[]),
                    first,
                    coordinates,
                    (sewing, limit),
                    forces
                )),
                Some(linear) => crate::simd::dispatch!(spring_forces::<STRIDE, true>(
                    s,
                    (ends, linear),
                    first,
                    coordinates,
                    (sewing, limit),
                    forces
                )),
            }
        })
        .reduce(|| false, |x, y| x | y);
    table[s.len()] = [-0.0; 3];
    over
}

/// Springs per block of [`spring_forces`]: the block's gathered differences (six arrays of
/// `f32`) stay in the first-level cache.
const BLOCK: usize = 256;

/// The force on the first end of springs `first..first + out.len()` into `out`; whether one of
/// them other than a seam is longer than `limit` times its rest length. Block by block, the
/// ends' position and velocity differences are gathered into contiguous arrays first, so that
/// the arithmetic (a square root and three divisions a spring) runs as one loop with no branch
/// and no bounds check, which each instruction set's build vectorises. The arithmetic is
/// glam's, component by component in the same order, so every build gives the same bits.
/// With `LINEAR`, each spring's force gains `linear[e] (x_b - x_a)` (isometric bending).
#[inline(always)]
fn spring_forces<const STRIDE: usize, const LINEAR: bool>(
    s: &EdgeSprings,
    (ends, linear): ((&[u32], &[u32]), &[f32]),
    first: usize,
    coordinates: [&[f32]; 6],
    (sewing, limit): (f32, f32),
    out: &mut [[f32; 3]],
) -> bool {
    let mut over = false;
    let mut gathered = [[0.0f32; BLOCK]; 6];
    for (b, out) in out.chunks_mut(BLOCK).enumerate() {
        let springs = first + b * BLOCK..first + b * BLOCK + out.len();
        let block_ends = (&ends.0[springs.clone()], &ends.1[springs.clone()]);
        gather_differences::<STRIDE>(block_ends, coordinates, &mut gathered);
        let n = out.len();
        let (rest, k, c) = (
            &s.rest[springs.clone()],
            &s.k[springs.clone()],
            &s.c[springs.clone()],
        );
        let lin = if LINEAR {
            &linear[springs.clone()]
        } else {
            &[]
        };
        let (kind, active) = (&s.kind[springs.clone()], &s.active[springs]);
        let [dx, dy, dz, wx, wy, wz] = &gathered;
        let (dx, dy, dz, wx, wy, wz) = (&dx[..n], &dy[..n], &dz[..n], &wx[..n], &wy[..n], &wz[..n]);
        for e in 0..n {
            let d = [dx[e], dy[e], dz[e]];
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let seam = kind[e] == EdgeKind::Seam;
            let rest = if seam { rest[e] * sewing } else { rest[e] };
            // A severed spring's ends part freely.
            over |= !seam & active[e] & overstretched(l, rest, 1.0, limit);
            let u = if l > 0.0 {
                [d[0] / l, d[1] / l, d[2] / l]
            } else {
                [d[0] * 0.0, d[1] * 0.0, d[2] * 0.0]
            };
            let closing = wx[e] * u[0] + wy[e] * u[1] + wz[e] * u[2];
            let magnitude = k[e] * (l - rest) + c[e] * closing;
            // A seam is a thread: it pulls its ends together, it never pushes them apart (a
            // pair that came closer than the seam's rest length is slack).
            let slack = seam & (l <= rest);
            let f = if slack {
                [0.0; 3]
            } else {
                [magnitude * u[0], magnitude * u[1], magnitude * u[2]]
            };
            out[e] = if LINEAR {
                let w = lin[e];
                [f[0] + w * d[0], f[1] + w * d[1], f[2] + w * d[2]]
            } else {
                f
            };
        }
    }
    over
}

/// `x_b - x_a` and `v_b - v_a` of the springs with ends `(a, b)` into `into` (x, y, z of the
/// position, then of the velocity), from the first entry on: vertex `i`'s coordinate `c` is
/// `coordinates[c][STRIDE * i]`.
#[inline(always)]
fn gather_differences<const STRIDE: usize>(
    (a, b): (&[u32], &[u32]),
    coordinates: [&[f32]; 6],
    into: &mut [[f32; BLOCK]; 6],
) {
    // One check of the block's largest end lets the loads below go unchecked, and so become
    // the vector unit's gathers.
    let len = coordinates.iter().map(|x| x.len()).min().unwrap_or(0);
    let top = a.iter().chain(b).fold(0, |t, &i| t.max(i as usize + 1));
    assert!(
        top == 0 || ((top - 1) * STRIDE < len && top * STRIDE <= i32::MAX as usize),
        "a spring's end ({}) beyond the {} particles",
        top - 1,
        len.div_ceil(STRIDE)
    );
    for (x, into) in coordinates.into_iter().zip(into.iter_mut()) {
        for ((&i, &j), into) in a.iter().zip(b).zip(into.iter_mut()) {
            // As signed 32-bit offsets, which the vector unit's gathers take directly (an
            // unsigned index is widened to 64 bits, and gathered half as wide).
            let (i, j) = (
                (i as i32 * STRIDE as i32) as isize,
                (j as i32 * STRIDE as i32) as isize,
            );
            // SAFETY: `i` and `j` are at most `(top - 1) * STRIDE < len <= x.len()`, and below
            // `i32::MAX`.
            *into = unsafe { *x.as_ptr().offset(j) - *x.as_ptr().offset(i) };
        }
    }
}

/// Adds to `f` (the forces of the vertices from group `first` on) each vertex's springs' forces
/// from `table` (per spring, on its first end; the padding entry `-0.0`), `+F` at a spring's
/// first end and `-F` at its second, in the order of the vertex's incidence list: a group's
/// [`LANES`] sums advance together, one row of its layout at a time.
#[inline(always)]
fn gather_forces(lanes: &IncidenceLanes, first: usize, table: &[[f32; 3]], f: Vec3SliceMut<'_>) {
    assert!(
        lanes.pad() < table.len() && table.len() <= i32::MAX as usize,
        "a force table without the padding entry"
    );
    let groups =
        f.x.chunks_mut(LANES)
            .zip(f.y.chunks_mut(LANES))
            .zip(f.z.chunks_mut(LANES));
    for (g, ((x, y), z)) in groups.enumerate() {
        let m = x.len();
        let mut sum = [[0.0f32; LANES]; 3];
        for (sum, f) in sum.iter_mut().zip([&*x, &*y, &*z]) {
            sum[..m].copy_from_slice(f);
        }
        add_group(lanes.group(first + g), table, &mut sum);
        for (f, sum) in [x, y, z].into_iter().zip(&sum) {
            f.copy_from_slice(&sum[..m]);
        }
    }
}

/// [`gather_forces`] on forces stored vertex by vertex (`f[k]` the x, y and z of vertex
/// `first * LANES + k` of the local numbering).
#[inline(always)]
fn gather_local_forces(
    lanes: &IncidenceLanes,
    first: usize,
    table: &[[f32; 3]],
    f: &mut [[f32; 3]],
) {
    assert!(
        lanes.pad() < table.len() && table.len() <= i32::MAX as usize,
        "a force table without the padding entry"
    );
    for (g, f) in f.chunks_mut(LANES).enumerate() {
        let mut sum = [[0.0f32; LANES]; 3];
        for (lane, f) in f.iter().enumerate() {
            (sum[0][lane], sum[1][lane], sum[2][lane]) = (f[0], f[1], f[2]);
        }
        add_group(lanes.group(first + g), table, &mut sum);
        for (lane, f) in f.iter_mut().enumerate() {
            *f = [sum[0][lane], sum[1][lane], sum[2][lane]];
        }
    }
}

/// Adds to each lane's `sum` the forces of the group's `rows` ([`IncidenceLanes::group`]) from
/// `table`, whose length the caller checked to be above [`IncidenceLanes::pad`] and at most
/// `i32::MAX`.
#[inline(always)]
fn add_group(rows: &[u32], table: &[[f32; 3]], sum: &mut [[f32; LANES]; 3]) {
    for row in rows.chunks_exact(LANES) {
        for (lane, &e) in row.iter().enumerate() {
            // SAFETY: every slot's spring is at most `lanes.pad()` (`IncidenceLanes::new`),
            // below `table.len()` and `i32::MAX` (a signed 32-bit offset, as above).
            let force = unsafe { &*table.as_ptr().offset((e >> 1) as i32 as isize) };
            // A multiply by +-1, not a branch; `sum + -1 * F` is bitwise `sum - F`.
            let sign = 1.0 - 2.0 * (e & 1) as f32;
            for c in 0..3 {
                sum[c][lane] += force[c] * sign;
            }
        }
    }
}
