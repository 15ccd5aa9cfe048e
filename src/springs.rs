//! The springs of the cloth as data: per kind, a rest length and a live flag at each anchor
//! particle, and the one way every pass walks them, a [`SpringRun`] of consecutive anchors
//! seen through a [`RunView`].
//!
//! Each spring is stored once, at its *anchor*, the end with the lower index; the other end is
//! `anchor + offset` (see [`crate::grid`]). A slot whose spring does not exist (off the grid) or
//! was cut holds `active = 0`: keeping the slots lets loops run over whole index ranges without
//! row-boundary branches, and a pass reads the flag to leave dead slots out.

use std::ops::Range;

use crate::grid::{Grid, SpringKind};
use crate::soa::{Floats, Vec3s};

/// Per-spring data, one array per [`SpringKind`], indexed by the spring's anchor particle.
#[derive(Clone, Debug)]
pub struct Springs {
    /// Rest length in m: the distance between the two particles when the cloth was built.
    pub rest: [Floats; 6],
    /// 1 for a live spring, 0 for none.
    pub active: [Floats; 6],
}

impl Springs {
    /// Every spring of the stencil, with rest lengths taken from `pos`.
    pub fn new(grid: Grid, pos: &Vec3s) -> Self {
        let n = grid.len();
        let mut rest: [Floats; 6] = Default::default();
        let mut active: [Floats; 6] = Default::default();
        for kind in SpringKind::ALL {
            let k = kind.index();
            rest[k] = Floats::zeros(n);
            active[k] = Floats::zeros(n);
            for p in 0..n {
                if let Some(q) = grid.partner(p, kind) {
                    rest[k][p] = (pos.get(q) - pos.get(p)).length();
                    active[k][p] = 1.0;
                }
            }
        }
        Springs { rest, active }
    }

    /// `n` slots of every kind, none live: a mesh cloth's, whose springs are a list of its own.
    pub fn none(n: usize) -> Self {
        Springs {
            rest: std::array::from_fn(|_| Floats::zeros(n)),
            active: std::array::from_fn(|_| Floats::zeros(n)),
        }
    }

    /// Removes every spring that touches particle `p`, and the bending springs that pass over
    /// it (`(i-1, j)-(i+1, j)` and `(i, j-1)-(i, j+1)`): they span the hole, and left in place
    /// they would hold the cloth together across a cut one particle wide.
    pub fn remove_particle(&mut self, grid: Grid, p: usize) {
        for kind in SpringKind::ALL {
            let k = kind.index();
            self.active[k][p] = 0.0;
            let o = grid.offset(kind);
            if p >= o && grid.partner(p - o, kind) == Some(p) {
                self.active[k][p - o] = 0.0;
            }
        }
        for kind in [SpringKind::BendI, SpringKind::BendJ] {
            let half = grid.offset(kind) / 2;
            if p >= half && grid.partner(p - half, kind) == Some(p + half) {
                self.active[kind.index()][p - half] = 0.0;
            }
        }
    }

    /// Visits every live spring of `kind` as `(anchor, partner, rest length)`.
    pub fn for_each(&self, grid: Grid, kind: SpringKind, mut f: impl FnMut(usize, usize, f32)) {
        let k = kind.index();
        let o = grid.offset(kind);
        for a in 0..grid.len().saturating_sub(o) {
            if self.active[k][a] != 0.0 {
                f(a, a + o, self.rest[k][a]);
            }
        }
    }

    /// The springs of `kind` over `run`, with their ends' values from `values` (positions or
    /// velocities).
    #[inline(always)]
    pub fn view<'a>(&'a self, kind: SpringKind, values: &'a Vec3s, run: SpringRun) -> RunView<'a> {
        let (a, b, s) = (run.a_range(), run.b_range(), run.slots());
        let len = run.len;
        RunView {
            a: ends(values, a),
            b: ends(values, b),
            rest: &self.rest[kind.index()][s.clone()][..len],
            active: &self.active[kind.index()][s][..len],
            len,
        }
    }

    pub fn heap_bytes(&self) -> usize {
        self.rest
            .iter()
            .chain(&self.active)
            .map(Floats::heap_bytes)
            .sum()
    }
}

/// The three components of `values` over `range`.
#[inline(always)]
fn ends(values: &Vec3s, range: Range<usize>) -> [&[f32]; 3] {
    let len = range.len();
    [
        &values.x[range.clone()][..len],
        &values.y[range.clone()][..len],
        &values.z[range][..len],
    ]
}

/// One kind's springs over a run of `len` consecutive particles `a..` and their neighbours
/// `b..`, stored in slots `spring..`. Built by [`neighbour_runs`] and [`anchored_run`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpringRun {
    pub a: usize,
    pub b: usize,
    pub spring: usize,
    pub len: usize,
}

impl SpringRun {
    pub fn a_range(&self) -> Range<usize> {
        self.a..self.a + self.len
    }

    pub fn b_range(&self) -> Range<usize> {
        self.b..self.b + self.len
    }

    pub fn slots(&self) -> Range<usize> {
        self.spring..self.spring + self.len
    }
}

/// The slices a loop over one [`SpringRun`] reads, every one exactly the run's length so that
/// the loop has no bounds checks and vectorises: the two ends' values (`a[c][i]`, `b[c][i]`
/// for component `c` of spring `i`), rest lengths and live flags.
pub struct RunView<'a> {
    pub a: [&'a [f32]; 3],
    pub b: [&'a [f32]; 3],
    pub rest: &'a [f32],
    pub active: &'a [f32],
    pub len: usize,
}

impl RunView<'_> {
    /// `b - a` of spring `i`, component by component.
    #[inline(always)]
    pub fn delta(&self, i: usize) -> [f32; 3] {
        [
            self.b[0][i] - self.a[0][i],
            self.b[1][i] - self.a[1][i],
            self.b[2][i] - self.a[2][i],
        ]
    }
}

/// The particles of `range` that have a neighbour along a spring kind of index offset `o`, as
/// at most two runs: those that anchor the spring (neighbour `a + o`, slot `a`) and those at its
/// far end (neighbour `a - o`, slot `a - o`). Slots of springs that do not exist are inactive,
/// so the runs need no row-boundary checks.
pub fn neighbour_runs(n: usize, o: usize, range: Range<usize>) -> [Option<SpringRun>; 2] {
    let anchors = range.start..range.end.min(n.saturating_sub(o));
    let ends = range.start.max(o)..range.end;
    [
        (!anchors.is_empty()).then(|| SpringRun {
            a: anchors.start,
            b: anchors.start + o,
            spring: anchors.start,
            len: anchors.len(),
        }),
        (!ends.is_empty()).then(|| SpringRun {
            a: ends.start,
            b: ends.start - o,
            spring: ends.start - o,
            len: ends.len(),
        }),
    ]
}

/// The slots of `range` that can anchor a spring of index offset `o` on a grid of `n`
/// particles, as a run from the anchors to their partners `a + o`, both inside the grid. Empty
/// (and still in bounds) where the whole range lies within `o` of the end, as on a grid wider
/// than a block.
pub fn anchored_run(n: usize, o: usize, range: Range<usize>) -> SpringRun {
    let end = range.end.min(n.saturating_sub(o)).max(range.start);
    let start = range.start.min(end);
    SpringRun {
        a: start,
        b: (start + o).min(n),
        spring: start,
        len: end - start,
    }
}

/// Whether a spring of length `l` (m), rest length `rest` and `active` flag (0 or 1) is longer
/// than `limit` times its rest length: the watchdog's stretch check, the same arithmetic in the
/// force loop and in the scans. A dead slot (`active = 0`) never is.
#[inline(always)]
pub fn overstretched(l: f32, rest: f32, active: f32, limit: f32) -> bool {
    active * l > limit * rest
}
