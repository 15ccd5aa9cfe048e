//! The passes a scene compiles into, and the ones that run after the integrator.
//!
//! A substep runs, in order, only the passes the scene needs:
//!
//! 1. forces (gravity, air drag, each spring family), evaluated by the integrator as often as
//!    its scheme needs;
//! 2. the integrator, writing the end-of-step state into a second buffer;
//! 3. kinematic pins (while the user drags a pinned particle);
//! 4. strain limiting (when the scene asks for it, `src/strain_limit/`);
//! 5. colliders (the `[[spheres]]`, then the `[[colliders]]` of any shape, then the floor);
//! 6. self-collision (when the scene asks for it, `src/self_collision/`), last, so that its
//!    guarantee covers everything the passes before it did. It only shortens a particle's
//!    motion along its path from the substep's start, so the floor (a half-space, which holds
//!    both ends of that path) stays satisfied.
//!
//! and once per step, after its last substep was accepted, tearing (when the scene asks for it,
//! `src/tearing.rs`): it changes the model (springs break), not the state, so it runs between
//! steps rather than inside one.

use std::time::Instant;

use glam::{DVec3, Vec3};

use crate::collisions::{Collider, Floor, Shapes};
use crate::forces::{Force, ForceModel};
use crate::grid::Family;
use crate::integrators::Integrator;
use crate::model::Model;
use crate::pins::KinematicPins;
use crate::profile::Profile;
use crate::scene::{ColliderSpec, Scene, SphereSpec};
use crate::self_collision::SelfCollision;
use crate::state::{Kinematics, State};
use crate::strain_limit::StrainLimit;
use crate::tearing::Tearing;

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
}

impl Pipeline {
    pub fn compile(scene: &Scene) -> Pipeline {
        Pipeline {
            forces: ForceModel::new(forces_of(scene)),
            integrator: scene.integrator.build(scene.solver_settings()),
            strain_limit: scene
                .strain_limit
                .as_ref()
                .map(|s| StrainLimit::new(s.max_strain as f32, s.iterations)),
            colliders: colliders_of(scene),
            self_collision: scene
                .self_collision
                .as_ref()
                .map(|s| SelfCollision::new(s.thickness as f32, s.friction as f32, s.iterations)),
            tearing: scene
                .tearing
                .as_ref()
                .map(|t| Tearing::new(t.max_strain as f32, t.max_per_step)),
        }
    }

    /// The passes a step runs, in order (kinematic pins only while a target is set).
    pub fn effects(&self, state: &State) -> Vec<&'static str> {
        let mut out: Vec<&'static str> = self.forces.forces().iter().map(Force::name).collect();
        out.push(self.integrator.name());
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

    /// The passes after the integrator, on `next`: kinematic pins, strain limiting,
    /// colliders, self-collision, for a substep of length `h` ending at `time` (s; where moving
    /// colliders are posed). Returns whether what they wrote is finite; they write few values (a drag,
    /// contacts, limited springs), so checking costs next to nothing.
    pub fn after_integration(
        &mut self,
        model: &Model,
        state: &State,
        next: &mut Kinematics,
        (h, time): (f32, f64),
        chunk: usize,
        profile: &mut Profile,
    ) -> bool {
        let mut finite = true;
        if !state.targets.is_empty() {
            let t = Instant::now();
            finite &= state
                .targets
                .apply(h, &state.kin.pos, &mut next.pos, &mut next.vel);
            profile.add(KinematicPins::NAME, t.elapsed());
        }
        // After the pins, so that the limit pulls the cloth after a dragged particle rather
        // than back to where it was; before the colliders, so that contacts have the last word.
        if let Some(limit) = &mut self.strain_limit {
            let t = Instant::now();
            let (grid, springs, particles) = (model.grid, &model.springs, &model.particles);
            finite &= limit.apply(grid, springs, particles, next, chunk).finite;
            profile.add(StrainLimit::NAME, t.elapsed());
        }
        for collider in &self.colliders {
            let t = Instant::now();
            finite &= collider.resolve(&state.kin, next, &model.particles, chunk, h, time);
            profile.add(collider.name(), t.elapsed());
        }
        if let Some(contact) = &mut self.self_collision {
            let t = Instant::now();
            finite &= contact.apply(model, &state.kin, next);
            profile.add(SelfCollision::NAME, t.elapsed());
        }
        finite
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
            + self
                .colliders
                .iter()
                .map(Collider::heap_bytes)
                .sum::<usize>()
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
