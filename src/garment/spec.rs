//! The tables of `[cloth.garment]`: panels, their placement, and seams. Compiled by
//! [`GarmentSpec::compile`](super::GarmentSpec::compile).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::material::MembraneKind;

/// A garment: panels and the seams that join them, compiled into a mesh cloth.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GarmentSpec {
    /// The flat pieces. At least one.
    pub panels: Vec<PanelSpec>,
    /// The seams, each joining two named edges. Default none.
    pub seams: Vec<SeamSpec>,
    /// Target edge length of the triangles in m (> 0). Default 0.03. The explicit
    /// integrators' stable step shrinks in proportion to it.
    pub edge_length: f64,
    /// Time in s over which the seams close (> 0). Default 1.
    pub sew_time: f64,
    /// Stiffness of each seam spring in N/m (> 0). Default 500, about three edge springs'
    /// at the default stretch modulus.
    pub seam_stiffness: f64,
    /// Damping along each seam spring in N s/m (>= 0). Default 0.05.
    pub seam_damping: f64,
    /// The material, as `cloth.mesh`'s (same units, defaults and meaning): density (kg/m^2),
    /// stretch, bend (N/m), damping (N s/m), the membrane (`"springs"` or `"triangle"`) and the
    /// triangle membrane's Poisson ratio.
    pub density: f64,
    pub stretch: f64,
    pub bend: f64,
    pub damping: f64,
    pub membrane: MembraneKind,
    pub poisson: f64,
}

impl Default for GarmentSpec {
    fn default() -> Self {
        GarmentSpec {
            panels: Vec::new(),
            seams: Vec::new(),
            edge_length: 0.03,
            sew_time: 1.0,
            seam_stiffness: 500.0,
            seam_damping: 0.05,
            density: 0.2,
            stretch: 600.0,
            bend: 80.0,
            damping: 0.07,
            membrane: MembraneKind::Springs,
            poisson: 1.0 / 3.0,
        }
    }
}

/// One flat panel.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PanelSpec {
    /// Its name, unique in the garment; seams name edges as `"panel.edge"`.
    pub name: String,
    /// The outline, a simple polygon of at least 3 points `(u, v)` in m.
    pub outline: Vec<[f64; 2]>,
    /// Holes, each a simple polygon inside the outline. Default none.
    pub holes: Vec<Vec<[f64; 2]>>,
    /// Named edges: `name = [start, end]`, the outline points from `start` to `end` walking
    /// forward through the outline (wrapping past its last point).
    pub edges: BTreeMap<String, [i64; 2]>,
    /// Where the flat panel goes in the scene.
    pub placement: Placement,
}

/// A panel's placement: flat in the plane through `origin` along `x_axis` and `y_axis`, or
/// wrapped on a cylinder about `y_axis`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Placement {
    /// Where the panel's `(0, 0)` goes, in m. Default the origin.
    pub origin: [f64; 3],
    /// The direction of the panel's `u`. Default `+x`.
    pub x_axis: [f64; 3],
    /// The direction of the panel's `v` (made perpendicular to `x_axis`). Default `+y`.
    pub y_axis: [f64; 3],
    /// Wraps the panel round a cylinder of this radius (m) about an axis along `y_axis`,
    /// `wrap_radius` behind `origin` (against `x_axis x y_axis`). Default none: flat.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wrap_radius: Option<f64>,
}

impl Default for Placement {
    fn default() -> Self {
        Placement {
            origin: [0.0; 3],
            x_axis: [1.0, 0.0, 0.0],
            y_axis: [0.0, 1.0, 0.0],
            wrap_radius: None,
        }
    }
}

/// A seam: two named edges, `"panel.edge"`, sewn point to point: `a`'s start to `b`'s end
/// (each outline taken counter-clockwise), the way two panels joined into one surface that
/// faces one way meet; `reverse` sews start to start (one panel turned over).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SeamSpec {
    pub a: String,
    pub b: String,
    /// Sews `a`'s start to `b`'s start. Default false.
    pub reverse: bool,
}
