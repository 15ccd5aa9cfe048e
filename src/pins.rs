//! Kinematic pins: pinned particles moved to a target position by the user (dragging).

use glam::Vec3;

use crate::soa::Vec3s;

/// Pinned particles with a target. Each substep puts the particle exactly on its target and
/// gives it the velocity of that move, `(target - x) / h`, so spring damping sees the motion.
/// In the pipeline only while at least one target is set.
///
/// Targets set with [`KinematicPins::glide_to`] (the grip's) are reached over a time instead:
/// a drag target arrives once per display frame, and a grip put on it in one substep moves a
/// whole frame's travel in 0.5 ms (a 0.85 m drag over 0.2 s at 60 Hz: 7 cm, 140 m/s), a jerk
/// that tears the springs round the grip whatever the cloth. Gliding, the grip moves between
/// the frame's targets at the hand's own speed.
#[derive(Clone, Debug, Default)]
pub struct KinematicPins {
    targets: Vec<(usize, Vec3)>,
    /// Per target: whether [`KinematicPins::glide`] moves it.
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
            self.put(p, to, true);
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
    /// `h`; returns whether the velocities it wrote are finite (a drag across float32's range
    /// overflows). `start` holds the positions at the start of the substep, `pos` and `vel`
    /// its result.
    pub fn apply(&self, h: f32, t: f64, start: &Vec3s, pos: &mut Vec3s, vel: &mut Vec3s) -> bool {
        let mut finite = true;
        let gap = self.gap(t);
        for (k, &(p, _)) in self.targets.iter().enumerate() {
            let at = self.placed(k, gap);
            let v = (at - start.get(p)) / h;
            vel.set(p, v);
            pos.set(p, at);
            finite &= v.is_finite();
        }
        finite
    }
}
