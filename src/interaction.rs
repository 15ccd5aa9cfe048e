//! The mouse's hold on the cloth: a grab makes a particle a kinematic pin that drags move, and
//! remembers the pin state it had so that letting go restores it. The facade's `grab`,
//! `drag_to` and `release` run it; cutting along rays is picking followed by a cut.

use glam::Vec3;

use crate::model::Model;
use crate::state::State;

/// A grabbed particle and the pin state to restore on release.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grab {
    pub index: usize,
    pub was_pinned: bool,
    /// The kinematic target it had before, if any.
    pub previous_target: Option<Vec3>,
}

impl Grab {
    /// A grab of particle `p`, remembering its pin state now.
    pub fn of(p: usize, model: &Model, state: &State) -> Grab {
        Grab {
            index: p,
            was_pinned: model.particles.pinned[p],
            previous_target: state.targets.target(p),
        }
    }
}
