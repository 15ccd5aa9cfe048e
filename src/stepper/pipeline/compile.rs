//! What a scene compiles into: its forces and its colliders, each in the order a step runs them.

use glam::{DVec3, Vec3};

use super::{Pipeline, StartEnergy};
use crate::collisions::{Collider, Floor, PredictedContacts, Shapes};
use crate::forces::{Force, ForceModel};
use crate::grid::Family;
use crate::integrators::Integrator;
use crate::scene::{ColliderSpec, Scene, SphereSpec};
use crate::self_collision::SelfCollision;
use crate::soa::Vec3s;
use crate::state::Kinematics;
use crate::strain_limit::StrainLimit;
use crate::tearing::Tearing;
use crate::wind::Wind;

impl Pipeline {
    /// The passes `scene` asks for, for a cloth of `particles` particles.
    pub fn compile(scene: &Scene, particles: usize) -> Pipeline {
        let colliders = colliders_of(scene);
        Pipeline {
            forces: ForceModel::new(forces_of(scene)),
            integrator: Integrator::new(scene.integrator, scene.solver_settings()),
            strain_limit: scene
                .strain_limit
                .as_ref()
                .map(|s| StrainLimit::new(s.max_strain as f32, s.iterations)),
            contacts: (!colliders.is_empty() || scene.self_collision.is_some())
                .then(|| PredictedContacts::new(particles)),
            colliders,
            self_collision: scene.self_collision.as_ref().map(|s| {
                let mut pass =
                    SelfCollision::new(s.thickness as f32, s.friction as f32, s.iterations);
                pass.solve_stiffness = s.solve_stiffness as f32;
                pass
            }),
            tearing: scene
                .tearing
                .as_ref()
                .map(|t| Tearing::new(t.max_strain as f32, t.max_per_step)),
            wind: scene.wind.as_ref().map(|w| Wind::new(w, particles)),
            halves: Vec::new(),
            last_piece: None,
            piece_start: Kinematics::zeros(0),
            put_out: Kinematics::zeros(0),
            halved: 0,
            start_energy: StartEnergy::Unjudged,
            unshortened: Vec3s::zeros(0),
            pass_input: Kinematics::zeros(0),
            contact_capped: false,
            draw_back: None,
            trial: Kinematics::zeros(0),
            moved_first: Kinematics::zeros(0),
            stable_substep: None,
        }
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
    if cloth.mesh.is_some() {
        // A mesh cloth's springs are its own list, not the stencil's families.
        return forces;
    }
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
