//! The state of a mesh cloth packed for the force pass: each vertex's position and velocity in
//! one 32-byte line, `[x, y, z, vx, vy, vz, 0, 0]`, and a row's [`LANES`] vertices loaded from
//! it transposed, one array a coordinate.
//!
//! The pass reads, for every slot, the six coordinates of the spring's other end. Kept as six
//! arrays, those are six gathers a row, and a gather can be slow: on an Ice Lake Xeon one 8- or
//! 16-wide gather measured 8 to 12 ns, 25 to 35 cycles (`benches/gather_cost.c`; Intel's
//! Gather Data Sampling microcode is the likely cause), and the gathers were most of the pass.
//! Compiled for AVX2, LLVM loads them element by element instead, which is no faster. Packed, a
//! lane's six coordinates are two aligned 16-byte loads, and eight lanes are transposed by a
//! dozen shuffles (AVX2's, in the AVX-512 build too: a 512-bit loader measured the same). The
//! values loaded are the same, so the force is bitwise the same on every instruction set.

use crate::scene::LANES;
use crate::soa::Vec3s;

/// One vertex's position and velocity, `[x, y, z, vx, vy, vz, 0, 0]`: the two halves are
/// 16-byte loads, and the alignment keeps each vertex in one cache line.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(32))]
pub struct Packed(pub [f32; 8]);

impl Packed {
    #[inline(always)]
    fn of(pos: &Vec3s, vel: &Vec3s, v: usize) -> Self {
        Packed([
            pos.x[v], pos.y[v], pos.z[v], vel.x[v], vel.y[v], vel.z[v], 0.0, 0.0,
        ])
    }
}

/// Sets `into[k]` to vertex `from + k`'s position and velocity, or with an `index`, to vertex
/// `index[k]`'s (the state in a local numbering). Compiled for the baseline instruction set: a
/// copy gains nothing from wider registers, and SSE2 has no gathers for LLVM to make of the
/// indexed loads.
pub fn pack(into: &mut [Packed], (pos, vel): (&Vec3s, &Vec3s), from: usize, index: Option<&[u32]>) {
    match index {
        None => {
            for (k, p) in into.iter_mut().enumerate() {
                *p = Packed::of(pos, vel, from + k);
            }
        }
        Some(index) => {
            for (p, &v) in into.iter_mut().zip(index) {
                *p = Packed::of(pos, vel, v as usize);
            }
        }
    }
}

/// A row's six coordinates, one array of [`LANES`] a coordinate: x, y, z of the position, then
/// of the velocity.
pub type Row = [[f32; LANES]; 6];

/// How a build of the force pass loads a row of vertices from the packed state, transposed.
/// Every implementation returns the same values.
pub trait LoadRow {
    /// The vertices `at` of `packed`, transposed.
    ///
    /// # Safety
    /// Every index of `at` is below `packed.len()`, and the CPU has the implementation's
    /// instruction set.
    unsafe fn load(packed: &[Packed], at: &[u32; LANES]) -> Row;
}

/// Element by element: any CPU.
pub struct Scalar;

impl LoadRow for Scalar {
    #[inline(always)]
    unsafe fn load(packed: &[Packed], at: &[u32; LANES]) -> Row {
        let mut row = [[0.0; LANES]; 6];
        for (lane, &v) in at.iter().enumerate() {
            // SAFETY: the caller keeps every index inside `packed`.
            let p = unsafe { packed.get_unchecked(v as usize) };
            for (c, row) in row.iter_mut().enumerate() {
                row[lane] = p.0[c];
            }
        }
        row
    }
}

#[cfg(target_arch = "x86_64")]
pub use x86::{Avx2, Sse2};

#[cfg(target_arch = "x86_64")]
mod x86 {
    //! Each register holds lanes four apart, one 16-byte half of a vertex in each of its 128-bit
    //! lanes: `A_i` the first halves `(x, y, z, vx)` of lanes `i, i + 4, ...`, `B_i` the second
    //! halves `(vy, vz, 0, 0)`. A 4 x 4 transpose inside every 128-bit lane (two unpacks and a
    //! shuffle an output) then leaves each coordinate's lanes in order.
    use std::arch::x86_64::*;

    use super::{LoadRow, Packed, Row, LANES};

    /// The first and second 16-byte halves of vertex `v`.
    ///
    /// # Safety
    /// `v` is inside `packed`.
    #[inline(always)]
    unsafe fn halves(packed: &[Packed], v: u32) -> (*const f32, *const f32) {
        // SAFETY: the caller keeps `v` inside `packed`; each `Packed` is 32 bytes, 32-aligned.
        let p = unsafe { packed.as_ptr().add(v as usize) }.cast::<f32>();
        (p, unsafe { p.add(4) })
    }

    /// SSE2, x86-64's baseline: four rows of four lanes.
    pub struct Sse2;

    impl LoadRow for Sse2 {
        #[inline(always)]
        unsafe fn load(packed: &[Packed], at: &[u32; LANES]) -> Row {
            let mut row = [[0.0f32; LANES]; 6];
            for quarter in 0..LANES / 4 {
                let mut a = [_mm_setzero_ps(); 4];
                let mut b = [_mm_setzero_ps(); 4];
                for i in 0..4 {
                    // SAFETY: every index is inside `packed` (the caller's promise), each half
                    // 16 aligned bytes.
                    unsafe {
                        let (a0, b0) = halves(packed, at[quarter * 4 + i]);
                        (a[i], b[i]) = (_mm_load_ps(a0), _mm_load_ps(b0));
                    }
                }
                let (lo01, hi01) = (_mm_unpacklo_ps(a[0], a[1]), _mm_unpackhi_ps(a[0], a[1]));
                let (lo23, hi23) = (_mm_unpacklo_ps(a[2], a[3]), _mm_unpackhi_ps(a[2], a[3]));
                let (v01, v23) = (_mm_unpacklo_ps(b[0], b[1]), _mm_unpacklo_ps(b[2], b[3]));
                let coordinates = [
                    _mm_movelh_ps(lo01, lo23),
                    _mm_movehl_ps(lo23, lo01),
                    _mm_movelh_ps(hi01, hi23),
                    _mm_movehl_ps(hi23, hi01),
                    _mm_movelh_ps(v01, v23),
                    _mm_movehl_ps(v23, v01),
                ];
                for (row, x) in row.iter_mut().zip(coordinates) {
                    // SAFETY: four floats from `quarter * 4` are inside the row's `LANES`.
                    unsafe { _mm_storeu_ps(row.as_mut_ptr().add(quarter * 4), x) };
                }
            }
            row
        }
    }

    /// AVX2: two rows of eight lanes.
    pub struct Avx2;

    impl LoadRow for Avx2 {
        #[inline(always)]
        unsafe fn load(packed: &[Packed], at: &[u32; LANES]) -> Row {
            // SAFETY: the caller keeps the indices inside `packed` and has AVX2.
            unsafe { load_avx2(packed, at) }
        }
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn load_avx2(packed: &[Packed], at: &[u32; LANES]) -> Row {
        let mut row = [[0.0f32; LANES]; 6];
        for half in 0..LANES / 8 {
            let lane = |i: usize| at[half * 8 + i];
            let mut a = [_mm256_setzero_ps(); 4];
            let mut b = [_mm256_setzero_ps(); 4];
            for i in 0..4 {
                // SAFETY: every index is inside `packed` (the caller's promise).
                let (a0, b0) = unsafe { halves(packed, lane(i)) };
                let (a1, b1) = unsafe { halves(packed, lane(i + 4)) };
                // SAFETY: each half is 16 aligned bytes.
                a[i] = unsafe { _mm256_set_m128(_mm_load_ps(a1), _mm_load_ps(a0)) };
                b[i] = unsafe { _mm256_set_m128(_mm_load_ps(b1), _mm_load_ps(b0)) };
            }
            let (lo01, hi01) = (
                _mm256_unpacklo_ps(a[0], a[1]),
                _mm256_unpackhi_ps(a[0], a[1]),
            );
            let (lo23, hi23) = (
                _mm256_unpacklo_ps(a[2], a[3]),
                _mm256_unpackhi_ps(a[2], a[3]),
            );
            let (v01, v23) = (
                _mm256_unpacklo_ps(b[0], b[1]),
                _mm256_unpacklo_ps(b[2], b[3]),
            );
            let coordinates = [
                _mm256_shuffle_ps::<0x44>(lo01, lo23),
                _mm256_shuffle_ps::<0xEE>(lo01, lo23),
                _mm256_shuffle_ps::<0x44>(hi01, hi23),
                _mm256_shuffle_ps::<0xEE>(hi01, hi23),
                _mm256_shuffle_ps::<0x44>(v01, v23),
                _mm256_shuffle_ps::<0xEE>(v01, v23),
            ];
            for (row, x) in row.iter_mut().zip(coordinates) {
                // SAFETY: eight floats from `half * 8` are inside the row's `LANES`.
                unsafe { _mm256_storeu_ps(row.as_mut_ptr().add(half * 8), x) };
            }
        }
        row
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state(n: usize) -> (Vec3s, Vec3s) {
        let c = |v: usize, k: usize| (v * 8 + k) as f32 + 0.25;
        let pos = Vec3s::from_fn(n, |v| glam::Vec3::new(c(v, 0), c(v, 1), c(v, 2)));
        let vel = Vec3s::from_fn(n, |v| glam::Vec3::new(c(v, 3), c(v, 4), c(v, 5)));
        (pos, vel)
    }

    #[test]
    fn every_build_loads_a_row_as_the_element_by_element_one() {
        let n = 300;
        let (pos, vel) = state(n);
        let mut packed = vec![Packed::default(); n];
        pack(&mut packed, (&pos, &vel), 0, None);
        let at: [u32; LANES] = std::array::from_fn(|i| ((i * 97 + 13) % n) as u32);
        // SAFETY: every index is below `n`.
        let want = unsafe { Scalar::load(&packed, &at) };
        for (lane, &v) in at.iter().enumerate() {
            let v = v as usize;
            let expect = [pos.x[v], pos.y[v], pos.z[v], vel.x[v], vel.y[v], vel.z[v]];
            assert_eq!(want.map(|c| c[lane]), expect, "lane {lane}");
        }
        #[cfg(target_arch = "x86_64")]
        {
            use crate::simd::{has, Isa};
            // SAFETY: as above; every x86-64 CPU has SSE2.
            assert_eq!(unsafe { Sse2::load(&packed, &at) }, want);
            if has(Isa::Avx2) {
                // SAFETY: as above, and the CPU has AVX2.
                assert_eq!(unsafe { Avx2::load(&packed, &at) }, want);
            }
        }
    }

    #[test]
    fn packing_by_an_index_takes_each_indexed_vertex() {
        let (pos, vel) = state(10);
        let index = [7u32, 0, 9, 3];
        let mut packed = vec![Packed::default(); 4];
        pack(&mut packed, (&pos, &vel), 0, Some(&index));
        for (p, &v) in packed.iter().zip(&index) {
            assert_eq!(*p, Packed::of(&pos, &vel, v as usize));
        }
        let mut tail = vec![Packed::default(); 3];
        pack(&mut tail, (&pos, &vel), 6, None);
        assert_eq!(tail[2], Packed::of(&pos, &vel, 8));
    }
}
