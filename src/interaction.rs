//! The mouse's hold on the cloth: a grab takes a *grip*, the patch of cloth within a radius
//! of the particle hit, and makes every particle of it a kinematic pin that drags move
//! rigidly (each moves as the hit particle does); each remembers the pin state it had
//! so that letting go restores it. The facade's `grab`, `drag_to` and `release` run it;
//! cutting along rays is picking followed by a cut.
//!
//! A hand pulls a patch, not a point: a one-particle grab concentrates the whole pull on the
//! 12 springs around that particle, which tear first and pluck it out of the sheet (a pinhole)
//! while the rest of the cloth barely moves. A grip spreads the pull over the springs around
//! its rim, so the sheet follows, and a tear opens where the cloth's own tension is highest.

use glam::Vec3;

use crate::error::{Error, Result};
use crate::grid::SpringKind;
use crate::model::Model;
use crate::state::State;

/// The default grip radius in grid spacings (of the smaller spacing): a patch about five
/// particles across, some 13 to 21 particles on an even grid.
pub const GRIP_SPACINGS: f64 = 2.5;

/// How many times a drag's move is slid along a collider's surface, each time along the
/// contact of the grip's deepest particle (`Simulation::drag_to`). One is enough against one
/// flat face; a curved face or two faces meeting (a table's rim, the floor beside a shape)
/// take a few more. A grip still touching after the last round is pushed out particle by
/// particle, which changes its shape, so more rounds keep it rigid in deeper corners at a few
/// contact tests of the grip's particles each (once a frame).
pub const GRIP_SLIDE_ROUNDS: usize = 8;

/// The default drag time in s: one frame of a 60 Hz display, the rate a demo calls
/// `drag_to` at. A grip that reaches each frame's target one frame later moves continuously at
/// the hand's speed; a shorter time moves it in bursts (a frame's travel, then a stop), each
/// jerking the springs round the grip by about the burst's speed over the cloth's wave speed,
/// and a longer one lags further behind the hand. 0 puts the grip on each target in the next
/// substep.
pub const DRAG_TIME: f64 = 1.0 / 60.0;

/// One particle held by a grip and the pin state to restore on release.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Held {
    pub index: usize,
    pub was_pinned: bool,
    /// The kinematic target it had before, if any.
    pub previous_target: Option<Vec3>,
    /// Its position when grabbed (m): a drag moves it by the grabbed particle's displacement.
    pub start: Vec3,
}

/// A grip: the particle hit first, then the others held with it.
#[derive(Clone, Debug, PartialEq)]
pub struct Grab {
    pub held: Vec<Held>,
}

impl Grab {
    /// A grip around particle `p`: `p` and every live particle within `radius` (m) of it that
    /// the live springs join to `p` without leaving that ball, so a grip never reaches across
    /// a cut or onto another layer of the cloth folded close by. Radius 0 holds `p` alone.
    pub fn around(p: usize, radius: f32, model: &Model, state: &State) -> Grab {
        let pos = &state.kin.pos;
        let centre = pos.get(p);
        let grid = model.grid;
        let (alive, active) = (&model.particles.alive, &model.springs.active);
        let mut held = vec![Held::of(p, model, state)];
        let mut seen = vec![false; grid.len()];
        seen[p] = true;
        let mut next = 0;
        while next < held.len() {
            let a = held[next].index;
            next += 1;
            if let Some(mesh) = model.mesh() {
                for b in mesh.neighbours(a) {
                    if seen[b] || !alive[b] {
                        continue;
                    }
                    seen[b] = true;
                    if pos.get(b).distance(centre) <= radius {
                        held.push(Held::of(b, model, state));
                    }
                }
                continue;
            }
            for kind in SpringKind::ALL {
                let o = grid.offset(kind);
                // The spring `a` anchors, and the one anchored at `a - offset` ending at `a`.
                let ends = [
                    grid.partner(a, kind).map(|b| (a, b)),
                    a.checked_sub(o)
                        .filter(|&b| grid.partner(b, kind) == Some(a))
                        .map(|b| (b, b)),
                ];
                for (anchor, b) in ends.into_iter().flatten() {
                    if seen[b] || !alive[b] || active[kind.index()][anchor] == 0.0 {
                        continue;
                    }
                    seen[b] = true;
                    if pos.get(b).distance(centre) <= radius {
                        held.push(Held::of(b, model, state));
                    }
                }
            }
        }
        Grab { held }
    }

    /// The particle the grip was taken at.
    pub fn index(&self) -> usize {
        self.held[0].index
    }

    /// Where each held particle goes when the grabbed one is dragged to `target`: that one to
    /// `target` itself, every other one by the same displacement from where it was grabbed,
    /// so the patch moves rigidly and a drag back to the start puts each exactly where it was.
    pub fn targets(&self, target: Vec3) -> impl Iterator<Item = (usize, Vec3)> + '_ {
        let moved = target - self.held[0].start;
        let rest = self.held[1..]
            .iter()
            .map(move |h| (h.index, h.start + moved));
        std::iter::once((self.held[0].index, target)).chain(rest)
    }
}

impl Held {
    /// Particle `p` held where it is, remembering its pin state now.
    pub fn of(p: usize, model: &Model, state: &State) -> Held {
        Held {
            index: p,
            was_pinned: model.particles.pinned[p],
            previous_target: state.targets.target(p),
            start: state.kin.pos.get(p),
        }
    }
}

/// A drag time: finite and >= 0 (s).
pub fn checked_drag_time(seconds: f64) -> Result<f64> {
    if !(seconds.is_finite() && seconds >= 0.0) {
        return Err(Error::value(
            "drag_time",
            format!("must be a finite number of seconds >= 0, got {seconds}"),
        ));
    }
    Ok(seconds)
}

/// A grip radius: finite and >= 0 within float32's range.
pub fn checked_grip_radius(radius: f64) -> Result<f32> {
    let r = radius as f32;
    if !(radius.is_finite() && r.is_finite() && radius >= 0.0) {
        return Err(Error::value(
            "grip_radius",
            format!("must be a finite number >= 0 within float32 range, got {radius}"),
        ));
    }
    Ok(r)
}
