//! The passes a scene compiles into, and the ones that run after the integrator.
//!
//! A substep runs, in order, only the passes the scene needs (`Stepper::substep` calls them):
//!
//! 1. predicted contacts (with colliders, for an integrator that holds contacts inside its
//!    solve: `src/collisions/predict.rs`);
//! 2. the integrator, evaluating the forces (gravity, air drag, each spring family) as often
//!    as its scheme needs and writing the end-of-substep state into a second buffer; with
//!    predicted contacts, solved again while the solve changes them, and in halves when it
//!    gained energy ([`Pipeline::integrate`]); friction of the predicted contacts;
//! 3. wind (when the scene asks for it, `src/wind.rs`): a change of velocity after the
//!    integrator, the same for every integrator;
//! 4. kinematic pins (while the user drags a pinned particle);
//! 5. strain limiting (when the scene asks for it, `src/strain_limit/`);
//! 6. colliders (the `[[spheres]]`, then the `[[colliders]]` of any shape, then the floor);
//! 7. self-collision (when the scene asks for it, `src/self_collision/`), last, so that its
//!    guarantee covers everything the passes before it did. It only shortens a particle's
//!    motion along its path from the substep's start, so the floor (a half-space, which holds
//!    both ends of that path) stays satisfied.
//!
//! and once per step, after its last substep was accepted, tearing (when the scene asks for it,
//! `src/tearing.rs`): it changes the model (springs break), not the state, so it runs between
//! steps rather than inside one.
//!
//! Each pass after the integrator returns whether what it wrote is finite; they write few
//! values (a drag, contacts, limited springs), so checking costs next to nothing.

use std::time::Instant;

use glam::{DVec3, Vec3};

use crate::collisions::{Collider, Floor, PredictedContacts, Shapes};
use crate::diagnostics::energy_of;
use crate::forces::{Force, ForceModel};
use crate::grid::Family;
use crate::integrators::{Integrator, StepContext};
use crate::model::Model;
use crate::parallel::chunk_len;
use crate::pins::KinematicPins;
use crate::profile::Profile;
use crate::scene::{ColliderSpec, Scene, SphereSpec};
use crate::self_collision::SelfCollision;
use crate::soa::Vec3s;
use crate::state::{Kinematics, State};
use crate::strain_limit::StrainLimit;
use crate::tearing::Tearing;
use crate::wind::Wind;

/// How many times at most an implicit solve runs in a substep with contacts: after each, the
/// contacts it pulled in are released and the particles it carried into a collider are held,
/// and the solve runs again while that changed anything. A contact set still changing after
/// the last round leaves its few particles to the collider passes after the solve.
const CONTACT_ROUNDS: u32 = 4;

/// How many times at most a solve holding contacts that gained energy is halved
/// ([`Pipeline::integrate`]): down to an eighth of the substep.
const SPLITS: u32 = 3;

/// The energy rise a solve may show before it is split, as a fraction of the energies' sum
/// `K + |G| + E` at its start: float32 positions near 1 m round at 6e-8 m, so the sum of
/// potential energies is known to about 1e-7 of that scale; ten times more is noise-proof and
/// still a thousandth of the smallest gain measured from a landing.
const ENERGY_SLACK: f64 = 1e-6;

/// What one solve of a substep reads and writes, apart from the states it goes between.
struct Solve<'a> {
    model: &'a Model,
    /// Length of the solve, s.
    h: f32,
    /// Time at its end, s.
    time: f64,
    chunk: usize,
    profile: &'a mut Profile,
    force: &'a mut Vec3s,
}

/// The passes of a step.
pub(super) struct Pipeline {
    pub forces: ForceModel,
    pub integrator: Integrator,
    /// Only when the scene asks for strain limiting.
    pub strain_limit: Option<StrainLimit>,
    pub colliders: Vec<Collider>,
    /// Only when the scene asks for self-collision.
    pub self_collision: Option<SelfCollision>,
    /// Only when the scene asks for tearing; runs after each whole step.
    pub tearing: Option<Tearing>,
    /// Only when the scene asks for wind.
    pub wind: Option<Wind>,
    /// With colliders: the contacts an implicit solver holds inside its solve (made for any
    /// integrator, since the integrator can change between steps).
    pub contacts: Option<PredictedContacts>,
    /// Whether the cloth is a mesh, whose springs the force model adds after its sweep.
    pub mesh_springs: bool,
    /// The midpoints of a solve split in halves, one per level ([`Pipeline::integrate`]).
    halves: Vec<Kinematics>,
}

/// What the passes of one substep read and write.
pub(super) struct Substep<'a> {
    pub model: &'a Model,
    /// The state the substep starts from.
    pub state: &'a State,
    /// Where the passes write the substep's result.
    pub next: &'a mut Kinematics,
    /// Length of the substep, s.
    pub h: f32,
    /// Time at its end, s: where moving colliders are posed.
    pub time: f64,
    /// Particles per parallel work item.
    pub chunk: usize,
    pub profile: &'a mut Profile,
}

impl<'a> Substep<'a> {
    /// A substep of length `h` ending at `time` from `state`, writing into `next`.
    pub fn new(
        model: &'a Model,
        state: &'a State,
        next: &'a mut Kinematics,
        (h, time): (f32, f64),
        profile: &'a mut Profile,
    ) -> Self {
        let chunk = chunk_len(model.grid.len());
        Substep {
            model,
            state,
            next,
            h,
            time,
            chunk,
            profile,
        }
    }
}

impl Pipeline {
    pub fn compile(scene: &Scene, particles: usize) -> Pipeline {
        let colliders = colliders_of(scene);
        Pipeline {
            forces: ForceModel::new(forces_of(scene)),
            integrator: Integrator::new(scene.integrator, scene.solver_settings()),
            strain_limit: scene
                .strain_limit
                .as_ref()
                .map(|s| StrainLimit::new(s.max_strain as f32, s.iterations)),
            contacts: (!colliders.is_empty()).then(|| PredictedContacts::new(particles)),
            colliders,
            self_collision: scene
                .self_collision
                .as_ref()
                .map(|s| SelfCollision::new(s.thickness as f32, s.friction as f32, s.iterations)),
            tearing: scene
                .tearing
                .as_ref()
                .map(|t| Tearing::new(t.max_strain as f32, t.max_per_step)),
            wind: scene.wind.as_ref().map(|w| Wind::new(w, particles)),
            mesh_springs: scene.cloth.mesh.is_some(),
            halves: Vec::new(),
        }
    }

    /// The passes a step runs, in order (kinematic pins only while a target is set).
    pub fn effects(&self, state: &State) -> Vec<&'static str> {
        let mut out: Vec<&'static str> = self.forces.forces().iter().map(Force::name).collect();
        if self.mesh_springs {
            out.push(crate::forces::MESH_SPRINGS);
        }
        out.push(self.integrator.name());
        if self.wind.is_some() {
            out.push(Wind::NAME);
        }
        if !state.targets.is_empty() {
            out.push(KinematicPins::NAME);
        }
        if self.strain_limit.is_some() {
            out.push(StrainLimit::NAME);
        }
        out.extend(self.colliders.iter().map(Collider::name));
        if self.self_collision.is_some() {
            out.push(SelfCollision::NAME);
        }
        if self.tearing.is_some() {
            out.push(Tearing::NAME);
        }
        out
    }

    /// Whether this substep's integrator holds the predicted contacts inside its solve.
    fn holds_contacts(&self) -> bool {
        self.contacts.is_some() && self.integrator.kind().holds_contacts()
    }

    /// Finds the contacts each particle's free motion would make with the colliders, for an
    /// integrator that holds them inside its solve.
    pub fn predict_contacts(&mut self, s: &mut Substep) {
        if !self.holds_contacts() {
            return;
        }
        let mut job = Solve {
            model: s.model,
            h: s.h,
            time: s.time,
            chunk: s.chunk,
            profile: &mut *s.profile,
            force: &mut Vec3s::zeros(0),
        };
        self.find_contacts(&mut job, &s.state.kin);
    }

    fn find_contacts(&mut self, job: &mut Solve, from: &Kinematics) {
        let Some(contacts) = self.contacts.as_mut() else {
            return;
        };
        let t = Instant::now();
        let g = DVec3::from(job.model.scene.gravity).as_vec3();
        let particles = &job.model.particles;
        contacts.find(
            &self.colliders,
            from,
            particles,
            g,
            (job.h, job.time),
            job.chunk,
        );
        job.profile.add(PredictedContacts::NAME, t.elapsed());
    }

    /// The integrator's step into `s.next`, with the predicted contacts' friction; returns
    /// whether every value it wrote is finite. Arms the force loop's stretch watch, read after
    /// it by [`ForceModel::overstretched`].
    ///
    /// A solve holding contacts that ends with more energy than it started with is run again
    /// as two halves, each with its own contacts, and each half the same way, down to
    /// `1 / 2^SPLITS` of the substep. A landing at a long step moves a row a spring's length
    /// or more into the rows that already landed; the solve's springs are linearised at the
    /// step's start, where a compressed spring has no sideways stiffness, and their true
    /// energy at the end can be joules above what the linear model traded for (the `pile`
    /// dropped 40 cm at 1/60 s: 3.2 J of elastic energy from one solve). Where nothing does
    /// work on the cloth ([`Pipeline::rose`]) the rise is the linearisation's error, and
    /// shorter solves shrink it (at 1/120 s and 1/240 s the same drops gain nothing).
    pub fn integrate(&mut self, s: &mut Substep, force: &mut Vec3s) -> bool {
        let started = Instant::now();
        let forces_before = s.profile.force_time;
        let (model, from) = (s.model, &s.state.kin);
        let mut job = Solve {
            model,
            h: s.h,
            time: s.time,
            chunk: s.chunk,
            profile: &mut *s.profile,
            force,
        };
        // The watch judges the state the substep starts from: the first force evaluation of
        // this solve, not a later round's or a half's, which start elsewhere.
        self.forces.arm_stretch_watch();
        self.forces.set_time(s.time - s.h as f64);
        let mut finite = self.solve(&mut job, from, s.next, false);
        if finite && self.holds_contacts() && self.rose(model, from, s.next, s.time) {
            finite = self.split(&mut job, from, s.next, 1);
        }
        let own_time = started
            .elapsed()
            .saturating_sub(s.profile.force_time - forces_before);
        s.profile.add(self.integrator.name(), own_time);
        finite
    }

    /// Whether the total energy of `to` is above that of `from` by more than the rounding of
    /// float32 positions and speeds can explain, in a solve where nothing does work on the
    /// cloth: with contacts held, no collider moving and no pinned particle moving (a dragged
    /// pin or a moving collider adds energy rightly, and is not split for it).
    fn rose(&self, model: &Model, from: &Kinematics, to: &Kinematics, time: f64) -> bool {
        if self.contacts.as_ref().is_none_or(|c| c.count == 0)
            || self.colliders.iter().any(|c| c.moves(time))
        {
            return false;
        }
        let pinned = &model.particles.pinned;
        if (0..pinned.len()).any(|p| pinned[p] && from.vel.get(p) != glam::Vec3::ZERO) {
            return false;
        }
        let (a, b) = (energy_of(model, from), energy_of(model, to));
        let scale = a.kinetic + a.gravitational.abs() + a.elastic;
        b.total() > a.total() + ENERGY_SLACK * scale
    }

    /// Steps `from` over `job.h` into `into` as two halves, splitting a half again while it
    /// gains energy and `depth < SPLITS`; see [`Pipeline::integrate`].
    fn split(
        &mut self,
        job: &mut Solve,
        from: &Kinematics,
        into: &mut Kinematics,
        depth: u32,
    ) -> bool {
        let (h, time) = (job.h, job.time);
        let n = from.pos.len();
        let slot = depth as usize - 1;
        if self.halves.len() <= slot {
            self.halves.resize_with(slot + 1, || Kinematics::zeros(n));
        }
        let mut mid = std::mem::replace(&mut self.halves[slot], Kinematics::zeros(0));
        job.h = h / 2.0;
        let mut finite = true;
        for (half, end) in [(0, time - (h / 2.0) as f64), (1, time)] {
            job.time = end;
            let (start, out) = if half == 0 {
                (from, &mut mid)
            } else {
                (&mid, &mut *into)
            };
            finite = self.solve(job, start, out, true);
            if !finite {
                break;
            }
            if depth < SPLITS && self.rose(job.model, start, out, job.time) {
                finite = self.split(job, start, out, depth + 1);
            }
        }
        self.halves[slot] = mid;
        job.h = h;
        job.time = time;
        finite
    }

    /// One solve of the integrator from `from` over `job.h` into `into` (contacts predicted
    /// first when `predict`), in rounds while the contacts change: after each, the contacts the
    /// solve pulled in are released and the particles it carried into a collider are held
    /// ([`PredictedContacts::correct`]). Then the contacts' friction.
    fn solve(
        &mut self,
        job: &mut Solve,
        from: &Kinematics,
        into: &mut Kinematics,
        predict: bool,
    ) -> bool {
        let holds = self.holds_contacts();
        if predict && holds {
            self.find_contacts(job, from);
        }
        let mut round = 0;
        let finite = loop {
            round += 1;
            let mut ctx = StepContext {
                grid: job.model.grid,
                current: from,
                next: into,
                particles: &job.model.particles,
                springs: &job.model.springs,
                mesh: job.model.mesh(),
                forces: &mut self.forces,
                force: job.force,
                chunk: job.chunk,
                profile: job.profile,
                contacts: self.contacts.as_ref().filter(|_| holds),
            };
            let finite = self.integrator.step(job.h, &mut ctx);
            let Some(contacts) = self.contacts.as_mut().filter(|_| holds) else {
                break finite;
            };
            if !finite || round == CONTACT_ROUNDS {
                break finite;
            }
            let t = Instant::now();
            let changed = contacts.correct(
                &self.colliders,
                (from, into),
                &job.model.particles,
                (job.h, job.time),
                job.chunk,
            );
            job.profile.add(PredictedContacts::NAME, t.elapsed());
            if changed == 0 {
                break finite;
            }
        };
        if let Some(contacts) = self.contacts.as_ref().filter(|c| holds && c.count > 0) {
            contacts.apply_friction(into, job.h, job.chunk);
        }
        finite
    }

    /// Pushes the cloth with the wind's drag and lift.
    pub fn blow_wind(&mut self, s: &mut Substep) -> bool {
        let Some(wind) = &mut self.wind else {
            return true;
        };
        let t = Instant::now();
        let start = s.time - s.h as f64;
        let finite = wind.apply(s.model, &s.state.kin, s.next, s.h, start);
        s.profile.add(Wind::NAME, t.elapsed());
        finite
    }

    /// Moves the dragged particles to their targets.
    pub fn pin_targets(&mut self, s: &mut Substep) -> bool {
        let targets = &s.state.targets;
        if targets.is_empty() {
            return true;
        }
        let t = Instant::now();
        let next = &mut *s.next;
        let finite = targets.apply(s.h, &s.state.kin.pos, &mut next.pos, &mut next.vel);
        s.profile.add(KinematicPins::NAME, t.elapsed());
        finite
    }

    /// Shortens the springs stretched beyond the limit. After the pins, so that the limit pulls
    /// the cloth after a dragged particle rather than back to where it was; before the
    /// colliders, so that contacts have the last word.
    pub fn limit_strain(&mut self, s: &mut Substep) -> bool {
        let Some(limit) = &mut self.strain_limit else {
            return true;
        };
        let t = Instant::now();
        let (grid, springs, particles) = (s.model.grid, &s.model.springs, &s.model.particles);
        let finite = limit
            .apply(grid, springs, particles, s.next, s.chunk)
            .finite;
        s.profile.add(StrainLimit::NAME, t.elapsed());
        finite
    }

    /// Puts the particles outside every collider, in the scene's order.
    pub fn collide(&mut self, s: &mut Substep) -> bool {
        let mut finite = true;
        for collider in &self.colliders {
            let t = Instant::now();
            let particles = &s.model.particles;
            let (start, time) = (&s.state.kin, (s.h, s.time));
            finite &= collider.resolve(start, s.next, None, particles, s.chunk, time);
            s.profile.add(collider.name(), t.elapsed());
        }
        finite
    }

    /// Keeps the cloth from passing through itself.
    pub fn separate_self_contacts(&mut self, s: &mut Substep) -> bool {
        let Some(contact) = &mut self.self_collision else {
            return true;
        };
        let t = Instant::now();
        let finite = contact.apply(s.model, &s.state.kin, s.next);
        s.profile.add(SelfCollision::NAME, t.elapsed());
        finite
    }

    /// Breaks the springs strained beyond the tearing limit, on the accepted end-of-step
    /// positions.
    pub fn tear(&mut self, model: &mut Model, state: &State, profile: &mut Profile) {
        if let Some(tearing) = &mut self.tearing {
            let t = Instant::now();
            tearing.apply(model, &state.kin.pos);
            profile.add(Tearing::NAME, t.elapsed());
        }
    }

    /// The `[[colliders]]`, when the scene has any.
    pub fn shapes(&self) -> Option<&Shapes> {
        self.colliders.iter().find_map(|c| match c {
            Collider::Shapes(s) => Some(s),
            _ => None,
        })
    }

    pub fn shapes_mut(&mut self) -> Option<&mut Shapes> {
        self.colliders.iter_mut().find_map(|c| match c {
            Collider::Shapes(s) => Some(s),
            _ => None,
        })
    }

    pub fn heap_bytes(&self) -> usize {
        self.forces.heap_bytes()
            + self
                .strain_limit
                .as_ref()
                .map_or(0, StrainLimit::heap_bytes)
            + self
                .self_collision
                .as_ref()
                .map_or(0, SelfCollision::heap_bytes)
            + self.tearing.as_ref().map_or(0, Tearing::heap_bytes)
            + self.wind.as_ref().map_or(0, Wind::heap_bytes)
            + self
                .colliders
                .iter()
                .map(Collider::heap_bytes)
                .sum::<usize>()
            + self
                .contacts
                .as_ref()
                .map_or(0, PredictedContacts::heap_bytes)
            + self
                .halves
                .iter()
                .map(Kinematics::heap_bytes)
                .sum::<usize>()
    }
}

/// The forces of a scene, in the order they are summed; a force that adds nothing is absent.
fn forces_of(scene: &Scene) -> Vec<Force> {
    let mut forces = Vec::new();
    let g = DVec3::from(scene.gravity).as_vec3();
    if g != Vec3::ZERO {
        forces.push(Force::Gravity { g });
    }
    if scene.air_drag > 0.0 {
        forces.push(Force::Drag {
            c: scene.air_drag as f32,
        });
    }
    let cloth = &scene.cloth;
    if cloth.mesh.is_some() {
        // A mesh cloth's springs are its own list, not the stencil's families.
        return forces;
    }
    for (family, k) in [
        (Family::Structural, cloth.k_structural),
        (Family::Shear, cloth.k_shear),
        (Family::Bend, cloth.k_bend),
    ] {
        if k > 0.0 {
            forces.push(Force::Springs {
                family,
                k: k as f32,
                c: cloth.damping as f32,
            });
        }
    }
    forces
}

/// The colliders of a scene: spheres, the shapes, then the floor (last, so that nothing ends
/// below it). The spheres are balls of the shapes' pass, one contact model for every shape; a
/// ball knows the floor's level, so that cloth in the crease where it meets the floor is put
/// outside both.
fn colliders_of(scene: &Scene) -> Vec<Collider> {
    let floor = scene
        .floor
        .as_ref()
        .map(|f| (f.height + f.thickness) as f32);
    let mut colliders = Vec::new();
    if !scene.spheres.is_empty() {
        let balls: Vec<ColliderSpec> = scene.spheres.iter().map(SphereSpec::as_collider).collect();
        colliders.push(Collider::Spheres(Shapes::new(&balls, floor)));
    }
    if !scene.colliders.is_empty() {
        colliders.push(Collider::Shapes(Shapes::new(&scene.colliders, floor)));
    }
    if let Some(floor) = &scene.floor {
        colliders.push(Collider::Floor(Floor {
            height: floor.height as f32,
            friction: floor.friction as f32,
            thickness: floor.thickness as f32,
        }));
    }
    colliders
}
