//! Pins in a scene: named groups of particles (`top_corners`, `left_edge`, ...) or one grid
//! cell, and the particle indices they name.

use super::specs::{ClothSpec, PinSpec};
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
        let grid = Grid {
            nx: self.nx as usize,
            ny: self.ny as usize,
        };
        let mut out: Vec<usize> = self
            .pins
            .iter()
            .flat_map(|pin| pin_indices(pin, grid).unwrap_or_default())
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }
}

/// The particles a pin entry names.
pub(super) fn pin_indices(pin: &PinSpec, grid: Grid) -> Result<Vec<usize>> {
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
