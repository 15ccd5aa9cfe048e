//! The springs of a mesh cloth added to the force, in one parallel pass over groups of
//! vertices ([`IncidenceLanes`]): each vertex computes the force of each spring that touches
//! it, in increasing spring order, from the slot's copy of the spring's parameters
//! ([`SpringSlots`]) and the other end's position and velocity, and adds `+F` at a spring's
//! first end or `-1 * F` at its second. Both ends compute `F` from `x_b - x_a` and `v_b - v_a`
//! in that order, so they get bitwise opposite forces (momentum is conserved up to the order
//! of summation), and every sum is bitwise that of a table of per-spring forces gathered by
//! vertex; the order of every sum is fixed by the mesh, so the result is bitwise the same for
//! any number of threads. Each spring is computed twice, but nothing is written per spring and
//! read back: a group's row of [`LANES`] springs gathers only the other ends' six
//! coordinates, which is what the pass waits on. No operation is reordered for the vector
//! unit, so every instruction set gives the same bits. A mesh whose numbering is scattered is
//! worked on in its own local numbering ([`crate::scene::MeshCloth::local`]): the state is
//! gathered into it, the pass runs there, the forces are scattered back, each vertex's sum the
//! same.

use rayon::prelude::*;

use super::{EdgeKind, MeshCloth};
use crate::scene::{gather_by, IncidenceLanes, SpringSlots, LANES, WINDOW};
use crate::simd::Isa;
use crate::soa::{Vec3SliceMut, Vec3s};
use crate::springs::overstretched;

impl MeshCloth {
    /// Adds the force of every spring at `(pos, vel)` into `out`, using `table` as scratch
    /// where the cloth has a local numbering (resized here), the seams' rest lengths scaled by
    /// `sewing` ([`MeshCloth::sewing`]). With a `watch` limit, also returns whether a spring
    /// other than a seam (whose rest length goes to zero) is longer than that many times its
    /// rest length (the watchdog's stretch check). A seam shorter than its rest length is slack.
    /// The pass runs on `isa` (one the CPU has, [`crate::simd::has`]; a simulation's
    /// [`crate::simd::Timed`] chooses it), with the same bits on any.
    #[allow(clippy::too_many_arguments)]
    pub fn add_spring_forces(
        &self,
        isa: Isa,
        (pos, vel): (&Vec3s, &Vec3s),
        sewing: f32,
        out: &mut Vec3s,
        table: &mut Vec<[f32; 3]>,
        chunk: usize,
        watch: Option<f32>,
    ) -> bool {
        assert!(
            crate::simd::has(isa),
            "{isa:?} is not an instruction set this CPU has"
        );
        let limit = watch.unwrap_or(f32::INFINITY);
        // Whole windows of vertices per work item, so that each group's vertices are in one;
        // each vertex's sum is the same in any split.
        let per_item = chunk.next_multiple_of(WINDOW);
        let slots = &self.slots;
        assert_eq!(
            slots.local,
            self.local.is_some(),
            "the force pass's slots are not in the cloth's numbering (MeshCloth::set_local)"
        );
        let law = (sewing, limit);
        let Some(local) = &self.local else {
            let coordinates = [&pos.x, &pos.y, &pos.z, &vel.x, &vel.y, &vel.z].map(|x| &x[..]);
            let pass = Pass {
                lanes: &self.lanes,
                slots,
                coordinates,
                law,
                isa,
            };
            let over = out
                .par_chunks_mut(per_item)
                .enumerate()
                .map(|(c, f)| {
                    let first = c * per_item / LANES;
                    cloth_forces(pass, first, f)
                })
                .reduce(|| false, |x, y| x | y);
            return watch.is_some() && over;
        };
        // In the local numbering: the positions, velocities and forces gathered into it, a
        // coordinate an array as in the state.
        let n = self.len();
        table.resize(3 * n, [0.0; 3]);
        let mut arrays = table.as_flattened_mut().chunks_exact_mut(n);
        let mut next = || arrays.next().expect("nine arrays of n");
        let [x0, x1, x2, v0, v1, v2, f0, f1, f2] = std::array::from_fn(|_| next());
        let (vertices, now) = (&local.vertices, &*out);
        let p = per_item;
        fn chunks(x: &mut [f32], p: usize) -> rayon::slice::ChunksMut<'_, f32> {
            x.par_chunks_mut(p)
        }
        let positions = (chunks(x0, p), chunks(x1, p), chunks(x2, p));
        let velocities = (chunks(v0, p), chunks(v1, p), chunks(v2, p));
        let forces = (chunks(f0, p), chunks(f1, p), chunks(f2, p));
        positions
            .into_par_iter()
            .zip(velocities.into_par_iter())
            .zip(forces.into_par_iter())
            .enumerate()
            .for_each(|(c, (((x0, x1, x2), (v0, v1, v2)), (f0, f1, f2)))| {
                let from = &vertices[c * p..c * p + x0.len()];
                let into = [x0, x1, x2, v0, v1, v2, f0, f1, f2];
                let sources = [
                    &pos.x, &pos.y, &pos.z, &vel.x, &vel.y, &vel.z, &now.x, &now.y, &now.z,
                ];
                crate::simd::dispatch!(@isa isa, gather_by(into, sources.map(|x| &x[..]), from));
            });
        let coordinates = [&*x0, &*x1, &*x2, &*v0, &*v1, &*v2];
        let pass = Pass {
            lanes: &local.lanes,
            slots,
            coordinates,
            law,
            isa,
        };
        let over = (
            f0.par_chunks_mut(p),
            f1.par_chunks_mut(p),
            f2.par_chunks_mut(p),
        )
            .into_par_iter()
            .enumerate()
            .map(|(c, (x, y, z))| {
                let first = c * p / LANES;
                let f = Vec3SliceMut { x, y, z };
                cloth_forces(pass, first, f)
            })
            .reduce(|| false, |x, y| x | y);
        let (f, place) = ([&*f0, &*f1, &*f2], &local.place);
        out.par_chunks_mut(p).enumerate().for_each(|(c, out)| {
            let from = &place[c * p..c * p + out.x.len()];
            crate::simd::dispatch!(@isa isa, gather_by([out.x, out.y, out.z], f, from));
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

/// [`vertex_forces`] in the build for the cloth (with isometric bending's term or without) and
/// the pass's instruction set. With AVX-512 each group's start and end are the vector unit's
/// gathers and scatters ([`avx512`]); the other instruction sets load and store them lane by
/// lane.
fn cloth_forces(pass: Pass<'_>, first: usize, f: Vec3SliceMut<'_>) -> bool {
    let linear = !pass.slots.linear.is_empty();
    #[cfg(target_arch = "x86_64")]
    if pass.isa == Isa::Avx512 {
        // SAFETY: the pass's instruction set is one the CPU has (`add_spring_forces` asserts it).
        return unsafe {
            match linear {
                false => avx512::vertex_forces::<false>(pass, first, f),
                true => avx512::vertex_forces::<true>(pass, first, f),
            }
        };
    }
    let isa = pass.isa;
    match linear {
        false => crate::simd::dispatch!(@isa isa, vertex_forces::<false, false>(pass, first, f)),
        true => crate::simd::dispatch!(@isa isa, vertex_forces::<true, false>(pass, first, f)),
    }
}

/// What every work item of the pass reads: the lanes and their slots, each vertex's
/// coordinates (x, y, z of the position, then of the velocity, vertex `i`'s coordinate `c` at
/// `coordinates[c][i]`), the seams' `sewing` and the watch's `limit`, and the instruction set
/// it runs on.
#[derive(Clone, Copy)]
struct Pass<'a> {
    lanes: &'a IncidenceLanes,
    slots: &'a SpringSlots,
    coordinates: [&'a [f32]; 6],
    law: (f32, f32),
    isa: Isa,
}

/// Adds to `f` (the forces of the vertices from group `first` on, component by component) the
/// forces of each vertex's springs ([`group_forces`]); whether one of them other than a seam is
/// longer than `limit` times its rest length. `f` holds whole windows ([`WINDOW`]) but at the
/// end, so each group's vertices ([`IncidenceLanes::members`]) are inside it. With `GATHER`
/// (only inside [`avx512::vertex_forces`]), a whole group's own coordinates and sums are loaded
/// by the vector unit's gathers and its sums stored by its scatters; else lane by lane, which is
/// what the narrower instruction sets do best. Plain loads and stores either way, so the bits
/// are the same.
#[inline(always)]
fn vertex_forces<const LINEAR: bool, const GATHER: bool>(
    pass: Pass<'_>,
    first: usize,
    f: Vec3SliceMut<'_>,
) -> bool {
    let Pass {
        lanes,
        slots,
        coordinates,
        law,
        ..
    } = pass;
    check_coordinates(slots, coordinates);
    let mut over = false;
    let base = first * LANES;
    let mut f = [f.x, f.y, f.z];
    let groups = first..first + f[0].len().div_ceil(LANES);
    let whole = |g: usize| match GATHER && groups.contains(&g) {
        true => <&[u32; LANES]>::try_from(lanes.members(g)).ok(),
        false => None,
    };
    // With `GATHER`, the next group's gathers are issued before this group's rows, so that
    // their latency overlaps the rows' arithmetic; its vertices are not this group's, so this
    // group's stores do not change what they load.
    let mut ahead = ([[0.0f32; LANES]; 3], [[0.0f32; LANES]; 6]);
    let gather =
        |g: usize, f: &[&mut [f32]; 3], into: &mut ([[f32; LANES]; 3], [[f32; LANES]; 6])| {
            #[cfg(target_arch = "x86_64")]
            if let Some(members) = whole(g) {
                let sums = [&*f[0], &*f[1], &*f[2]];
                // SAFETY: `GATHER` is only set inside a function compiled for AVX-512.
                unsafe {
                    avx512::load_group(members, base, sums, coordinates, &mut into.0, &mut into.1)
                };
            }
        };
    gather(groups.start, &f, &mut ahead);
    for g in groups.clone() {
        let members = lanes.members(g);
        let gathered = whole(g);
        let (mut sum, mut own) = ahead;
        gather(g + 1, &f, &mut ahead);
        if gathered.is_none() {
            (sum, own) = ([[0.0; LANES]; 3], [[0.0; LANES]; 6]);
            for (lane, &v) in members.iter().enumerate() {
                let v = v as usize;
                for (sum, f) in sum.iter_mut().zip(&f) {
                    sum[lane] = f[v - base];
                }
                for (own, x) in own.iter_mut().zip(coordinates) {
                    own[lane] = x[v];
                }
            }
        }
        let range = lanes.group_slots(g);
        over |= group_forces::<LINEAR>(slots, range, coordinates, &own, law, &mut sum);
        match gathered {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as for the loads (`store_group` checks its places against `f` itself).
            Some(members) => unsafe { avx512::store_group(members, base, &sum, &mut f) },
            _ => {
                for (lane, &v) in members.iter().enumerate() {
                    for (f, sum) in f.iter_mut().zip(&sum) {
                        f[v as usize - base] = sum[lane];
                    }
                }
            }
        }
    }
    over
}

/// Checks once per pass what lets [`group_forces`] load the other ends unchecked: every
/// vertex of the numbering is inside each coordinate array.
#[inline(always)]
fn check_coordinates(slots: &SpringSlots, coordinates: [&[f32]; 6]) {
    let len = coordinates.iter().map(|x| x.len()).min().unwrap_or(0);
    let top = slots.vertices();
    assert!(
        top <= len,
        "{len} particles for the springs' {top} vertices"
    );
}

/// Adds to each lane's `sum` the forces of the group's slots `range` (rows of [`LANES`], one
/// spring a lane) on the lane's vertex, whose coordinates are `own` (x, y, z of the position,
/// then of the velocity), the other ends' read from `coordinates`; whether a spring other than
/// a seam is longer than `limit` times its rest length.
///
/// Each spring is computed at both of its ends, from `x_b - x_a` and `v_b - v_a` taken in that
/// order at either end, so both ends compute bitwise the force on the first end `F` (the
/// grid's arithmetic, glam's component by component) and add `+F` at the first end and
/// `-1 * F` at the second, in the order of each vertex's incidence list: bitwise the sums of a
/// per-spring table gathered by vertex, with no table. A padding slot adds `-0.0`, which leaves
/// every sum as it is. With `LINEAR`, each spring's force gains `linear (x_b - x_a)`
/// (isometric bending).
#[inline(always)]
fn group_forces<const LINEAR: bool>(
    slots: &SpringSlots,
    range: std::ops::Range<usize>,
    coordinates: [&[f32]; 6],
    own: &[[f32; LANES]; 6],
    (sewing, limit): (f32, f32),
    sum: &mut [[f32; LANES]; 3],
) -> bool {
    let mut over = false;
    let others = slots.other(range.clone());
    let (rest, k, c) = (
        &slots.rest[range.clone()],
        &slots.k[range.clone()],
        &slots.c[range.clone()],
    );
    let flags = &slots.flags[range.clone()];
    let lin = if LINEAR { &slots.linear[range] } else { &[] };
    for r in (0..others.len()).step_by(LANES) {
        let row = r..r + LANES;
        let (others, flags) = (&others[row.clone()], &flags[row.clone()]);
        let (rest, k, c) = (&rest[row.clone()], &k[row.clone()], &c[row.clone()]);
        let lin = if LINEAR { &lin[row] } else { &[][..] };
        for lane in 0..LANES {
            // As a signed 32-bit offset, which the vector unit's gathers take directly (an
            // unsigned index is widened to 64 bits, and gathered half as wide).
            let j = others[lane] as i32 as isize;
            let second = flags[lane] & SpringSlots::SECOND_END != 0;
            let mut d = [0.0f32; 6];
            for (d, (x, own)) in d.iter_mut().zip(coordinates.iter().zip(own)) {
                // SAFETY: every other end is below `slots.vertices()`, which
                // `check_coordinates` found inside each array, and below `i32::MAX`
                // (`SpringSlots::new`).
                let there = unsafe { *x.as_ptr().offset(j) };
                let here = own[lane];
                let (b, a) = if second { (here, there) } else { (there, here) };
                *d = b - a;
            }
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let seam = flags[lane] & SpringSlots::SEAM != 0;
            let rest = if seam {
                rest[lane] * sewing
            } else {
                rest[lane]
            };
            // A severed spring's ends part freely.
            let active = flags[lane] & SpringSlots::ACTIVE != 0;
            over |= !seam & active & overstretched(l, rest, 1.0, limit);
            let u = if l > 0.0 {
                [d[0] / l, d[1] / l, d[2] / l]
            } else {
                [d[0] * 0.0, d[1] * 0.0, d[2] * 0.0]
            };
            let closing = d[3] * u[0] + d[4] * u[1] + d[5] * u[2];
            let magnitude = k[lane] * (l - rest) + c[lane] * closing;
            // A seam is a thread: it pulls its ends together, it never pushes them apart (a
            // pair that came closer than the seam's rest length is slack).
            let slack = seam & (l <= rest);
            let f = if slack {
                [0.0; 3]
            } else {
                [magnitude * u[0], magnitude * u[1], magnitude * u[2]]
            };
            let f = if LINEAR {
                let w = lin[lane];
                [f[0] + w * d[0], f[1] + w * d[1], f[2] + w * d[2]]
            } else {
                f
            };
            // A multiply by +-1, not a branch; `sum + -1 * F` is bitwise `sum - F`.
            let sign = 1.0 - 2.0 * second as u32 as f32;
            let padding = flags[lane] & SpringSlots::PADDING != 0;
            for (sum, f) in sum.iter_mut().zip(f) {
                sum[lane] += if padding { -0.0 } else { f * sign };
            }
        }
    }
    over
}

/// The force pass's AVX-512 build, whose groups' starts and ends are gathers and scatters. A
/// group's 16 vertices are scattered over a window ([`WINDOW`]), so lane by lane they cost 16
/// loads and inserts per array (nine of them a group); LLVM does not turn those into gathers
/// itself, and written as unchecked loads in plain Rust they made it leave the rows' loop
/// scalar, so they are written here with the intrinsics.
/// (The AVX-512 intrinsics need Rust 1.89, the crate's `rust-version`.)
#[cfg(target_arch = "x86_64")]
mod avx512 {
    use std::arch::x86_64::*;

    use super::{Pass, LANES};
    use crate::soa::Vec3SliceMut;

    /// [`super::vertex_forces`] compiled for AVX-512, with the groups' gathers.
    #[target_feature(enable = "avx512f,avx512vl,avx2")]
    pub(super) unsafe fn vertex_forces<const LINEAR: bool>(
        pass: Pass<'_>,
        first: usize,
        f: Vec3SliceMut<'_>,
    ) -> bool {
        super::vertex_forces::<LINEAR, true>(pass, first, f)
    }

    /// Gathers the group `members`' sums so far (vertex `v`'s at `sums[c][v - base]`) into
    /// `sum` and their coordinates (at `coordinates[c][v]`) into `own`. Panics where a member
    /// is outside either, which the lane-by-lane loads' bounds checks would also have caught.
    #[inline]
    #[target_feature(enable = "avx512f,avx512vl,avx2")]
    pub(super) fn load_group(
        members: &[u32; LANES],
        base: usize,
        sums: [&[f32]; 3],
        coordinates: [&[f32]; 6],
        sum: &mut [[f32; LANES]; 3],
        own: &mut [[f32; LANES]; 6],
    ) {
        let (vertices, places) = offsets(members, base);
        let len = coordinates.iter().map(|x| x.len()).min().unwrap_or(0);
        // Unsigned compares, so that an offset that wrapped below zero is caught too.
        let outside = _mm512_cmpge_epu32_mask(vertices, _mm512_set1_epi32(clamp(len)))
            | _mm512_cmpge_epu32_mask(places, _mm512_set1_epi32(clamp(sums[0].len())));
        assert!(
            outside == 0 && sums.iter().all(|s| s.len() == sums[0].len()),
            "a group's vertex outside the state or its work item"
        );
        for (sum, from) in sum.iter_mut().zip(sums) {
            // SAFETY: every offset is inside `from` (checked above).
            let x = unsafe { _mm512_i32gather_ps::<4>(places, from.as_ptr()) };
            // SAFETY: `sum` holds `LANES` floats.
            unsafe { _mm512_storeu_ps(sum.as_mut_ptr(), x) };
        }
        for (own, from) in own.iter_mut().zip(coordinates) {
            // SAFETY: every vertex is inside `from` (checked above).
            let x = unsafe { _mm512_i32gather_ps::<4>(vertices, from.as_ptr()) };
            // SAFETY: `own` holds `LANES` floats.
            unsafe { _mm512_storeu_ps(own.as_mut_ptr(), x) };
        }
    }

    /// Scatters `sum` back to the group `members`' places in `f` (vertex `v`'s at
    /// `f[c][v - base]`); the members are distinct, so no lane overwrites another's.
    #[inline]
    #[target_feature(enable = "avx512f,avx512vl,avx2")]
    pub(super) fn store_group(
        members: &[u32; LANES],
        base: usize,
        sum: &[[f32; LANES]; 3],
        f: &mut [&mut [f32]; 3],
    ) {
        let len = f.iter().map(|f| f.len()).min().unwrap_or(0);
        let (_, places) = offsets(members, base);
        let outside = _mm512_cmpge_epu32_mask(places, _mm512_set1_epi32(clamp(len)));
        assert!(outside == 0, "a group's vertex outside its work item");
        for (f, sum) in f.iter_mut().zip(sum) {
            // SAFETY: `sum` holds `LANES` floats.
            let x = unsafe { _mm512_loadu_ps(sum.as_ptr()) };
            // SAFETY: every offset is inside `f` (checked above).
            unsafe { _mm512_i32scatter_ps::<4>(f.as_mut_ptr(), places, x) };
        }
    }

    /// The members as 32-bit vertices, and their places in a work item starting at `base`.
    #[inline]
    #[target_feature(enable = "avx512f,avx512vl,avx2")]
    fn offsets(members: &[u32; LANES], base: usize) -> (__m512i, __m512i) {
        // SAFETY: `members` holds `LANES` 32-bit integers.
        let vertices = unsafe { _mm512_loadu_si512(members.as_ptr().cast()) };
        let places = _mm512_sub_epi32(vertices, _mm512_set1_epi32(base as u32 as i32));
        (vertices, places)
    }

    /// A length as the bound of a 32-bit unsigned compare. The gathers read their offsets as
    /// signed, so the bound is at most `i32::MAX`: an offset at or above 2^31 is refused, not
    /// read below the array.
    #[inline]
    fn clamp(len: usize) -> i32 {
        len.min(i32::MAX as usize) as i32
    }
}
