//! rustcloth: a mass-spring cloth solver.
//!
//! A cloth is an `nx` x `ny` grid of particles joined by structural, shear and bending springs
//! (the 12-neighbour stencil), pushed by gravity and air drag, stepped with a fixed time step
//! by one of six integrators. It drapes on colliders of any shape (a floor, spheres, boxes,
//! capsules, cylinders, planes, triangle meshes, moving or still), can be kept from passing
//! through itself, and can be grabbed, dragged, cut and torn. A [`Scene`] describes it; a [`Simulation`] runs it.
//!
//! One step runs the scene's passes in order: `src/stepper/mod.rs` (`Stepper::step` and
//! `Stepper::substep`) is the place to start reading.
//!
//! ```
//! use rustcloth::{Scene, Simulation};
//!
//! let scene = Scene::builtin("hanging").unwrap();
//! let mut sim = Simulation::new(scene).unwrap();
//! sim.step(100).unwrap();
//! assert!((sim.time() - 0.1).abs() < 1e-9);
//! ```
//!
//! This crate is pure Rust; the Python binding lives behind the `python` feature.

pub mod collisions;
pub mod cutting;
pub mod cutting_rest;
pub mod diagnostics;
pub mod error;
pub mod forces;
pub mod garment;
pub mod grid;
pub mod incidence;
pub mod integrators;
pub mod interaction;
pub mod linear;
pub mod material;
pub mod mesh_cloth;
pub mod model;
pub mod parallel;
pub mod particles;
pub mod picking;
pub mod pins;
pub mod profile;
pub mod ray;
pub mod render_mesh;
pub mod scene;
pub mod self_collision;
pub mod simd;
pub mod simulation;
pub mod snapshot;
pub mod soa;
pub mod springs;
pub mod state;
pub mod stepper;
pub mod strain_limit;
pub mod tearing;
pub mod wind;

#[cfg(feature = "python")]
mod python;

pub use diagnostics::Energy;
pub use error::{Error, Result, Trouble};
pub use integrators::IntegratorKind;
pub use scene::Scene;
pub use simulation::Simulation;
