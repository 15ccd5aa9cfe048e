//! Changing the state from outside a step: positions, velocities and masses replaced, particles
//! pinned and released. Each call checks all its input first and changes nothing when any of
//! it is bad; each tells the stepper what changed, so caches and the watchdog stay honest.

use glam::Vec3;

use super::Simulation;
use crate::error::{check_vec3s, Error, Result};
use crate::soa::Vec3s;

impl Simulation {
    /// Replaces every position (m). Rejects non-finite values, changing nothing.
    pub fn set_positions(&mut self, pos: &Vec3s) -> Result<()> {
        self.check_state_array("positions", pos)?;
        self.state.kin.pos.copy_from(pos);
        self.motion_changed();
        Ok(())
    }

    /// Replaces every velocity (m/s). Rejects non-finite values, changing nothing. Particles
    /// that cannot move (pinned, cut) keep zero velocity.
    pub fn set_velocities(&mut self, vel: &Vec3s) -> Result<()> {
        self.check_state_array("velocities", vel)?;
        self.state.kin.vel.copy_from(vel);
        for p in 0..self.model.grid.len() {
            if !self.model.particles.is_dynamic(p) {
                self.state.kin.vel.set(p, Vec3::ZERO);
            }
        }
        self.motion_changed();
        Ok(())
    }

    /// Replaces every particle's mass (kg, each finite and > 0, within float32), for cloths of
    /// uneven weight: a weighted hem, a heavy patch. Rejects a bad value, changing nothing.
    /// Pinned and cut particles keep their new mass for when they move again. The explicit
    /// integrators' stable step follows the lightest particle (`stable_dt`).
    pub fn set_masses(&mut self, masses: &[f64]) -> Result<()> {
        self.model.set_masses(masses)?;
        self.stepper.masses_changed();
        Ok(())
    }

    fn check_state_array(&self, name: &str, values: &Vec3s) -> Result<()> {
        check_vec3s(name, values, self.model.grid.len())
    }

    pub(crate) fn check_index(&self, name: &str, index: i64) -> Result<usize> {
        let n = self.model.grid.len();
        if (0..n as i64).contains(&index) {
            Ok(index as usize)
        } else {
            Err(Error::index(name, index, n))
        }
    }

    /// Something other than a step changed the state: caches are stale, and the watchdog must
    /// not blame the last step for it.
    pub(super) fn state_changed(&mut self) {
        self.state.version += 1;
        self.stepper.state_replaced();
    }

    /// Something other than a step set positions or velocities: as
    /// [`Simulation::state_changed`], and an integrator with history forgets it.
    pub(super) fn motion_changed(&mut self) {
        self.state.version += 1;
        self.stepper.motion_replaced();
    }

    /// Pins particle `index`: it stops and integration no longer moves it. With a `target`
    /// (m), the particle moves there over the next step and stays (a kinematic pin); calling
    /// again with a new target drags it.
    pub fn pin(&mut self, index: i64, target: Option<Vec3>) -> Result<()> {
        let p = self.check_pin(("index", "target"), index, target)?;
        self.pin_live(p, target);
        Ok(())
    }

    /// Pins every particle of `indices` as [`Simulation::pin`] pins one, at `targets[k]` for
    /// `indices[k]` when given: one call for a whole edge moved every step (a driver) instead
    /// of one per particle. Every index and target is checked before anything changes, so a
    /// bad one (named `indices[k]` or `targets[k]`) pins nothing. A repeated index takes its
    /// last target.
    pub fn pin_many(&mut self, indices: &[i64], targets: Option<&Vec3s>) -> Result<()> {
        if let Some(t) = targets.filter(|t| t.len() != indices.len()) {
            return Err(Error::value(
                "targets",
                format!(
                    "must have one row per index: {} rows for {} indices",
                    t.len(),
                    indices.len()
                ),
            ));
        }
        let target = |k: usize| targets.map(|t| t.get(k));
        let checked = indices
            .iter()
            .enumerate()
            .map(|(k, &i)| {
                let names = (format!("indices[{k}]"), format!("targets[{k}]"));
                self.check_pin((&names.0, &names.1), i, target(k))
            })
            .collect::<Result<Vec<usize>>>()?;
        for (k, p) in checked.into_iter().enumerate() {
            self.pin_live(p, target(k));
        }
        Ok(())
    }

    /// The particle `index` names, if it can be pinned (live) at `target` (finite); errors
    /// name the index and the target with `names`.
    fn check_pin(&self, names: (&str, &str), index: i64, target: Option<Vec3>) -> Result<usize> {
        let p = self.check_index(names.0, index)?;
        if let Some(t) = target.filter(|t| !t.is_finite()) {
            return Err(Error::value(
                names.1,
                format!("must be finite, got {:?}", t.to_array()),
            ));
        }
        if !self.model.particles.alive[p] {
            return Err(Error::value(
                names.0,
                format!("particle {p} was cut and cannot be pinned"),
            ));
        }
        Ok(p)
    }

    /// Pins live particle `p`, statically (`None`: it stops where it is) or at a target.
    pub(super) fn pin_live(&mut self, p: usize, target: Option<Vec3>) {
        self.model.particles.set_pinned(p, true);
        match target {
            Some(t) => self.state.targets.set(p, t),
            None => {
                self.state.targets.remove(p);
                self.state.kin.vel.set(p, Vec3::ZERO);
                self.state_changed();
            }
        }
    }

    /// Releases particle `index`; it keeps its current velocity. Unpinning a particle that is
    /// not pinned does nothing.
    pub fn unpin(&mut self, index: i64) -> Result<()> {
        let p = self.check_index("index", index)?;
        self.model.particles.set_pinned(p, false);
        self.state.targets.remove(p);
        Ok(())
    }
}
