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
use crate::diagnostics::energy_of;
use crate::state::Kinematics;

/// Bisections of the fraction of a substep's motion kept when the self-collision pass left the
/// cloth with energy nothing gave it ([`Pipeline::keep_contact_passive`]): the fraction kept is
/// found to within `1 / 2^DRAW_BACK_BISECTIONS`, two energy evaluations each.
const DRAW_BACK_BISECTIONS: u32 = 6;

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
    /// what the pass was given, for [`Pipeline::hold_self_contacts`] and the energy guard.
    pub fn separate_self_contacts(&mut self, s: &mut Substep) -> bool {
        let holds = self.holds_contacts();
        let Some(contact) = &mut self.self_collision else {
            return true;
        };
        let t = Instant::now();
        // Only a solver that holds contacts reruns the substep or has its energy guarded
        // (`Pipeline::contact_gained`): the copies are kept for those alone.
        if holds {
            let n = s.next.pos.len();
            if self.unshortened.len() != n {
                self.unshortened = Vec3s::zeros(n);
                self.pass_input = Kinematics::zeros(n);
                self.trial = Kinematics::zeros(n);
                self.moved_first = Kinematics::zeros(n);
            }
            self.unshortened.copy_from(&s.next.pos);
            self.pass_input.copy_from(s.next);
        }
        let before = contact.stats();
        let finite = contact.apply(s.model, &s.state.kin, s.next);
        let after = contact.stats();
        self.contact_capped = after.capped != before.capped;
        self.draw_back = None;
        s.profile.add(SelfCollision::NAME, t.elapsed());
        finite
    }

    /// Keeps the self-collision pass from leaving energy in the cloth that nothing gave it,
    /// drawing the substep back along its paths where it did
    /// (`self_collision_stats()["drawn_back"]` counts them).
    ///
    /// The cap stops each vertex short where its move would cross the cloth, so its result
    /// mixes vertices near their start with vertices where the solve sent them, and the springs
    /// between the two can end stretched more than in either. Solved and capped again, a cloth
    /// held by a grip climbed from 5.6 J to 45.6 J in twelve frames with no work done on it
    /// (docs/notes/garments.md). The pass's result `x` lies on straight paths from the substep's
    /// start `x0` that it checked, so every `x0 + s (x - x0)`, `0 <= s <= 1`, is as uncrossed.
    ///
    /// The held particles (inverse mass 0: pins, a grip) are where the substep puts them, so
    /// their work is counted as if they moved first: the bound is the energy of the start with
    /// the held particles moved to their end, which is what an implicit step's energy
    /// inequality bounds its result by. An integrator that gains energy on its own (explicit
    /// ones do, by their truncation error) keeps what it gained: the bound is the larger of
    /// that and the energy of what the pass was given, with the held particles at their end.
    /// Above both, the substep is drawn back along its paths (free velocities scaled by `s`)
    /// to the largest `s` found by bisection whose energy is within the bound of the same `s`
    /// (held particles at `x0 + s (x - x0)`); `s = 0` always is, having the start's energy
    /// less its free particles' kinetic energy.
    ///
    /// Only with the implicit integrators ([`Pipeline::contact_gained`]).
    ///
    /// Colliders: a drawn-back particle lies on the chord between two points outside a
    /// collider, inside a curved surface by at most `d^2 / 8R` for a move `d` along a
    /// surface of radius of curvature `R` (0.04 mm for 1 cm on a 30 cm sphere); a moving
    /// collider's work is in the pass's input, so a substep it pushed is drawn back only
    /// past that.
    pub fn keep_contact_passive(&mut self, s: &mut Substep) {
        let Some(kept) = self.passive_fraction(s) else {
            return;
        };
        along_paths(
            &s.state.kin,
            &*s.next,
            &s.model.particles.inv_mass,
            kept,
            &mut self.trial,
        );
        s.next.copy_from(&self.trial);
        if let Some(contact) = &mut self.self_collision {
            contact.count_drawn_back();
        }
    }

    /// The fraction of the substep's motion [`Pipeline::keep_contact_passive`] would keep, None
    /// where it keeps it all: the largest found by bisection whose energy is within its bound.
    pub(super) fn passive_fraction(&mut self, s: &Substep) -> Option<f32> {
        if let Some(sized) = self.draw_back {
            return sized;
        }
        let sized = self.size_draw_back(s);
        self.draw_back = Some(sized);
        sized
    }

    fn size_draw_back(&mut self, s: &Substep) -> Option<f32> {
        if !self.contact_gained(s) {
            return None;
        }
        let (model, w) = (s.model, &s.model.particles.inv_mass);
        let (mut kept, mut over) = (0.0f32, 1.0f32);
        for _ in 0..DRAW_BACK_BISECTIONS {
            let mid = 0.5 * (kept + over);
            along_paths(&s.state.kin, &*s.next, w, mid, &mut self.trial);
            held_moved_first(model, s, mid, &mut self.moved_first);
            let bound = energy_of(model, &self.moved_first);
            if gained(bound, energy_of(model, &self.trial)) {
                over = mid;
            } else {
                kept = mid;
            }
        }
        Some(kept)
    }

    /// Whether the self-collision pass's cap acted in the substep's last round and left the cloth
    /// with more energy than both its start with the held particles moved first and what the
    /// pass was given with them where they end ([`Pipeline::keep_contact_passive`]). Only for
    /// the integrators that hold contacts in their solve (implicit Euler, projective dynamics):
    /// the bound is their energy inequality's, and they can run the substep again holding what
    /// the pass moved. With an explicit integrator, which has neither, the draw-back alone
    /// stopped a grip dragged into its own cloth (the shirt on symplectic Euler: the grip still
    /// from frame 19 of 30 while its target moved on, 3,543 substeps drawn back).
    fn contact_gained(&mut self, s: &Substep) -> bool {
        if !self.contact_capped || !self.holds_contacts() {
            return false;
        }
        let model = s.model;
        let end = energy_of(model, s.next);
        held_moved_first(model, s, 1.0, &mut self.moved_first);
        if !gained(energy_of(model, &self.moved_first), end) {
            return false;
        }
        let (w, alive) = (&model.particles.inv_mass, &model.particles.alive);
        for p in (0..w.len()).filter(|&p| w[p] == 0.0 && alive[p]) {
            self.pass_input.pos.set(p, s.next.pos.get(p));
            self.pass_input.vel.set(p, s.next.vel.get(p));
        }
        gained(energy_of(model, &self.pass_input), end)
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

/// The substep's start with its held particles (inverse mass 0, alive) at `x0 + scale (x - x0)`
/// and their end velocity, into `into`.
fn held_moved_first(model: &Model, s: &Substep, scale: f32, into: &mut Kinematics) {
    let (w, alive) = (&model.particles.inv_mass, &model.particles.alive);
    let (start, end) = (&s.state.kin, &*s.next);
    into.copy_from(start);
    for p in (0..w.len()).filter(|&p| w[p] == 0.0 && alive[p]) {
        let a = start.pos.get(p);
        into.pos.set(p, a + scale * (end.pos.get(p) - a));
        into.vel.set(p, end.vel.get(p));
    }
}

/// `x0 + scale (x - x0)` into `trial` for every particle, from the substep's start `x0` and its
/// result `(x, v)`; velocity `scale v` for a free particle, `v` for a held one (inverse mass 0),
/// whose velocity is its prescribed motion's.
fn along_paths(
    start: &Kinematics,
    end: &Kinematics,
    inv_mass: &[f32],
    scale: f32,
    trial: &mut Kinematics,
) {
    for (p, &w) in inv_mass.iter().enumerate() {
        let a = start.pos.get(p);
        trial.pos.set(p, a + scale * (end.pos.get(p) - a));
        let v = end.vel.get(p);
        trial.vel.set(p, if w == 0.0 { v } else { scale * v });
    }
}
