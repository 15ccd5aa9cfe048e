//! Wind: air moving past the cloth, pushing on each triangle.
//!
//! **The air.** Its velocity at a point `x` (m) and time `t` (s) is
//!
//! ```text
//! w(x, t) = U (1 + g(t)) + T(x, t)
//! g(t)    = gust * sum_k a_k sin(2 pi t / P_k + phi_k)                 (three terms, sum a_k = 1)
//! T(x, t) = turbulence * sum_k e_k sin(kappa_k . (x - U t) + psi_k) / 4  (four terms)
//! ```
//!
//! `U` the mean wind (m/s); `g` the gusts, slow swells of the whole wind of at most `gust` times
//! its strength, with periods `P_k` around `gust_period`; `T` the turbulence, eddies of size
//! `turbulence_scale` (`|kappa_k| = 2 pi / turbulence_scale`) carried along by the mean wind,
//! each of speed at most `turbulence / 4` (m/s) along a unit direction `e_k`, so that together
//! they add at most `turbulence`. Periods, directions and phases come from `seed`: the same seed
//! blows the same wind.
//!
//! **The force.** A triangle of area `A` and unit normal `n`, whose corners move at mean
//! velocity `v`, sees the air at `u = w - v` (`w` the mean of the air at its corners), and feels
//! the aerodynamic drag and lift of a flat plate, as newton's cloth model writes them:
//!
//! ```text
//! F_drag = 1/2 rho C_d A |u_hat . n| |u| u          (the flow's push on the area it sees)
//! F_lift = 1/2 rho C_l A alpha |u|^2 n,  alpha = asin(u_hat . n)   (the angle of attack)
//! ```
//!
//! `rho` the air's density (kg/m^3), `C_d` and `C_l` dimensionless. A third of each goes to each
//! corner.
//!
//! **The step.** The pass runs after the integrator, as a change of each moving particle's
//! velocity over the substep `h` (operator splitting: first order in `h`, the same for every
//! integrator). Both forces are linear in the relative velocity once their sizes are frozen:
//! `F = K u` with the rate matrix `K = r I + k n n^T`, `r = 1/2 rho C_d A |u_hat . n| |u|` and
//! `k = 1/2 rho C_l A |u| alpha / (u_hat . n)` (N s/m). Each corner takes a third of `K`
//! applied to its own velocity, `K (w - v_p) / 3`, which sums to the triangle's force, and the
//! step is implicit in it:
//!
//! ```text
//! dv_p = h (m_p I + h K_p)^-1 K_p (w_p - v_p),   K_p, K_p w_p: sums of the corner's thirds
//! ```
//!
//! so a light cloth in a strong wind approaches the air's speed and never overshoots it, however
//! long the step. The position moves by `h dv` with it. The air and the rates are evaluated on
//! the substep's starting state, at its start time.

use std::f64::consts::TAU;

use glam::{DVec3, Mat3, Vec3};
use rayon::prelude::*;

use crate::model::Model;
use crate::scene::WindSpec;
use crate::soa::Vec3s;
use crate::state::Kinematics;

/// Gust terms and turbulence terms of the air's velocity.
const GUSTS: usize = 3;
const EDDIES: usize = 4;

/// Particles per parallel work item of the per-particle loops.
const CHUNK: usize = 4096;

/// The wind of a scene, compiled: the air's terms, and the per-particle sums a substep fills.
pub struct Wind {
    mean: DVec3,
    /// `(amplitude, angular frequency in rad/s, phase)` of each gust term.
    gusts: [(f64, f64, f64); GUSTS],
    /// `(amplitude in m/s along its direction, wave vector in rad/m, phase)` of each eddy.
    eddies: [(Vec3, DVec3, f64); EDDIES],
    /// `1/2 rho C_d` and `1/2 rho C_l`, in kg/m^3.
    drag: f32,
    lift: f32,
    /// The air's velocity at each particle this substep, m/s.
    air: Vec3s,
    /// Per particle, summed over its triangles' thirds: the rate matrix `K` (N s/m) and `K w`
    /// (N).
    rates: Vec<Mat3>,
    /// The cloth's drawn triangles, and the model's `topology_version` they were listed at:
    /// listed again only after a cut or a tear, not every substep.
    triangles: Vec<[u32; 3]>,
    triangles_at: Option<u64>,
    pulls: Vec<Vec3>,
}

impl Wind {
    pub const NAME: &'static str = "wind";

    pub fn new(spec: &WindSpec, particles: usize) -> Wind {
        let mut random = SplitMix64(spec.seed);
        // Periods from 0.6 to 1.6 times `gust_period`, weights summing to one.
        let weights = [0.5, 0.3, 0.2];
        let gusts = weights.map(|a| {
            let period = spec.gust_period * (0.6 + random.unit());
            (spec.gust * a, TAU / period, TAU * random.unit())
        });
        let eddies = [(); EDDIES].map(|()| {
            let along = random.direction();
            let wave = random.direction() * (TAU / spec.turbulence_scale);
            let amplitude = (along * spec.turbulence / EDDIES as f64).as_vec3();
            (amplitude, wave, TAU * random.unit())
        });
        Wind {
            mean: DVec3::from(spec.velocity),
            gusts,
            eddies,
            drag: (0.5 * spec.air_density * spec.drag) as f32,
            lift: (0.5 * spec.air_density * spec.lift) as f32,
            air: Vec3s::zeros(particles),
            rates: vec![Mat3::ZERO; particles],
            triangles: Vec::new(),
            triangles_at: None,
            pulls: vec![Vec3::ZERO; particles],
        }
    }

    /// The air's velocity (m/s) at `x` (m) at time `t` (s): the mean wind with its gusts and
    /// the turbulence.
    pub fn air_at(&self, x: Vec3, t: f64) -> Vec3 {
        self.mean_at(t) + eddies_at(&self.eddies, self.mean, x.as_dvec3(), t)
    }

    /// The mean wind with its gusts at time `t`.
    fn mean_at(&self, t: f64) -> Vec3 {
        let swell: f64 = self
            .gusts
            .iter()
            .map(|&(a, omega, phase)| a * (omega * t + phase).sin())
            .sum();
        (self.mean * (1.0 + swell)).as_vec3()
    }

    /// Blows on the cloth for a substep of length `h` from `current`, starting at time `t`:
    /// changes the velocities (and positions, by `h dv`) in `next` of every particle that
    /// moves. Returns whether what it wrote is finite.
    pub fn apply(
        &mut self,
        model: &Model,
        current: &Kinematics,
        next: &mut Kinematics,
        h: f32,
        t: f64,
    ) -> bool {
        self.blow_air(current, t);
        self.sum_triangle_rates(model, current);
        self.change_velocities(model, current, next, h)
    }

    /// The air at every particle.
    fn blow_air(&mut self, current: &Kinematics, t: f64) {
        let mean = self.mean_at(t);
        let still = self.eddies.iter().all(|e| e.0 == Vec3::ZERO);
        if still {
            self.air.fill(mean);
            return;
        }
        let (eddies, wind, pos) = (self.eddies, self.mean, &current.pos);
        let air = &mut self.air;
        let (ax, ay, az) = (&mut air.x, &mut air.y, &mut air.z);
        (
            ax.par_chunks_mut(CHUNK),
            ay.par_chunks_mut(CHUNK),
            az.par_chunks_mut(CHUNK),
        )
            .into_par_iter()
            .enumerate()
            .for_each(|(c, (ax, ay, az))| {
                for k in 0..ax.len() {
                    let p = c * CHUNK + k;
                    let w = mean + eddies_at(&eddies, wind, pos.get(p).as_dvec3(), t);
                    (ax[k], ay[k], az[k]) = (w.x, w.y, w.z);
                }
            });
    }

    /// Each drawn triangle's rate matrix `K = r I + k n n^T`, a third to each corner with a
    /// third of `K w`. In the triangles' order, one thread: every particle's sum has one order.
    fn sum_triangle_rates(&mut self, model: &Model, current: &Kinematics) {
        self.rates.fill(Mat3::ZERO);
        self.pulls.fill(Vec3::ZERO);
        if self.triangles_at != Some(model.topology_version) {
            self.triangles.clear();
            self.triangles.extend(model.triangles());
            self.triangles_at = Some(model.topology_version);
        }
        let (pos, vel) = (&current.pos, &current.vel);
        for &[a, b, c] in &self.triangles {
            let [a, b, c] = [a as usize, b as usize, c as usize];
            let (xa, xb, xc) = (pos.get(a), pos.get(b), pos.get(c));
            let twice_area = (xb - xa).cross(xc - xa);
            let double = twice_area.length();
            if double.is_nan() || double <= 0.0 {
                continue; // a collapsed triangle has no area to push on
            }
            let (n, area) = (twice_area / double, 0.5 * double);
            let air = (self.air.get(a) + self.air.get(b) + self.air.get(c)) / 3.0;
            let u = air - (vel.get(a) + vel.get(b) + vel.get(c)) / 3.0;
            let speed = u.length();
            if speed.is_nan() || speed <= 0.0 {
                continue; // moving with the air: no force
            }
            let cos = (u.dot(n) / speed).clamp(-1.0, 1.0);
            // alpha / cos alpha's complement, 1 where the flow runs along the plate.
            let lift_per_cos = if cos.abs() > 1e-4 {
                cos.asin() / cos
            } else {
                1.0
            };
            let drag = self.drag * area * cos.abs() * speed;
            let lift = self.lift * area * speed * lift_per_cos;
            let rate = (Mat3::from_diagonal(Vec3::splat(drag)) + lift * outer(n)) / 3.0;
            let pull = rate * air;
            for p in [a, b, c] {
                self.rates[p] += rate;
                self.pulls[p] += pull;
            }
        }
    }

    /// `dv = h (m I + h K)^-1 (K w - K v)` for every particle integration moves.
    fn change_velocities(
        &self,
        model: &Model,
        current: &Kinematics,
        next: &mut Kinematics,
        h: f32,
    ) -> bool {
        let (mass, inv_mass) = (&model.particles.mass, &model.particles.inv_mass);
        let mut finite = true;
        for p in 0..next.pos.len() {
            if inv_mass[p] == 0.0 || self.rates[p] == Mat3::ZERO {
                continue;
            }
            let rate = self.rates[p];
            let force = self.pulls[p] - rate * current.vel.get(p);
            let system = Mat3::from_diagonal(Vec3::splat(mass[p])) + rate * h;
            let dv = system.inverse() * (force * h);
            next.vel.set(p, next.vel.get(p) + dv);
            next.pos.set(p, next.pos.get(p) + dv * h);
            finite &= dv.is_finite();
        }
        finite
    }

    pub fn heap_bytes(&self) -> usize {
        self.air.heap_bytes()
            + self.rates.capacity() * size_of::<Mat3>()
            + self.pulls.capacity() * size_of::<Vec3>()
            + self.triangles.capacity() * size_of::<[u32; 3]>()
    }
}

/// `n n^T`.
fn outer(n: Vec3) -> Mat3 {
    Mat3::from_cols(n * n.x, n * n.y, n * n.z)
}

/// The turbulence at `x` at time `t`: the eddies, carried along by the mean `wind`.
fn eddies_at(eddies: &[(Vec3, DVec3, f64); EDDIES], wind: DVec3, x: DVec3, t: f64) -> Vec3 {
    let carried = x - wind * t;
    eddies
        .iter()
        .map(|&(amplitude, wave, phase)| amplitude * (wave.dot(carried) + phase).sin() as f32)
        .sum()
}

/// SplitMix64 (Steele, Lea and Flood 2014): a tiny, well-mixed generator, so that a seed gives
/// the same wind on every machine without a dependency.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform on the unit sphere.
    fn direction(&mut self) -> DVec3 {
        let z = 2.0 * self.unit() - 1.0;
        let phi = TAU * self.unit();
        let r = (1.0 - z * z).sqrt();
        DVec3::new(r * phi.cos(), r * phi.sin(), z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gusts_and_eddies_stay_within_their_bounds_and_follow_the_seed() {
        let spec = WindSpec {
            velocity: [3.0, 0.0, 1.0],
            gust: 0.4,
            turbulence: 0.8,
            ..WindSpec::default()
        };
        let (wind, again) = (Wind::new(&spec, 1), Wind::new(&spec, 1));
        let other = Wind::new(
            &WindSpec {
                seed: 1,
                ..spec.clone()
            },
            1,
        );
        let mean = DVec3::from(spec.velocity);
        let (mut widest_swell, mut strongest_eddy) = (0.0f64, 0.0f64);
        let mut differs = false;
        for k in 0..2000 {
            let t = 0.01 * k as f64;
            let x = Vec3::new(
                (k % 7) as f32 * 0.3,
                (k % 5) as f32 * 0.2,
                (k % 3) as f32 * 0.5,
            );
            let swell = (wind.mean_at(t).as_dvec3().length() / mean.length() - 1.0).abs();
            let eddy = (wind.air_at(x, t) - wind.mean_at(t)).length() as f64;
            widest_swell = widest_swell.max(swell);
            strongest_eddy = strongest_eddy.max(eddy);
            assert_eq!(
                wind.air_at(x, t),
                again.air_at(x, t),
                "the same seed, the same air"
            );
            differs |= wind.air_at(x, t) != other.air_at(x, t);
        }
        assert!(
            widest_swell <= 0.4 + 1e-6,
            "gusts swelled the wind by {widest_swell}"
        );
        assert!(widest_swell > 0.1, "gusts too weak to see: {widest_swell}");
        assert!(
            strongest_eddy <= 0.8 + 1e-5,
            "eddies reached {strongest_eddy} m/s"
        );
        assert!(
            strongest_eddy > 0.2,
            "eddies too weak to see: {strongest_eddy} m/s"
        );
        assert!(differs, "another seed blew the same air");
    }
}
