//! Torque-consistent prescribed trajectories of a surface PMSM (motor A, examples/motor-a.toml): pick
//! the mechanical speed `ω_m(t)`, set `i_q = (J ω̇_m + B ω_m + T_L)/K_T`, `i_d = 0`, and compute
//! `v = R i + L di/dt + e` (docs/solsona2000.md §1, with optional EMF harmonics). This is how Solsona, Valla, Muravchik (2000)
//! runs its observers: open loop, on the voltages and currents of a simulated drive.

use pmsm_core::MotorParams;
use std::f64::consts::PI;

/// A speed profile through breakpoints `(t_s, ω_m rad/s)`, joined by raised-cosine
/// transitions so that the acceleration is continuous (a step in `i_q` would need a Dirac in
/// the voltage).
#[derive(Clone, Debug)]
pub struct Profile {
    points: Vec<(f64, f64)>,
}

impl Profile {
    /// Through `points` (times increasing); constant before the first and after the last.
    pub fn new(points: &[(f64, f64)]) -> Self {
        assert!(points.windows(2).all(|w| w[1].0 > w[0].0));
        Self {
            points: points.to_vec(),
        }
    }

    /// Constant speed.
    pub fn constant(omega_m_rad_s: f64) -> Self {
        Self::new(&[(0.0, omega_m_rad_s)])
    }

    /// `(ω_m, ω̇_m, ω̈_m)` at `t`.
    pub fn at(&self, t: f64) -> (f64, f64, f64) {
        let first = self.points[0];
        if t <= first.0 {
            return (first.1, 0.0, 0.0);
        }
        for w in self.points.windows(2) {
            let ((t0, w0), (t1, w1)) = (w[0], w[1]);
            if t <= t1 {
                let d = t1 - t0;
                let x = PI * (t - t0) / d;
                let a = 0.5 * (w1 - w0);
                return (
                    w0 + a * (1.0 - x.cos()),
                    a * x.sin() * PI / d,
                    a * x.cos() * (PI / d).powi(2),
                );
            }
        }
        (self.points[self.points.len() - 1].1, 0.0, 0.0)
    }

    /// `∫₀ᵗ ω_m dt` (exact).
    pub fn angle_m(&self, t: f64) -> f64 {
        let mut acc = 0.0;
        let first = self.points[0];
        if t <= first.0 {
            return first.1 * t;
        }
        acc += first.1 * first.0;
        for w in self.points.windows(2) {
            let ((t0, w0), (t1, w1)) = (w[0], w[1]);
            let d = t1 - t0;
            let tau = (t.min(t1) - t0).max(0.0);
            let a = 0.5 * (w1 - w0);
            acc += w0 * tau + a * (tau - d / PI * (PI * tau / d).sin());
            if t <= t1 {
                return acc;
            }
        }
        acc + self.points[self.points.len() - 1].1 * (t - self.points[self.points.len() - 1].0)
    }
}

/// One sample of a trajectory: the true state and the measurements at `t_s`.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    /// Time, s.
    pub t_s: f64,
    /// Electrical angle, rad (continuous).
    pub theta_e_rad: f64,
    /// Electrical speed, rad/s.
    pub omega_e_rad_s: f64,
    /// Stator current (α, β), A.
    pub i_a: [f64; 2],
    /// Stator voltage (α, β), V, at this instant.
    pub v_v: [f64; 2],
    /// True back-EMF (α, β), V.
    pub e_v: [f64; 2],
}

/// A surface motor following a profile.
#[derive(Clone, Debug)]
pub struct Trajectory {
    /// Motor parameters (surface: `ld_h` is used as `L`).
    pub motor: MotorParams,
    /// Relative 5th and 7th EMF harmonics.
    pub h5: f64,
    /// See `h5`.
    pub h7: f64,
    /// Speed profile.
    pub profile: Profile,
    /// Electrical angle at `t = 0`, rad.
    pub theta0_rad: f64,
    /// Constant load torque, N·m.
    pub load_nm: f64,
}

impl Trajectory {
    /// motor A (examples/motor-a.toml) on `profile`, no harmonics, no load.
    pub fn new(motor: MotorParams, profile: Profile) -> Self {
        Self {
            motor,
            h5: 0.0,
            h7: 0.0,
            profile,
            theta0_rad: 0.3,
            load_nm: 0.0,
        }
    }

    /// The state and the measurements at `t`.
    pub fn sample(&self, t: f64) -> Sample {
        let m = &self.motor;
        let p = m.p();
        let (w, dw, ddw) = self.profile.at(t);
        let th = self.theta0_rad + p * self.profile.angle_m(t);
        let we = p * w;
        let iq = (m.j_kg_m2 * dw + m.b_nm_s * w + self.load_nm) / m.kt_nm_per_a;
        let diq = (m.j_kg_m2 * ddw + m.b_nm_s * dw) / m.kt_nm_per_a;
        let (s, c) = th.sin_cos();
        let i = [-iq * s, iq * c];
        let di = [-diq * s - iq * we * c, diq * c - iq * we * s];
        let (s5, c5) = (-5.0 * th).sin_cos();
        let (s7, c7) = (7.0 * th).sin_cos();
        let e = [
            -m.flux_wb * we * (s + self.h5 * s5 + self.h7 * s7),
            m.flux_wb * we * (c + self.h5 * c5 + self.h7 * c7),
        ];
        let v = [
            m.rs_ohm * i[0] + m.ld_h * di[0] + e[0],
            m.rs_ohm * i[1] + m.ld_h * di[1] + e[1],
        ];
        Sample {
            t_s: t,
            theta_e_rad: th,
            omega_e_rad_s: we,
            i_a: i,
            v_v: v,
            e_v: e,
        }
    }

    /// Samples at `k · ts` for `k = 0..n`.
    pub fn samples(&self, ts: f64, n: usize) -> Vec<Sample> {
        (0..n).map(|k| self.sample(k as f64 * ts)).collect()
    }
}

/// motor A (examples/motor-a.toml) (Solsona, Valla, Muravchik (2000)), with the paper's `K_T`.
pub fn motor_a() -> MotorParams {
    let mut m = MotorParams::new(3, 1.6, 0.0134, 0.0134, 0.288, 0.04256, 0.004256);
    m.kt_nm_per_a = 1.108;
    m.rated_current_a = Some(6.1);
    m.rated_speed_rpm = Some(1200.0);
    m
}

/// Wraps an angle difference to (−π, π].
pub fn wrap(x: f64) -> f64 {
    let y = (x + PI).rem_euclid(2.0 * PI) - PI;
    if y <= -PI { y + 2.0 * PI } else { y }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angle_is_the_integral_of_speed() {
        let p = Profile::new(&[(0.5, 3.0), (2.5, 120.0), (3.5, 120.0), (5.5, -3.0)]);
        let (mut acc, n) = (0.0, 600_000);
        let dt = 6.0 / n as f64;
        for k in 0..n {
            acc += p.at((k as f64 + 0.5) * dt).0 * dt;
        }
        assert!(
            (acc - p.angle_m(6.0)).abs() < 1e-6,
            "{acc} vs {}",
            p.angle_m(6.0)
        );
        // ω̇ is the derivative of ω.
        let t = 1.3;
        let d = (p.at(t + 1e-6).0 - p.at(t - 1e-6).0) / 2e-6;
        assert!((d - p.at(t).1).abs() < 1e-5);
    }

    #[test]
    fn voltage_balances_the_model() {
        // L di/dt = v − R i − e, checked by finite differences of the current.
        let tr = Trajectory::new(motor_a(), Profile::new(&[(0.0, 3.0), (1.0, 120.0)]));
        let (a, b, c) = (tr.sample(0.5 - 1e-7), tr.sample(0.5), tr.sample(0.5 + 1e-7));
        for k in 0..2 {
            let di = (c.i_a[k] - a.i_a[k]) / 2e-7;
            let rhs = b.v_v[k] - 1.6 * b.i_a[k] - b.e_v[k];
            assert!((0.0134 * di - rhs).abs() < 1e-4, "{} vs {rhs}", 0.0134 * di);
        }
    }
}
