//! The passes of a substep taken one at a time, to see what each leaves.

use glam::Vec3;

use super::{Pipeline, Substep};
use crate::model::Model;
use crate::profile::Profile;
use crate::scene::{IntegratorKind, Plane, Scene};
use crate::soa::Vec3s;
use crate::state::{Kinematics, State};

/// `steps` substeps of `scene`'s, each readied (its contacts predicted, its work judged) and
/// handed to `passes` with its index and a force buffer, to run the passes it looks at.
fn substeps(
    scene: Scene,
    steps: usize,
    mut passes: impl FnMut(usize, &mut Pipeline, Substep, &mut Vec3s),
) {
    let (model, pos) = Model::new(scene).unwrap();
    let n = pos.len();
    let mut pipeline = Pipeline::compile(&model.scene, n);
    let mut state = State::new(pos);
    let (h, mut time) = (model.scene.dt as f32, 0.0);
    let (mut profile, mut force, mut next) = (Profile::default(), Vec3s::zeros(n), None);
    for step in 0..steps {
        time += h as f64;
        let mut out = next.take().unwrap_or_else(|| Kinematics::zeros(n));
        let mut s = Substep::new(&model, &state, &mut out, (h, time), &mut profile);
        pipeline.predict_contacts(&mut s);
        pipeline.judge_work(&s);
        passes(step, &mut pipeline, s, &mut force);
        next = Some(std::mem::replace(&mut state.kin, out));
    }
}

/// Implicit Euler held each predicted contact with a stiff spring along its normal, which left
/// a landing particle about a thousandth of its free motion behind its plane (here up to
/// 0.43 mm); the floor's pass after the solve pushed it out, adding the energy of the springs
/// it stretched. Filtered out of the conjugate gradient's directions, the
/// contact puts each held particle on its target within the solve, and the floor's pass after
/// it has nothing left to move.
#[test]
fn implicit_euler_landing_leaves_no_particle_below_its_contact_plane() {
    // The pile's square dropped edge first from 40 cm onto its floor alone.
    let mut scene = Scene::builtin("pile").unwrap();
    scene.integrator = IntegratorKind::ImplicitEuler;
    (scene.dt, scene.substeps) = (1.0 / 60.0, 1);
    scene.cloth.plane = Plane::Xy;
    scene.cloth.pins.clear();
    scene.cloth.center = [0.0, 0.4 + scene.cloth.size[1] / 2.0, 0.0];
    (scene.spheres, scene.colliders, scene.self_collision) = (vec![], vec![], None);
    let (mut held, mut worst_depth, mut worst_push) = (0, 0.0f32, 0.0f32);
    substeps(scene, 40, |_, pipeline, mut s, force| {
        let n = s.next.pos.len();
        assert!(pipeline.integrate(&mut s, force, 0));
        // The last solve's start: the substep's, or its last half's where it was split.
        let start = match pipeline.last_piece {
            Some(_) => &pipeline.piece_start.pos,
            None => &s.state.kin.pos,
        };
        let contacts = pipeline.contacts.as_ref().unwrap();
        for p in 0..n {
            let normal = contacts.normal.get(p);
            if normal == Vec3::ZERO {
                continue;
            }
            let target = contacts.offset[p].min(normal.dot(start.get(p)));
            worst_depth = worst_depth.max(target - normal.dot(s.next.pos.get(p)));
            held += 1;
        }
        let solved = s.next.pos.clone();
        assert!(pipeline.collide(&mut s));
        for p in 0..n {
            worst_push = worst_push.max((s.next.pos.get(p) - solved.get(p)).length());
        }
    });
    assert!(held > 100, "{held} held particles: the cloth did not land");
    assert!(
        worst_depth <= 1e-6,
        "a held particle ended {worst_depth} m behind its target"
    );
    assert!(
        worst_push <= 1e-6,
        "the floor's pass moved a particle {worst_push} m"
    );
}

/// Implicit Euler held inside its solve only the self-contact pairs that a step's inertial
/// motion closes while a collider contact was held (the floor under a pile always is): in a
/// pile at rest that is almost none, so the springs pressed the layers through each other in
/// the solve and the self-collision pass pushed hundreds of vertices back every step, up to
/// 10.6 mm here, storing again the energy the solve had let go of. Holding the pairs the first
/// solve closes, the pass after the solve only tidies: no vertex moves a `thickness`.
#[test]
fn in_a_pile_at_rest_on_the_floor_the_self_collision_pass_moves_no_vertex_a_thickness() {
    let scene = Scene::builtin("pile").unwrap();
    let thickness = scene.self_collision.as_ref().unwrap().thickness as f32;
    let mut worst_push = 0.0f32;
    // 4 s: the ball is below the floor from 2.8 s and the pile at rest from about 4 s; the
    // last 30 steps are judged.
    let steps = (4.0 / scene.dt).round() as usize;
    substeps(scene, steps, |step, pipeline, mut s, force| {
        assert!(pipeline.integrate(&mut s, force, 0));
        assert!(pipeline.collide(&mut s));
        let solved = s.next.pos.clone();
        assert!(pipeline.separate_self_contacts(&mut s));
        if step + 30 >= steps {
            for p in 0..solved.len() {
                worst_push = worst_push.max((s.next.pos.get(p) - solved.get(p)).length());
            }
        }
    });
    assert!(
        worst_push < thickness,
        "the self-collision pass moved a vertex {worst_push} m"
    );
}

/// Each contact round of a pile's substep is corrected from the round before's solve, and a
/// resting pile's contacts change in nearly every round. Solved as a whole step (a loose solve
/// finding the self-contact pairs and one holding them), each round would cost two solves only
/// for its result to be corrected and solved again. Stopped at its loose solve, a round that
/// another follows costs one, and the substep still ends on a solve at the scene's
/// `cg_tolerance`.
#[test]
fn a_pile_s_contact_round_followed_by_another_takes_one_solve() {
    let scene = Scene::builtin("pile").unwrap();
    let tolerance = scene.cg_tolerance as f32;
    // To 1.2 s: the cloth first meets itself at 0.56 s, folded over its ball onto the floor.
    let steps = (1.2 / scene.dt).round() as usize;
    // Every round but the last one solve; the last, the step's two.
    let bound = super::solve::CONTACT_ROUNDS as u64 + 1;
    let (mut most, mut every_round) = (0, 0);
    substeps(scene, steps, |step, pipeline, mut s, force| {
        let before = (pipeline.integrator.solver_stats().unwrap(), pipeline.halved);
        assert!(pipeline.integrate(&mut s, force, 0));
        let after = (pipeline.integrator.solver_stats().unwrap(), pipeline.halved);
        assert!(
            after.0.last_residual <= tolerance,
            "substep {step}: the last solve ended at {}",
            after.0.last_residual
        );
        // A halved substep solves each half in its own rounds.
        if after.1 == before.1 {
            let solves = after.0.solves - before.0.solves;
            most = most.max(solves);
            every_round += (solves == bound) as usize;
        }
    });
    assert!(most <= bound, "a substep took {most} solves");
    assert!(
        every_round > 10,
        "{every_round} substeps ran every contact round: the pile did not pile"
    );
}
