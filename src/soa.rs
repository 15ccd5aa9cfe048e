//! Structure-of-arrays storage for per-particle 3-vectors.
//!
//! The hot loops run over one component at a time for many particles, so each component is its
//! own contiguous `f32` array: the compiler vectorises across particles, and row slices of the
//! grid map straight onto slices of these arrays. glam's `Vec3` is the interface for scalar code.
//! Every array starts on a cache line ([`Floats`]), so that the vector loads and stores of a loop
//! over a block of particles do not straddle two lines.

use std::ops::{Deref, DerefMut};

use glam::Vec3;

/// Lanes in a cache line of `f32`s (64 bytes: one AVX-512 vector).
pub const LINE: usize = 16;

/// A fixed-length array of `f32` whose first element starts a 64-byte cache line. It derefs to
/// `[f32]`. A vector load of 64 bytes at a particle index that is a multiple of [`LINE`] then
/// reads one cache line, not two: with `malloc`'s 16-byte alignment every such load straddled
/// two lines, a measurable cost in the hot loops (docs/benchmarks.md).
#[derive(Clone, Default)]
pub struct Floats {
    lines: Vec<Line>,
    len: usize,
}

/// The storage unit of [`Floats`]: one cache line of `f32`s.
#[derive(Clone, Copy, Default)]
#[repr(C, align(64))]
struct Line([f32; LINE]);

impl Floats {
    /// `n` copies of `value`.
    pub fn filled(n: usize, value: f32) -> Self {
        Floats {
            lines: vec![Line([value; LINE]); n.div_ceil(LINE)],
            len: n,
        }
    }

    pub fn zeros(n: usize) -> Self {
        Self::filled(n, 0.0)
    }

    /// Makes the length `n`, new elements `value` (as `Vec::resize`).
    pub fn resize(&mut self, n: usize, value: f32) {
        let old = self.len;
        self.lines.resize(n.div_ceil(LINE), Line([value; LINE]));
        self.len = n;
        if n > old {
            self[old..].fill(value);
        }
    }

    /// Bytes of heap memory held.
    pub fn heap_bytes(&self) -> usize {
        self.lines.capacity() * size_of::<Line>()
    }
}

impl Deref for Floats {
    type Target = [f32];

    #[inline]
    fn deref(&self) -> &[f32] {
        // SAFETY: `Line` is `repr(C)` around `[f32; LINE]`, 64 bytes with no padding, so the
        // lines are `LINE * lines.len() >= len` consecutive, initialised `f32`s.
        unsafe { std::slice::from_raw_parts(self.lines.as_ptr().cast::<f32>(), self.len) }
    }
}

impl DerefMut for Floats {
    #[inline]
    fn deref_mut(&mut self) -> &mut [f32] {
        // SAFETY: as in `deref`, and `&mut self` makes the borrow unique.
        unsafe { std::slice::from_raw_parts_mut(self.lines.as_mut_ptr().cast::<f32>(), self.len) }
    }
}

impl PartialEq for Floats {
    fn eq(&self, other: &Self) -> bool {
        **self == **other
    }
}

impl std::fmt::Debug for Floats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        (**self).fmt(f)
    }
}

/// `n` 3-vectors stored as three arrays.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Vec3s {
    pub x: Floats,
    pub y: Floats,
    pub z: Floats,
}

impl Vec3s {
    pub fn zeros(n: usize) -> Self {
        Vec3s {
            x: Floats::zeros(n),
            y: Floats::zeros(n),
            z: Floats::zeros(n),
        }
    }

    pub fn from_fn(n: usize, mut f: impl FnMut(usize) -> Vec3) -> Self {
        let mut out = Self::zeros(n);
        for i in 0..n {
            out.set(i, f(i));
        }
        out
    }

    pub fn copy_from(&mut self, other: &Vec3s) {
        self.x.copy_from_slice(&other.x);
        self.y.copy_from_slice(&other.y);
        self.z.copy_from_slice(&other.z);
    }

    /// Makes this a copy of `other`, of any length, keeping its buffers where the lengths
    /// already match (a copy kept from step to step allocates once).
    pub fn assign(&mut self, other: &Vec3s) {
        if self.len() == other.len() {
            self.copy_from(other);
        } else {
            *self = other.clone();
        }
    }

    /// Interleaves into `out` as `[x0, y0, z0, x1, ...]`, the layout of an `(N, 3)` array.
    pub fn write_interleaved(&self, out: &mut [f32]) {
        for (i, p) in out.chunks_exact_mut(3).enumerate() {
            p[0] = self.x[i];
            p[1] = self.y[i];
            p[2] = self.z[i];
        }
    }

    /// Bytes of heap memory held.
    pub fn heap_bytes(&self) -> usize {
        self.x.heap_bytes() + self.y.heap_bytes() + self.z.heap_bytes()
    }

    /// Component `c` (0 = x, 1 = y, 2 = z) restricted to `range`.
    #[inline]
    pub fn component(&self, c: usize, range: &std::ops::Range<usize>) -> &[f32] {
        let v = match c {
            0 => &self.x,
            1 => &self.y,
            _ => &self.z,
        };
        &v[range.clone()]
    }

    /// Mutable views of the three components restricted to `range`.
    pub fn slices_mut(&mut self, range: std::ops::Range<usize>) -> Vec3SliceMut<'_> {
        Vec3SliceMut {
            x: &mut self.x[range.clone()],
            y: &mut self.y[range.clone()],
            z: &mut self.z[range],
        }
    }

    /// Read-only views of the three components restricted to `range`.
    pub fn slices(&self, range: std::ops::Range<usize>) -> Vec3Slice<'_> {
        Vec3Slice {
            x: &self.x[range.clone()],
            y: &self.y[range.clone()],
            z: &self.z[range],
        }
    }
}

/// Read-only component slices of equal length.
#[derive(Clone, Copy)]
pub struct Vec3Slice<'a> {
    pub x: &'a [f32],
    pub y: &'a [f32],
    pub z: &'a [f32],
}

impl<'a> Vec3Slice<'a> {
    /// The sub-range `range` of these slices.
    pub fn slices_at(&self, range: std::ops::Range<usize>) -> Vec3Slice<'a> {
        Vec3Slice {
            x: &self.x[range.clone()],
            y: &self.y[range.clone()],
            z: &self.z[range],
        }
    }
}

/// Mutable component slices of equal length.
pub struct Vec3SliceMut<'a> {
    pub x: &'a mut [f32],
    pub y: &'a mut [f32],
    pub z: &'a mut [f32],
}

impl Vec3SliceMut<'_> {
    /// The sub-range `range` of these slices.
    pub fn sub_mut(&mut self, range: std::ops::Range<usize>) -> Vec3SliceMut<'_> {
        Vec3SliceMut {
            x: &mut self.x[range.clone()],
            y: &mut self.y[range.clone()],
            z: &mut self.z[range],
        }
    }

    /// Read-only views of these slices, for reading back what was just written.
    pub fn as_slices(&self) -> Vec3Slice<'_> {
        Vec3Slice {
            x: self.x,
            y: self.y,
            z: self.z,
        }
    }

    /// Component `c` (0 = x, 1 = y, 2 = z).
    #[inline]
    pub fn component_mut(&mut self, c: usize) -> &mut [f32] {
        match c {
            0 => &mut *self.x,
            1 => &mut *self.y,
            _ => &mut *self.z,
        }
    }
}

/// The per-particle accessors of three equal-length component arrays, for the owned arrays and
/// for views into them alike: both hold `x`, `y`, `z` that index and fill as `f32` slices.
macro_rules! vec3_accessors {
    ($t:ty) => {
        impl $t {
            pub fn len(&self) -> usize {
                self.x.len()
            }

            pub fn is_empty(&self) -> bool {
                self.x.is_empty()
            }

            #[inline]
            pub fn get(&self, i: usize) -> Vec3 {
                Vec3::new(self.x[i], self.y[i], self.z[i])
            }

            #[inline]
            pub fn set(&mut self, i: usize, v: Vec3) {
                self.x[i] = v.x;
                self.y[i] = v.y;
                self.z[i] = v.z;
            }

            pub fn fill(&mut self, v: Vec3) {
                self.x.fill(v.x);
                self.y.fill(v.y);
                self.z.fill(v.z);
            }
        }
    };
}

vec3_accessors!(Vec3s);
vec3_accessors!(Vec3SliceMut<'_>);

impl Vec3s {
    /// Parallel iterator over consecutive chunks of `chunk` particles (the last may be shorter).
    pub fn par_chunks_mut(
        &mut self,
        chunk: usize,
    ) -> impl rayon::iter::IndexedParallelIterator<Item = Vec3SliceMut<'_>> {
        use rayon::prelude::*;
        self.x
            .par_chunks_mut(chunk)
            .zip(self.y.par_chunks_mut(chunk))
            .zip(self.z.par_chunks_mut(chunk))
            .map(|((x, y), z)| Vec3SliceMut { x, y, z })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_start_on_a_cache_line_and_resize_like_a_vec() {
        let mut v = Floats::filled(20, 1.5);
        assert_eq!(v.as_ptr() as usize % 64, 0);
        assert_eq!(v.len(), 20);
        v.resize(5, 0.0);
        assert_eq!(&v[..], &[1.5; 5]);
        // Growing again overwrites what the shrink left in the last line.
        v.resize(40, 2.0);
        assert_eq!(&v[..5], &[1.5; 5]);
        assert_eq!(&v[5..], &[2.0; 35]);
        assert_eq!(v.as_ptr() as usize % 64, 0);
        assert_eq!(v, v.clone());
        assert_ne!(v, Floats::filled(40, 2.0));
    }
}
