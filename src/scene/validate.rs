//! Validation of a scene, in one place: every value is checked once, and the error names the
//! first offending parameter and its value.

use super::mesh::{check_mesh, is_closed};
use super::pins::pin_indices;
use super::specs::{ClothSpec, ColliderSpec, Plane, ShapeKind, WatchdogSpec};
use super::Scene;
use crate::error::{check_scalar, check_vector, Bound, Error, Result};

/// Upper bound on particles per scene: indices are exposed as `u32` and the triangle list must
/// fit a GPU index buffer. 4096 x 4096 is far beyond interactive rates anyway.
pub const MAX_PARTICLES: usize = 1 << 24;

thread_local! {
    static VALIDATIONS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// How many scenes this thread has validated, for the tests that check a scene is validated
/// once on its way in (with a big mesh collider, each validation costs a second).
pub fn validations() -> u64 {
    VALIDATIONS.get()
}

impl Scene {
    /// Checks every value; the error names the first offending parameter and its value.
    pub fn validate(&self) -> Result<()> {
        if self.cloth.garment.is_some() {
            // A scene built in code, not read: check the cloth its garment compiles to.
            return self.sewn()?.validate();
        }
        VALIDATIONS.set(VALIDATIONS.get() + 1);
        check_scalar("dt", self.dt, Bound::Positive)?;
        if self.substeps == 0 {
            return Err(Error::value("substeps", "must be an integer >= 1, got 0"));
        }
        check_substep("dt", self.dt, self.substeps)?;
        check_vector("gravity", &self.gravity, Bound::Any)?;
        check_scalar("air_drag", self.air_drag, Bound::NonNegative)?;
        check_scalar("cg_tolerance", self.cg_tolerance, Bound::Positive)?;
        check_iterations("cg_max_iterations", self.cg_max_iterations)?;
        check_iterations("pd_iterations", self.pd_iterations)?;
        check_scalar("pd_tolerance", self.pd_tolerance, Bound::NonNegative)?;
        let rho = self.pd_chebyshev_rho;
        if !(rho.is_finite() && (0.0..1.0).contains(&rho)) {
            return Err(Error::value(
                "pd_chebyshev_rho",
                format!("must be a number in [0, 1), got {rho}"),
            ));
        }
        self.cloth.validate()?;
        check_membrane_integrator(
            "cloth.mesh",
            self.cloth.mesh.as_ref().map(|m| m.membrane),
            self.integrator,
        )?;
        if let Some(floor) = &self.floor {
            check_scalar("floor.height", floor.height, Bound::Any)?;
            check_scalar("floor.friction", floor.friction, Bound::NonNegative)?;
            check_scalar("floor.thickness", floor.thickness, Bound::NonNegative)?;
            // The collider keeps particles at `height + thickness`, summed in float32.
            if !(floor.height as f32 + floor.thickness as f32).is_finite() {
                return Err(Error::value(
                    "floor.thickness",
                    format!(
                        "height + thickness must be within f32 range (<= 3.4e38), got {} + {}",
                        floor.height, floor.thickness
                    ),
                ));
            }
        }
        for (s, sphere) in self.spheres.iter().enumerate() {
            check_vector(&format!("spheres[{s}].center"), &sphere.center, Bound::Any)?;
            within_collider_limit(&format!("spheres[{s}].center"), &sphere.center)?;
            check_scalar(
                &format!("spheres[{s}].radius"),
                sphere.radius,
                Bound::Positive,
            )?;
            check_scalar(
                &format!("spheres[{s}].friction"),
                sphere.friction,
                Bound::NonNegative,
            )?;
            check_scalar(
                &format!("spheres[{s}].thickness"),
                sphere.thickness,
                Bound::NonNegative,
            )?;
            // A sphere is a ball of the colliders' pass, within the same float32 limits.
            if sphere.radius + sphere.thickness > MAX_COLLIDER_VALUE {
                return Err(Error::value(
                    format!("spheres[{s}].radius"),
                    format!(
                        "radius + thickness must be at most {MAX_COLLIDER_VALUE:e} m, got {} + {}",
                        sphere.radius, sphere.thickness
                    ),
                ));
            }
        }
        for (c, collider) in self.colliders.iter().enumerate() {
            collider.validate(&format!("colliders[{c}]"))?;
        }
        self.watchdog.validate()?;
        if let Some(limit) = &self.strain_limit {
            check_scalar("strain_limit.max_strain", limit.max_strain, Bound::Positive)?;
            check_iterations("strain_limit.iterations", limit.iterations)?;
        }
        if let Some(wind) = &self.wind {
            wind.validate()?;
        }
        if let Some(sc) = &self.self_collision {
            check_scalar("self_collision.thickness", sc.thickness, Bound::Positive)?;
            let (spacing, what) = self.cloth.rest_spacing();
            if sc.thickness >= 0.5 * spacing {
                return Err(Error::value(
                    "self_collision.thickness",
                    format!(
                        "must be below half the cloth's {what} ({spacing} m), so that a \
                         cloth at rest is not in contact with itself; got {}",
                        sc.thickness
                    ),
                ));
            }
            check_scalar("self_collision.friction", sc.friction, Bound::NonNegative)?;
            check_iterations("self_collision.iterations", sc.iterations)?;
            check_scalar(
                "self_collision.solve_stiffness",
                sc.solve_stiffness,
                Bound::NonNegative,
            )?;
        }
        if let Some(tearing) = &self.tearing {
            check_scalar("tearing.max_strain", tearing.max_strain, Bound::Positive)?;
            // Compared in float32 in the pass.
            if !(tearing.max_strain as f32).is_finite() {
                return Err(Error::value(
                    "tearing.max_strain",
                    format!(
                        "must be within float32 range (3.4e38), got {}",
                        tearing.max_strain
                    ),
                ));
            }
            if tearing.max_per_step == 0 {
                return Err(Error::value(
                    "tearing.max_per_step",
                    "must be an integer >= 1, got 0",
                ));
            }
        }
        Ok(())
    }
}

/// Most iterations a solver, strain limiting or self-collision may be asked for per step or
/// substep. They all run inside one step, which an interrupt (Ctrl-C) cannot stop: at this
/// bound a step of a 256 x 256 cloth still ends within seconds, and none of these iterations
/// gains anything in float32 long before it (their defaults are 4 to 200).
pub const MAX_ITERATIONS: u32 = 10_000;

/// Refuses an iteration count of 0 or above [`MAX_ITERATIONS`], naming it `name`.
fn check_iterations(name: &str, n: u32) -> Result<()> {
    if (1..=MAX_ITERATIONS).contains(&n) {
        Ok(())
    } else {
        Err(Error::value(
            name,
            format!("must be an integer from 1 to {MAX_ITERATIONS}, got {n}"),
        ))
    }
}

/// Largest size (m), speed (m/s) or rate (rad/s) of a collider: the contact works in float32
/// and squares lengths, so anything near float32's limit would overflow to infinity.
pub const MAX_COLLIDER_VALUE: f64 = 1e15;

/// Refuses a collider value beyond [`MAX_COLLIDER_VALUE`], naming it `name`.
fn within_collider_limit(name: &str, v: &[f64]) -> Result<()> {
    match v.iter().find(|x| x.abs() > MAX_COLLIDER_VALUE) {
        Some(x) => Err(Error::value(
            name,
            format!("must be at most {MAX_COLLIDER_VALUE:e} in size, got {x}"),
        )),
        None => Ok(()),
    }
}

impl ColliderSpec {
    fn validate(&self, at: &str) -> Result<()> {
        let name = |key: &str| format!("{at}.{key}");
        let within = |key: &str, v: &[f64]| within_collider_limit(&name(key), v);
        let (radius, half_extents, half_height, mesh) = match self.shape {
            ShapeKind::Sphere => (true, false, false, false),
            ShapeKind::Box => (false, true, false, false),
            ShapeKind::Capsule | ShapeKind::Cylinder => (true, false, true, false),
            ShapeKind::Plane => (false, false, false, false),
            ShapeKind::Mesh => (false, false, false, true),
        };
        let shape = format!("{:?}", self.shape).to_lowercase();
        let presence = [
            ("radius", radius, self.radius.is_some()),
            ("half_extents", half_extents, self.half_extents.is_some()),
            ("half_height", half_height, self.half_height.is_some()),
            ("vertices", mesh, self.vertices.is_some()),
            ("triangles", mesh, self.triangles.is_some()),
        ];
        for (key, needed, given) in presence {
            match (needed, given) {
                (true, false) => {
                    return Err(Error::value(
                        name(key),
                        format!("is required for shape = \"{shape}\""),
                    ))
                }
                (false, true) => {
                    return Err(Error::value(
                        name(key),
                        format!("is not a key of shape = \"{shape}\""),
                    ))
                }
                _ => {}
            }
        }
        if let Some(r) = self.radius {
            check_scalar(&name("radius"), r, Bound::Positive)?;
            within("radius", &[r])?;
        }
        if let Some(h) = &self.half_extents {
            check_vector(&name("half_extents"), h, Bound::Positive)?;
            within("half_extents", h)?;
        }
        if let Some(h) = self.half_height {
            check_scalar(&name("half_height"), h, Bound::Positive)?;
            within("half_height", &[h])?;
        }
        if let (Some(vertices), Some(triangles)) = (&self.vertices, &self.triangles) {
            let triangles = check_mesh(at, vertices, triangles, within_collider_limit)?;
            is_closed(at, vertices, &triangles)?;
        }
        for (key, v) in [
            ("center", &self.center),
            ("rotation", &self.rotation),
            ("velocity", &self.velocity),
            ("angular_velocity", &self.angular_velocity),
        ] {
            check_vector(&name(key), v, Bound::Any)?;
            within(key, v)?;
        }
        check_scalar(&name("friction"), self.friction, Bound::NonNegative)?;
        check_scalar(&name("thickness"), self.thickness, Bound::NonNegative)?;
        within("thickness", &[self.thickness])?;
        Ok(())
    }
}

impl WatchdogSpec {
    fn validate(&self) -> Result<()> {
        if let Some(r) = self.max_stretch {
            // Compared in float32: a ratio that is not above 1 there trips on a cloth at rest.
            if !(r.is_finite() && (r as f32).is_finite() && (r as f32) > 1.0) {
                return Err(Error::value(
                    "watchdog.max_stretch",
                    format!("must be a ratio > 1 within float32 range (3.4e38), got {r}"),
                ));
            }
        }
        if self.max_substeps == 0 {
            return Err(Error::value(
                "watchdog.max_substeps",
                "must be an integer >= 1, got 0",
            ));
        }
        Ok(())
    }
}

impl ClothSpec {
    fn validate(&self) -> Result<()> {
        if self.mesh.is_some() {
            return self.validate_mesh();
        }
        for (name, n) in [("cloth.nx", self.nx), ("cloth.ny", self.ny)] {
            if n < 2 {
                return Err(Error::value(
                    name,
                    format!("must be an integer >= 2, got {n}"),
                ));
            }
        }
        let count = self.nx as usize * self.ny as usize;
        if count > MAX_PARTICLES {
            return Err(Error::value(
                "cloth.nx",
                format!(
                    "nx * ny = {} * {} = {count} particles exceeds the limit of {MAX_PARTICLES}",
                    self.nx, self.ny
                ),
            ));
        }
        check_vector("cloth.size", &self.size, Bound::Positive)?;
        check_vector("cloth.center", &self.center, Bound::Any)?;
        // The starting positions, `center +- size / 2` along the plane's axes, are float32.
        let (ei, ej) = match self.plane {
            Plane::Xz => (0, 2),
            Plane::Xy => (0, 1),
        };
        for (axis, half) in [(ei, self.size[0] / 2.0), (ej, self.size[1] / 2.0)] {
            let reach = self.center[axis].abs() + half;
            if reach > f32::MAX as f64 {
                return Err(Error::value(
                    "cloth.size",
                    format!(
                        "the cloth reaches {}{reach:e} m along {}, beyond f32 range (3.4e38)",
                        if self.center[axis] < 0.0 { "-" } else { "" },
                        ["x", "y", "z"][axis]
                    ),
                ));
            }
        }
        match (self.particle_mass, self.mass) {
            (Some(_), Some(_)) => {
                return Err(Error::value(
                    "cloth.mass",
                    "give either cloth.particle_mass or cloth.mass (the total), not both",
                ))
            }
            (Some(m), None) => check_scalar("cloth.particle_mass", m, Bound::Positive)?,
            (None, Some(m)) => check_scalar("cloth.mass", m, Bound::Positive)?,
            (None, None) => {}
        }
        // Each particle's mass is float32 and so is its inverse, as `set_masses` demands.
        let (name, m) = match (self.particle_mass, self.mass) {
            (Some(m), _) => ("cloth.particle_mass", m),
            (None, Some(total)) => ("cloth.mass", total / count as f64),
            (None, None) => ("cloth.particle_mass", 0.001),
        };
        if (m as f32) == 0.0 || !(1.0 / m as f32).is_finite() {
            return Err(Error::value(
                name,
                format!(
                    "each particle's mass ({m:e} kg) must be representable in float32 with a \
                     finite inverse"
                ),
            ));
        }
        check_scalar("cloth.k_structural", self.k_structural, Bound::NonNegative)?;
        check_scalar("cloth.k_shear", self.k_shear, Bound::NonNegative)?;
        check_scalar("cloth.k_bend", self.k_bend, Bound::NonNegative)?;
        check_scalar("cloth.damping", self.damping, Bound::NonNegative)?;
        for (k, cut) in self.cuts.iter().enumerate() {
            cut.validate(&format!("cloth.cuts[{k}]"))?;
        }
        self.check_pins()
    }
}

impl ClothSpec {
    /// How close two parts of the cloth that share no particle come at rest, a lower bound (m),
    /// and what it is: the grid spacing, or a mesh's shortest triangle altitude. In a flat mesh
    /// a vertex is farther than that from every triangle and edge it is not on (they all lie
    /// beyond the triangles around it), and two edges with no shared vertex are as far apart
    /// as some vertex is from the other edge. A curved mesh can bring distant parts closer,
    /// which is the pass's own business once it runs. Called on a validated cloth.
    pub(crate) fn rest_spacing(&self) -> (f64, &'static str) {
        match &self.mesh {
            Some(mesh) => (
                super::mesh_checks::min_altitude(&mesh.vertices, &mesh.triangles),
                "shortest triangle altitude",
            ),
            None => (
                (self.size[0] / (self.nx - 1) as f64).min(self.size[1] / (self.ny - 1) as f64),
                "grid spacing",
            ),
        }
    }

    /// A mesh cloth: the mesh's own checks ([`super::MeshCloth::new`]), the grid's
    /// keys left at their defaults (a value there would be silently ignored), and the pins.
    fn validate_mesh(&self) -> Result<()> {
        let Some(mesh) = &self.mesh else {
            return Ok(());
        };
        let grid = ClothSpec::default();
        let grid_keys = [
            ("cloth.nx", self.nx != grid.nx),
            ("cloth.ny", self.ny != grid.ny),
            ("cloth.size", self.size != grid.size),
            ("cloth.center", self.center != grid.center),
            ("cloth.plane", self.plane != grid.plane),
            ("cloth.particle_mass", self.particle_mass.is_some()),
            ("cloth.mass", self.mass.is_some()),
            ("cloth.k_structural", self.k_structural != grid.k_structural),
            ("cloth.k_shear", self.k_shear != grid.k_shear),
            ("cloth.k_bend", self.k_bend != grid.k_bend),
            ("cloth.damping", self.damping != grid.damping),
            ("cloth.cuts", !self.cuts.is_empty()),
        ];
        if let Some((name, _)) = grid_keys.iter().find(|(_, set)| *set) {
            return Err(Error::value(
                *name,
                "is a grid cloth's key; a mesh cloth takes its shape from cloth.mesh.vertices \
                 and its material from cloth.mesh.density, stretch, bend and damping: remove it",
            ));
        }
        super::MeshCloth::new(mesh)?;
        self.check_pins()
    }
}

/// Projective dynamics' global matrix is the springs' constant Laplacian, which has no place
/// for a triangle element's rotated stiffness: the triangle membrane refuses it.
/// The error names `{at}.membrane` (`cloth.mesh` or `cloth.garment`).
pub(crate) fn check_membrane_integrator(
    at: &str,
    membrane: Option<super::MembraneKind>,
    integrator: super::IntegratorKind,
) -> Result<()> {
    let triangle = membrane == Some(super::MembraneKind::Triangle);
    if triangle && integrator == super::IntegratorKind::ProjectiveDynamics {
        return Err(Error::value(
            format!("{at}.membrane"),
            "\"triangle\" does not run under integrator = \"projective_dynamics\"; use \
             \"implicit_euler\" or an explicit integrator, or membrane = \"springs\"",
        ));
    }
    Ok(())
}

impl ClothSpec {
    /// Each pin names particles of this cloth; the error names `cloth.pins[n]`.
    fn check_pins(&self) -> Result<()> {
        for (n, pin) in self.pins.iter().enumerate() {
            pin_indices(pin, self).map_err(|e| match e {
                Error::InvalidValue { message, .. } => {
                    Error::value(format!("cloth.pins[{n}]"), message)
                }
                other => other,
            })?;
        }
        Ok(())
    }
}

/// The scene's tables (`cloth`, `floor`, ..., each sphere) must be tables: serde would also
/// fill a struct from a list of its fields in order, so `cloth = [8, 8]` meant nx = ny = 8 and
/// `floor = [0.5, 0.1, 0.01]` a floor, silently.
pub(super) fn require_tables(scene: &toml::Value) -> Result<()> {
    let Some(scene) = scene.as_table() else {
        return Err(Error::InvalidType {
            name: "scene".into(),
            message: format!("must be a table of keys, got {}", scene.type_str()),
        });
    };
    let not_a_table = |name: String, value: &toml::Value| Error::InvalidType {
        name,
        message: format!(
            "must be a table of keys (a dict), got {} {value}",
            value.type_str()
        ),
    };
    for key in [
        "cloth",
        "floor",
        "watchdog",
        "strain_limit",
        "self_collision",
        "tearing",
        "wind",
    ] {
        match scene.get(key) {
            Some(value) if !value.is_table() => return Err(not_a_table(key.into(), value)),
            _ => {}
        }
    }
    for key in ["spheres", "colliders"] {
        if let Some(toml::Value::Array(items)) = scene.get(key) {
            for (s, item) in items.iter().enumerate() {
                if !item.is_table() {
                    return Err(not_a_table(format!("{key}[{s}]"), item));
                }
            }
        }
    }
    Ok(())
}

/// The solver steps in float32 by `h = dt / substeps`: below a nanosecond it is a rounding
/// error next to any time scale of cloth, and at float32's limit it becomes zero.
pub(crate) fn check_substep(name: &str, dt: f64, substeps: u32) -> Result<()> {
    let h = dt / substeps as f64;
    if h < MIN_SUBSTEP {
        return Err(Error::value(
            name,
            format!(
                "dt / substeps must be at least {MIN_SUBSTEP:e} s, got {dt:e} / {substeps} = {h:e}"
            ),
        ));
    }
    Ok(())
}

/// The shortest substep `dt / substeps` in s.
pub const MIN_SUBSTEP: f64 = 1e-9;

impl super::specs::WindSpec {
    fn validate(&self) -> Result<()> {
        check_vector("wind.velocity", &self.velocity, Bound::Any)?;
        // Far beyond any wind, and it keeps |u|^2 in the force within float32.
        let speed = self.velocity.iter().map(|v| v * v).sum::<f64>().sqrt();
        if speed > MAX_WIND_SPEED {
            return Err(Error::value(
                "wind.velocity",
                format!("must be at most {MAX_WIND_SPEED} m/s, got {speed} m/s"),
            ));
        }
        check_scalar("wind.gust", self.gust, Bound::NonNegative)?;
        if self.gust > 1.0 {
            return Err(Error::value(
                "wind.gust",
                format!("must be a fraction in [0, 1], got {}", self.gust),
            ));
        }
        check_scalar("wind.gust_period", self.gust_period, Bound::Positive)?;
        check_scalar("wind.turbulence", self.turbulence, Bound::NonNegative)?;
        if self.turbulence > MAX_WIND_SPEED {
            return Err(Error::value(
                "wind.turbulence",
                format!(
                    "must be at most {MAX_WIND_SPEED} m/s, got {}",
                    self.turbulence
                ),
            ));
        }
        check_scalar(
            "wind.turbulence_scale",
            self.turbulence_scale,
            Bound::Positive,
        )?;
        check_scalar("wind.drag", self.drag, Bound::NonNegative)?;
        check_scalar("wind.lift", self.lift, Bound::NonNegative)?;
        check_scalar("wind.air_density", self.air_density, Bound::Positive)?;
        for (name, value) in [
            ("wind.drag", self.drag),
            ("wind.lift", self.lift),
            ("wind.air_density", self.air_density),
        ] {
            if value > MAX_AERO_VALUE {
                return Err(Error::value(
                    name,
                    format!("must be at most {MAX_AERO_VALUE}, got {value}"),
                ));
            }
        }
        Ok(())
    }
}

/// Fastest wind or turbulence in m/s: ten times the strongest gust ever measured.
pub const MAX_WIND_SPEED: f64 = 1000.0;

/// Largest drag or lift coefficient and air density: far beyond any cloth in any gas, and it
/// keeps the force's float32 product finite.
const MAX_AERO_VALUE: f64 = 1e6;
