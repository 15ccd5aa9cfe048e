//! A pair of primitives that may touch, a vertex and a triangle without it or two edges with
//! no shared vertex, and its closest points: the narrow phase of self-collision.

use glam::DVec3;

use crate::self_collision::geometry;
use crate::soa::Vec3s;

/// A candidate pair: a vertex and a triangle without it (`split = 1`: `verts[0]` against
/// `verts[1..]`) or two edges with no shared vertex (`split = 2`).
#[derive(Clone, Copy, Debug)]
pub struct Pair {
    pub verts: [u32; 4],
    pub split: usize,
    /// Weights of the closest points at the start: the gap vector is `sum c_i x_i`.
    pub c: [f64; 4],
    /// Unit normal at the start, from the second primitive to the first (zero if degenerate).
    pub n: DVec3,
    /// Distance at the start, in m.
    pub d0: f64,
}

/// A pair by its vertices alone, as the pair list keeps it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    pub verts: [u32; 4],
    pub split: u8,
}

impl Candidate {
    /// What orders pairs the same way whenever they were found.
    pub fn key(&self) -> (u8, [u32; 4]) {
        (self.split, self.verts)
    }

    /// The pair with its closest points at `x`.
    pub fn at(self, x: &Vec3s) -> Pair {
        match self.split {
            1 => vertex_triangle(x, self.verts),
            _ => edge_edge(x, self.verts),
        }
    }
}

impl Pair {
    pub fn candidate(&self) -> Candidate {
        Candidate {
            verts: self.verts,
            split: self.split as u8,
        }
    }

    pub fn gap(&self, x: &Vec3s) -> f64 {
        let mut g = DVec3::ZERO;
        for k in 0..4 {
            g += self.c[k] * x.get(self.verts[k] as usize).as_dvec3();
        }
        g.dot(self.n)
    }
}

/// How many times the change a contact asks of its pair's relative motion (a gap to close, an
/// approach to stop) one vertex of the pair may be given. Exact sharing by inverse mass gives
/// vertex `i` the change `w_i c_i / sum_j w_j c_j^2` times the pair's: when the only vertices
/// that can move have small weights (two edges that meet near a gripped vertex, the free end
/// with `c = 1e-4`), that is `1 / c`, and a 1 m/s approach flung the free vertex at 10 km/s.
/// Where every vertex can move and all weigh the same, `sum_j c_j^2 >= 1 >= |c_i|` and the
/// limit never acts; nor for a pinned vertex against a free triangle
/// (`sum c^2 >= max c^2`, and `>= 1/3` for any barycentric weights). Where it acts, every
/// vertex's change shrinks by the same factor: momentum is kept as before, the pair's
/// relative motion is corrected in part, and the next sweep or step goes on with it.
pub const LEVER: f64 = 2.0;

/// A pair's inverse effective mass along the normal, `sum_i w_i c_i^2`, raised where needed so
/// that no vertex is given more than [`LEVER`] times the pair's change; None when no vertex of
/// it can move.
pub fn inverse_mass(pair: &Pair, inv_mass: &[f32]) -> Option<f64> {
    let (mut sum, mut lever) = (0.0f64, 0.0f64);
    for (&v, c) in pair.verts.iter().zip(pair.c) {
        let w = inv_mass[v as usize] as f64;
        sum += w * c * c;
        lever = lever.max(w * c.abs());
    }
    (sum > 0.0).then_some(sum.max(lever / LEVER))
}

/// Vertex `q[0]` against triangle `q[1..]` at positions `x`.
pub fn vertex_triangle(x: &Vec3s, q: [u32; 4]) -> Pair {
    let ([_, a, b, c], w, gap) = vertex_triangle_gap(x, q);
    let fallback = || (b - a).cross(c - a).normalize_or_zero();
    finish(q, 1, [1.0, -w[0], -w[1], -w[2]], gap, fallback)
}

/// Edge `q[0..2]` against edge `q[2..]` at positions `x`.
pub fn edge_edge(x: &Vec3s, q: [u32; 4]) -> Pair {
    let ([a, b, c, d], (s, t), gap) = edge_edge_gap(x, q);
    let fallback = || (b - a).cross(d - c).normalize_or_zero();
    finish(q, 2, [1.0 - s, s, t - 1.0, -t], gap, fallback)
}

/// The distance of the pair `q` split at `split` at positions `x` (m): bitwise the `d0` of its
/// [`vertex_triangle`] or [`edge_edge`], without the weights and the normal.
pub fn distance(x: &Vec3s, q: [u32; 4], split: usize) -> f64 {
    match split {
        1 => vertex_triangle_gap(x, q).2.length(),
        _ => edge_edge_gap(x, q).2.length(),
    }
}

/// The positions of `q`, the closest point's weights on the triangle and the gap vector.
#[inline]
fn vertex_triangle_gap(x: &Vec3s, q: [u32; 4]) -> ([DVec3; 4], [f64; 3], DVec3) {
    let [p, a, b, c] = q.map(|v| x.get(v as usize).as_dvec3());
    let w = geometry::point_triangle(p, a, b, c);
    let gap = p - (w[0] * a + w[1] * b + w[2] * c);
    ([p, a, b, c], w, gap)
}

/// The positions of `q`, the closest points' parameters on the two edges and the gap vector.
#[inline]
fn edge_edge_gap(x: &Vec3s, q: [u32; 4]) -> ([DVec3; 4], (f64, f64), DVec3) {
    let [a, b, c, d] = q.map(|v| x.get(v as usize).as_dvec3());
    let (s, t) = geometry::segment_segment(a, b, c, d);
    let gap = (a + s * (b - a)) - (c + t * (d - c));
    ([a, b, c, d], (s, t), gap)
}

fn finish(
    verts: [u32; 4],
    split: usize,
    c: [f64; 4],
    gap: DVec3,
    fallback: impl Fn() -> DVec3,
) -> Pair {
    let d0 = gap.length();
    let n = if d0 > 0.0 { gap / d0 } else { fallback() };
    Pair {
        verts,
        split,
        c,
        n,
        d0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn pair_weights_sum_to_zero_and_the_normal_points_from_the_triangle() {
        // Zero-sum weights are what make every correction keep momentum.
        let x0 = Vec3s::from_fn(4, |v| {
            [Vec3::new(0.2, 0.01, 0.2), Vec3::ZERO, Vec3::X, Vec3::Z][v]
        });
        let pair = vertex_triangle(&x0, [0, 1, 2, 3]);
        assert!((pair.d0 - 0.01).abs() < 1e-8, "{}", pair.d0);
        assert!((pair.n - DVec3::Y).length() < 1e-12);
        assert_eq!(pair.c.iter().sum::<f64>(), 0.0);
        let e = edge_edge(&x0, [0, 1, 2, 3]);
        assert!(e.c.iter().sum::<f64>().abs() < 1e-15);
    }

    /// Pairs at random positions, vertex-triangle and edge-edge alike.
    fn random_pairs() -> impl Iterator<Item = Pair> {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f32 / (1u64 << 53) as f32
        };
        (0..2000).map(move |i| {
            let x = Vec3s::from_fn(4, |_| Vec3::new(next(), next(), next()));
            match i % 2 {
                0 => vertex_triangle(&x, [0, 1, 2, 3]),
                _ => edge_edge(&x, [0, 1, 2, 3]),
            }
        })
    }

    #[test]
    fn a_contact_never_gives_a_vertex_more_than_lever_times_the_pairs_change() {
        // Only the edge's end next to the contact is free: exact sharing gave it 1 / 1e-4 times
        // the pair's change.
        let lever = Pair {
            verts: [0, 1, 2, 3],
            split: 2,
            c: [1.0 - 1e-4, 1e-4, -0.5, -0.5],
            n: DVec3::Y,
            d0: 0.001,
        };
        let w = inverse_mass(&lever, &[0.0, 1.0, 0.0, 0.0]).unwrap();
        assert!(1e-4 / w <= LEVER, "{}", 1e-4 / w);
        for (i, pair) in random_pairs().enumerate() {
            let inv_mass = [0.5, 1.0, 2.0, 3.0].map(|m| {
                if (i >> m as usize) & 1 == 1 {
                    0.0
                } else {
                    1.0 / m
                }
            });
            let Some(w) = inverse_mass(&pair, &inv_mass) else {
                continue;
            };
            for (&w_k, c_k) in inv_mass.iter().zip(pair.c) {
                let share = w_k as f64 * c_k.abs() / w;
                assert!(share <= LEVER * (1.0 + 1e-12), "pair {i}: {share}");
            }
        }
    }

    #[test]
    fn the_lever_limit_never_acts_on_free_vertices_of_equal_mass_nor_on_a_pinned_vertex() {
        // Where it does not act the repulsion is bitwise exact sharing by inverse mass.
        for pair in random_pairs() {
            let exact = |inv_mass: [f32; 4]| -> f64 {
                (0..4)
                    .map(|k| inv_mass[k] as f64 * pair.c[k] * pair.c[k])
                    .sum()
            };
            let free = [2.0; 4];
            assert_eq!(inverse_mass(&pair, &free), Some(exact(free)));
            if pair.split == 1 {
                let pinned = [0.0, 2.0, 2.0, 2.0];
                assert_eq!(inverse_mass(&pair, &pinned), Some(exact(pinned)));
            }
        }
    }
}
