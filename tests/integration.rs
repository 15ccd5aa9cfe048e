//! The Rust integration tests as one test binary: each `tests/NAME.rs` is a module here, so the
//! scaffolding in `tests/common` and the dependencies' generic code are compiled and linked
//! once, not once per file. Select a file's tests by its module path:
//!
//! ```sh
//! cargo test --test integration shapes::
//! cargo test --release --test integration golden::
//! ```
//!
//! A file whose tests need a process of their own (`allocations.rs`: a counting global
//! allocator) stays its own `[[test]]` in Cargo.toml. `autotests = false` there means a new
//! `tests/*.rs` file runs only once it is named here or there; `every_test_file_is_compiled`
//! below fails until it is.

mod common;

#[path = "colliders.rs"]
mod colliders;
#[path = "cutting.rs"]
mod cutting;
#[path = "dead_particles.rs"]
mod dead_particles;
#[path = "energy.rs"]
mod energy;
#[path = "fuzz.rs"]
mod fuzz;
#[path = "garment.rs"]
mod garment;
#[path = "garment_drag.rs"]
mod garment_drag;
#[path = "golden.rs"]
mod golden;
#[path = "grip.rs"]
mod grip;
#[path = "implicit_friction.rs"]
mod implicit_friction;
#[path = "integrators.rs"]
mod integrators;
#[path = "mesh_bending.rs"]
mod mesh_bending;
#[path = "mesh_cloth.rs"]
mod mesh_cloth;
#[path = "mesh_colliders.rs"]
mod mesh_colliders;
#[path = "mesh_cut_edge.rs"]
mod mesh_cut_edge;
#[path = "mesh_implicit.rs"]
mod mesh_implicit;
#[path = "mesh_membrane.rs"]
mod mesh_membrane;
#[path = "meshtear.rs"]
mod meshtear;
#[path = "physics.rs"]
mod physics;
#[path = "picking.rs"]
mod picking;
#[path = "scene_folds.rs"]
mod scene_folds;
#[path = "self_collision.rs"]
mod self_collision;
#[path = "self_collision_toggle.rs"]
mod self_collision_toggle;
#[path = "shapes.rs"]
mod shapes;
#[path = "snapshot.rs"]
mod snapshot;
#[path = "stability.rs"]
mod stability;
#[path = "stepping.rs"]
mod stepping;
#[path = "stiff.rs"]
mod stiff;
#[path = "strain_limit.rs"]
mod strain_limit;
#[path = "tearing.rs"]
mod tearing;
#[path = "watchdog.rs"]
mod watchdog;
#[path = "wind.rs"]
mod wind;

/// Every `tests/*.rs` file is a module of this binary or a `[[test]]` target of its own in
/// Cargo.toml: with `autotests = false`, a file named in neither would never run.
#[test]
fn every_test_file_is_compiled() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let here = std::fs::read_to_string(root.join("tests/integration.rs")).unwrap();
    let manifest = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    let mut missing = vec![];
    for entry in std::fs::read_dir(root.join("tests")).unwrap() {
        let name = entry.unwrap().file_name().into_string().unwrap();
        if !name.ends_with(".rs") || name == "integration.rs" {
            continue;
        }
        let as_module = format!("#[path = \"{name}\"]");
        let as_target = format!("path = \"tests/{name}\"");
        if !here.contains(&as_module) && !manifest.contains(&as_target) {
            missing.push(name);
        }
    }
    assert!(
        missing.is_empty(),
        "{missing:?} in tests/ run nowhere: add `#[path = \"NAME.rs\"] mod NAME;` here"
    );
}
