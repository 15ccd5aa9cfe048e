//! The scene's `[[colliders]]` for Python: posing them between steps and reading their poses,
//! what a renderer needs to draw them where the cloth sees them.

use pyo3::prelude::*;

use super::conv::Rows;
use super::errors::IntoPyResult;
use super::simulation::PySimulation;

super::simulation::methods! {
    /// Puts collider ``index`` at ``position`` (m) with ``rotation`` (a unit quaternion
    /// ``(x, y, z, w)``) by the end of the next step; see ``rustcloth.Simulation``.
    fn set_collider_pose(index: i64, position: [f64; 3], rotation: [f64; 4]) -> () =
        with |h| h.sim.set_collider_pose(index, position, rotation).py();
    /// ``(positions, rotations)``: each collider's position now, ``(K, 3)`` float64 in m, and
    /// orientation, ``(K, 4)`` float64 unit quaternions ``(x, y, z, w)``.
    fn collider_poses() -> (Rows<f64>, Rows<f64>) = read |h| {
        let poses = h.sim.collider_poses();
        let positions = poses.iter().flat_map(|p| p.position.to_array()).collect();
        (Rows(positions, 3), Rows(poses.iter().flat_map(|p| p.rotation.to_array()).collect(), 4))
    };
}
