//! Pins in a scene: named groups of particles (`top_corners`, `left_edge`, ...) or one grid
//! cell, an index, the selections (a box, the boundary, the highest particles), and the
//! particle indices they name.

use super::specs::{ClothSpec, PinBox, PinSpec};
use crate::error::{Error, Result};
use crate::grid::Grid;

/// Names accepted in `cloth.pins`; "top" is the row `j = ny - 1`.
pub const PIN_GROUPS: &[&str] = &[
    "top_corners",
    "bottom_corners",
    "corners",
    "top_edge",
    "bottom_edge",
    "left_edge",
    "right_edge",
    "center",
];

impl ClothSpec {
    /// Every pinned particle index, sorted and without repeats.
    pub fn pinned_indices(&self) -> Vec<usize> {
        let mut out: Vec<usize> = self
            .pins
            .iter()
            .flat_map(|pin| pin_indices(pin, self).unwrap_or_default())
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }
}

impl ClothSpec {
    /// Where grid particle `p` starts (m): `center + (i/(nx-1) - 1/2) size[0] e1 + (j/(ny-1) -
    /// 1/2) size[1] e2`, in f64 (the model rounds it to float32).
    pub fn grid_rest_position(&self, p: usize) -> [f64; 3] {
        let nx = self.nx as usize;
        let (i, j) = (p % nx, p / nx);
        let (e1, e2) = self.plane.axes();
        let u = i as f64 / (nx - 1) as f64 - 0.5;
        let v = j as f64 / (self.ny as usize - 1) as f64 - 0.5;
        let center = glam::DVec3::from(self.center);
        (center + u * self.size[0] * e1.as_dvec3() + v * self.size[1] * e2.as_dvec3()).to_array()
    }
}

/// The particles a pin entry of `cloth` names.
pub(super) fn pin_indices(pin: &PinSpec, cloth: &ClothSpec) -> Result<Vec<usize>> {
    if let Some(mesh) = &cloth.mesh {
        return mesh_pin_indices(pin, &mesh.vertices, &mesh.triangles);
    }
    let grid = Grid {
        nx: cloth.nx as usize,
        ny: cloth.ny as usize,
    };
    let (nx, ny) = (grid.nx, grid.ny);
    if grid.is_empty() {
        // `pinned_indices` may be asked before validation: nothing to pin, and no `nx - 1`.
        return Err(Error::value(
            "pins",
            format!("the {nx} x {ny} grid has no particles"),
        ));
    }
    let (last_i, last_j) = (nx - 1, ny - 1);
    let row = |j: usize| (0..nx).map(move |i| grid.index(i, j));
    let column = |i: usize| (0..ny).map(move |j| grid.index(i, j));
    Ok(match pin {
        PinSpec::Cell([i, j]) => {
            let inside = (0..nx as i64).contains(i) && (0..ny as i64).contains(j);
            if !inside {
                return Err(Error::value(
                    "pins",
                    format!("[{i}, {j}] is outside the {nx} x {ny} grid"),
                ));
            }
            vec![grid.index(*i as usize, *j as usize)]
        }
        PinSpec::Index(p) => {
            vec![checked_index(
                *p,
                grid.len(),
                "particle",
                &format!("the {nx} x {ny} grid"),
            )?]
        }
        PinSpec::Region(region) => {
            let positions: Vec<[f64; 3]> = (0..grid.len())
                .map(|p| cloth.grid_rest_position(p))
                .collect();
            in_box(region, &positions)?
        }
        PinSpec::Boundary(pin) => {
            check_boundary(pin.boundary)?;
            (0..grid.len())
                .filter(|&p| {
                    let (i, j) = grid.coords(p);
                    i == 0 || j == 0 || i == last_i || j == last_j
                })
                .collect()
        }
        PinSpec::Top(pin) => {
            let positions: Vec<[f64; 3]> = (0..grid.len())
                .map(|p| cloth.grid_rest_position(p))
                .collect();
            highest(pin.top, &positions)?
        }
        PinSpec::Named(name) => match name.as_str() {
            "top_corners" => vec![grid.index(0, last_j), grid.index(last_i, last_j)],
            "bottom_corners" => vec![grid.index(0, 0), grid.index(last_i, 0)],
            "corners" => vec![
                grid.index(0, 0),
                grid.index(last_i, 0),
                grid.index(0, last_j),
                grid.index(last_i, last_j),
            ],
            "top_edge" => row(last_j).collect(),
            "bottom_edge" => row(0).collect(),
            "left_edge" => column(0).collect(),
            "right_edge" => column(last_i).collect(),
            "center" => vec![grid.index(nx / 2, ny / 2)],
            other => {
                return Err(Error::value(
                    "pins",
                    format!("unknown pin group {other:?}; valid ones are {PIN_GROUPS:?} or [i, j]"),
                ))
            }
        },
    })
}

/// The vertices a pin entry names on a mesh cloth: an index or a selection; named groups and
/// grid cells are the grid's.
fn mesh_pin_indices(
    pin: &PinSpec,
    vertices: &[[f64; 3]],
    triangles: &[[i64; 3]],
) -> Result<Vec<usize>> {
    match pin {
        PinSpec::Index(k) => {
            let n = vertices.len();
            Ok(vec![checked_index(
                *k,
                n,
                "vertex",
                &format!("the mesh's {n} vertices"),
            )?])
        }
        PinSpec::Region(region) => in_box(region, vertices),
        PinSpec::Boundary(pin) => {
            check_boundary(pin.boundary)?;
            Ok(boundary_vertices(vertices.len(), triangles))
        }
        PinSpec::Top(pin) => highest(pin.top, vertices),
        PinSpec::Named(_) | PinSpec::Cell(_) => Err(Error::value(
            "pins",
            format!(
                "{pin:?} names the grid's particles; a mesh cloth is pinned by vertex index (3), \
                 box ({{ box = [[x0, y0, z0], [x1, y1, z1]] }}), {{ boundary = true }} or \
                 {{ top = 0.001 }}; pins = [] for none"
            ),
        )),
    }
}

/// Index `k` of a pin entry, refused unless one of the `len` particles `of` describes: the one
/// message for a grid's particle and a mesh's vertex.
fn checked_index(k: i64, len: usize, what: &str, of: &str) -> Result<usize> {
    let last = len.saturating_sub(1);
    let message = || format!("{what} {k} is outside {of} (0 to {last})");
    let k = usize::try_from(k).ok().filter(|&k| k < len);
    k.ok_or_else(|| Error::value("pins", message()))
}

/// The particles whose starting positions lie in the box (bounds included); an empty
/// selection is refused.
fn in_box(region: &PinBox, positions: &[[f64; 3]]) -> Result<Vec<usize>> {
    let [lo, hi] = region.corners;
    for (name, v) in [("box[0]", lo), ("box[1]", hi)] {
        if v.iter().any(|x| !x.is_finite()) {
            return Err(Error::value(
                "pins",
                format!("{name} must be finite, got {v:?}"),
            ));
        }
    }
    if (0..3).any(|c| lo[c] > hi[c]) {
        return Err(Error::value(
            "pins",
            format!("box {lo:?} to {hi:?} is empty: each of box[0]'s coordinates must be at most box[1]'s"),
        ));
    }
    let inside: Vec<usize> = (0..positions.len())
        .filter(|&p| (0..3).all(|c| (lo[c]..=hi[c]).contains(&positions[p][c])))
        .collect();
    if inside.is_empty() {
        return Err(Error::value(
            "pins",
            format!("box {lo:?} to {hi:?} holds no particle"),
        ));
    }
    Ok(inside)
}

fn check_boundary(boundary: bool) -> Result<()> {
    if boundary {
        Ok(())
    } else {
        Err(Error::value(
            "pins",
            "{ boundary = false } selects nothing: remove the entry",
        ))
    }
}

/// The vertices of the edges only one triangle has, ascending. Indices out of range are the
/// mesh's checks' to report; they are skipped here.
fn boundary_vertices(n: usize, triangles: &[[i64; 3]]) -> Vec<usize> {
    let mut edges: Vec<(usize, usize)> = triangles
        .iter()
        .filter(|t| t.iter().all(|&k| (0..n as i64).contains(&k)))
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .map(|(a, b)| (a.min(b) as usize, a.max(b) as usize))
        .collect();
    edges.sort_unstable();
    let mut on = vec![false; n];
    for run in edges.chunk_by(|x, y| x == y) {
        if run.len() == 1 {
            (on[run[0].0], on[run[0].1]) = (true, true);
        }
    }
    (0..n).filter(|&v| on[v]).collect()
}

/// The particles whose starting height (y) is within `tolerance` m of the highest one's.
fn highest(tolerance: f64, positions: &[[f64; 3]]) -> Result<Vec<usize>> {
    if !(tolerance.is_finite() && tolerance >= 0.0) {
        return Err(Error::value(
            "pins",
            format!("top must be a finite number >= 0 (m), got {tolerance}"),
        ));
    }
    let top = positions
        .iter()
        .map(|x| x[1])
        .fold(f64::NEG_INFINITY, f64::max);
    Ok((0..positions.len())
        .filter(|&p| positions[p][1] >= top - tolerance)
        .collect())
}
