//! The cheap passes after the integrator, each a change of the substep's result: wind, kinematic
//! pins, strain limiting, colliders, self-collision; and tearing, after a whole step.

use std::time::Instant;

use super::{Pipeline, Substep};
use crate::model::Model;
use crate::pins::KinematicPins;
use crate::profile::Profile;
use crate::self_collision::SelfCollision;
use crate::soa::Vec3s;
use crate::state::State;
use crate::stepper::watchdog;
use crate::strain_limit::StrainLimit;
use crate::tearing::Tearing;
use crate::wind::Wind;

use super::solve::gained;
use crate::diagnostics::{energy_of, Energy};
use crate::state::Kinematics;

/// How many times at most a substep the self-collision pass left with energy nothing gave it is
/// drawn halfway back along its paths before it is put back at its start at rest.
const DRAW_BACK_HALVINGS: u32 = 6;

impl Pipeline {
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
        let finite = targets.apply(s.h, s.time, &s.state.kin.pos, &mut next.pos, &mut next.vel);
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
        let finite = match s.model.mesh() {
            Some(mesh) => limit.apply_mesh((grid, springs), mesh, particles, s.next, s.chunk),
            None => limit.apply(grid, springs, particles, s.next, s.chunk),
        }
        .finite;
        s.profile.add(StrainLimit::NAME, t.elapsed());
        finite
    }

    /// Puts the particles outside every collider, in the scene's order, along the path of
    /// the last piece of the solve (`Pipeline::last_piece`).
    pub fn collide(&mut self, s: &mut Substep) -> bool {
        let mut finite = true;
        for collider in &self.colliders {
            let t = Instant::now();
            let particles = &s.model.particles;
            let (start, time) = match self.last_piece {
                Some(h) => (&self.piece_start, (h, s.time)),
                None => (&s.state.kin, (s.h, s.time)),
            };
            finite &= collider.resolve(start, s.next, None, particles, s.chunk, time);
            s.profile.add(collider.name(), t.elapsed());
        }
        finite
    }

    /// Keeps the cloth from passing through itself; for a solver that holds contacts, keeps
    /// where the particles were before, for [`Pipeline::hold_self_contacts`].
    pub fn separate_self_contacts(&mut self, s: &mut Substep) -> bool {
        let holds = self.holds_contacts();
        let Some(contact) = &mut self.self_collision else {
            return true;
        };
        let t = Instant::now();
        if holds {
            let n = s.next.pos.len();
            if self.unshortened.len() != n {
                self.unshortened = Vec3s::zeros(n);
            }
            self.unshortened.copy_from(&s.next.pos);
        }
        let before = contact.stats();
        let finite = contact.apply(s.model, &s.state.kin, s.next);
        let after = contact.stats();
        let acted = (after.contacts, after.capped) != (before.contacts, before.capped);
        if finite && acted && self.wind.is_none() && !self.colliders_move(s) {
            self.keep_contact_passive(s);
        }
        s.profile.add(SelfCollision::NAME, t.elapsed());
        finite
    }

    /// Whether a collider moves at the substep's start or end (it then does work on the cloth).
    fn colliders_move(&self, s: &Substep) -> bool {
        let start = s.time - s.h as f64;
        (self.colliders.iter()).any(|c| c.moves(s.time) || c.moves(start))
    }

    /// Keeps the self-collision pass from leaving energy in the cloth that nothing gave it.
    ///
    /// The cap stops each vertex short where its move would cross the cloth, so the result
    /// mixes vertices near their start with vertices where the solve sent them, and the springs
    /// between the two can end stretched more than in either; solved again and capped again,
    /// a cloth held by a grip climbed from 5.6 J to 45.6 J in twelve frames with no work done
    /// on it (docs/garments.md). The pass's result `x` lies on straight paths from the
    /// substep's start `x0` that it checked, so every `x0 + s (x - x0)`, `0 <= s <= 1`, with
    /// velocities `s v`, is as uncrossed, and `s = 0` has at most the start's energy. Where
    /// the result's energy is above the start's plus the held particles' work (the mean of
    /// moving them first and moving them last), `s` is halved until it is not.
    fn keep_contact_passive(&mut self, s: &mut Substep) {
        let (model, start_kin) = (s.model, &s.state.kin);
        let start = energy_of(model, start_kin);
        let end = energy_of(model, s.next);
        if !gained(start, end) {
            return;
        }
        let n = start_kin.pos.len();
        if self.trial.pos.len() != n {
            self.trial = Kinematics::zeros(n);
        }
        let (w, alive) = (&model.particles.inv_mass, &model.particles.alive);
        let held = |p: usize| w[p] == 0.0 && alive[p];
        // The held particles moved last (from the result with them at their start) and first
        // (from the start with them at their end).
        self.trial.copy_from(s.next);
        for p in (0..n).filter(|&p| held(p)) {
            self.trial.pos.set(p, start_kin.pos.get(p));
            self.trial.vel.set(p, start_kin.vel.get(p));
        }
        let last = end.total() - energy_of(model, &self.trial).total();
        self.trial.copy_from(start_kin);
        for p in (0..n).filter(|&p| held(p)) {
            self.trial.pos.set(p, s.next.pos.get(p));
            self.trial.vel.set(p, s.next.vel.get(p));
        }
        let first = energy_of(model, &self.trial).total() - start.total();
        let work = (0.5 * (last + first)).max(0.0);
        let allowed = Energy {
            elastic: start.elastic + work,
            ..start
        };
        if !gained(allowed, end) {
            return;
        }
        let mut scale = 1.0f32;
        for _ in 0..DRAW_BACK_HALVINGS {
            scale *= 0.5;
            self.along_paths(s, scale);
            if !gained(allowed, energy_of(model, &self.trial)) {
                break;
            }
        }
        if gained(allowed, energy_of(model, &self.trial)) {
            self.along_paths(s, 0.0);
        }
        s.next.copy_from(&self.trial);
        if let Some(contact) = &mut self.self_collision {
            contact.count_drawn_back();
        }
    }

    /// `x0 + scale (x - x0)` and `scale v` into `trial`, from the substep's start `x0` and its
    /// result `(x, v)`.
    fn along_paths(&mut self, s: &Substep, scale: f32) {
        let (x0, next) = (&s.state.kin.pos, &*s.next);
        for p in 0..x0.len() {
            let a = x0.get(p);
            self.trial.pos.set(p, a + scale * (next.pos.get(p) - a));
            self.trial.vel.set(p, scale * next.vel.get(p));
        }
    }

    /// With self-collision and an integrator past its estimated stable substep
    /// ([`Model::stable_substep`]), whether the substep left motion it does not resolve
    /// ([`watchdog::unresolved_motion`]): the first particle at fault and the share of edges.
    /// Only there: the runaway this catches is the one the estimate foretells, and within the
    /// estimate (or with the implicit solvers, which have none) a violent drag legitimately
    /// swings more edges than the test allows.
    pub fn unresolved_motion(&mut self, s: &Substep) -> Option<(usize, f32)> {
        let contact = self.self_collision.as_ref()?;
        let kind = self.integrator.kind();
        let limit = *self
            .stable_substep
            .get_or_insert_with(|| s.model.stable_substep(kind));
        if !limit.is_some_and(|h| s.h as f64 > h) {
            return None;
        }
        let spacing = s.model.min_spacing() as f32;
        let (x0, x1) = (&s.state.kin.pos, &s.next.pos);
        let inv_mass = &s.model.particles.inv_mass;
        watchdog::unresolved_motion(contact.edges(), inv_mass, x0, x1, spacing)
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
}
