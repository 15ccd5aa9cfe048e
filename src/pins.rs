//! Kinematic pins: pinned particles moved to a target position by the user (dragging).

use glam::Vec3;

use crate::soa::Vec3s;

/// How fast a gliding particle left behind its path catches up with it, m/s.
///
/// Were it put on its target each substep, the pass would put it back where the cloth lets it
/// be; the jump and the pull back act on different cloths (the free vertices move in between),
/// so every such round trip leaves energy in the cloth, more the longer the jump. The shirt's
/// hem dragged sideways into its own fold at one implicit step a frame
/// (`tests/garment_drag.rs`), its target 0.2 m past where the pass let it be: jumping the
/// whole way, 0.2-0.35 J a frame beyond the grip's work (2.2 J in one); at 1 m/s (1.7 cm a
/// step) within 0.01 J. Slower pumps less; faster follows the hand sooner once the cloth lets
/// the grip go. A particle on its path moves exactly as before.
pub const CATCH_UP: f32 = 1.0;

/// Pinned particles with a target. Each substep puts the particle exactly on its target and
/// gives it the velocity of that move, `(target - x) / h`, so spring damping sees the motion.
/// In the pipeline only while at least one target is set.
///
/// Targets set with [`KinematicPins::glide_to`] (the grip's) are reached over a time instead:
/// a drag target arrives once per display frame, and a grip put on it in one substep moves a
/// whole frame's travel in 0.5 ms (a 0.85 m drag over 0.2 s at 60 Hz: 7 cm, 140 m/s), a jerk
/// that tears the springs round the grip whatever the cloth. Gliding, the grip moves between
/// the frame's targets at the hand's own speed.
///
/// A gliding particle the self-collision pass held back (a hand pulling the cloth against a
/// fold of itself) follows its path's motion and closes the distance it was left behind at
/// [`CATCH_UP`] at most, rather than jumping back onto its target every substep.
#[derive(Clone, Debug, Default)]
pub struct KinematicPins {
    targets: Vec<(usize, Vec3)>,
    /// Per target: whether it is a drag's ([`KinematicPins::glide_to`] over a time > 0), which
    /// [`KinematicPins::glide`] moves and which catches up at [`CATCH_UP`] when held back.
    gliding: Vec<bool>,
    glide: Option<Glide>,
}

/// The move of the gliding targets: at time `from` each was `shift` away from its target,
/// and it closes that gap at a constant velocity, arriving at time `until` (s).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Glide {
    pub shift: Vec3,
    pub from: f64,
    pub until: f64,
}

impl Glide {
    /// How far a gliding particle is from its target at time `t` (m).
    pub fn gap(&self, t: f64) -> Vec3 {
        let span = self.until - self.from;
        if t >= self.until || span <= 0.0 {
            return Vec3::ZERO;
        }
        let left = ((self.until - t) / span).min(1.0);
        self.shift * left as f32
    }
}

impl KinematicPins {
    pub const NAME: &'static str = "kinematic_pins";

    pub fn is_empty(&self) -> bool {
        self.targets.is_empty()
    }

    /// Puts `p` on `target` from the next substep on; it no longer glides.
    pub fn set(&mut self, p: usize, target: Vec3) {
        self.put(p, target, false);
    }

    fn put(&mut self, p: usize, target: Vec3, glides: bool) {
        match self.targets.iter().position(|&(q, _)| q == p) {
            Some(k) => {
                self.targets[k].1 = target;
                self.gliding[k] = glides;
            }
            None => {
                self.targets.push((p, target));
                self.gliding.push(glides);
            }
        }
    }

    /// Moves the particles of `moves` (each `(particle, target)`) to their targets rigidly,
    /// the first from `here` (where it is at time `now`, [`KinematicPins::at`]), at a constant
    /// velocity, arriving at `now + over` (s; 0 puts them there in the next substep). Every
    /// other gliding target stops gliding. Each of `moves` must be as far from its target as
    /// the first, as a grip's particles are, for the move to stay rigid.
    pub fn glide_to(&mut self, moves: &[(usize, Vec3)], here: Vec3, now: f64, over: f64) {
        let Some(&(_, target)) = moves.first() else {
            return;
        };
        for g in &mut self.gliding {
            *g = false;
        }
        for &(p, to) in moves {
            self.put(p, to, over > 0.0);
        }
        self.glide = (over > 0.0 && here != target).then_some(Glide {
            shift: here - target,
            from: now,
            until: now + over,
        });
    }

    /// Where particle `p`'s target is at time `t` (on its way, while it glides).
    pub fn at(&self, p: usize, t: f64) -> Option<Vec3> {
        self.position(p).map(|k| self.placed(k, self.gap(t)))
    }

    /// Where target `k` is while the gliding ones are `gap` from theirs.
    fn placed(&self, k: usize, gap: Vec3) -> Vec3 {
        let target = self.targets[k].1;
        if self.gliding[k] {
            target + gap
        } else {
            target
        }
    }

    fn position(&self, p: usize) -> Option<usize> {
        self.targets.iter().position(|&(q, _)| q == p)
    }

    fn gap(&self, t: f64) -> Vec3 {
        self.glide.map_or(Vec3::ZERO, |g| g.gap(t))
    }

    /// The glide in progress, if any, and the particles it moves.
    pub fn glide(&self) -> Option<(Glide, Vec<usize>)> {
        let glide = self.glide?;
        let moved = self.targets.iter().zip(&self.gliding);
        let moved: Vec<usize> = moved.filter(|(_, &g)| g).map(|(&(p, _), _)| p).collect();
        (!moved.is_empty()).then_some((glide, moved))
    }

    /// Restores a glide saved by [`KinematicPins::glide`]: `particles` glide (each must have
    /// a target already) as `glide` says.
    pub fn restore_glide(&mut self, glide: Glide, particles: &[usize]) {
        for &p in particles {
            if let Some(k) = self.position(p) {
                self.gliding[k] = true;
            }
        }
        self.glide = Some(glide);
    }

    /// The particles whose targets a drag glides to, in the order they were set (with or
    /// without a glide in progress).
    pub fn gliding(&self) -> Vec<usize> {
        let targets = self.targets.iter().zip(&self.gliding);
        targets.filter(|(_, &g)| g).map(|(&(p, _), _)| p).collect()
    }

    /// Marks `particles` (each must have a target already) as a drag's, as
    /// [`KinematicPins::gliding`] listed them.
    pub fn restore_gliding(&mut self, particles: &[usize]) {
        for &p in particles {
            if let Some(k) = self.position(p) {
                self.gliding[k] = true;
            }
        }
    }

    /// The target of particle `p`, if it has one (where a glide ends).
    pub fn target(&self, p: usize) -> Option<Vec3> {
        self.position(p).map(|k| self.targets[k].1)
    }

    /// Every `(particle, target)`, in the order they were set (where a glide ends).
    pub fn targets(&self) -> &[(usize, Vec3)] {
        &self.targets
    }

    pub fn remove(&mut self, p: usize) {
        if let Some(k) = self.position(p) {
            self.targets.remove(k);
            self.gliding.remove(k);
        }
        if !self.gliding.contains(&true) {
            self.glide = None;
        }
    }

    pub fn clear(&mut self) {
        self.targets.clear();
        self.gliding.clear();
        self.glide = None;
    }

    /// Puts every target's particle where it is at time `t`, the end of a substep of length
    /// `h` (a gliding one left behind its path closer by [`CATCH_UP`] `h` at most); returns
    /// whether the velocities it wrote are finite (a drag across float32's range overflows).
    /// `start` holds the positions at the start of the substep, `pos` and `vel` its result.
    pub fn apply(&self, h: f32, t: f64, start: &Vec3s, pos: &mut Vec3s, vel: &mut Vec3s) -> bool {
        let mut finite = true;
        let (gap, gap_before) = (self.gap(t), self.gap(t - h as f64));
        for (k, &(p, _)) in self.targets.iter().enumerate() {
            let mut at = self.placed(k, gap);
            if self.gliding[k] {
                at = catch_up(start.get(p), self.placed(k, gap_before), at, CATCH_UP * h);
            }
            let v = (at - start.get(p)) / h;
            vel.set(p, v);
            pos.set(p, at);
            finite &= v.is_finite();
        }
        finite
    }
}

/// Where a particle at `x`, whose path runs from `was` to `to` over the substep, ends it: on
/// `to` when it is within `reach` of `was`, else moved with its path and `reach` nearer it.
fn catch_up(x: Vec3, was: Vec3, to: Vec3, reach: f32) -> Vec3 {
    let behind = was - x;
    let far = behind.length();
    if far <= reach {
        return to;
    }
    x + (to - was) + behind * (reach / far)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A one-particle grip at `x`, gliding from `here` to `to` over 1 s from time 0.
    fn gliding(x: Vec3, here: Vec3, to: Vec3) -> (KinematicPins, Vec3s) {
        let mut pins = KinematicPins::default();
        pins.glide_to(&[(0, to)], here, 0.0, 1.0);
        let mut start = Vec3s::zeros(1);
        start.set(0, x);
        (pins, start)
    }

    fn applied(pins: &KinematicPins, start: &Vec3s, h: f32, t: f64) -> Vec3 {
        let (mut pos, mut vel) = (start.clone(), Vec3s::zeros(1));
        assert!(pins.apply(h, t, start, &mut pos, &mut vel));
        assert_eq!(vel.get(0), (pos.get(0) - start.get(0)) / h);
        pos.get(0)
    }

    #[test]
    fn a_grip_on_its_path_lands_on_its_target_exactly() {
        let (here, to) = (Vec3::new(0.1, 0.2, 0.3), Vec3::new(0.5, 0.2, -0.4));
        let (pins, start) = gliding(here, here, to);
        let h = 1.0 / 60.0;
        assert_eq!(
            applied(&pins, &start, h, h as f64),
            pins.at(0, h as f64).unwrap()
        );
    }

    #[test]
    fn a_grip_held_back_closes_on_its_path_at_the_catch_up_speed() {
        let (here, to) = (Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0));
        let held = Vec3::new(-0.2, 0.0, 0.0);
        let (pins, start) = gliding(held, here, to);
        let h = 1.0 / 60.0;
        let at = applied(&pins, &start, h, h as f64);
        let path = pins.at(0, h as f64).unwrap();
        // The path moved h * 1 m/s; the particle moves with it and CATCH_UP h nearer.
        let behind = (path - at).length();
        assert!((behind - (0.2 - CATCH_UP * h)).abs() < 1e-6, "{behind}");
        assert!(
            (at.x - (held.x + path.x + CATCH_UP * h)).abs() < 1e-6,
            "{at}"
        );
    }

    #[test]
    fn a_target_set_without_a_glide_is_reached_in_one_substep_wherever_its_particle_is() {
        let mut pins = KinematicPins::default();
        let to = Vec3::new(0.3, -0.2, 0.1);
        pins.set(0, to);
        let mut start = Vec3s::zeros(1);
        start.set(0, Vec3::new(-1.0, 0.0, 0.0));
        assert_eq!(applied(&pins, &start, 1e-3, 1e-3), to);
    }
}
