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
//!
//! Where each lives: `compile.rs` turns a scene into its passes; `solve.rs` is step 2 for an
//! integrator that holds contacts (the rounds, the halving judged by energy, the self-collision
//! rerun); `passes.rs` the passes after it and tearing; this file the pipeline itself and what
//! a substep hands its passes.

mod compile;
mod passes;
mod solve;

use solve::StartEnergy;

use glam::Vec3;

use crate::collisions::{Collider, PredictedContacts, Shapes};
use crate::forces::{Force, ForceModel};
use crate::integrators::Integrator;
use crate::model::Model;
use crate::parallel::chunk_len;
use crate::pins::KinematicPins;
use crate::profile::Profile;
use crate::self_collision::SelfCollision;
use crate::soa::Vec3s;
use crate::state::{Kinematics, State};
use crate::strain_limit::StrainLimit;
use crate::tearing::Tearing;
use crate::wind::Wind;

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
    /// The midpoints of a solve split in halves, one per level (`solve.rs`).
    halves: Vec<Kinematics>,
    /// Where the last piece of a substep's solve split in halves started, and its length (s);
    /// None while the substep's solve was whole. The collider passes after the solve follow
    /// that piece's path, the one its last contact rounds checked, not a straight path from
    /// the substep's start: a particle that went round a ball over two halves would be taken
    /// for one that went through it.
    last_piece: Option<f32>,
    piece_start: Kinematics,
    /// A projective-dynamics solve's result as the colliders' passes would leave it, for its
    /// energy judge (`solve.rs`).
    put_out: Kinematics,
    /// Solves split in halves since the pipeline was compiled.
    pub halved: u64,
    /// Whether the substep's solves and holds are judged against the energy at its start
    /// (`Pipeline::judge_work`), and that energy once something asked for it.
    start_energy: StartEnergy,
    /// Where the passes before self-collision left the particles, for a solver that holds
    /// contacts: what the self-collision pass moved (`Pipeline::hold_self_contacts`).
    unshortened: Vec3s,
    /// What the self-collision pass was given, and trial states of a substep it left with
    /// energy nothing gave it (`Pipeline::keep_contact_passive`).
    pass_input: Kinematics,
    /// Whether the self-collision pass's cap shortened any motion in the last round.
    contact_capped: bool,
    /// The last round's draw-back once sized: None inside when it keeps the whole motion.
    draw_back: Option<Option<f32>>,
    trial: Kinematics,
    moved_first: Kinematics,
    /// The current integrator's estimated stable substep (s), None when any is; computed when
    /// first needed and forgotten when the integrator or the masses change.
    pub stable_substep: Option<Option<f64>>,
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
    /// The passes a step runs, in order (kinematic pins only while a target is set); a mesh
    /// cloth's springs are added after the force model's sweep.
    pub fn effects(&self, model: &Model, state: &State) -> Vec<&'static str> {
        let mut out: Vec<&'static str> = self.forces.forces().iter().map(Force::name).collect();
        if let Some(mesh) = model.mesh() {
            out.push(crate::forces::MESH_SPRINGS);
            if mesh.membrane.is_some() {
                out.push(crate::forces::MESH_MEMBRANE);
            }
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

    /// Where the colliders posed at `time` (s), in the order the step runs them (the floor
    /// last), put a particle that moved from `from` to `to` and stays.
    pub fn push_out(&self, from: Vec3, to: Vec3, time: f64) -> Vec3 {
        self.colliders
            .iter()
            .fold(to, |to, c| c.push_out(from, to, time))
    }

    /// The deepest contact the colliders posed at `time` (s) make with a particle that moved
    /// from `from` to `to`, each tested on that path alone: the outward normal and where that
    /// collider puts the particle, of the one that puts it farthest along its normal.
    pub fn contact(&self, from: Vec3, to: Vec3, time: f64) -> Option<(Vec3, Vec3)> {
        let contacts = self
            .colliders
            .iter()
            .filter_map(|c| c.contact(from, to, time));
        crate::collisions::deepest(to, contacts)
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
            + [
                &self.pass_input,
                &self.trial,
                &self.moved_first,
                &self.put_out,
            ]
            .iter()
            .map(|k| k.pos.heap_bytes() + k.vel.heap_bytes())
            .sum::<usize>()
    }
}

#[cfg(test)]
mod tests;
