//! The tables of a scene: the cloth, the floor, the spheres, the watchdog and strain
//! limiting, each with its keys' units, defaults and trade-offs.

use serde::{Deserialize, Serialize};

pub use crate::garment::FlatPanels;

pub use crate::material::{BendingKind, MembraneKind};

/// What a step does on trouble: a non-finite value, or (with `max_stretch`) a spring stretched
/// beyond the limit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum OnTrouble {
    /// Restore the last good state and raise `SimulationDiverged`.
    Raise,
    /// Retry the failed step with twice the substeps, then four times, ... up to
    /// `max_substeps`; raise only if that fails too. Retries are counted in `watchdog_stats`.
    Substep,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WatchdogSpec {
    /// Largest allowed stretch of any live spring, as the ratio `l / L` of its length to its
    /// rest length (> 1). Absent by default: only non-finite values count as trouble. Checked
    /// for free while the forces are evaluated (one compare per spring), one substep late, so a
    /// state is judged when the next substep starts from it. Set it well above what the scene
    /// legitimately reaches: dragging a particle with the mouse stretches its springs too.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_stretch: Option<f64>,
    /// `"raise"` (default) or `"substep"`; see [`OnTrouble`].
    pub on_trouble: OnTrouble,
    /// Most substeps a retried step may use, with `on_trouble = "substep"`. Default 64: a step
    /// that needs more than that is better served by a smaller `dt` or `implicit_euler`.
    pub max_substeps: u32,
    /// With `on_trouble = "substep"`: steps after a rescued step that keep its substeps before
    /// the scene's own are tried again. Default 100. A stiff scene whose every step needs more
    /// substeps then fails once per `hold_steps` rather than every other step; 0 retries each
    /// step on its own. After a self-collision cascade the hold is at most twice the scene's
    /// substeps (`CASCADE_HELD`, `stepper/watchdog.rs`) and at first shorter: 8 steps
    /// (`CASCADE_HOLD_FIRST`), doubled each time the cluster cascades again while held, up to
    /// `hold_steps`.
    pub hold_steps: u32,
}

impl Default for WatchdogSpec {
    fn default() -> Self {
        WatchdogSpec {
            max_stretch: None,
            on_trouble: OnTrouble::Raise,
            max_substeps: 64,
            hold_steps: 100,
        }
    }
}

/// Provot (1995) strain limiting: after each substep, structural and shear springs longer than
/// `(1 + max_strain)` times their rest length are shortened back, and the velocities corrected.
/// Lets a soft cloth (cheap, large `dt`) keep a stiff cloth's shape under load.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StrainLimitSpec {
    /// Largest allowed strain `(l - L) / L` (> 0). Default 0.1, Provot's 10 %.
    pub max_strain: f64,
    /// Jacobi iterations per substep (>= 1). Default 4. More iterations get closer to the limit
    /// where many springs are over it at once, at one pass over the springs each.
    pub iterations: u32,
}

impl Default for StrainLimitSpec {
    fn default() -> Self {
        StrainLimitSpec {
            max_strain: 0.1,
            iterations: 4,
        }
    }
}

/// Self-collision (`src/self_collision/`): the cloth never passes through itself, and layers
/// in contact are pushed about `thickness` apart, with friction. Absent: no pass, and the step
/// is bitwise the one without it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SelfCollisionSpec {
    /// Gap the repulsion keeps between a particle and any triangle without it, and between
    /// edges with no shared particle, in m (> 0, below half the cloth's grid spacing, or a
    /// mesh cloth's shortest triangle altitude, so that a cloth at rest has no pair this close). Default 0.002. A thicker gap holds layers apart
    /// more visibly and lets the cap act less often; a thinner one looks tighter.
    pub thickness: f64,
    /// Coulomb friction coefficient between layers (>= 0, dimensionless). Default 0.2: each
    /// contact takes at most `friction` times its normal velocity change off the sliding
    /// speed. 0 lets layers slide freely.
    pub friction: f64,
    /// Jacobi sweeps of the repulsion per substep (>= 1). Default 4. More sweeps bring piled
    /// layers closer to `thickness` apart, at one pass over the pairs in contact each; the
    /// guarantee of no crossing does not depend on them.
    pub iterations: u32,
    /// `implicit_euler` on a grid cloth only: how stiffly its linear solve holds apart the pairs
    /// its step's inertial motion would bring within `thickness`, a penalty as a multiple of
    /// each pair's effective mass over the step squared (>= 0, dimensionless; 0 turns the term
    /// off). Default 0. The solve leaves `1 / (1 + solve_stiffness)` of a lone pair's predicted
    /// overlap for the pass after it; stiffer leaves less but costs CG iterations. The pass
    /// after the solve stays and keeps the guarantee either way.
    pub solve_stiffness: f64,
}

impl Default for SelfCollisionSpec {
    fn default() -> Self {
        SelfCollisionSpec {
            thickness: 0.002,
            friction: 0.2,
            iterations: 4,
            solve_stiffness: 0.0,
        }
    }
}

/// Tearing: after each step, the springs stretched past `max_strain` break (severed as a cut
/// severs them: the mesh, the picking trees and `topology_version` follow), the most strained
/// first, at most `max_per_step` of them. Absent means none (no pass, the step bitwise as
/// without it).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TearingSpec {
    /// Strain `(l - L) / L` past which a spring breaks (> 0, dimensionless). Default 0.5: a
    /// spring half again its rest length. Lower tears under its own weight (a heavy cloth
    /// hanging from two corners reaches 0.1 to 0.3 there); with strain limiting on, keep it
    /// above `strain_limit.max_strain`, or nothing ever tears.
    pub max_strain: f64,
    /// Most springs that break in one step (>= 1). Default 16. Fewer makes a tear run along
    /// the cloth over several steps (each break passes its load to the next spring, as a real
    /// rip does) rather than a whole overstretched region letting go at once; more lets a
    /// violent pull rip at once.
    pub max_per_step: u32,
}

impl Default for TearingSpec {
    fn default() -> Self {
        TearingSpec {
            max_strain: 0.5,
            max_per_step: 16,
        }
    }
}

/// Wind (`[wind]`): air moving past the cloth, with gusts and turbulence, pushing on each
/// triangle with the drag and lift of a flat plate; the equations are in `src/wind.rs`. Absent
/// means none (no pass, the step bitwise as without it).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WindSpec {
    /// Mean velocity of the air in m/s. Default `[3, 0, 0]`: a light breeze along +x, in which
    /// a 0.4 kg/m^2 curtain hung by its top edge settles about 55 degrees from the vertical.
    pub velocity: [f64; 3],
    /// Gusts: how far the whole wind swells above and below its mean, as a fraction of it,
    /// in `[0, 1]`. Default 0.3; 0 blows steadily.
    pub gust: f64,
    /// Typical period of a gust in s (> 0). Default 2.
    pub gust_period: f64,
    /// Turbulence: the most speed (m/s, >= 0) its eddies add to the air at a point. Default
    /// 0.5; 0 turns it off and saves four sines per particle and substep.
    pub turbulence: f64,
    /// Size of an eddy in m (> 0). Default 0.5: about the cloth's size flutters it as a whole,
    /// a tenth of it ripples it.
    pub turbulence_scale: f64,
    /// Seed of the gusts' periods and the eddies' directions and phases: the same seed blows
    /// the same wind. Default 0.
    pub seed: u64,
    /// Drag coefficient `C_d` of the cloth (>= 0, dimensionless). Default 1.2, a flat plate
    /// broadside to the flow.
    pub drag: f64,
    /// Lift coefficient `C_l` (>= 0, dimensionless), per radian of the angle of attack.
    /// Default 0.5. Lift makes a flag ripple rather than only lean; 0 leaves drag alone.
    pub lift: f64,
    /// Density of the air in kg/m^3 (> 0). Default 1.2 (sea level, 20 C).
    pub air_density: f64,
}

impl Default for WindSpec {
    fn default() -> Self {
        WindSpec {
            velocity: [3.0, 0.0, 0.0],
            gust: 0.3,
            gust_period: 2.0,
            turbulence: 0.5,
            turbulence_scale: 0.5,
            seed: 0,
            drag: 1.2,
            lift: 0.5,
            air_density: 1.2,
        }
    }
}

/// The plane the cloth starts in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Plane {
    /// Grid `i` along +x, `j` along +z: a horizontal sheet.
    Xz,
    /// Grid `i` along +x, `j` along +y: a vertical sheet.
    Xy,
}

impl Plane {
    /// The unit vectors `(e_i, e_j)` a grid cloth starts along.
    pub fn axes(self) -> (glam::Vec3, glam::Vec3) {
        match self {
            Plane::Xz => (glam::Vec3::X, glam::Vec3::Z),
            Plane::Xy => (glam::Vec3::X, glam::Vec3::Y),
        }
    }
}

/// A pin: a named group of particles or one `[i, j]` grid position (a grid cloth only), one
/// particle index (a mesh cloth's vertex index; on a grid, `j * nx + i`), or a selection on
/// either cloth: every particle whose starting position lies in a box, the boundary, or the
/// highest particles.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum PinSpec {
    Named(String),
    Cell([i64; 2]),
    Index(i64),
    Region(PinBox),
    Boundary(PinBoundary),
    Top(PinTop),
}

/// `{ boundary = true }`: every particle on the cloth's boundary, the vertices of the edges
/// that only one triangle has (a mesh's outline and the rims of its holes; the grid's four
/// edges). `false` selects nothing and is refused.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PinBoundary {
    pub boundary: bool,
}

/// `{ top = 0.001 }`: the highest particles at the start, those within `top` m (finite, >= 0)
/// below the highest along +y: a mesh's top row, however its vertices are numbered. 0 takes
/// only those exactly as high as the highest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PinTop {
    pub top: f64,
}

/// `{ box = [[x0, y0, z0], [x1, y1, z1]] }`: the particles whose starting positions lie in the
/// axis-aligned box with these corners (m, bounds included). A box that holds no particle is
/// refused, so a mistyped box never pins nothing silently.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PinBox {
    #[serde(rename = "box")]
    pub corners: [[f64; 3]; 2],
}

/// A cloth made from a triangle mesh (`[cloth.mesh]`) instead of the `nx` x `ny` grid; see
/// `src/mesh_cloth/` for the model and docs/mesh_cloth.md for the equations. Its particles are
/// the vertices, in their order. Material is in physical units that do not change with the
/// mesh's resolution: a coarse and a fine mesh of the same square hang alike.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MeshSpec {
    /// Vertex positions in m, where the cloth starts, at rest: at least 3, each finite, each
    /// used by a triangle (an unused vertex is refused, naming it, rather than dropped, so
    /// that vertex `k` is always particle `k`). No default: required.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles, each three vertex indices, wound consistently (every shared edge walked in
    /// opposite directions by its two triangles: the normals agree). Refused: an index out of
    /// range, a triangle of zero area, the same triangle twice, an edge shared by more than two
    /// triangles (non-manifold). Several pieces are allowed. No default: required.
    pub triangles: Vec<[i64; 3]>,
    /// Texture coordinates per vertex, for the renderer and export. Default: none (the
    /// renderer projects the rest shape onto its best-fit plane).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uvs: Option<Vec<[f64; 2]>>,
    /// Areal density in kg/m^2 (> 0). Default 0.2, a light cotton. Each vertex gets a third of
    /// the mass of every triangle it is a corner of.
    pub density: f64,
    /// Stretch modulus `Y` in N/m (>= 0): a uniform strain `e` in every direction stores
    /// `Y e^2 / 2` J per m^2. Default 600, the modulus of the default grid cloth's structural
    /// and shear springs (`2 (k_structural + 2 k_shear)`). The spring on an edge gets
    /// `k = Y A_e / L^2`, `A_e` a third of the area of its triangles.
    pub stretch: f64,
    /// Bending modulus in N/m (>= 0) of the springs across each interior edge (between the two
    /// vertices opposite it): `k = bend A_e / L^2`, `A_e` a third of the two triangles' area,
    /// `L` the springs' rest length. Default 80, the in-plane modulus of the default grid
    /// cloth's bending springs (`8 k_bend`). Like the grid's bending springs they resist folding
    /// only to second order in the fold angle.
    pub bend: f64,
    /// Damping modulus in N s/m (>= 0): a spring of either family gets `c = damping A_e / L^2`
    /// along it, so a uniform strain rate `r` dissipates about `2 damping r^2` W per m^2 (both
    /// families) at any resolution. Default 0.07: the default grid cloth's springs dissipate
    /// `14 c r^2 = 0.14 r^2`.
    pub damping: f64,
    /// What resists stretch and shear: `"springs"` (default), a spring on every edge with
    /// `k = stretch A_e / L^2`, or `"triangle"`, a co-rotational linear element on every
    /// triangle (docs/mesh_cloth.md, "The triangle membrane"). The element stores exactly
    /// `A Psi(strain)` for any uniform strain, so its response does not depend on how the
    /// triangles' edges line up with the load; it costs more a step, and `projective_dynamics`
    /// is refused with it. The bend springs, the damping along every edge, strain limiting,
    /// cuts and tears are the same under either.
    pub membrane: MembraneKind,
    /// Poisson's ratio of the `"triangle"` membrane (`0 <= poisson < 1`, dimensionless).
    /// Default 1/3, the ratio of an isotropic spread of edge springs, so that `stretch` means
    /// the same under either membrane. The Lame parameters are `mu = stretch (1 - poisson) /
    /// (4 (1 + poisson))`, `lambda = stretch poisson / (2 (1 + poisson))`: a uniform strain `e`
    /// in every direction stores `stretch e^2 / 2` J per m^2 at any ratio. Higher keeps the
    /// cloth's width as it is pulled; lower lets it narrow less. Only read by `"triangle"`
    /// (another value with `"springs"` is refused).
    pub poisson: f64,
    /// What resists bending: `"springs"` (default), a spring across every interior edge with
    /// `k = bend A_h / L^2`, which resists a fold only to second order in its angle, so that a
    /// finer mesh is softer in bending; or `"isometric"`, the quadratic bending energy of
    /// Bergou et al. 2006, `bend_modulus / 2 * integral |mean curvature vector|^2 dA`, the same
    /// at every resolution (docs/mesh_cloth.md, "Isometric bending"). It needs a flat rest
    /// shape (a curved mesh is refused, naming this key); the bend springs then keep only
    /// their damping, and `bend` is not read.
    pub bending: BendingKind,
    /// Bending modulus of `bending = "isometric"` in N m (>= 0): a sheet curved to radius `R`
    /// stores `bend_modulus / (2 R^2)` J per m^2. Default 5e-5, a cotton's order of
    /// magnitude (with the default density its bending length `(B / (rho g))^(1/3)` is 3 cm).
    /// Higher folds in wider curves and lowers the explicit integrators' stable step as
    /// `1 / sqrt(bend_modulus)` once it dominates the stretch (the stiffest bending mode grows
    /// as `1 / h^4` with the spacing `h`). Only read by `"isometric"` (another value with
    /// `"springs"` is refused).
    pub bend_modulus: f64,
    /// Vertices sewn together (a garment's seams, `cloth.garment` fills it in). Default none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seams: Option<SeamsSpec>,
    /// Each triangle on the flat panel it was cut from (`cloth.garment` fills it in): what a
    /// live cut holds its stroke on (docs/cutting.md). Default none: a mesh whose rest shape is
    /// flat is cut on its own plane, a curved one by the stroke's swept surface. Refused, naming
    /// it: not one entry per triangle, a corner not finite.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub panels: Option<FlatPanels>,
}

/// Seams of a mesh cloth: pairs of vertices pulled together by springs whose rest length goes
/// from the pair's starting distance to zero over `sew_time`, then stays zero.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SeamsSpec {
    /// The vertex pairs sewn, each two different vertex indices.
    pub pairs: Vec<[i64; 2]>,
    /// Seconds over which the seams close (> 0). Default 1.
    pub sew_time: f64,
    /// Stiffness of each seam spring in N/m (> 0). Default 500.
    pub stiffness: f64,
    /// Damping along each seam spring in N s/m (>= 0). Default 0.05.
    pub damping: f64,
}

impl Default for SeamsSpec {
    fn default() -> Self {
        SeamsSpec {
            pairs: Vec::new(),
            sew_time: 1.0,
            stiffness: 500.0,
            damping: 0.05,
        }
    }
}

impl Default for MeshSpec {
    fn default() -> Self {
        MeshSpec {
            vertices: Vec::new(),
            triangles: Vec::new(),
            uvs: None,
            density: 0.2,
            stretch: 600.0,
            bend: 80.0,
            damping: 0.07,
            membrane: MembraneKind::Springs,
            poisson: 1.0 / 3.0,
            bending: BendingKind::Springs,
            bend_modulus: 5e-5,
            seams: None,
            panels: None,
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ClothSpec {
    /// Particles along `i` (>= 2). Default 32.
    pub nx: u32,
    /// Particles along `j` (>= 2). Default 32.
    pub ny: u32,
    /// Extent along `i` and `j` in m. Default `[1, 1]`.
    pub size: [f64; 2],
    /// Centre of the cloth in m. Default `[0, 1, 0]`.
    pub center: [f64; 3],
    /// Starting plane. Default `"xz"`.
    pub plane: Plane,
    /// Mass of each particle in kg. Default 0.001 when `mass` is not given either.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub particle_mass: Option<f64>,
    /// Total mass in kg, shared equally; give this or `particle_mass`, not both.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mass: Option<f64>,
    /// Stiffness of the structural springs in N/m. Default 200. Zero removes the family.
    /// Explicit integrators need `dt * sqrt(4 (k_structural + k_shear + k_bend) / m)` below
    /// about 2; stiffer springs need a smaller `dt`, more substeps or `implicit_euler`.
    pub k_structural: f64,
    /// Stiffness of the shear springs in N/m. Default 50. Zero removes the family.
    pub k_shear: f64,
    /// Stiffness of the bending springs in N/m. Default 10. Zero removes the family.
    pub k_bend: f64,
    /// Damping along each spring in N s/m, `c ((v_b - v_a) . u) u`. Default 0.01. Damps
    /// stretching oscillations without slowing rigid motion.
    pub damping: f64,
    /// Pinned particles. Default `["top_corners"]`. A mesh cloth has no named groups: give
    /// it vertex indices and boxes, or `pins = []`.
    pub pins: Vec<PinSpec>,
    /// Cuts made in a grid cloth as it is built (`[[cloth.cuts]]`, [`super::cuts::CutSpec`]):
    /// slits or perforations for a tear to run along. Default none.
    pub cuts: Vec<super::cuts::CutSpec>,
    /// A cloth from a triangle mesh instead of the grid: `nx`, `ny`, `size`, `center`,
    /// `plane`, `particle_mass`, `mass`, the `k_*` and `damping` keys are the grid's and must
    /// keep their defaults (the mesh carries its own material). Absent (default): the grid.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mesh: Option<MeshSpec>,
    /// A garment sewn from flat panels (`src/garment/`, docs/garments.md). Compiled when the
    /// scene is read into `mesh` (its vertices, triangles, UVs, material and seams), which is
    /// what a scene serialises to; give a garment or a mesh, not both. Absent (default): none.
    #[serde(skip_serializing)]
    pub garment: Option<crate::garment::GarmentSpec>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FloorSpec {
    /// Height of the floor plane (y) in m. Default 0.
    pub height: f64,
    /// Coulomb friction coefficient (dimensionless). Default 0.3.
    pub friction: f64,
    /// Particles are kept this far above the plane, in m. Default 0.002.
    pub thickness: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SphereSpec {
    /// Centre in m. Default `[0, 0.5, 0]`.
    pub center: [f64; 3],
    /// Radius in m. Default 0.3.
    pub radius: f64,
    /// Coulomb friction coefficient. Default 0.2.
    pub friction: f64,
    /// Particles are kept this far outside the surface, in m. Default 0.002.
    pub thickness: f64,
}

impl Default for ClothSpec {
    fn default() -> Self {
        ClothSpec {
            nx: 32,
            ny: 32,
            size: [1.0, 1.0],
            center: [0.0, 1.0, 0.0],
            plane: Plane::Xz,
            particle_mass: None,
            mass: None,
            k_structural: 200.0,
            k_shear: 50.0,
            k_bend: 10.0,
            damping: 0.01,
            pins: vec![PinSpec::Named("top_corners".into())],
            cuts: Vec::new(),
            mesh: None,
            garment: None,
        }
    }
}

impl Default for FloorSpec {
    fn default() -> Self {
        FloorSpec {
            height: 0.0,
            friction: 0.3,
            thickness: 0.002,
        }
    }
}

impl Default for SphereSpec {
    fn default() -> Self {
        SphereSpec {
            center: [0.0, 0.5, 0.0],
            radius: 0.3,
            friction: 0.2,
            thickness: 0.002,
        }
    }
}

impl SphereSpec {
    /// The same ball as a static `[[colliders]]` sphere.
    pub fn as_collider(&self) -> ColliderSpec {
        ColliderSpec {
            shape: ShapeKind::Sphere,
            radius: Some(self.radius),
            center: self.center,
            friction: self.friction,
            thickness: self.thickness,
            ..ColliderSpec::default()
        }
    }
}

/// The shape of a collider (parry3d's `Ball`, `Cuboid`, `Capsule`, `Cylinder`, `HalfSpace`,
/// `TriMesh`), in its local frame: centred on the origin, capsule and cylinder along local +y.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ShapeKind {
    /// Needs `radius`.
    Sphere,
    /// Needs `half_extents`.
    Box,
    /// Needs `half_height` (of the segment between the two caps' centres) and `radius`.
    Capsule,
    /// Needs `half_height` and `radius`.
    Cylinder,
    /// An infinite plane: the half-space below local y = 0 is solid, its outward normal is
    /// local +y. Needs no size: `center` is a point on the plane and `rotation` turns the normal
    /// (world +y unrotated; `[0, 0, 0.3]` tilts it 0.3 rad about z). Nothing tunnels through
    /// it: a particle below it at the end of a substep is caught however fast it came.
    Plane,
    /// A triangle mesh: needs `vertices` and `triangles` (see there). A closed mesh (every
    /// edge shared by exactly two triangles) is a solid, whose inside is told by parry's
    /// angle-weighted pseudo-normals; an open mesh is a one-sided sheet that pushes towards the
    /// side its triangles face (counter-clockwise seen from that side).
    Mesh,
}

/// A collider of any of [`ShapeKind`]'s shapes, static or moving kinematically (its motion is
/// prescribed; the cloth does not push it). Keys a shape does not use must be absent.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ColliderSpec {
    /// `"sphere"`, `"box"`, `"capsule"`, `"cylinder"`, `"plane"` or `"mesh"`. Default `"box"`.
    pub shape: ShapeKind,
    /// Sphere, capsule, cylinder: radius in m (> 0). No default: required by those shapes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    /// Box: half its size along local x, y, z in m (each > 0). No default: required by `box`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub half_extents: Option<[f64; 3]>,
    /// Capsule, cylinder: half the length along local y in m (> 0; for a capsule, between the
    /// centres of its end caps). No default: required by those shapes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub half_height: Option<f64>,
    /// Mesh: the vertices in the collider's local frame (m; `center` and `rotation` pose that
    /// frame), at least 3, each finite. Duplicate positions are merged. No default: required by
    /// `mesh`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vertices: Option<Vec<[f64; 3]>>,
    /// Mesh: the triangles, each three indices into `vertices`, wound counter-clockwise seen
    /// from outside (the side that pushes), at least one. A triangle of zero area (repeated or
    /// collinear corners) is refused, as is a closed mesh wound inside out or inconsistently.
    /// No default: required by `mesh`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub triangles: Option<Vec<[i64; 3]>>,
    /// Centre of the shape at time 0, in m (a plane: a point on it; a mesh: its frame's
    /// origin). Default `[0, 0.5, 0]`.
    pub center: [f64; 3],
    /// Orientation at time 0 as a rotation vector (axis times angle, in rad, right-handed).
    /// Default `[0, 0, 0]`. A rotation vector has no unit-norm constraint to break, unlike a
    /// quaternion; `[0, 0, 0.3]` tilts the shape 0.3 rad about z.
    pub rotation: [f64; 3],
    /// Coulomb friction coefficient against the shape's surface (>= 0, dimensionless). Default
    /// 0.3, as the floor's. Applied to the velocity relative to the moving surface, so a
    /// moving collider carries cloth that sticks to it.
    pub friction: f64,
    /// Particles are kept this far outside the surface, in m (>= 0). Default 0.002. A thicker
    /// gap hides the cloth's triangles dipping into the shape between particles; a thinner one
    /// looks tighter.
    pub thickness: f64,
    /// Velocity of the centre in m/s. Default `[0, 0, 0]`: the centre at time `t` is
    /// `center + velocity t`.
    pub velocity: [f64; 3],
    /// Angular velocity about the centre in rad/s (axis times rate). Default `[0, 0, 0]`: the
    /// orientation at time `t` is `rotation` followed by a turn of `angular_velocity t`. Poses
    /// are functions of the simulated time, so snapshots, retries and thread counts all see the
    /// same ones.
    pub angular_velocity: [f64; 3],
}

impl Default for ColliderSpec {
    fn default() -> Self {
        ColliderSpec {
            shape: ShapeKind::Box,
            radius: None,
            half_extents: None,
            half_height: None,
            vertices: None,
            triangles: None,
            center: [0.0, 0.5, 0.0],
            rotation: [0.0; 3],
            friction: 0.3,
            thickness: 0.002,
            velocity: [0.0; 3],
            angular_velocity: [0.0; 3],
        }
    }
}
