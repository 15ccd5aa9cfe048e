//! Tearing: springs past `tearing.max_strain` break after a step, the most strained
//! first and at most `max_per_step`; a corner dragged far enough rips off; the pass is absent
//! without `[tearing]`, and a tear is the same for any number of threads.

use crate::common;

use common::{bare_scene, state_hash, with_threads, Drawn};
use glam::Vec3;
use rustcloth::grid::{Family, SpringKind};
use rustcloth::scene::TearingSpec;
use rustcloth::{Error, Scene, Simulation};

/// The built-in `tear` curtain as a plain sheet: without its perforation, tearing at 0.3
/// strain, so that a pull rips where the pull alone puts the most strain (the scene itself
/// rips along its perforation: tests/test_grip.py).
fn tear_scene() -> Scene {
    let mut scene = Scene::builtin("tear").unwrap();
    scene.cloth.cuts.clear();
    let tearing = scene.tearing.take().expect("the tear scene tears");
    scene.tearing = Some(TearingSpec {
        max_strain: 0.3,
        ..tearing
    });
    scene
}

/// Every live spring of the stiff families as `(kind, anchor, strain)`.
fn strains(sim: &Simulation) -> Vec<(SpringKind, usize, f32)> {
    let (grid, springs, pos) = (sim.grid(), sim.springs(), sim.positions());
    let scene = sim.scene();
    let mut out = Vec::new();
    for family in Family::ALL {
        let k = match family {
            Family::Structural => scene.cloth.k_structural,
            Family::Shear => scene.cloth.k_shear,
            Family::Bend => scene.cloth.k_bend,
        };
        if k == 0.0 {
            continue;
        }
        for kind in family.kinds() {
            springs.for_each(grid, kind, |a, b, rest| {
                out.push((kind, a, (pos.get(b) - pos.get(a)).length() / rest - 1.0));
            });
        }
    }
    out
}

/// The particles of the grip: the left third of the bottom row of the tear scene.
const GRIP: std::ops::Range<usize> = 0..13;

/// Pulls the bottom-left corner of the tear scene down, to the left and towards the viewer at
/// about 1 m/s, holding it by kinematic pins on the left third of its bottom row (a hand's
/// grip: a single grabbed particle concentrates the whole pull on its own few springs and
/// tears out alone), calling `each` after every step; returns the simulation.
fn drag_corner(steps: u32, mut each: impl FnMut(&mut Simulation)) -> Simulation {
    let mut sim = Simulation::new(tear_scene()).unwrap();
    sim.step(100).unwrap();
    let start: Vec<Vec3> = GRIP.map(|p| sim.positions().get(p)).collect();
    for s in 1..=steps {
        let f = s as f32 * 0.001;
        for (p, x) in GRIP.zip(&start) {
            let target = *x + Vec3::new(-0.8 * f, -0.5 * f, 0.3 * f);
            sim.pin(p as i64, Some(target)).unwrap();
        }
        sim.step(1).unwrap();
        each(&mut sim);
    }
    sim
}

#[test]
fn a_corner_dragged_far_enough_rips_off() {
    let mut torn_at = None;
    let mut step = 0;
    let sim = drag_corner(1500, |sim| {
        step += 1;
        if torn_at.is_none() && sim.pieces() > 1 {
            torn_at = Some(step);
        }
    });
    let torn_at = torn_at.expect("the corner never tore off");
    assert!(
        torn_at > 10,
        "tore at once, at step {torn_at}: the cloth is too weak"
    );
    // The dragged corner is a piece of its own, apart from the pinned curtain, with the whole
    // grip on it (the rip runs along the grip's edge, where the pull concentrates).
    let labels = sim.piece_labels();
    let top = sim.grid().len() - 1;
    assert_ne!(labels[0], labels[top]);
    let mut grip = GRIP;
    assert!(grip.all(|p| labels[p] == labels[0]));
    assert_eq!(sim.pieces(), 2);
    // The corner went with the drag, and the curtain hangs as before, far from it.
    let corner = sim.positions().get(0);
    let nearest = (0..labels.len())
        .filter(|&p| labels[p] == labels[top])
        .map(|p| (sim.positions().get(p) - corner).length())
        .fold(f32::INFINITY, f32::min);
    assert!(
        nearest > 0.1,
        "the torn corner is {nearest} m from the curtain"
    );
    assert!((0..labels.len()).all(|p| sim.velocities().get(p).is_finite()));
}

/// Checks one step's tear: `before` the live springs (`strains`) before the step, `sim` after
/// it. At most `cap` broke, each past `limit` on the positions the pass ran on (the ones after
/// the step), and a spring left past the limit only when the cap stopped the pass, and then no
/// more strained than any that broke; a tear moves the topology version past `version`.
/// Returns how many broke.
fn check_tear_step(
    before: &[(SpringKind, usize, f32)],
    sim: &Simulation,
    limit: f32,
    cap: usize,
    version: u64,
) -> usize {
    let now = strains(sim);
    let live: std::collections::HashSet<(usize, usize)> =
        now.iter().map(|&(k, a, _)| (k.index(), a)).collect();
    let broke: Vec<_> = before
        .iter()
        .filter(|&&(k, a, _)| !live.contains(&(k.index(), a)))
        .collect();
    assert!(broke.len() <= cap, "{} broke in one step", broke.len());
    let spring_strain = |k: SpringKind, a: usize| {
        let (grid, pos) = (sim.grid(), sim.positions());
        let b = a + grid.offset(k);
        (pos.get(b) - pos.get(a)).length() / sim.springs().rest[k.index()][a] - 1.0
    };
    let weakest = broke
        .iter()
        .map(|&&(k, a, _)| spring_strain(k, a))
        .fold(f32::INFINITY, f32::min);
    assert!(
        broke.is_empty() || weakest > limit,
        "broke at strain {weakest}"
    );
    let strongest_left = now.iter().map(|s| s.2).fold(f32::NEG_INFINITY, f32::max);
    if broke.len() < cap {
        assert!(strongest_left <= limit, "{strongest_left} left unbroken");
    } else {
        assert!(
            strongest_left <= weakest,
            "a spring at strain {strongest_left} was left while one at {weakest} broke"
        );
    }
    if !broke.is_empty() {
        assert!(sim.topology_version() > version);
    }
    broke.len()
}

#[test]
fn only_springs_past_the_limit_break_the_most_strained_first() {
    let spec = tear_scene().tearing.unwrap();
    let (limit, cap) = (spec.max_strain as f32, spec.max_per_step as usize);
    let mut before: Vec<(SpringKind, usize, f32)> = Vec::new();
    let mut broke_total = 0;
    let mut version = 0;
    drag_corner(1200, |sim| {
        if !before.is_empty() {
            broke_total += check_tear_step(&before, sim, limit, cap, version);
        }
        version = sim.topology_version();
        before = strains(sim);
    });
    assert!(broke_total > 0, "nothing tore");
}

/// The cap and the order, where a drag never reaches them (it breaks a few springs a step):
/// a free 10 x 10 cloth set down stretched along x, by `0.1 i` between columns `i` and
/// `i + 1`, so that nearly 200 springs are past a limit of 0.25 at once. Each step must break
/// exactly `max_per_step` of them, the most strained: the rip starts at the most stretched
/// side and works back, `max_per_step` springs a step.
#[test]
fn a_cloth_stretched_past_the_limit_everywhere_tears_the_most_strained_first_a_few_a_step() {
    let (limit, cap) = (0.25f32, 8usize);
    let mut scene = bare_scene(10, 10);
    scene.tearing = Some(TearingSpec {
        max_strain: limit as f64,
        max_per_step: cap as u32,
    });
    let mut sim = Simulation::new(scene).unwrap();
    let (nx, n) = (10, sim.positions().len());
    let mut pos = sim.positions().clone();
    let dx = pos.get(1).x - pos.get(0).x;
    for p in 0..n {
        let i = (p % nx) as f32;
        pos.set(
            p,
            pos.get(p) + Vec3::new(dx * 0.05 * i * (i - 1.0), 0.0, 0.0),
        );
    }
    sim.set_positions(&pos).unwrap();
    let over = strains(&sim).iter().filter(|s| s.2 > limit).count();
    assert!(over > 5 * cap, "only {over} springs past the limit");
    for _ in 0..5 {
        let (before, version) = (strains(&sim), sim.topology_version());
        sim.step(1).unwrap();
        let broke = check_tear_step(&before, &sim, limit, cap, version);
        assert_eq!(broke, cap, "springs broken in one step");
    }
}

#[test]
fn without_tearing_or_below_its_limit_the_step_is_bitwise_the_same() {
    let run = |tearing: Option<TearingSpec>| {
        let mut scene = tear_scene();
        scene.tearing = tearing;
        let mut sim = Simulation::new(scene).unwrap();
        sim.step(200).unwrap();
        (
            state_hash(&sim),
            sim.topology_version(),
            sim.effects().contains(&"tearing"),
        )
    };
    let (plain, version, listed) = run(None);
    assert!(!listed);
    let high = Some(TearingSpec {
        max_strain: 1e30,
        max_per_step: 16,
    });
    assert_eq!(run(high), (plain, version, true));
}

#[test]
fn tears_are_deterministic_for_any_thread_count() {
    let run = |threads| {
        with_threads(threads, || {
            let mut sim = drag_corner(900, |_| {});
            (
                state_hash(&sim),
                sim.topology_version(),
                sim.pieces(),
                sim.triangles().len(),
            )
        })
    };
    let one = run(1);
    assert!(one.2 > 1, "nothing tore");
    for threads in [2, 3, 7] {
        assert_eq!(run(threads), one, "{threads} threads");
    }
}

#[test]
fn bad_tearing_settings_are_named() {
    let name = |e: Error| match e {
        Error::InvalidValue { name, .. } => name,
        other => panic!("{other:?}"),
    };
    for (max_strain, max_per_step, want) in [
        (0.0, 4, "tearing.max_strain"),
        (f64::NAN, 4, "tearing.max_strain"),
        (1e300, 4, "tearing.max_strain"),
        (0.3, 0, "tearing.max_per_step"),
    ] {
        let mut scene = tear_scene();
        scene.tearing = Some(TearingSpec {
            max_strain,
            max_per_step,
        });
        let err = Simulation::new(scene).err().expect("refused");
        assert_eq!(name(err), want);
    }
    let toml = "[tearing]\nmax_strain = 0.2\nmax_per_step = 3\n";
    let scene = Scene::from_toml_str(toml).unwrap();
    assert_eq!(
        scene.tearing,
        Some(TearingSpec {
            max_strain: 0.2,
            max_per_step: 3
        })
    );
}

/// A tear has no stroke: the drawn mesh opens each broken spring at its midpoint, each side
/// with its own vertices, and as the corner is pulled away no drawn triangle reaches across
/// the tear. The story: this tear runs just above the grip's row, which is left a strip one
/// particle wide with no two-dimensional frame; its cut vertices first sat on their particles
/// and then pointed straight at the other side, and the slivers along the strip were drawn
/// 2.0 and then 1.7 times their rest length. `Frame::Strip` keeps the rest offset.
#[test]
fn a_tear_along_a_one_particle_strip_draws_a_clean_edge() {
    let mut torn = None;
    let mut sim = drag_corner(1500, |sim| {
        if torn.is_none() && sim.pieces() > 1 {
            torn = Some(sim.steps());
        }
    });
    assert!(torn.is_some(), "the corner did not rip off");
    let drawn = Drawn::of(&mut sim);
    assert!(
        drawn.positions.len() > drawn.particles,
        "no cut vertex along the tear"
    );
    drawn.assert_pieces_share_no_vertex(&sim.piece_labels());
    let stretch = drawn.max_edge_stretch(0.05 * 1.0 / (sim.grid().ny - 1) as f32);
    assert!(
        stretch < 1.5,
        "a drawn edge is stretched {stretch} times its rest length"
    );
}
