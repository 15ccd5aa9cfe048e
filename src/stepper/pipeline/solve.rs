//! The integrator's solve with contacts held inside it, judged by its energy.
//!
//! For an integrator that holds contacts (implicit Euler, projective dynamics), a substep's
//! solve is:
//!
//! 1. the contacts each particle's free motion would make ([`Pipeline::predict_contacts`]);
//! 2. the solve, in rounds while the contacts change: after each, the contacts it pulled in are
//!    released and the particles it carried into a collider are held, at most
//!    [`CONTACT_ROUNDS`] times ([`Pipeline::solve`]); a round that may be followed by another
//!    stops at implicit Euler's loose pair-finding solve, finished only where the contacts
//!    stayed ([`crate::integrators::StepContext::may_stop_loose`]);
//! 3. where nothing does work on the cloth ([`Pipeline::judge_work`]) and the solve ended with
//!    more energy than it started with (for projective dynamics, also as the colliders' passes
//!    after it would leave it, [`Pipeline::put_out_gains`]), the same again as two halves, each
//!    judged the same way, down to `1 / 2^SPLITS` of the substep ([`Pipeline::solve_judged`]);
//! 4. after the passes that follow the integrator, where the self-collision pass moved particles
//!    and the substep gained energy, the passes once more, the solve holding each particle where
//!    the pass left it ([`Pipeline::hold_self_contacts`]); for projective dynamics, and for
//!    implicit Euler holding the self-contact pairs inside its solve, in one round, the first
//!    solve's rounds having settled the colliders' contacts ([`contact_rounds`]).

use std::time::Instant;

use glam::{DVec3, Vec3};

use super::{Pipeline, Substep};
use crate::collisions::PredictedContacts;
use crate::diagnostics::{energy_of, Energy};
use crate::integrators::{SelfPairs, StepContext};
use crate::model::Model;
use crate::profile::Profile;
use crate::scene::IntegratorKind;
use crate::self_collision::SelfCollision;
use crate::soa::Vec3s;
use crate::state::{Kinematics, State};

/// How many times at most an implicit solve runs in a substep with contacts: after each, the
/// contacts it pulled in are released and the particles it carried into a collider are held,
/// and the solve runs again while that changed anything. A contact set still changing after
/// the last round leaves its few particles to the collider passes after the solve. A resting
/// pile's set changes in every round (a few particles released, then held again), so this is
/// what most of its solves cost: 3 keeps every case of `benches/contact_energy.py` from
/// gaining energy, 2 let projective dynamics gain 5 % on the pile dropped 40 cm at 1/60 s.
pub(super) const CONTACT_ROUNDS: u32 = 3;

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

/// How many times at most the solve of a rerun holding the self-collision pass's particles runs
/// with an integrator whose contacts only push, or whose solve holds the self-contact pairs
/// apart as well ([`contact_rounds`]). Its contact set is the one the first solve's rounds
/// settled, plus those holds; further rounds mostly release holds the solve left ahead of their
/// planes, which changes nothing the solve converges to, at a whole solve each: 1.7 of
/// projective dynamics' 4.6 solves a step on the `pile` dropped 10 cm at 1/60 s. With 3, one
/// such rerun (the pile dropped 40 cm at 1/60 s) ended 8 % above its substep's start energy;
/// with 1, every rerun of `tests/test_contact_energy.py`'s landings ends below it. Implicit
/// Euler's rerun is an implicit step of two solves (the loose pair-finding one and its finish):
/// newton's wound twist at two steps a frame takes up to 8 solves a step with 3 rounds, 4 with
/// 1, for 0.83 of the CPU time over its first 3 s (`docs/notes/contact.md`, "rerunkeep").
const RERUN_ROUNDS: u32 = 1;

/// The fraction of a substep's motion below which a substep that does work and that the energy
/// guard would draw back ([`Pipeline::keep_contact_passive`]) runs its passes again, the solve
/// holding the particles the self-collision pass moved. Above it the draw-back alone is kept.
const RERUN_KEPT: f32 = 0.5;

/// How many times at most the solve of round `round` (from 0) of a substep's passes runs while
/// its contacts change, for an integrator of `kind` whose solve holds the self-contact pairs
/// ahead of it apart where `pairs_in_solve`.
///
/// A projective-dynamics contact is the term `w_c/2 |x - P(x)|^2`, zero on the plane's outer
/// side: a hold ahead of its plane exerts nothing where the iteration converges, and releasing
/// it changes nothing but the cost. Implicit Euler holds a contact exactly, pulling as well as
/// pushing, so a hold its rerun left ahead of its plane keeps its vertex there to the
/// substep's end. Where its solve holds the pairs apart too, that vertex is not all that keeps
/// the layers apart, and one round is kept (what it costs and what it changes is measured in
/// `docs/notes/contact.md`, "rerunkeep"). Without the pairs the holds are all that keep the pass's
/// vertices apart in the solve, and the rerun settles them in rounds: with one,
/// `a_long_step_twist_without_the_in_solve_term_does_not_tear_itself_apart`
/// (`tests/self_collision.rs`) stretched past its bound.
fn contact_rounds(kind: IntegratorKind, round: u32, pairs_in_solve: bool) -> u32 {
    match (round, kind) {
        (0, _) => CONTACT_ROUNDS,
        (_, IntegratorKind::ProjectiveDynamics) => RERUN_ROUNDS,
        (_, IntegratorKind::ImplicitEuler) if pairs_in_solve => RERUN_ROUNDS,
        _ => CONTACT_ROUNDS,
    }
}

/// Whether the total energy `end` is above `start` by more than the rounding of float32
/// positions and speeds can explain ([`ENERGY_SLACK`] of the energies' sum at the start).
pub(super) fn gained(start: Energy, end: Energy) -> bool {
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
    /// How many times at most it runs while its contacts change ([`Pipeline::solve`]).
    rounds: u32,
}

/// Whether a solve's values are all finite, and the energy at its end where it was evaluated.
type Judged = (bool, Option<Energy>);

/// The energy a substep's solves and holds are judged against: that of the state it starts
/// from, taken the first time a judge needs it (a quiet substep holds nothing and needs none).
#[derive(Clone, Copy, Debug)]
pub(super) enum StartEnergy {
    /// Nothing of this substep is judged: no solver holds contacts, or something does work.
    Unjudged,
    /// Judged, not yet asked for.
    Untaken,
    Taken(Energy),
}

/// What a solve is judged against: nothing, the substep's start (taken on demand), or a
/// known energy (the start of a half).
#[derive(Clone, Copy)]
enum Judge {
    No,
    SubstepStart,
    Known(Energy),
}

impl Pipeline {
    /// Whether this substep's integrator holds the predicted contacts inside its solve.
    pub(super) fn holds_contacts(&self) -> bool {
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
        // An exact constraint (one that reports its impulses) can hold a sticking contact in
        // all three directions inside the solve.
        let sticks = self.integrator.contact_impulses().is_some();
        let particles = &model.particles;
        contacts.find(&self.colliders, from, particles, g, span, chunk, sticks);
        profile.add(PredictedContacts::NAME, t.elapsed());
    }

    /// Keeps the energy at the substep's start where a solver holds contacts and nothing does
    /// work on the cloth ([`Pipeline::does_work`]), None elsewhere: what every solve of the
    /// substep (each round of its passes, each half) is judged against. Once per substep,
    /// before its first round.
    pub fn judge_work(&mut self, s: &Substep) {
        let idle = self.holds_contacts() && !self.does_work(s.model, s.state, (s.h, s.time));
        self.start_energy = if idle {
            StartEnergy::Untaken
        } else {
            StartEnergy::Unjudged
        };
    }

    /// The energy of `start`, the state the substep starts from, where the substep is judged
    /// ([`Pipeline::judge_work`]); taken once a substep.
    fn start_energy(&mut self, model: &Model, start: &Kinematics) -> Option<Energy> {
        match self.start_energy {
            StartEnergy::Unjudged => None,
            StartEnergy::Taken(energy) => Some(energy),
            StartEnergy::Untaken => {
                let energy = energy_of(model, start);
                self.start_energy = StartEnergy::Taken(energy);
                Some(energy)
            }
        }
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

    /// The integrator's step into `s.next` in round `round` (from 0) of the substep's passes,
    /// with the predicted contacts' friction; returns whether every value it wrote is finite.
    /// Arms the force loop's stretch watch, read after it by
    /// [`crate::forces::ForceModel::overstretched`].
    ///
    /// A solve holding contacts that ends with more energy than it started with is run again
    /// as two halves ([`Pipeline::solve_judged`]). A landing at a long step moves a row a
    /// spring's length or more into the rows that already landed; the solve's springs are
    /// linearised at the step's start, where a compressed spring has no sideways stiffness,
    /// and their true energy at the end can be joules above what the linear model traded for
    /// (the `pile` dropped 40 cm at 1/60 s: 3.2 J of elastic energy from one solve). Where
    /// nothing does work on the cloth ([`Pipeline::rose`]) the rise is the linearisation's
    /// error, and shorter solves shrink it (at 1/120 s and 1/240 s the same drops gain
    /// nothing).
    pub fn integrate(&mut self, s: &mut Substep, force: &mut Vec3s, round: u32) -> bool {
        let started = Instant::now();
        let forces_before = s.profile.force_time;
        let pairs_in_solve = self.self_collision.as_ref().is_some_and(|p| p.in_solve());
        let mut job = Solve {
            model: s.model,
            h: s.h,
            time: s.time,
            chunk: s.chunk,
            profile: &mut *s.profile,
            force,
            rounds: contact_rounds(self.integrator.kind(), round, pairs_in_solve),
        };
        // The watch judges the state the substep starts from: the first force evaluation of
        // this solve, not a later round's or a half's, which start elsewhere.
        self.forces.arm_stretch_watch();
        self.forces.set_time(s.time - s.h as f64);
        let judge = match self.start_energy {
            StartEnergy::Unjudged => Judge::No,
            _ => Judge::SubstepStart,
        };
        self.last_piece = None;
        let (finite, _) = self.solve_judged(&mut job, (&s.state.kin, s.next), false, judge, 0);
        let own_time = started
            .elapsed()
            .saturating_sub(s.profile.force_time - forces_before);
        s.profile.add(self.integrator.name(), own_time);
        finite
    }

    /// The energy at the end of a solve from `from` into `into` (`job`'s span), or None when
    /// it is above the energy `start` at its start by more than the rounding of float32
    /// positions and speeds can explain, with contacts held; for projective dynamics, also
    /// when the colliders' passes after the solve would leave it so ([`Pipeline::put_out_gains`]).
    /// Called only where nothing does work on the cloth ([`Pipeline::does_work`]).
    fn rose(
        &mut self,
        job: &Solve,
        (from, into): (&Kinematics, &Kinematics),
        start: Energy,
    ) -> Option<Energy> {
        let end = energy_of(job.model, into);
        let held = self.contacts.as_ref().is_some_and(|c| c.count > 0);
        let rose = held && (gained(start, end) || self.put_out_gains(job, (from, into), start));
        (!rose).then_some(end)
    }

    /// Whether the colliders' passes, run on a projective-dynamics solve's result `into` as the
    /// substep will run them after it, leave more energy than `start`.
    ///
    /// Projective dynamics holds a contact by a penalty, and settles its contacts in
    /// [`CONTACT_ROUNDS`] rounds: at a hard landing the set still changes at the last one (a
    /// landing particle left ahead of its plane is released, and the last solve carries it
    /// centimetres into the floor). The passes after the solve then put such particles back
    /// on the surface with their springs crushed: the `pile` dropped 1 m at 1/60 s without
    /// self-collision gained 2.6 J (18 % of the step's start energy) in its landing step that
    /// way, which with self-collision its cap hid by stopping the whole cloth. Judged with the
    /// solve, such a result is solved again in halves, whose shorter paths go less far into
    /// the floor. Implicit Euler's exact contacts leave those passes little to do (under
    /// 0.03 J a substep on the same drops), and its scenes step as they did.
    fn put_out_gains(
        &mut self,
        job: &Solve,
        (from, into): (&Kinematics, &Kinematics),
        start: Energy,
    ) -> bool {
        if self.integrator.kind() != IntegratorKind::ProjectiveDynamics {
            return false;
        }
        if self.put_out.pos.len() != into.pos.len() {
            self.put_out = Kinematics::zeros(into.pos.len());
        }
        self.put_out.copy_from(into);
        let particles = &job.model.particles;
        for collider in &self.colliders {
            collider.resolve(
                from,
                &mut self.put_out,
                None,
                particles,
                job.chunk,
                (job.h, job.time),
            );
        }
        gained(start, energy_of(job.model, &self.put_out))
    }

    /// Steps `from` over `job.h` into `into` (contacts predicted first when `predict`): the
    /// whole solve, and, when it is judged (`judge`: the energy at `from`) and gained energy,
    /// two halves instead ([`Pipeline::in_halves`]). `depth` is how many times this solve's
    /// span was halved already.
    fn solve_judged(
        &mut self,
        job: &mut Solve,
        (from, into): (&Kinematics, &mut Kinematics),
        predict: bool,
        judge: Judge,
        depth: u32,
    ) -> Judged {
        let finite = self.solve(job, from, into, predict);
        // A solve that held no contact is not judged ([`Pipeline::rose`]).
        let held = self.contacts.as_ref().is_some_and(|c| c.count > 0);
        if !(finite && held) {
            return (finite, None);
        }
        let start = match judge {
            Judge::No => return (finite, None),
            Judge::SubstepStart => self.start_energy(job.model, from),
            Judge::Known(energy) => Some(energy),
        };
        let Some(start) = start else {
            return (finite, None);
        };
        match self.rose(job, (from, into), start) {
            Some(end) => (true, Some(end)),
            None => self.in_halves(job, (from, into), start, depth + 1),
        }
    }

    /// Steps `from` (whose energy is `start`) over `job.h` into `into` as two halves, each
    /// judged as a whole solve is while `depth < SPLITS` (so halved again while it gains
    /// energy), and taken as it comes at the last level.
    fn in_halves(
        &mut self,
        job: &mut Solve,
        (from, into): (&Kinematics, &mut Kinematics),
        start: Energy,
        depth: u32,
    ) -> Judged {
        self.halved += 1;
        let (h, time, rounds) = (job.h, job.time, job.rounds);
        // Each half predicts its own contacts, and settles them in rounds.
        job.rounds = CONTACT_ROUNDS;
        let mut mid = self.take_half(depth, from.pos.len());
        let judged = depth < SPLITS;
        job.h = h / 2.0;
        job.time = time - (h / 2.0) as f64;
        let first = if judged {
            Judge::Known(start)
        } else {
            Judge::No
        };
        let (mut finite, at_mid) = self.solve_judged(job, (from, &mut mid), true, first, depth);
        let mut end = None;
        if finite {
            job.time = time;
            // A second half halved again sets its own last piece after this.
            self.last_piece = Some(job.h);
            if self.piece_start.pos.len() != mid.pos.len() {
                self.piece_start = Kinematics::zeros(mid.pos.len());
            }
            self.piece_start.copy_from(&mid);
            let second = if judged {
                Judge::Known(at_mid.unwrap_or_else(|| energy_of(job.model, &mid)))
            } else {
                Judge::No
            };
            (finite, end) = self.solve_judged(job, (&mid, into), true, second, depth);
        }
        self.halves[depth as usize - 1] = mid;
        (job.h, job.time, job.rounds) = (h, time, rounds);
        (finite, end)
    }

    /// The buffer for the midpoint of a solve halved `depth` times (from 1), taken out of
    /// `halves` until [`Pipeline::in_halves`] puts it back.
    fn take_half(&mut self, depth: u32, n: usize) -> Kinematics {
        let slot = depth as usize - 1;
        if self.halves.len() <= slot {
            self.halves.resize_with(slot + 1, || Kinematics::zeros(n));
        }
        std::mem::replace(&mut self.halves[slot], Kinematics::zeros(0))
    }

    /// One solve of the integrator from `from` over `job.h` into `into` (contacts predicted
    /// first when `predict`), in rounds while the contacts change, `job.rounds` at most: after
    /// each, the contacts the solve pulled in are released and the particles it carried into a
    /// collider are held ([`PredictedContacts::correct`]). Then the sliding contacts' friction.
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
        let kind = self.integrator.kind();
        let mut self_pairs = pairs_ahead(&mut self.self_collision, kind, job, from);
        let mut round = 0;
        // Set once a round's loose step found its contacts unchanged: that step is finished.
        let mut finishing = false;
        let finite = loop {
            // A round whose contacts are corrected after it, and solved again where they
            // changed, needs only to show where the step goes; without a collider or a hold
            // there is nothing to correct.
            let correctable =
                (self.contacts.as_ref()).is_some_and(|c| c.count > 0 || !self.colliders.is_empty());
            let may_stop_loose = holds && correctable && !finishing && round + 1 < job.rounds;
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
                self_pairs,
                may_stop_loose,
            };
            let finite = if finishing {
                self.integrator.finish_loose(job.h, &mut ctx)
            } else {
                self.integrator.step(job.h, &mut ctx)
            };
            if self_pairs.is_some_and(|p| p.asked()) {
                // The solve moved farther than the pairs left out allowed for: the same step
                // again with them, as if they had been given.
                self_pairs = given_pairs_ahead(&mut self.self_collision, job, from);
                finishing = false;
                continue;
            }
            if finishing {
                break finite;
            }
            round += 1;
            let Some(contacts) = self.contacts.as_mut().filter(|_| holds) else {
                break finite;
            };
            if !finite || round >= job.rounds {
                break finite;
            }
            let t = Instant::now();
            let changed = contacts.correct(
                &self.colliders,
                (from, into),
                self.integrator.contact_impulses(),
                &job.model.particles,
                (job.h, job.time),
                job.chunk,
            );
            job.profile.add(PredictedContacts::NAME, t.elapsed());
            if changed == 0 {
                if self.integrator.stopped_loose() {
                    finishing = true;
                    continue;
                }
                break finite;
            }
        };
        if let Some(contacts) = self.contacts.as_ref().filter(|c| holds && c.count > 0) {
            contacts.apply_friction(into, job.h, job.chunk);
        }
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
        // A pass that moved nothing leaves nothing to hold: no energy to weigh (a quiet cloth).
        let (before, after) = (&self.unshortened, &s.next.pos);
        if (0..after.len()).all(|p| after.get(p) == before.get(p)) {
            return false;
        }
        // Where something does work, only a substep the energy guard would draw back by more
        // than [`RERUN_KEPT`] is run again: a smaller draw-back costs less than a second
        // solve, and a larger one stops the cloth where it stood (a grip held by its own
        // cloth froze mid-drag, every substep drawn back to its start).
        let gain = match self.start_energy(s.model, &s.state.kin) {
            Some(start) => gained(start, energy_of(s.model, s.next)),
            None => self
                .passive_fraction(s)
                .is_some_and(|kept| kept < RERUN_KEPT),
        };
        let Some(contacts) = self.contacts.as_mut().filter(|_| gain) else {
            return false;
        };
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
}

/// The self-collision pairs ahead of a solve from `from`, for implicit Euler (`kind`), on a grid
/// or a mesh cloth, with `self_collision.solve_stiffness` (`src/integrators/self_contact.rs`);
/// None otherwise. Timed as the self-collision pass.
fn pairs_ahead<'p>(
    pass: &'p mut Option<SelfCollision>,
    kind: IntegratorKind,
    job: &mut Solve,
    from: &Kinematics,
) -> Option<SelfPairs<'p>> {
    let pass = pass.as_mut().filter(|p| p.in_solve())?;
    if kind != IntegratorKind::ImplicitEuler {
        return None;
    }
    let t = Instant::now();
    pass.pairs_ahead(job.model, from, job.h);
    job.profile.add(SelfCollision::NAME, t.elapsed());
    Some(given_to_the_solve(pass))
}

/// The pairs ahead of a solve from `from` that [`pairs_ahead`] left out, for the step to be
/// solved again with them. Timed as the self-collision pass.
fn given_pairs_ahead<'p>(
    pass: &'p mut Option<SelfCollision>,
    job: &mut Solve,
    from: &Kinematics,
) -> Option<SelfPairs<'p>> {
    let pass = pass.as_mut()?;
    let t = Instant::now();
    pass.give_pairs_ahead(from);
    job.profile.add(SelfCollision::NAME, t.elapsed());
    Some(given_to_the_solve(pass))
}

/// What `pass`'s last pairs ahead give the solve: the pairs, and what it left out of them.
fn given_to_the_solve(pass: &SelfCollision) -> SelfPairs<'_> {
    SelfPairs {
        pairs: pass.pairs_ahead_given(),
        thickness: pass.thickness,
        stiffness: pass.solve_stiffness,
        apart: pass.ahead_apart().map(|apart| (apart, pass)),
    }
}
