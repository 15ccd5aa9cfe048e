//! The scene: everything that describes a simulation before it starts (cloth, forces,
//! colliders, stepping). Read from TOML or, through the Python binding, from a dict with the
//! same keys; parsed and validated once into this typed value, so every caller gets the same
//! errors. The tables are in `specs.rs`, the checks in `validate.rs` (a mesh collider's in `mesh.rs`), pins in `pins.rs`, the
//! stability estimate in `stability.rs`.
//!
//! Units are SI throughout: metres, kilograms, seconds, newtons.

mod bending;
mod cuts;
mod edge_springs;
mod lanes;
mod local_numbering;
mod membrane;
mod mesh;
mod mesh_checks;
mod mesh_cloth;
mod pins;
mod solvers;
mod specs;
mod stability;
mod validate;

use serde::{Deserialize, Serialize};

pub use bending::IsometricBending;
pub use cuts::CutSpec;
pub use edge_springs::{EdgeKind, EdgeSprings};
pub use lanes::{IncidenceLanes, SpringSlots, LANES, WINDOW};
pub use local_numbering::{gather_by, LocalNumbering};
pub use membrane::Membrane;
pub use mesh::{is_closed, merged_indices};
pub use mesh_cloth::MeshCloth;
pub use pins::PIN_GROUPS;
pub use solvers::{IntegratorKind, Preconditioner, SolverSettings};
pub use specs::{
    BendingKind, ClothSpec, ColliderSpec, FlatPanels, FloorSpec, MembraneKind, MeshSpec, OnTrouble,
    PinBoundary, PinBox, PinSpec, PinTop, Plane, SeamsSpec, SelfCollisionSpec, ShapeKind,
    SphereSpec, StrainLimitSpec, TearingSpec, WatchdogSpec, WindSpec,
};
pub use stability::stable_substep;
use validate::require_tables;
pub(crate) use validate::{check_membrane_integrator, check_substep};
pub use validate::{validations, MAX_COLLIDER_VALUE, MAX_ITERATIONS, MAX_PARTICLES, MIN_SUBSTEP};

use crate::error::{Error, Result};
use crate::grid::Grid;

/// A whole scene. Field defaults are those of [`Scene::default`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Scene {
    /// Time integrator. Default `"symplectic_euler"`: as cheap as explicit Euler, but its
    /// energy stays bounded instead of growing.
    pub integrator: IntegratorKind,
    /// Fixed time step in s. Default 0.001. Explicit integrators are stable only while
    /// `dt / substeps * sqrt(4 (k_structural + k_shear + k_bend) / m)` stays below about 2.
    /// Kept in f64 so that step counts and `time = steps * dt` are exact for decimal steps;
    /// the solver steps in f32.
    pub dt: f64,
    /// Substeps per step: each step runs `substeps` steps of `dt / substeps`. Default 1. More
    /// substeps buy stability with stiff springs at a proportional cost.
    pub substeps: u32,
    /// Gravitational acceleration in m/s^2. Default `[0, -9.81, 0]`; zero removes the pass.
    pub gravity: [f64; 3],
    /// Air drag coefficient in N s/m per particle, `f = -air_drag * v`. Default 0 (no pass).
    pub air_drag: f64,
    /// `implicit_euler` only: relative residual `|r| / |b|` at which the conjugate gradient
    /// stops. Default 1e-4. Smaller costs iterations; float32 stalls a little below 1e-6.
    pub cg_tolerance: f64,
    /// `implicit_euler` only: most CG iterations per step. Default 200. A solve that reaches
    /// it is counted as not converged in `profile()` and warned about once.
    pub cg_max_iterations: u32,
    /// `implicit_euler` only: the CG preconditioner, `"jacobi"`, `"block_jacobi"` or
    /// `"multigrid"` (default). Multigrid costs about five matrix-vector products to set up and
    /// four per iteration, and cuts stiff solves from hundreds of iterations to about ten.
    pub preconditioner: Preconditioner,
    /// `projective_dynamics` only: most local-global iterations per substep. Default 20. Each
    /// costs a pass over the springs and two triangular solves with the prefactored matrix.
    pub pd_iterations: u32,
    /// `projective_dynamics` only: relative gradient norm of the step's incremental potential
    /// (`|g_k| / |g_0|`) at which the iterations stop early; a substep that ends above it is
    /// counted as not converged and warned about once. Default 0: always run `pd_iterations`
    /// and count nothing as unconverged (the residual is still reported).
    pub pd_tolerance: f64,
    /// `projective_dynamics` only: Chebyshev acceleration's spectral-radius estimate, in
    /// `[0, 1)`. Default 0.8; 0 turns it off. Larger values overshoot in the first
    /// iterations, which the solver detects (the gradient grows) and restarts from.
    pub pd_chebyshev_rho: f64,
    pub cloth: ClothSpec,
    /// An infinite floor; absent means none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub floor: Option<FloorSpec>,
    /// Spheres the cloth collides with; empty means none.
    pub spheres: Vec<SphereSpec>,
    /// Colliders of any shape, static or moving (`[[colliders]]`); empty means none (no pass).
    pub colliders: Vec<ColliderSpec>,
    /// What a step does when it goes wrong (see `src/watchdog.rs`).
    pub watchdog: WatchdogSpec,
    /// Provot strain limiting after each substep; absent means none (no pass).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub strain_limit: Option<StrainLimitSpec>,
    /// Self-collision after each substep; absent means none (no pass).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub self_collision: Option<SelfCollisionSpec>,
    /// Springs break past a strain, after each step; absent means none (no pass).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tearing: Option<TearingSpec>,
    /// Wind pushing on the cloth after each integration; absent means none (no pass).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wind: Option<WindSpec>,
}

impl Default for Scene {
    fn default() -> Self {
        Scene {
            integrator: IntegratorKind::SymplecticEuler,
            dt: 0.001,
            substeps: 1,
            gravity: [0.0, -9.81, 0.0],
            air_drag: 0.0,
            cg_tolerance: 1e-4,
            cg_max_iterations: 200,
            preconditioner: Preconditioner::Multigrid,
            pd_iterations: 20,
            pd_tolerance: 0.0,
            pd_chebyshev_rho: 0.8,
            cloth: ClothSpec::default(),
            floor: None,
            spheres: Vec::new(),
            colliders: Vec::new(),
            watchdog: WatchdogSpec::default(),
            strain_limit: None,
            self_collision: None,
            tearing: None,
            wind: None,
        }
    }
}

/// Built-in scenes: name, TOML source. The files live in the repository's `scenes/`.
const BUILTIN: &[(&str, &str)] = &[
    ("hanging", include_str!("../../scenes/hanging.toml")),
    ("drape", include_str!("../../scenes/drape.toml")),
    ("freefall", include_str!("../../scenes/freefall.toml")),
    ("curtain", include_str!("../../scenes/curtain.toml")),
    ("twist", include_str!("../../scenes/twist.toml")),
    ("fold", include_str!("../../scenes/fold.toml")),
    ("pile", include_str!("../../scenes/pile.toml")),
    ("tear", include_str!("../../scenes/tear.toml")),
    ("flag", include_str!("../../scenes/flag.toml")),
    ("drape_box", include_str!("../../scenes/drape_box.toml")),
    ("tablecloth", include_str!("../../scenes/tablecloth.toml")),
    ("mannequin", include_str!("../../scenes/mannequin.toml")),
    ("spinner", include_str!("../../scenes/spinner.toml")),
    // Mesh cloths (their meshes inline; scripts/mesh_scenes.py writes them).
    (
        "round_tablecloth",
        include_str!("../../scenes/round_tablecloth.toml"),
    ),
    ("flag_hole", include_str!("../../scenes/flag_hole.toml")),
    (
        "delaunay_sheet",
        include_str!("../../scenes/delaunay_sheet.toml"),
    ),
    ("shirt", include_str!("../../scenes/shirt.toml")),
    ("skirt", include_str!("../../scenes/skirt.toml")),
];

impl Scene {
    /// Bytes the scene holds on the heap beyond its fixed fields: the lists of spheres and
    /// colliders, and each mesh collider's vertices and triangles.
    pub fn heap_bytes(&self) -> usize {
        let meshes: usize = self
            .colliders
            .iter()
            .map(|c| {
                c.vertices
                    .as_ref()
                    .map_or(0, |v| v.capacity() * size_of::<[f64; 3]>())
                    + c.triangles
                        .as_ref()
                        .map_or(0, |t| t.capacity() * size_of::<[i64; 3]>())
            })
            .sum();
        self.spheres.capacity() * size_of::<SphereSpec>()
            + self.colliders.capacity() * size_of::<ColliderSpec>()
            + meshes
    }
}

impl Scene {
    /// Parses and validates a TOML document.
    pub fn from_toml_str(text: &str) -> Result<Scene> {
        // Through a parsed table, the path a Python dict takes, so that both give the same
        // errors. (Deserialised straight from the text, a TOML date-time is a private one-key
        // map, whose key `$__toml_private_datetime` leaked into the messages.)
        let table: toml::Table = text.parse().map_err(|e: toml::de::Error| {
            Error::value("scene", format!("not valid TOML: {}", e.message()))
        })?;
        Self::from_toml_value(toml::Value::Table(table))
    }

    /// Builds and validates a scene from an already parsed TOML value (the binding converts a
    /// Python dict into one).
    pub fn from_toml_value(value: toml::Value) -> Result<Scene> {
        let scene = Self::read_toml_value(value)?;
        scene.validate()?;
        Ok(scene)
    }

    /// As [`Scene::from_toml_value`], with its errors for keys, types and tables, but not yet
    /// validated: for a caller that validates it next, as [`crate::Simulation::new`] does
    /// (with a big mesh collider, validating twice costs a second).
    pub fn read_toml_value(value: toml::Value) -> Result<Scene> {
        require_tables(&value)?;
        Self::from_deserializer(value)
    }

    fn from_deserializer<'de, D>(deserializer: D) -> Result<Scene>
    where
        D: serde::Deserializer<'de, Error = toml::de::Error>,
    {
        let scene: Scene = serde_path_to_error::deserialize(deserializer).map_err(|e| {
            let path = e.path().to_string();
            let name = if path == "." {
                "scene".to_string()
            } else {
                path
            };
            let message = e.inner().message().to_string();
            // serde reports a value of the wrong kind as "invalid type: ..."; everything else
            // (unknown keys, out-of-range integers, unknown variants) is a bad value.
            if message.starts_with("invalid type") {
                Error::InvalidType { name, message }
            } else {
                Error::InvalidValue { name, message }
            }
        })?;
        let mut scene = scene;
        scene.sew_garment()?;
        Ok(scene)
    }

    /// Serialises to TOML with every key spelled out (a garment as the mesh it compiles to).
    pub fn to_toml_string(&self) -> String {
        let sewn = self.sewn().expect("a validated scene's garment compiles");
        toml::to_string(&sewn).expect("a validated scene always serialises")
    }

    /// This scene with its garment, if any, compiled into its mesh cloth (a scene read from
    /// TOML or a dict already is).
    pub fn sewn(&self) -> Result<Scene> {
        let mut scene = self.clone();
        scene.sew_garment()?;
        Ok(scene)
    }

    /// Compiles the cloth's garment, if any, into its mesh cloth, the errors naming the
    /// garment's keys (`cloth.garment.membrane` under an integrator it does not run on).
    fn sew_garment(&mut self) -> Result<()> {
        if let Some(garment) = &self.cloth.garment {
            let membrane = Some(garment.membrane);
            check_membrane_integrator("cloth.garment", membrane, self.integrator)?;
        }
        self.cloth.sew_garment()
    }

    /// The built-in scene called `name`.
    pub fn builtin(name: &str) -> Result<Scene> {
        match BUILTIN.iter().find(|(n, _)| *n == name) {
            Some((_, text)) => Scene::from_toml_str(text),
            None => Err(Error::value(
                "name",
                format!(
                    "unknown scene {name:?}; built-in scenes are {:?}",
                    Self::builtin_names()
                ),
            )),
        }
    }

    pub fn builtin_names() -> Vec<&'static str> {
        BUILTIN.iter().map(|(n, _)| *n).collect()
    }

    /// The settings of the implicit solvers.
    pub fn solver_settings(&self) -> SolverSettings {
        SolverSettings {
            tolerance: self.cg_tolerance as f32,
            max_iterations: self.cg_max_iterations,
            preconditioner: self.preconditioner,
            pd_iterations: self.pd_iterations,
            pd_tolerance: self.pd_tolerance as f32,
            pd_chebyshev_rho: self.pd_chebyshev_rho as f32,
        }
    }

    /// The particles' layout: the cloth's grid, or for a mesh cloth one row of its vertices
    /// (`nx` = vertex count, `ny` = 1), whose stencil holds no spring.
    pub fn grid(&self) -> Grid {
        if let Some(mesh) = &self.cloth.mesh {
            return Grid {
                nx: mesh.vertices.len(),
                ny: 1,
            };
        }
        Grid {
            nx: self.cloth.nx as usize,
            ny: self.cloth.ny as usize,
        }
    }

    /// Mass of each particle in kg; for a mesh cloth the lightest vertex's (what bounds its
    /// stable step), or the density's kg/m^2 times nothing when the mesh is invalid.
    pub fn particle_mass(&self) -> f64 {
        if let Some(mesh) = &self.cloth.mesh {
            return MeshCloth::new(mesh).map_or(mesh.density, |m| {
                m.masses.iter().copied().fold(f64::INFINITY, f64::min)
            });
        }
        match (self.cloth.particle_mass, self.cloth.mass) {
            (Some(m), _) => m,
            (None, Some(total)) => total / self.grid().len() as f64,
            (None, None) => 0.001,
        }
    }

    /// The largest `dt` (s) at which `integrator` is estimated to stay stable with this scene's
    /// substeps, or None when any `dt` is (implicit Euler, or no springs); see
    /// [`stable_substep`].
    pub fn stable_dt(&self, integrator: IntegratorKind) -> Option<f64> {
        stable_substep(self, integrator, self.particle_mass()).map(|h| h * self.substeps as f64)
    }

    /// The angular frequency (rad/s) of the cloth's stiffest mode, `sqrt(4 (k_structural +
    /// k_shear + k_bend) / m)`.
    pub fn max_frequency(&self) -> f64 {
        if let Some(mesh) = &self.cloth.mesh {
            return MeshCloth::new(mesh).map_or(0.0, |m| m.max_omega2().sqrt());
        }
        let c = &self.cloth;
        (4.0 * (c.k_structural + c.k_shear + c.k_bend) / self.particle_mass()).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_validate_and_round_trip_through_toml() {
        let scene = Scene::default();
        scene.validate().unwrap();
        let again = Scene::from_toml_str(&scene.to_toml_string()).unwrap();
        assert_eq!(scene, again);
    }

    #[test]
    fn every_builtin_scene_parses() {
        for name in Scene::builtin_names() {
            Scene::builtin(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        }
    }

    #[test]
    fn errors_name_the_parameter_and_value() {
        let err = Scene::from_toml_str("dt = -1.0").unwrap_err();
        assert_eq!(
            err,
            Error::value("dt", "must be a finite number > 0, got -1")
        );
        let err = Scene::from_toml_str("[cloth]\nk_shear = nan").unwrap_err();
        assert!(err.to_string().contains("cloth.k_shear"), "{err}");
        let err = Scene::from_toml_str("[cloth]\nnx = \"many\"").unwrap_err();
        assert!(
            matches!(err, Error::InvalidType { ref name, .. } if name == "cloth.nx"),
            "{err}"
        );
        let err = Scene::from_toml_str("[cloth]\nwidth = 3").unwrap_err();
        assert!(err.to_string().contains("unknown field `width`"), "{err}");
        let err = Scene::from_toml_str("[cloth]\npins = [[40, 0]]").unwrap_err();
        assert!(err.to_string().starts_with("cloth.pins[0]"), "{err}");
        let err = Scene::from_toml_str("[cloth]\nmass = 1.0\nparticle_mass = 0.1").unwrap_err();
        assert!(err.to_string().contains("not both"), "{err}");
    }

    #[test]
    fn named_pins_pick_the_documented_particles() {
        let mut cloth = ClothSpec {
            nx: 4,
            ny: 3,
            ..Default::default()
        };
        assert_eq!(cloth.pinned_indices(), vec![8, 11]);
        cloth.pins = vec![PinSpec::Named("left_edge".into()), PinSpec::Cell([3, 0])];
        assert_eq!(cloth.pinned_indices(), vec![0, 3, 4, 8]);
    }
}
