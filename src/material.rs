//! The material choices a mesh cloth and a garment share (the grid cloth's springs are its
//! own): kept apart from `scene` so the garment, which `scene` compiles, can name them too.

use serde::{Deserialize, Serialize};

/// What resists a mesh cloth's stretch and shear (`cloth.mesh.membrane`,
/// `cloth.garment.membrane`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MembraneKind {
    /// A spring on every edge, `k = stretch A_e / L^2`.
    Springs,
    /// A co-rotational linear constant-strain element on every triangle.
    Triangle,
}
