//! The springs of a mesh cloth added to the force, in one parallel pass over groups of
//! vertices ([`IncidenceLanes`]): each vertex computes the force of each spring that touches
//! it, in increasing spring order, from the slot's copy of the spring's parameters
//! ([`SpringSlots`]) and the other end's position and velocity, and adds `+F` at a spring's
//! first end or `-1 * F` at its second. Both ends compute `F` from `x_b - x_a` and `v_b - v_a`
//! in that order, so they get bitwise opposite forces (momentum is conserved up to the order
//! of summation), and every sum is bitwise that of a table of per-spring forces gathered by
//! vertex; the order of every sum is fixed by the mesh, so the result is bitwise the same for
//! any number of threads. Each spring is computed twice, but nothing is written per spring and
//! read back: a group's row of [`LANES`] springs loads only the other ends' positions and
//! velocities, from the state packed a vertex to a line ([`super::packed`]). No operation is
//! reordered for the vector unit, so every instruction set gives the same bits. A mesh whose
//! numbering is scattered is worked on in its own local numbering
//! ([`crate::scene::MeshCloth::local`]): the state is packed into it, the forces are copied
//! into it and back, each vertex's sum the same.

use rayon::prelude::*;

use super::packed::{pack, LoadRow, Packed};
use super::{EdgeKind, MeshCloth};
use crate::scene::{gather_by, IncidenceLanes, SpringSlots, LANES, WINDOW};
use crate::simd::{dispatch, Isa};
use crate::soa::{Vec3SliceMut, Vec3s};
use crate::springs::overstretched;

/// The force pass's scratch, kept between calls so that a step allocates nothing: the state
/// packed a vertex to a line ([`Packed`]) in the numbering the pass runs in, and in a local
/// numbering the forces, a coordinate an array.
#[derive(Clone, Debug, Default)]
pub struct PassScratch {
    packed: Vec<Packed>,
    forces: Vec<f32>,
}

impl PassScratch {
    pub fn heap_bytes(&self) -> usize {
        self.packed.capacity() * size_of::<Packed>() + self.forces.capacity() * 4
    }
}

impl MeshCloth {
    /// Adds the force of every spring at `(pos, vel)` into `out`, using `scratch` (resized
    /// here), the seams' rest lengths scaled by `sewing` ([`MeshCloth::sewing`]). With a
    /// `watch` limit, also returns whether a spring other than a seam (whose rest length goes
    /// to zero) is longer than that many times its rest length (the watchdog's stretch check).
    /// A seam shorter than its rest length is slack.
    /// The pass runs on `isa` (one the CPU has, [`crate::simd::has`]; a simulation gives
    /// [`crate::simd::isa`]), with the same bits on any.
    #[allow(clippy::too_many_arguments)]
    pub fn add_spring_forces(
        &self,
        isa: Isa,
        (pos, vel): (&Vec3s, &Vec3s),
        sewing: f32,
        out: &mut Vec3s,
        scratch: &mut PassScratch,
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
        let p = chunk.next_multiple_of(WINDOW);
        let slots = &self.slots;
        assert_eq!(
            slots.local,
            self.local.is_some(),
            "the force pass's slots are not in the cloth's numbering (MeshCloth::set_local)"
        );
        let n = self.len();
        let law = (sewing, limit);
        let (lanes, index) = match &self.local {
            Some(local) => (&local.lanes, Some(&local.vertices[..])),
            None => (&self.lanes, None),
        };
        let PassScratch { packed, forces } = scratch;
        packed.resize(n, Packed::default());
        packed.par_chunks_mut(p).enumerate().for_each(|(c, into)| {
            let index = index.map(|index| &index[c * p..c * p + into.len()]);
            pack(into, (pos, vel), c * p, index);
        });
        let pass = Pass {
            lanes,
            slots,
            packed,
            law,
            isa,
        };
        let Some(local) = &self.local else {
            let over = out
                .par_chunks_mut(p)
                .enumerate()
                .map(|(c, f)| cloth_forces(pass, c * p / LANES, f))
                .reduce(|| false, |x, y| x | y);
            return watch.is_some() && over;
        };
        // In the local numbering: the forces copied into it, a coordinate an array as in the
        // state, and back after the pass.
        forces.resize(3 * n, 0.0);
        let (f0, f12) = forces.split_at_mut(n);
        let (f1, f2) = f12.split_at_mut(n);
        let now = &*out;
        let over = (
            f0.par_chunks_mut(p),
            f1.par_chunks_mut(p),
            f2.par_chunks_mut(p),
        )
            .into_par_iter()
            .enumerate()
            .map(|(c, (x, y, z))| {
                let from = &local.vertices[c * p..c * p + x.len()];
                let sources = [&now.x, &now.y, &now.z].map(|x| &x[..]);
                dispatch!(@isa isa, gather_by([&mut *x, &mut *y, &mut *z], sources, from));
                cloth_forces(pass, c * p / LANES, Vec3SliceMut { x, y, z })
            })
            .reduce(|| false, |x, y| x | y);
        let (f, place) = ([&*f0, &*f1, &*f2], &local.place);
        out.par_chunks_mut(p).enumerate().for_each(|(c, out)| {
            let from = &place[c * p..c * p + out.x.len()];
            dispatch!(@isa isa, gather_by([out.x, out.y, out.z], f, from));
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
/// the pass's instruction set, each loading its rows from the packed state with that set's
/// shuffles ([`LoadRow`]).
#[cfg(target_arch = "x86_64")]
fn cloth_forces(pass: Pass<'_>, first: usize, f: Vec3SliceMut<'_>) -> bool {
    use super::packed::{Avx2, Sse2};
    let (isa, linear) = (pass.isa, !pass.slots.linear.is_empty());
    // The AVX-512 build loads its rows with AVX2's shuffles: a 512-bit loader measured the
    // same. Each arm runs on an instruction set the CPU has (`add_spring_forces` asserts it).
    match (isa, linear) {
        (Isa::Avx512 | Isa::Avx2, false) => {
            dispatch!(@isa isa, vertex_forces::<false, Avx2>(pass, first, f))
        }
        (Isa::Avx512 | Isa::Avx2, true) => {
            dispatch!(@isa isa, vertex_forces::<true, Avx2>(pass, first, f))
        }
        (Isa::Baseline, false) => vertex_forces::<false, Sse2>(pass, first, f),
        (Isa::Baseline, true) => vertex_forces::<true, Sse2>(pass, first, f),
    }
}

/// [`vertex_forces`] in the build for the cloth, element by element elsewhere than x86-64.
#[cfg(not(target_arch = "x86_64"))]
fn cloth_forces(pass: Pass<'_>, first: usize, f: Vec3SliceMut<'_>) -> bool {
    use super::packed::Scalar;
    match !pass.slots.linear.is_empty() {
        false => vertex_forces::<false, Scalar>(pass, first, f),
        true => vertex_forces::<true, Scalar>(pass, first, f),
    }
}

/// What every work item of the pass reads: the lanes and their slots, each vertex's position
/// and velocity packed ([`Packed`], vertex `i` at `packed[i]`), the seams' `sewing` and the
/// watch's `limit`, and the instruction set it runs on.
#[derive(Clone, Copy)]
struct Pass<'a> {
    lanes: &'a IncidenceLanes,
    slots: &'a SpringSlots,
    packed: &'a [Packed],
    law: (f32, f32),
    isa: Isa,
}

/// Adds to `f` (the forces of the vertices from group `first` on, component by component) the
/// forces of each vertex's springs ([`group_forces`]); whether one of them other than a seam is
/// longer than `limit` times its rest length. `f` holds whole windows ([`WINDOW`]) but at the
/// end, so each group's vertices ([`IncidenceLanes::members`]) are inside it. A whole group's
/// own coordinates are loaded as its rows' other ends are, by `L`; its sums lane by lane.
#[inline(always)]
fn vertex_forces<const LINEAR: bool, L: LoadRow>(
    pass: Pass<'_>,
    first: usize,
    f: Vec3SliceMut<'_>,
) -> bool {
    let Pass {
        lanes,
        slots,
        packed,
        law,
        ..
    } = pass;
    check_packed(slots, packed);
    let mut over = false;
    let base = first * LANES;
    let mut f = [f.x, f.y, f.z];
    for g in first..first + f[0].len().div_ceil(LANES) {
        let members = lanes.members(g);
        let mut own = [[0.0f32; LANES]; 6];
        match <&[u32; LANES]>::try_from(members) {
            Ok(members) => {
                assert!(members.iter().all(|&v| (v as usize) < packed.len()));
                // SAFETY: every member is inside `packed` (checked above); the build's
                // instruction set is the pass's, which the CPU has.
                own = unsafe { L::load(packed, members) };
            }
            Err(_) => {
                for (lane, &v) in members.iter().enumerate() {
                    for (own, x) in own.iter_mut().zip(packed[v as usize].0) {
                        own[lane] = x;
                    }
                }
            }
        }
        let mut sum = [[0.0f32; LANES]; 3];
        for (lane, &v) in members.iter().enumerate() {
            for (sum, f) in sum.iter_mut().zip(&f) {
                sum[lane] = f[v as usize - base];
            }
        }
        let range = lanes.group_slots(g);
        over |= group_forces::<LINEAR, L>(slots, range, packed, &own, law, &mut sum);
        for (lane, &v) in members.iter().enumerate() {
            for (f, sum) in f.iter_mut().zip(&sum) {
                f[v as usize - base] = sum[lane];
            }
        }
    }
    over
}

/// Checks once per pass what lets [`group_forces`] load the other ends unchecked: every
/// vertex of the numbering is inside the packed state.
#[inline(always)]
fn check_packed(slots: &SpringSlots, packed: &[Packed]) {
    let top = slots.vertices();
    let len = packed.len();
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
fn group_forces<const LINEAR: bool, L: LoadRow>(
    slots: &SpringSlots,
    range: std::ops::Range<usize>,
    packed: &[Packed],
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
        let others: &[u32; LANES] = others.try_into().expect("whole rows");
        // SAFETY: every other end is below `slots.vertices()`, which `check_packed` found
        // inside `packed`; the build's instruction set is the pass's, which the CPU has.
        let there = unsafe { L::load(packed, others) };
        for lane in 0..LANES {
            let second = flags[lane] & SpringSlots::SECOND_END != 0;
            let mut d = [0.0f32; 6];
            for (d, (there, own)) in d.iter_mut().zip(there.iter().zip(own)) {
                let (there, here) = (there[lane], own[lane]);
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
