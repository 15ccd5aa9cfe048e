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
//!    both ends of that path) stays satisfied. For a solver that holds contacts, the passes
//!    from 2 on run once more when it moved a particle, the solve holding each one where the
//!    pass left it ([`Pipeline::hold_self_contacts`]).
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
use crate::diagnostics::{energy_of, Energy};
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
/// the last round leaves its few particles to the collider passes after the solve. A resting
/// pile's set changes in every round (a few particles released, then held again), so this is
/// what most of its solves cost: 3 keeps every case of `benches/contact_energy.py` from
/// gaining energy, 2 let projective dynamics gain 5 % on the pile dropped 40 cm at 1/60 s.
const CONTACT_ROUNDS: u32 = 3;

/// How many times at most a solve holding contacts that gained energy is halved
/// ([`Pipeline::integrate`]): down to an eighth of the substep.
const SPLITS: u32 = 3;

/// The energy rise a solve may show before it is split, as a fraction of the energies' sum
/// `K + |G| + E` at its start: float32 positions near 1 m round at 6e-8 m, so the sum of
/// potential energies is known to about 1e-7 of that scale; ten times more is noise-proof and
/// still a thousandth of the smallest gain measured from a landing.
const ENERGY_SLACK: f64 = 1e-6;

/// How many times at most a substep's passes run, the solve after the first holding the
/// particles the self-collision pass moved ([`Pipeline::hold_self_contacts`]).
const SELF_ROUNDS: u32 = 2;

/// Whether the total energy `end` is above `start` by more than the rounding of float32
/// positions and speeds can explain ([`ENERGY_SLACK`] of the energies' sum at the start).
fn gained(start: Energy, end: Energy) -> bool {
    let scale = start.kinetic + start.gravitational.abs() + start.elastic;
    end.total() > start.total() + ENERGY_SLACK * scale
}

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
    /// The midpoints of a solve split in halves, one per level ([`Pipeline::integrate`]).
    halves: Vec<Kinematics>,
    /// Solves split in halves since the pipeline was compiled.
    pub halved: u64,
    /// The energy at the substep's start, where a solver holds contacts and nothing does work
    /// on the cloth ([`Pipeline::does_work`]); None otherwise.
    start_energy: Option<Energy>,
    /// Where the passes before self-collision left the particles, for a solver that holds
    /// contacts: what the self-collision pass moved ([`Pipeline::hold_self_contacts`]).
    unshortened: Vec3s,
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
            contacts: (!colliders.is_empty() || scene.self_collision.is_some())
                .then(|| PredictedContacts::new(particles)),
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
            halves: Vec::new(),
            halved: 0,
            start_energy: None,
            unshortened: Vec3s::zeros(0),
        }
    }

    /// The passes a step runs, in order (kinematic pins only while a target is set); a mesh
    /// cloth's springs are added after the force model's sweep.
    pub fn effects(&self, model: &Model, state: &State) -> Vec<&'static str> {
        let mut out: Vec<&'static str> = self.forces.forces().iter().map(Force::name).collect();
        if model.mesh().is_some() {
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
        if self.holds_contacts() {
            let span = (s.h, s.time);
            self.find_contacts(s.model, &s.state.kin, span, s.chunk, s.profile);
        }
    }

    /// The contacts of a solve from `from` over `(h, time)`: its length and the time at its end.
    fn find_contacts(
        &mut self,
        model: &Model,
        from: &Kinematics,
        span: (f32, f64),
        chunk: usize,
        profile: &mut Profile,
    ) {
        let Some(contacts) = self.contacts.as_mut() else {
            return;
        };
        let t = Instant::now();
        let g = DVec3::from(model.scene.gravity).as_vec3();
        contacts.find(&self.colliders, from, &model.particles, g, span, chunk);
        profile.add(PredictedContacts::NAME, t.elapsed());
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
        let mut finite = self.solve(&mut job, from, s.next, false);
        if let (true, Some(start)) = (finite, self.start_energy) {
            if self.rose(start, || energy_of(model, s.next)).is_none() {
                finite = self.split(&mut job, from, start, s.next, 1).0;
            }
        }
        let own_time = started
            .elapsed()
            .saturating_sub(s.profile.force_time - forces_before);
        s.profile.add(self.integrator.name(), own_time);
        finite
    }

    /// Keeps the energy at the substep's start where a solver holds contacts and nothing does
    /// work on the cloth ([`Pipeline::does_work`]), None elsewhere: what every solve of the
    /// substep (each round of its passes, each half) is judged against. Once per substep,
    /// before its first round.
    pub fn judge_work(&mut self, s: &Substep) {
        let idle = self.holds_contacts() && !self.does_work(s.model, s.state, (s.h, s.time));
        self.start_energy = idle.then(|| energy_of(s.model, &s.state.kin));
    }

    /// Whether something may do work on the cloth within the substep of length `h` ending at
    /// `time`, from `state`: a collider moving at its start or end, a kinematic pin's target,
    /// or a pinned particle moving (a pin dragged in the step before). Such a substep adds
    /// energy rightly and is never split for it; judged once per substep, for all its halves.
    fn does_work(&self, model: &Model, state: &State, (h, time): (f32, f64)) -> bool {
        let start = time - h as f64;
        if (self.colliders.iter()).any(|c| c.moves(time) || c.moves(start)) {
            return true;
        }
        let (pinned, vel) = (&model.particles.pinned, &state.kin.vel);
        !state.targets.is_empty()
            || (0..pinned.len()).any(|p| pinned[p] && vel.get(p) != Vec3::ZERO)
    }

    /// The energy at a solve's end (`end` evaluated), or None when it is above the energy
    /// `start` at its start by more than the rounding of float32 positions and speeds can
    /// explain, with contacts held. Called only where nothing does work on the cloth
    /// ([`Pipeline::does_work`]).
    fn rose(&self, start: Energy, end: impl FnOnce() -> Energy) -> Option<Energy> {
        let end = end();
        let held = self.contacts.as_ref().is_some_and(|c| c.count > 0);
        (!(held && gained(start, end))).then_some(end)
    }

    /// Steps `from` (whose energy is `energy`) over `job.h` into `into` as two halves,
    /// splitting a half again while it gains energy and `depth < SPLITS`; see
    /// [`Pipeline::integrate`]. Returns whether every value is finite, and the energy at
    /// `into` when it was evaluated.
    fn split(
        &mut self,
        job: &mut Solve,
        from: &Kinematics,
        energy: Energy,
        into: &mut Kinematics,
        depth: u32,
    ) -> (bool, Option<Energy>) {
        self.halved += 1;
        let (h, time) = (job.h, job.time);
        let n = from.pos.len();
        let slot = depth as usize - 1;
        if self.halves.len() <= slot {
            self.halves.resize_with(slot + 1, || Kinematics::zeros(n));
        }
        let mut mid = std::mem::replace(&mut self.halves[slot], Kinematics::zeros(0));
        job.h = h / 2.0;
        let (mut finite, mut at_start) = (true, Some(energy));
        for (half, end) in [(0, time - (h / 2.0) as f64), (1, time)] {
            job.time = end;
            let (start, out) = if half == 0 {
                (from, &mut mid)
            } else {
                (&mid, &mut *into)
            };
            finite = self.solve(job, start, out, true);
            if !finite || depth == SPLITS {
                at_start = None;
                if !finite {
                    break;
                }
                continue;
            }
            let model = job.model;
            let start_energy = at_start.unwrap_or_else(|| energy_of(model, start));
            at_start = match self.rose(start_energy, || energy_of(model, out)) {
                Some(end) => Some(end),
                None => {
                    let (ok, end) = self.split(job, start, start_energy, out, depth + 1);
                    finite = ok;
                    if !finite {
                        break;
                    }
                    end
                }
            };
        }
        self.halves[slot] = mid;
        job.h = h;
        job.time = time;
        (finite, at_start)
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
            let span = (job.h, job.time);
            self.find_contacts(job.model, from, span, job.chunk, job.profile);
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
        if self.contacts.is_some() && self.integrator.kind().holds_contacts() {
            let n = s.next.pos.len();
            if self.unshortened.len() != n {
                self.unshortened = Vec3s::zeros(n);
            }
            self.unshortened.copy_from(&s.next.pos);
        }
        let finite = contact.apply(s.model, &s.state.kin, s.next);
        s.profile.add(SelfCollision::NAME, t.elapsed());
        finite
    }

    /// After round `round` (from 0) of a substep's passes, holds inside the solve the particles
    /// the self-collision pass moved, and returns whether the substep must run again.
    ///
    /// Self-collision runs after the solve and shortens motion: at a display-frame step it
    /// stops a vertex of a landing layer a spring's length short of where its neighbours go,
    /// and the springs between them hold joules the solve never traded for (the `pile` dropped
    /// 10 cm at 1/60 s with projective dynamics: +0.6 J in one substep, +4 % over the drop).
    /// Held on the plane through where the pass left it, normal to the pass's correction (the
    /// side it pushed toward is free), a vertex stops within the solve, and its springs slow
    /// its neighbours there instead of straining. The pass then runs again on the new result.
    /// Only where it matters: where nothing does work on the cloth and the substep ended with
    /// more energy than it started with (by more than rounding, [`gained`]).
    pub fn hold_self_contacts(&mut self, s: &Substep, round: u32) -> bool {
        if round + 1 >= SELF_ROUNDS || self.self_collision.is_none() || !self.holds_contacts() {
            return false;
        }
        let (Some(start), Some(contacts)) = (self.start_energy, self.contacts.as_mut()) else {
            return false;
        };
        if !gained(start, energy_of(s.model, s.next)) {
            return false;
        }
        let (before, after) = (&self.unshortened, &s.next.pos);
        let mut held = false;
        for p in 0..after.len() {
            let push = after.get(p) - before.get(p);
            let length = push.length();
            if length > 0.0 && length.is_finite() {
                held |= contacts.hold(p, push / length, after.get(p));
            }
        }
        held
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
            + self.unshortened.heap_bytes()
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
