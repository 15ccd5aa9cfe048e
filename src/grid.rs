//! The cloth's grid: particle indexing, the 12-neighbour spring stencil and the triangle mesh.
//!
//! Particle `(i, j)` has index `p = j * nx + i`. Each spring is stored once, at its *anchor*,
//! the end with the lower index; the other end is `anchor + offset`. Because every spring kind
//! has a positive index offset, a particle gathers the force of one kind from two places: the
//! spring it anchors (partner `p + offset`) and the spring anchored at `p - offset`.

/// The six spring kinds of the stencil; each particle anchors at most one of each, so there are
/// at most six springs per particle and twelve neighbours.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SpringKind {
    /// Structural, `(i, j)-(i+1, j)`.
    StructuralI,
    /// Structural, `(i, j)-(i, j+1)`.
    StructuralJ,
    /// Shear, `(i, j)-(i+1, j+1)`.
    ShearDiagonal,
    /// Shear, `(i+1, j)-(i, j+1)`, anchored at `(i+1, j)`.
    ShearAntiDiagonal,
    /// Bending, `(i, j)-(i+2, j)`.
    BendI,
    /// Bending, `(i, j)-(i, j+2)`.
    BendJ,
}

/// One spring: its kind and its anchor particle (the slot it is stored in).
pub type SpringSlot = (SpringKind, usize);

impl SpringKind {
    pub const ALL: [SpringKind; 6] = [
        SpringKind::StructuralI,
        SpringKind::StructuralJ,
        SpringKind::ShearDiagonal,
        SpringKind::ShearAntiDiagonal,
        SpringKind::BendI,
        SpringKind::BendJ,
    ];

    /// Position in [`SpringKind::ALL`], used to index per-kind storage.
    pub fn index(self) -> usize {
        self as usize
    }

    /// Grid step `(di, dj)` from the anchor to the partner.
    pub fn step(self) -> (i64, i64) {
        match self {
            SpringKind::StructuralI => (1, 0),
            SpringKind::StructuralJ => (0, 1),
            SpringKind::ShearDiagonal => (1, 1),
            SpringKind::ShearAntiDiagonal => (-1, 1),
            SpringKind::BendI => (2, 0),
            SpringKind::BendJ => (0, 2),
        }
    }

    /// The kind whose step is `(di, dj)`, if one is.
    pub fn from_step(step: (i64, i64)) -> Option<SpringKind> {
        SpringKind::ALL.into_iter().find(|k| k.step() == step)
    }

    pub fn family(self) -> Family {
        match self {
            SpringKind::StructuralI | SpringKind::StructuralJ => Family::Structural,
            SpringKind::ShearDiagonal | SpringKind::ShearAntiDiagonal => Family::Shear,
            SpringKind::BendI | SpringKind::BendJ => Family::Bend,
        }
    }
}

/// The three spring families, each with its own stiffness.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Family {
    Structural,
    Shear,
    Bend,
}

impl Family {
    pub const ALL: [Family; 3] = [Family::Structural, Family::Shear, Family::Bend];

    pub fn kinds(self) -> [SpringKind; 2] {
        match self {
            Family::Structural => [SpringKind::StructuralI, SpringKind::StructuralJ],
            Family::Shear => [SpringKind::ShearDiagonal, SpringKind::ShearAntiDiagonal],
            Family::Bend => [SpringKind::BendI, SpringKind::BendJ],
        }
    }

    /// [`Family::kinds`] as a static slice.
    pub fn kinds_slice(self) -> &'static [SpringKind] {
        const STRUCTURAL: [SpringKind; 2] = [SpringKind::StructuralI, SpringKind::StructuralJ];
        const SHEAR: [SpringKind; 2] = [SpringKind::ShearDiagonal, SpringKind::ShearAntiDiagonal];
        const BEND: [SpringKind; 2] = [SpringKind::BendI, SpringKind::BendJ];
        match self {
            Family::Structural => &STRUCTURAL,
            Family::Shear => &SHEAR,
            Family::Bend => &BEND,
        }
    }

    /// The pass name under which the family's force appears in `effects` and `profile()`.
    pub fn pass_name(self) -> &'static str {
        match self {
            Family::Structural => "structural_springs",
            Family::Shear => "shear_springs",
            Family::Bend => "bend_springs",
        }
    }
}

/// Grid dimensions and index arithmetic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Grid {
    pub nx: usize,
    pub ny: usize,
}

impl Grid {
    pub fn len(&self) -> usize {
        self.nx * self.ny
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    #[inline]
    pub fn index(&self, i: usize, j: usize) -> usize {
        j * self.nx + i
    }

    #[inline]
    pub fn coords(&self, p: usize) -> (usize, usize) {
        (p % self.nx, p / self.nx)
    }

    /// Index distance from a spring's anchor to its partner.
    pub fn offset(&self, kind: SpringKind) -> usize {
        let (di, dj) = kind.step();
        (di + dj * self.nx as i64) as usize
    }

    /// The partner of the spring of `kind` anchored at `p`, if that spring exists on the grid.
    pub fn partner(&self, p: usize, kind: SpringKind) -> Option<usize> {
        let (i, j) = self.coords(p);
        let (di, dj) = kind.step();
        let (pi, pj) = (i as i64 + di, j as i64 + dj);
        let inside = (0..self.nx as i64).contains(&pi) && (0..self.ny as i64).contains(&pj);
        inside.then(|| self.index(pi as usize, pj as usize))
    }

    /// The spring slot `(kind, anchor)` joining particles `p` and `q`, if the stencil has one.
    pub fn spring_between(&self, p: usize, q: usize) -> Option<(SpringKind, usize)> {
        let (lo, hi) = (p.min(q), p.max(q));
        let ((i0, j0), (i1, j1)) = (self.coords(lo), self.coords(hi));
        let step = (i1 as i64 - i0 as i64, j1 as i64 - j0 as i64);
        SpringKind::from_step(step).map(|kind| (kind, lo))
    }

    /// The two triangles of each cell `(i, j)-(i+1, j+1)`, split along the shear diagonal,
    /// wound so that their normal is `e_i x e_j` for a flat cloth. Cells touching a removed
    /// particle (`alive[p] == false`) are left out.
    pub fn triangles(&self, alive: &[bool]) -> Vec<[u32; 3]> {
        let mut out = Vec::with_capacity(2 * (self.nx - 1) * (self.ny - 1));
        for j in 0..self.ny - 1 {
            for i in 0..self.nx - 1 {
                let a = self.index(i, j);
                let b = a + 1;
                let c = a + self.nx;
                let d = c + 1;
                if alive[a] && alive[b] && alive[d] {
                    out.push([a as u32, b as u32, d as u32]);
                }
                if alive[a] && alive[d] && alive[c] {
                    out.push([a as u32, d as u32, c as u32]);
                }
            }
        }
        out
    }
}

/// Whether every corner of triangle `id` is alive: removing a particle takes its triangles
/// away. [`crate::model::Model::triangle_drawn`] adds severed springs.
pub fn triangle_alive(grid: Grid, alive: &[bool], id: usize) -> bool {
    cell_triangle(grid, id).iter().all(|&q| alive[q])
}

/// Number of triangle ids of `grid`: two per cell.
pub fn triangle_slots(grid: Grid) -> usize {
    2 * (grid.nx - 1) * (grid.ny - 1)
}

/// The vertices of triangle `id`: cell `id / 2` (cell `(i, j)` is `j * (nx - 1) + i`) and half
/// `id % 2`, in the order and winding of [`Grid::triangles`]. Triangle ids are stable across cuts,
/// which is what lets the picking trees and the mesh key their triangles by them.
pub fn cell_triangle(grid: Grid, id: usize) -> [usize; 3] {
    let cell = id / 2;
    let (i, j) = (cell % (grid.nx - 1), cell / (grid.nx - 1));
    let a = grid.index(i, j);
    let (b, c) = (a + 1, a + grid.nx);
    let d = c + 1;
    if id.is_multiple_of(2) {
        [a, b, d]
    } else {
        [a, d, c]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_has_a_positive_offset_so_the_anchor_is_the_lower_index() {
        for nx in 2..6 {
            for kind in SpringKind::ALL {
                let (di, dj) = kind.step();
                assert!(di + dj * nx as i64 > 0, "{kind:?} at nx={nx}");
            }
        }
    }

    #[test]
    fn partners_match_the_stencil_and_stay_on_the_grid() {
        let grid = Grid { nx: 5, ny: 4 };
        let count = |kind| {
            (0..grid.len())
                .filter(|&p| grid.partner(p, kind).is_some())
                .count()
        };
        assert_eq!(count(SpringKind::StructuralI), 4 * 4);
        assert_eq!(count(SpringKind::StructuralJ), 5 * 3);
        assert_eq!(count(SpringKind::ShearDiagonal), 4 * 3);
        assert_eq!(count(SpringKind::ShearAntiDiagonal), 4 * 3);
        assert_eq!(count(SpringKind::BendI), 3 * 4);
        assert_eq!(count(SpringKind::BendJ), 5 * 2);
        for kind in SpringKind::ALL {
            for p in 0..grid.len() {
                if let Some(q) = grid.partner(p, kind) {
                    assert_eq!(q, p + grid.offset(kind));
                }
            }
        }
        // (i+1, j)-(i, j+1): the anti-diagonal anchored at i = 0 has no partner.
        assert_eq!(
            grid.partner(grid.index(0, 0), SpringKind::ShearAntiDiagonal),
            None
        );
    }

    #[test]
    fn triangles_cover_every_cell_twice_and_skip_dead_particles() {
        let grid = Grid { nx: 4, ny: 3 };
        let mut alive = vec![true; grid.len()];
        assert_eq!(grid.triangles(&alive).len(), 2 * 3 * 2);
        alive[grid.index(0, 0)] = false;
        let tris = grid.triangles(&alive);
        assert_eq!(tris.len(), 2 * 3 * 2 - 2);
        assert!(tris.iter().flatten().all(|&p| alive[p as usize]));
    }
}
