//! The pair list after a partial rebuild against a search of the whole mesh at its anchor.

use super::*;
use crate::scene::IntegratorKind;
use crate::{Scene, Simulation};

/// The positions after each of the steps from `from` to `to` of `scene`, its left and
/// right edges (when pinned) turned about the x axis through its centre at `omega` rad/s,
/// in opposite ways.
fn recorded(scene: Scene, from: u64, to: u64, omega: f64) -> Vec<Vec3s> {
    let (nx, dt, centre) = (scene.cloth.nx as usize, scene.dt, scene.cloth.center);
    let mut sim = Simulation::new(scene).unwrap();
    let start = sim.positions().clone();
    let mut out = Vec::new();
    for step in 1..=to {
        let angle = omega * step as f64 * dt;
        for p in (0..start.len()).filter(|_| omega != 0.0) {
            let sign = match p % nx {
                0 => 1.0,
                i if i == nx - 1 => -1.0,
                _ => continue,
            };
            let r = start.get(p).as_dvec3() - glam::DVec3::from(centre);
            let (s, c) = (sign * angle).sin_cos();
            let turned = glam::DVec3::new(r.x, c * r.y - s * r.z, s * r.y + c * r.z);
            let target = glam::DVec3::from(centre) + turned;
            sim.pin(p as i64, Some(target.as_vec3())).unwrap();
        }
        sim.step(1).unwrap();
        if step >= from {
            out.push(sim.positions().clone());
        }
    }
    out
}

/// The built-in scene as these replays were built on: symplectic Euler at 1 ms steps, the
/// springs damped 0.01 N s/m, no contact term in a solve. The built-ins themselves run
/// implicit Euler at display-frame steps (docs/contact.md).
fn at_1ms(name: &str) -> Scene {
    let mut scene = Scene::builtin(name).unwrap();
    (scene.integrator, scene.dt, scene.substeps) = (IntegratorKind::SymplecticEuler, 0.001, 1);
    scene.cloth.damping = 0.01;
    if let Some(spec) = scene.self_collision.as_mut() {
        spec.solve_stiffness = 0.0;
    }
    scene
}

/// The scenes replayed: a 48 x 48 pile at 0.5 ms steps (the pile's 1 ms in two substeps, one
/// step a substep), and a 40 x 40 twist.
fn pile_and_twist() -> (Scene, Scene) {
    let mut pile = at_1ms("pile");
    (pile.cloth.nx, pile.cloth.ny) = (48, 48);
    pile.dt = 0.0005;
    let mut twist = at_1ms("twist");
    (twist.cloth.nx, twist.cloth.ny, twist.cloth.size) = (40, 40, [0.3, 0.3]);
    (pile, twist)
}

/// The list a search of the whole mesh at the list's anchor finds, with the reach and
/// margin the list was built with.
fn searched_at_anchor(pass: &SelfCollision) -> Vec<(pair::Candidate, f64)> {
    let anchor = pass.list.anchor().unwrap();
    let (reach, eps) = (pass.list.reach(), pass.list_eps);
    let mut boxes = Vec::new();
    list_boxes(&mut boxes, anchor, reach, eps);
    let mut broad = Broad::default();
    let margin = 1e-3 * eps as f64;
    broad.search_near(&pass.topology, &boxes, anchor, reach, margin, None);
    broad.near_found(&pass.topology).collect()
}

/// Querying again only the vertices past their bound must leave the list exactly as a
/// search of the whole mesh at its anchor lists it: every pair, in its order, with its
/// distance to the bit. Otherwise a pair the substep needs could be missing, or the pairs
/// come in another order and the result depends on when the list was built. The pass is
/// replayed over the steps of a settling pile and of a twist, one step a substep.
#[test]
fn a_partial_rebuild_finds_the_full_searchs_pairs_in_its_order() {
    let (pile, twist) = pile_and_twist();
    for (name, scene, (from, to), omega) in [
        ("pile", pile, (1600, 2000), 0.0),
        ("twist", twist, (1, 1000), 2.0),
    ] {
        let frames = recorded(scene.clone(), from, to, omega);
        let spec = scene.self_collision.clone().unwrap();
        let (model, _) = Model::new(scene).unwrap();
        let mut pass = SelfCollision::new(spec.thickness as f32, spec.friction as f32, 1);
        let mut checked = 0;
        for w in frames.windows(2) {
            let n = w[0].len();
            let start = Kinematics {
                pos: w[0].clone(),
                vel: Vec3s::zeros(n),
            };
            let mut next = Kinematics {
                pos: w[1].clone(),
                vel: Vec3s::zeros(n),
            };
            let requeries = pass.stats.requeries;
            assert!(pass.apply(&model, &start, &mut next));
            if pass.stats.requeries > requeries {
                let full = searched_at_anchor(&pass);
                let (candidates, distances) = pass.list.listed();
                assert_eq!(candidates.len(), full.len());
                for ((c, d), (f, e)) in candidates.iter().zip(distances).zip(&full) {
                    assert_eq!((c, d.to_bits()), (f, e.to_bits()));
                }
                checked += !candidates.is_empty() as usize;
            }
        }
        eprintln!("{name}: {checked} requeries checked, {:?}", pass.stats);
        assert!(checked > 5, "{name}: {checked} requeries checked");
    }
}

/// Each particle's position and velocity, to the bit.
fn bits(k: &Kinematics) -> Vec<[u32; 6]> {
    let b = |p: glam::Vec3| p.to_array().map(f32::to_bits);
    (0..k.pos.len())
        .map(|v| {
            let (x, u) = (b(k.pos.get(v)), b(k.vel.get(v)));
            [x[0], x[1], x[2], u[0], u[1], u[2]]
        })
        .collect()
}

/// The repulsion and the cap look at the listed pairs the substep's motion can bring within
/// `(1 + HOT) thickness`, and at the others only where they have not shown that those cannot
/// act. A bound that let a pair through which the repulsion would correct or the cap would
/// slow, or a stage that went on without the others where it had to look at them, would end
/// the substep elsewhere than a pass that looks at every pair the substep needs. Replayed over
/// a settling pile (in contact) and a twist, each substep from recorded positions with their
/// velocities, both passes must end every substep bitwise the same, and so must a pass that
/// leaves out all but the pairs that may come within `1.02 thickness` (`HOT` 0.02), which has
/// to look at all of them, listing them first, whenever the repulsion moves a vertex by more
/// than a hundredth of `thickness`.
#[test]
fn leaving_out_the_pairs_the_motion_cannot_bring_near_ends_each_substep_as_looking_at_all() {
    let (pile, twist) = pile_and_twist();
    let (mut contacts, mut widened) = (0, 0);
    for (name, scene, (from, to), omega) in [
        ("pile", pile, (1600, 1800), 0.0),
        ("twist", twist, (1, 400), 2.0),
    ] {
        let dt = scene.dt as f32;
        let frames = recorded(scene.clone(), from, to, omega);
        let spec = scene.self_collision.clone().unwrap();
        let (model, _) = Model::new(scene).unwrap();
        let new = || SelfCollision::new(spec.thickness as f32, spec.friction as f32, 4);
        let (mut pass, mut all, mut narrow) = (new(), new(), new());
        all.look_at_all = true;
        narrow.hot = Some(0.02);
        for w in frames.windows(2) {
            let n = w[0].len();
            let start = Kinematics {
                pos: w[0].clone(),
                vel: Vec3s::zeros(n),
            };
            let moved = Kinematics {
                pos: w[1].clone(),
                vel: Vec3s::from_fn(n, |v| (w[1].get(v) - w[0].get(v)) / dt),
            };
            let mut ends = [(); 3].map(|_| Kinematics::zeros(n));
            for (p, end) in [&mut pass, &mut all, &mut narrow]
                .into_iter()
                .zip(&mut ends)
            {
                end.copy_from(&moved);
                assert!(p.apply(&model, &start, end));
            }
            let every = bits(&ends[1]);
            assert!(bits(&ends[0]) == every, "{name}: a substep ended elsewhere");
            assert!(
                bits(&ends[2]) == every,
                "{name}: a narrow substep ended elsewhere"
            );
        }
        let (left, every) = (pass.stats, all.stats);
        eprintln!(
            "{name}: {left:?}\nlooking at all: {every:?}\nnarrow: {:?}",
            narrow.stats
        );
        assert_eq!(left.contacts, every.contacts, "{name}");
        contacts += every.contacts;
        widened += narrow.stats.widened;
        let listed = every.substeps - every.swept_substeps;
        assert!(
            listed > 50 && left.pairs < every.pairs,
            "{name}: no pair was left out"
        );
    }
    // The settling pile's layers touch: the repulsion corrected pairs, and the narrow pass had
    // to look at all of them then.
    assert!(contacts > 0 && widened > 0);
}
