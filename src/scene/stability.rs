//! The stability estimate: the largest step each integrator takes on a scene's cloth without
//! blowing up, from the cloth's stiffest mode.

use super::IntegratorKind;
use super::Scene;

/// The largest substep `h` (s) at which `integrator` stays stable on the scene's cloth with
/// particles of mass `m` (kg), or None when any is (implicit Euler, or no springs).
///
/// The stiffest mode of the cloth at rest has `omega^2 = 4 (k_structural + k_shear + k_bend) / m`
/// to within 5 % (checked against the eigenvalues of the assembled stiffness matrix). Spring
/// damping has the stiffness's pattern, so the same mode is damped at a rate `gamma` of at most
/// `4 n c / m` (`n` families with k > 0; bending springs damp it less, down to about `2 n c /
/// m`), plus `air_drag / m`. Each integrator's limit for that damped mode is
/// [`IntegratorKind::stable_substep`]; docs/stability.md measures the estimate against
/// bisection.
pub fn stable_substep(scene: &Scene, integrator: IntegratorKind, m: f64) -> Option<f64> {
    if let Some(mesh) = &scene.cloth.mesh {
        return mesh_substep(scene, integrator, mesh);
    }
    let cloth = &scene.cloth;
    let families = [cloth.k_structural, cloth.k_shear, cloth.k_bend];
    let k_sum: f64 = families.iter().sum();
    if k_sum == 0.0 {
        return None;
    }
    let omega2 = 4.0 * k_sum / m;
    let damped = families.iter().filter(|&&k| k > 0.0).count() as f64 * cloth.damping / m;
    let drag = scene.air_drag / m;
    integrator.stable_substep(omega2, 4.0 * damped + drag, 2.0 * damped + drag)
}

/// A mesh cloth's stable substep, from Gershgorin's bounds on its stiffest and most damped
/// vertex ([`super::MeshCloth::max_omega2`]): an upper bound on the frequency, so
/// the estimate errs towards a shorter step. The lightest vertex's drag rate is added.
fn mesh_substep(scene: &Scene, integrator: IntegratorKind, mesh: &super::MeshSpec) -> Option<f64> {
    let cloth = super::MeshCloth::new(mesh).ok()?;
    let omega2 = cloth.max_omega2();
    if omega2 == 0.0 {
        return None;
    }
    let lightest = cloth.masses.iter().copied().fold(f64::INFINITY, f64::min);
    let damped = cloth.max_damping_rate() + scene.air_drag / lightest;
    integrator.stable_substep(omega2, damped, damped / 2.0)
}
