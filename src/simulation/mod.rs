//! The simulation: one facade over the parts a running cloth is made of. The [`Model`] (what
//! the scene compiles to), the [`State`] (what a step changes), the [`Stepper`] (the passes,
//! their workspace and the watchdog), the [`Picker`] (ray queries and their trees), the mouse's
//! [`Grab`], and the derived [`Mesh`]. Every public call checks its input first and changes
//! nothing when it fails.

use glam::Vec3;

use crate::collisions::Pose;
use crate::cutting::StrokeCutter;
use crate::diagnostics::{self, Energy, Mesh};
use crate::error::{check_scalar, Bound, Error, Result};
use crate::grid::Grid;
use crate::integrators::{IntegratorKind, SolverStats};
use crate::interaction::Grab;
use crate::model::Model;
use crate::particles::Particles;
use crate::picking::Picker;
use crate::profile::Profile;
use crate::render_mesh::{CutVertex, RenderMesh};
use crate::scene::{check_substep, Scene, SelfCollisionSpec};
use crate::snapshot::Snapshot;
use crate::soa::Vec3s;
use crate::springs::Springs;
use crate::state::State;
use crate::stepper::{Stepper, WatchdogStats};

mod edits;
mod interaction;

pub use crate::stepper::MAX_ADVANCE_STEPS;

/// A running cloth simulation.
pub struct Simulation {
    model: Model,
    state: State,
    stepper: Stepper,
    picker: Picker,
    grab: Option<Grab>,
    /// `None`: the default grip radius.
    grip_radius: Option<f32>,
    /// `None`: the default drag time.
    drag_time: Option<f64>,
    mesh: Mesh,
    render: RenderMesh,
    cutter: StrokeCutter,
    /// The live stroke in progress ([`Simulation::sever_live_stroke`]).
    live: crate::cutting_rest::LiveStroke,
    /// A mesh cloth's live stroke, on every layer its rays pass through.
    layers: crate::cutting_rest::LayeredStroke,
    /// A mesh cloth's rest sheet, built by its first live stroke: `Some(None)` where its rest
    /// shape is curved (the rest shape never changes, so neither does this).
    mesh_sheet: Option<Option<crate::cutting_rest::MeshSheet>>,
}

impl Simulation {
    /// Builds the cloth the scene describes, at rest.
    pub fn new(scene: Scene) -> Result<Simulation> {
        let (model, pos) = Model::new(scene)?;
        let mut sim = Simulation {
            stepper: Stepper::new(&model),
            state: State::new(pos),
            model,
            picker: Picker::default(),
            grab: None,
            grip_radius: None,
            drag_time: None,
            mesh: Mesh::default(),
            render: RenderMesh::default(),
            cutter: StrokeCutter::default(),
            live: Default::default(),
            layers: Default::default(),
            mesh_sheet: None,
        };
        sim.make_scene_cuts()?;
        Ok(sim)
    }

    // ----- stepping -------------------------------------------------------------------------

    /// Advances exactly `n` steps of `dt`. If a step produces a non-finite state, the state
    /// from before that step is kept and [`Error::Diverged`] names the step and the particle.
    pub fn step(&mut self, n: u64) -> Result<()> {
        self.step_interruptible(n, &mut || false)
    }

    /// [`Simulation::step`], asking `interrupted` every few milliseconds (between whole steps)
    /// whether to stop; then [`Error::Interrupted`], with the state at that step boundary.
    pub fn step_interruptible(
        &mut self,
        n: u64,
        interrupted: &mut dyn FnMut() -> bool,
    ) -> Result<()> {
        let outcome = self
            .stepper
            .run(&mut self.model, &mut self.state, n, interrupted);
        self.after_stepping(outcome)
    }

    /// Adds `seconds` of requested time and runs the whole steps it covers, carrying the
    /// remainder to the next call; returns the steps taken. The result depends only on the total
    /// time requested, not on how it was split into calls. After a failed step the time not
    /// simulated stays owed, so the next call tries those steps again. At most
    /// [`MAX_ADVANCE_STEPS`] steps per call.
    pub fn advance(&mut self, seconds: f64) -> Result<u64> {
        self.advance_interruptible(seconds, &mut || false)
    }

    /// [`Simulation::advance`], asking `interrupted` between steps as
    /// [`Simulation::step_interruptible`] does. An interrupted call abandons the rest of its request.
    pub fn advance_interruptible(
        &mut self,
        seconds: f64,
        interrupted: &mut dyn FnMut() -> bool,
    ) -> Result<u64> {
        let outcome = self
            .stepper
            .advance(&mut self.model, &mut self.state, seconds, interrupted);
        self.after_stepping(outcome)
    }

    /// A step that panicked was rolled back by the stepper; the caches it may have left
    /// half-built go too.
    fn after_stepping<T>(&mut self, outcome: Result<T>) -> Result<T> {
        if let Err(Error::Internal { .. }) = &outcome {
            self.drop_caches();
        }
        outcome
    }

    /// Makes the next force evaluation panic on a worker thread: a stand-in for a bug, to test
    /// that a panic is caught, rolled back and reported as [`Error::Internal`].
    #[doc(hidden)]
    pub fn inject_panic(&mut self) {
        self.stepper.inject_panic();
    }

    /// Makes the simulation usable again after a panic caught anywhere in it (the Python
    /// binding's last resort): derived data and picking trees are dropped and rebuilt on
    /// request, the watchdog forgets the last step, and the force model starts its next
    /// evaluation afresh. The state itself is whatever the interrupted call left, which every
    /// call keeps consistent by checking its input before changing anything.
    pub fn after_panic(&mut self) {
        self.stepper.after_panic();
        self.drop_caches();
    }

    fn drop_caches(&mut self) {
        self.picker.drop_caches();
        self.mesh = Mesh::default();
        self.render = RenderMesh::default();
        self.state.version += 1;
        self.model.topology_version += 1;
    }

    // ----- reading --------------------------------------------------------------------------

    pub fn grid(&self) -> Grid {
        self.model.grid
    }

    /// The scene, with the run-time settings (integrator, dt, substeps) as they are now.
    /// The compiled model: topology, particles, springs.
    pub fn model(&self) -> &Model {
        &self.model
    }

    pub fn scene(&self) -> &Scene {
        &self.model.scene
    }

    pub fn positions(&self) -> &Vec3s {
        &self.state.kin.pos
    }

    pub fn velocities(&self) -> &Vec3s {
        &self.state.kin.vel
    }

    pub fn particles(&self) -> &Particles {
        &self.model.particles
    }

    pub fn springs(&self) -> &Springs {
        &self.model.springs
    }

    pub fn steps(&self) -> u64 {
        self.state.clock.steps
    }

    /// Simulated time in s: the time of every step taken, each with the `dt` it was taken
    /// with; exactly `steps * dt` while `dt` has not changed.
    pub fn time(&self) -> f64 {
        self.state.clock.time(self.model.scene.dt)
    }

    pub fn dt(&self) -> f64 {
        self.model.scene.dt
    }

    /// The passes a step runs, in order.
    pub fn effects(&self) -> Vec<&'static str> {
        self.stepper.effects(&self.model, &self.state)
    }

    pub fn profile(&self) -> &Profile {
        self.stepper.profile()
    }

    /// The largest step `dt` (s) at which the current integrator is estimated to stay stable
    /// with the current substeps, or None when any step is (implicit Euler, or no springs):
    /// [`Scene::stable_dt`] with the lightest moving particle's mass, which bounds the stiffest
    /// mode also when masses differ (`set_masses`).
    pub fn stable_dt(&self) -> Option<f64> {
        let substeps = self.model.scene.substeps as f64;
        self.model
            .stable_substep(self.stepper.integrator())
            .map(|h| h * substeps)
    }

    /// What the watchdog caught and retried so far.
    pub fn watchdog_stats(&self) -> WatchdogStats {
        self.stepper.watchdog_stats()
    }

    /// Statistics of the linear solver, when the integrator solves one (`implicit_euler`).
    pub fn solver_stats(&self) -> Option<SolverStats> {
        self.stepper.solver_stats()
    }

    /// What the self-collision pass did since the simulation was built (None without
    /// `[self_collision]`).
    pub fn self_collision_stats(&self) -> Option<crate::self_collision::SelfCollisionStats> {
        self.stepper.self_collision_stats()
    }

    /// How far a garment's seams are from closed: the largest distance between two vertices
    /// sewn together (m), in float32 as the positions are. None without seams.
    pub fn seam_gap(&self) -> Option<f32> {
        let pos = &self.state.kin.pos;
        self.model
            .sewn()
            .map(|[a, b]| pos.get(a as usize).distance(pos.get(b as usize)))
            .reduce(f32::max)
    }

    /// Increments whenever positions change.
    pub fn state_version(&self) -> u64 {
        self.state.version
    }

    /// Increments whenever the triangle list changes (a cut).
    pub fn topology_version(&self) -> u64 {
        self.model.topology_version
    }

    /// Energy of the current state, in f64 (see [`diagnostics::energy`]).
    pub fn energy(&self) -> Energy {
        diagnostics::energy(&self.model, &self.state)
    }

    /// Per particle, the largest relative stretch `l / L - 1` of its live springs.
    pub fn spring_strain(&self) -> Vec<f32> {
        diagnostics::spring_strain(&self.model, &self.state)
    }

    /// The largest relative stretch `l / L - 1` over all live springs.
    pub fn max_stretch(&self) -> f32 {
        self.spring_strain().into_iter().fold(0.0, f32::max)
    }

    /// The triangles of the live cloth, two per grid cell, computed on first request after a
    /// change of topology.
    pub fn triangles(&mut self) -> &[[u32; 3]] {
        self.mesh.triangles(&self.model)
    }

    /// Unit vertex normals, computed on first request after the state changed.
    pub fn normals(&mut self) -> &Vec3s {
        self.mesh.normals(&self.model, &self.state)
    }

    /// The drawn mesh's triangles: the particles' and the cut vertices' indices, the cut
    /// vertices numbered from `grid().len()` on ([`crate::render_mesh`]); rebuilt on first
    /// request after the topology changed.
    pub fn render_triangles(&mut self) -> &[[u32; 3]] {
        self.render.triangles(&self.model)
    }

    /// The drawn mesh's cut vertices, vertex `grid().len() + k` being entry `k`.
    pub fn render_cut_vertices(&mut self) -> &[CutVertex] {
        self.render.cut_vertices(&self.model)
    }

    /// The drawn mesh's vertex positions and unit normals (particles first), computed on
    /// first request after the state or the topology changed.
    pub fn render_frame(&mut self) -> (&Vec3s, &Vec3s) {
        let normals = self.mesh.normals(&self.model, &self.state);
        self.render.frame(&self.model, &self.state, normals)
    }

    /// Heap memory held by the simulation, in bytes: state, scratch, springs, force tables,
    /// derived data and the picking trees once built.
    pub fn memory_bytes(&self) -> usize {
        self.model.heap_bytes()
            + self.state.heap_bytes()
            + self.stepper.heap_bytes()
            + self.mesh.heap_bytes()
            + self.render.heap_bytes()
            + self.cutter.heap_bytes()
            + (self.mesh_sheet.as_ref().and_then(Option::as_ref))
                .map_or(0, crate::cutting_rest::MeshSheet::heap_bytes)
            + self.picker.heap_bytes()
    }

    /// Total force on each particle of the current state, for tests and diagnostics.
    pub fn total_force(&mut self) -> Vec3s {
        self.stepper.total_force(&self.model, &self.state)
    }

    /// Removes particle `index` and every spring touching it from the cloth; its triangles
    /// leave the mesh. Cutting a particle twice does nothing the second time. The particle's
    /// mass leaves the cloth. [`Simulation::sever_stroke`] cuts
    /// without removing anything.
    pub fn cut(&mut self, index: i64) -> Result<()> {
        let p = self.check_index("index", index)?;
        if self.model.particles.alive[p] {
            self.cut_live(p);
        }
        Ok(())
    }

    fn cut_live(&mut self, p: usize) {
        self.model.cut(p);
        self.state.targets.remove(p);
        self.state.kin.vel.set(p, Vec3::ZERO);
        self.state_changed();
    }

    /// Switches the integrator at run time; the state carries over.
    pub fn set_integrator(&mut self, name: &str) -> Result<()> {
        let kind = IntegratorKind::by_name(name, "integrator")?;
        let membrane = self.model.scene.cloth.mesh.as_ref().map(|m| m.membrane);
        crate::scene::check_membrane_integrator("cloth.mesh", membrane, kind)?;
        self.model.scene.integrator = kind;
        self.stepper.set_integrator(&self.model);
        Ok(())
    }

    /// Turns self-collision on with `spec`'s settings, or off with `None`, at run time. The
    /// state carries over bit for bit (positions, velocities, pins, the grip, tears, the
    /// clock, the watchdog, the integrator's history: the simulation goes on as one restored
    /// from its snapshot with the scene's `[self_collision]` changed), so turning it off and
    /// on again leaves the run as it would have been with it on. The profile and the
    /// self-collision statistics start afresh. Settings the scene would refuse (a thickness
    /// past half the grid spacing, or a mesh cloth's limit) are refused the same way, naming
    /// the `self_collision` key, changing nothing.
    pub fn set_self_collision(&mut self, spec: Option<SelfCollisionSpec>) -> Result<()> {
        let mut snapshot = self.snapshot();
        snapshot.scene.self_collision = spec;
        *self = Simulation::restore(snapshot)?;
        Ok(())
    }

    /// Changes the number of substeps per step (>= 1).
    pub fn set_substeps(&mut self, substeps: i64) -> Result<()> {
        if !(1..=u32::MAX as i64).contains(&substeps) {
            return Err(Error::value(
                "substeps",
                format!("must be an integer >= 1, got {substeps}"),
            ));
        }
        check_substep("substeps", self.model.scene.dt, substeps as u32)?;
        self.model.scene.substeps = substeps as u32;
        self.stepper.substeps_changed(&self.model);
        Ok(())
    }

    /// Changes the time step (s, > 0). The time already simulated stays as it was; the carried
    /// remainder of `advance` is kept in seconds.
    pub fn set_dt(&mut self, dt: f64) -> Result<()> {
        check_scalar("dt", dt, Bound::Positive)?;
        check_substep("dt", dt, self.model.scene.substeps)?;
        self.state.clock.change_dt(self.model.scene.dt);
        self.model.scene.dt = dt;
        self.stepper.dt_changed();
        Ok(())
    }

    /// Back to the scene's starting state (keeping the run-time integrator and substeps).
    pub fn reset(&mut self) -> Result<()> {
        // The versions keep counting up, so a cache stamped before the reset never matches.
        let (topology, state) = (self.model.topology_version + 1, self.state.version + 1);
        *self = Simulation::new(self.model.scene.clone())?;
        self.model.topology_version = topology;
        self.state.version = state;
        Ok(())
    }

    // ----- colliders ------------------------------------------------------------------------

    /// Puts collider `index` (of the scene's `[[colliders]]`) at `position` (m, its frame's
    /// origin) with orientation `rotation`, a unit quaternion `[x, y, z, w]`, by the end of the
    /// next step. Over that step it moves there from where it is now at the constant velocity
    /// and turn rate that this takes, which friction sees: cloth resting on a collider set each
    /// step is carried along. It rests there after, its scripted `velocity` and
    /// `angular_velocity` over. Refuses an index out of range (naming `index`), a non-finite
    /// position (`position`) or a rotation that is not a unit quaternion within
    /// [`crate::collisions::ROTATION_TOLERANCE`] (`rotation`), changing nothing.
    pub fn set_collider_pose(
        &mut self,
        index: i64,
        position: [f64; 3],
        rotation: [f64; 4],
    ) -> Result<()> {
        let n = self.model.scene.colliders.len();
        if !(0..n as i64).contains(&index) {
            return Err(Error::index("index", index, n));
        }
        let pose = Pose::checked(("position", "rotation"), position, rotation)?;
        let (now, dt) = (self.time(), self.model.scene.dt);
        if let Some(shapes) = self.stepper.shapes_mut() {
            shapes.set_pose(index as usize, pose, now, dt);
        }
        Ok(())
    }

    /// Each collider's pose now (see [`Simulation::set_collider_pose`]), in the scene's order.
    pub fn collider_poses(&self) -> Vec<Pose> {
        let time = self.time();
        self.stepper.shapes().map_or_else(Vec::new, |shapes| {
            (0..shapes.len()).map(|i| shapes.pose(i, time)).collect()
        })
    }

    // ----- saving and restoring -------------------------------------------------------------

    /// The whole state, to save or send elsewhere; [`Simulation::restore`] continues it bit for
    /// bit.
    pub fn snapshot(&self) -> Snapshot {
        // Work the integrator reuses between steps is not in a snapshot: this run drops it at
        // its next step, as the restored run (which never had it) does.
        self.stepper.integrator_scheme().restart_point();
        Snapshot::capture(
            &self.model,
            &self.state,
            &self.stepper,
            &self.picker,
            self.grab.as_ref(),
            (self.grip_radius, self.drag_time),
        )
    }

    /// A simulation continuing `snapshot` exactly. Every part is checked against the scene
    /// (lengths, finite values, masses, indices, springs the grid has); a bad one is named.
    pub fn restore(snapshot: Snapshot) -> Result<Simulation> {
        Simulation::new(snapshot.scene.clone())?.continuing(snapshot)
    }

    /// This simulation, new and built from `snapshot`'s scene, continuing `snapshot` as
    /// [`Simulation::restore`] does; the snapshot's own scene is not read. For a caller that
    /// needs the validated scene (its particle count) to read the rest of a snapshot, as the
    /// Python binding does, without validating the scene twice.
    pub fn continuing(mut self, snapshot: Snapshot) -> Result<Simulation> {
        let (model, state, stepper, picker) = (
            &mut self.model,
            &mut self.state,
            &mut self.stepper,
            &mut self.picker,
        );
        self.grip_radius = snapshot.grip_radius;
        self.drag_time = snapshot.drag_time;
        self.grab = snapshot.apply(model, state, stepper, picker)?;
        Ok(self)
    }
}

/// Total force on each particle of the current state, for tests and diagnostics.
pub fn total_force(sim: &mut Simulation) -> Vec3s {
    sim.total_force()
}
