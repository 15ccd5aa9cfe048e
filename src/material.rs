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

/// What resists a mesh cloth's bending (`cloth.mesh.bending`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BendingKind {
    /// A spring across every interior edge, `k = bend A_h / L^2`.
    Springs,
    /// The quadratic isometric bending energy of Bergou et al. 2006 on every interior edge,
    /// with the bending modulus `bend_modulus`.
    Isometric,
}
