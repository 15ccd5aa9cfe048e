//! The interactive scenes that turn `[self_collision]` on (docs/contact.md, "Self-collision in
//! the scenes"): a drag that folds the cloth onto itself, driven as the demo drives it (a grip
//! of the default radius, one `drag_to` per 1/60 s frame), leaves no two triangles crossing by
//! the independent checker (tests/common/crossings.rs), and the same drag without the pass
//! does leave some, so the test can fail. The pass must not stop the grip either: at the end of
//! every frame the grabbed particle is on that frame's target, or, where a collider holds the
//! grip back, it ends as near its target as without the pass.
//!
//! The story: without self-collision, a user dragging a corner of such a scene across the cloth
//! saw the layers pass through each other.

use crate::common;

use common::crossings::intersecting_pairs;
use glam::Vec3;
use rustcloth::{Scene, Simulation};

const FRAME: f64 = 1.0 / 60.0;

/// What a fold leaves: the crossings found every fifth frame of the drag and the hold, the
/// farthest the grabbed particle was from its frame's target at the end of a frame, and how
/// far it is from the last target at the end of the hold (m).
struct Folded {
    found: Vec<usize>,
    off_target: f32,
    behind_at_end: f32,
}

/// Opens the scene for a second, then grabs the free particle farthest from the pinned ones
/// (or from the cloth's centre) and draws it over 0.75 s past the centre to 0.6 of its distance
/// on the other side, 5 cm above the cloth's top, and holds it 0.5 s.
fn fold(scene: Scene) -> Folded {
    let mut sim = Simulation::new(scene).unwrap();
    for _ in 0..60 {
        sim.advance(FRAME).unwrap();
    }
    let x = sim.positions();
    let p = sim.particles();
    let mean = |keep: &dyn Fn(usize) -> bool| {
        let (sum, n) = (0..x.len())
            .filter(|&i| keep(i))
            .fold((Vec3::ZERO, 0.0), |(s, n), i| (s + x.get(i), n + 1.0));
        sum / n
    };
    let anchor = if p.pinned.iter().any(|&b| b) {
        mean(&|i| p.pinned[i])
    } else {
        mean(&|i| p.alive[i])
    };
    let grab = (0..x.len())
        .filter(|&i| p.alive[i] && !p.pinned[i])
        .max_by(|&a, &b| {
            let (da, db) = (x.get(a).distance(anchor), x.get(b).distance(anchor));
            da.total_cmp(&db)
        })
        .unwrap();
    let centre = mean(&|i| p.alive[i]);
    let start = x.get(grab);
    let mut target = centre + 0.6 * (centre - start);
    let top = (0..x.len()).map(|i| x.get(i).y).fold(f32::MIN, f32::max);
    target.y = target.y.max(top + 0.05);
    sim.grab(grab as i64).unwrap();
    let mut found = Vec::new();
    let (mut off_target, mut behind_at_end) = (0.0f32, 0.0f32);
    for f in 1..=75 {
        let to = start + (target - start) * (f as f32 / 45.0).min(1.0);
        sim.drag_to(to).unwrap();
        sim.advance(FRAME).unwrap();
        behind_at_end = sim.positions().get(grab).distance(to);
        off_target = off_target.max(behind_at_end);
        if f % 5 == 0 {
            let tris: Vec<[u32; 3]> = sim.triangles().to_vec();
            found.push(intersecting_pairs(&tris, sim.positions(), |q| q).len());
        }
    }
    Folded {
        found,
        off_target,
        behind_at_end,
    }
}

/// The scene `name`, which turns the pass on, folded as it ships and without the pass: with it
/// no two triangles cross, and without it some do, so the check can fail. Returns both folds.
fn folded_with_and_without(name: &str) -> (Folded, Folded) {
    let scene = Scene::builtin(name).unwrap();
    assert!(
        scene.self_collision.is_some(),
        "{name} has no [self_collision]"
    );
    let mut without = scene.clone();
    without.self_collision = None;
    let (with, without) = (fold(scene), fold(without));
    assert!(
        with.found.iter().all(|&c| c == 0),
        "{name}: {:?}",
        with.found
    );
    assert!(
        without.found.iter().any(|&c| c > 0),
        "{name} folds without crossing anyway"
    );
    (with, without)
}

/// The scenes that turn the pass on, and the fold keeps them free of crossings with the grip
/// on its target.
fn folds_without_crossing(name: &str) {
    let (with, _) = folded_with_and_without(name);
    // A third of the grid spacing: the glide to each target ends within the frame.
    assert!(
        with.off_target < 0.01,
        "{name}: the grip lags its target by {} m",
        with.off_target
    );
}

/// A scene with the pass whose drag runs into a collider: the fold keeps it free of crossings,
/// and the grip ends within 10 cm of where it ends without the pass (the collider holds it
/// back in both; the pass must not hold it back further). Its own patch must not stop it: a
/// grip whose particles are each pushed round the collider on their own paths changes shape
/// from frame to frame, pairs inside the grip close, and the pass stops the whole grip on them
/// (`round_tablecloth` 650 mm behind its target against 127 mm without the pass, `flag_hole`
/// 669 mm against 0).
fn follows_round_a_collider_as_without_the_pass(name: &str) {
    let (with, without) = folded_with_and_without(name);
    let (on, off) = (with.behind_at_end, without.behind_at_end);
    assert!(
        on.is_finite() && off.is_finite() && on < off + 0.1,
        "{name}: the grip ends {on} m from its target with the pass, {off} m without"
    );
}

#[test]
fn a_grip_dragged_over_the_round_table_with_the_pass_on_follows_as_without_it() {
    follows_round_a_collider_as_without_the_pass("round_tablecloth");
}

#[test]
fn a_grip_dragged_past_the_flag_pole_with_the_pass_on_follows_as_without_it() {
    follows_round_a_collider_as_without_the_pass("flag_hole");
}

#[test]
fn a_fold_of_freefall_by_a_drag_leaves_no_crossing() {
    folds_without_crossing("freefall");
}
