//! An independent reference of the motor model: another formulation, another integrator.
//!
//! The plant crate integrates currents in αβ (surface) or dq (interior) with fixed-step RK4.
//! This reference integrates the stator **flux linkage in the stationary frame**, with the
//! position-dependent inductance matrix, using an adaptive Dormand–Prince 5(4) integrator at a
//! tight tolerance:
//!
//! ```text
//! λ = L(θ) i + ψ_m(θ),   dλ/dt = v − R i,   i = L(θ)⁻¹ (λ − ψ_m(θ))
//! L(θ) = L0 I + L2 [[cos 2θ, sin 2θ], [sin 2θ, −cos 2θ]],  L0 = (L_d+L_q)/2, L2 = (L_d−L_q)/2
//! ψ_m(θ) = ψ [(cos θ, sin θ) − h5/5 (cos 5θ, −sin 5θ) + h7/7 (cos 7θ, sin 7θ)]
//! T = K_T/(1.5 p ψ) · 1.5 p [ψ_m'(θ)·i + ½ iᵀ L'(θ) i]        (co-energy, linear magnetics)
//! J dω_m/dt = T − B ω_m − T_L,   dθ/dt = p ω_m
//! ```
//!
//! Only linear magnetics: that is what the plant's accuracy is checked against.

use pmsm_core::MotorParams;

/// State of the reference: flux linkage (Wb), electrical angle (rad, continuous), speed.
#[derive(Clone, Copy, Debug)]
pub struct RefState {
    /// Stator flux linkage, α and β, Wb.
    pub lambda: [f64; 2],
    /// Electrical angle, rad (continuous).
    pub theta_e_rad: f64,
    /// Mechanical speed, rad/s.
    pub omega_m_rad_s: f64,
}

/// The reference motor.
#[derive(Clone, Copy, Debug)]
pub struct RefMotor {
    /// Parameters (linear magnetics).
    pub params: MotorParams,
    /// Relative 5th and 7th EMF harmonics.
    pub h5: f64,
    /// See `h5`.
    pub h7: f64,
}

impl RefMotor {
    /// Magnet flux vector ψ_m(θ) and its derivative dψ_m/dθ.
    fn magnet(&self, th: f64) -> ([f64; 2], [f64; 2]) {
        let psi = self.params.flux_wb;
        let (s1, c1) = th.sin_cos();
        let (s5, c5) = (5.0 * th).sin_cos();
        let (s7, c7) = (7.0 * th).sin_cos();
        let (a5, a7) = (self.h5 / 5.0, self.h7 / 7.0);
        let m = [
            psi * (c1 - a5 * c5 + a7 * c7),
            psi * (s1 + a5 * s5 + a7 * s7),
        ];
        let dm = [
            psi * (-s1 + 5.0 * a5 * s5 - 7.0 * a7 * s7),
            psi * (c1 + 5.0 * a5 * c5 + 7.0 * a7 * c7),
        ];
        (m, dm)
    }

    /// Inductance matrix entries (a, b, d) of [[a, b], [b, d]] and their θ-derivatives.
    fn inductance(&self, th: f64) -> ([f64; 3], [f64; 3]) {
        let l0 = 0.5 * (self.params.ld_h + self.params.lq_h);
        let l2 = 0.5 * (self.params.ld_h - self.params.lq_h);
        let (s2, c2) = (2.0 * th).sin_cos();
        (
            [l0 + l2 * c2, l2 * s2, l0 - l2 * c2],
            [-2.0 * l2 * s2, 2.0 * l2 * c2, 2.0 * l2 * s2],
        )
    }

    /// Stator currents of a state, A (α, β).
    pub fn currents(&self, s: &RefState) -> [f64; 2] {
        let (m, _) = self.magnet(s.theta_e_rad);
        let ([a, b, d], _) = self.inductance(s.theta_e_rad);
        let det = a * d - b * b;
        let (x, y) = (s.lambda[0] - m[0], s.lambda[1] - m[1]);
        [(d * x - b * y) / det, (a * y - b * x) / det]
    }

    /// State with the given currents, angle and speed.
    pub fn state(&self, i: [f64; 2], theta_e_rad: f64, omega_m_rad_s: f64) -> RefState {
        let (m, _) = self.magnet(theta_e_rad);
        let ([a, b, d], _) = self.inductance(theta_e_rad);
        RefState {
            lambda: [a * i[0] + b * i[1] + m[0], b * i[0] + d * i[1] + m[1]],
            theta_e_rad,
            omega_m_rad_s,
        }
    }

    /// Electromagnetic torque, N·m.
    pub fn torque_nm(&self, s: &RefState) -> f64 {
        let i = self.currents(s);
        let (_, dm) = self.magnet(s.theta_e_rad);
        let (_, [da, db, dd]) = self.inductance(s.theta_e_rad);
        let p = self.params.p();
        let co = dm[0] * i[0]
            + dm[1] * i[1]
            + 0.5 * (da * i[0] * i[0] + 2.0 * db * i[0] * i[1] + dd * i[1] * i[1]);
        self.params.kt_nm_per_a / (1.5 * p * self.params.flux_wb) * 1.5 * p * co
    }

    fn derivative(&self, s: &[f64; 4], v: [f64; 2], load_nm: f64) -> [f64; 4] {
        let st = RefState {
            lambda: [s[0], s[1]],
            theta_e_rad: s[2],
            omega_m_rad_s: s[3],
        };
        let i = self.currents(&st);
        let r = self.params.rs_ohm;
        let t = self.torque_nm(&st);
        let pm = &self.params;
        [
            v[0] - r * i[0],
            v[1] - r * i[1],
            pm.p() * s[3],
            (t - pm.b_nm_s * s[3] - load_nm) / pm.j_kg_m2,
        ]
    }

    /// Integrates over `dt_s` with constant αβ voltage and load, adaptive DOPRI5 at `rtol`.
    pub fn advance(&self, s: &mut RefState, v: [f64; 2], load_nm: f64, dt_s: f64, rtol: f64) {
        let mut y = [s.lambda[0], s.lambda[1], s.theta_e_rad, s.omega_m_rad_s];
        // Error scale per component: fluxes relative to ψ, angle in rad, speed in rad/s.
        let scale = [self.params.flux_wb, self.params.flux_wb, 1.0, 1.0];
        let mut t = 0.0;
        let mut h = (dt_s).min(1e-5);
        while t < dt_s {
            let h_try = h.min(dt_s - t);
            let (y_new, err) = dopri5_step(|y| self.derivative(y, v, load_nm), &y, h_try);
            let norm = err
                .iter()
                .zip(&scale)
                .map(|(e, sc)| (e / (rtol * sc)).powi(2))
                .sum::<f64>()
                / 4.0;
            let norm = norm.sqrt();
            if norm <= 1.0 {
                t += h_try;
                y = y_new;
            }
            let factor = if norm <= f64::MIN_POSITIVE {
                5.0
            } else {
                (0.9 * norm.powf(-0.2)).clamp(0.2, 5.0)
            };
            h = h_try * factor;
        }
        *s = RefState {
            lambda: [y[0], y[1]],
            theta_e_rad: y[2],
            omega_m_rad_s: y[3],
        };
    }
}

/// One Dormand–Prince 5(4) step: the 5th-order solution and the error estimate.
fn dopri5_step(f: impl Fn(&[f64; 4]) -> [f64; 4], y: &[f64; 4], h: f64) -> ([f64; 4], [f64; 4]) {
    const A: [[f64; 6]; 6] = [
        [1.0 / 5.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0],
        [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0],
        [
            19372.0 / 6561.0,
            -25360.0 / 2187.0,
            64448.0 / 6561.0,
            -212.0 / 729.0,
            0.0,
            0.0,
        ],
        [
            9017.0 / 3168.0,
            -355.0 / 33.0,
            46732.0 / 5247.0,
            49.0 / 176.0,
            -5103.0 / 18656.0,
            0.0,
        ],
        [
            35.0 / 384.0,
            0.0,
            500.0 / 1113.0,
            125.0 / 192.0,
            -2187.0 / 6784.0,
            11.0 / 84.0,
        ],
    ];
    const B5: [f64; 7] = [
        35.0 / 384.0,
        0.0,
        500.0 / 1113.0,
        125.0 / 192.0,
        -2187.0 / 6784.0,
        11.0 / 84.0,
        0.0,
    ];
    const B4: [f64; 7] = [
        5179.0 / 57600.0,
        0.0,
        7571.0 / 16695.0,
        393.0 / 640.0,
        -92097.0 / 339200.0,
        187.0 / 2100.0,
        1.0 / 40.0,
    ];
    let mut k = [[0.0f64; 4]; 7];
    k[0] = f(y);
    for stage in 1..7 {
        let mut ys = *y;
        for (j, kj) in k.iter().enumerate().take(stage) {
            for (yi, ki) in ys.iter_mut().zip(kj) {
                *yi += h * A[stage - 1][j] * ki;
            }
        }
        k[stage] = f(&ys);
    }
    let mut y5 = *y;
    let mut err = [0.0; 4];
    for (j, kj) in k.iter().enumerate() {
        for c in 0..4 {
            y5[c] += h * B5[j] * kj[c];
            err[c] += h * (B5[j] - B4[j]) * kj[c];
        }
    }
    (y5, err)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reference itself: at constant speed (huge inertia) its steady-state dq currents
    /// solve the phasor equations of docs/khlaief2012.md §1.
    #[test]
    fn steady_state_matches_phasor_solution() {
        let mut p = MotorParams::new(3, 7.2, 0.025025, 0.04017, 0.305, 1e9, 0.0);
        p.kt_nm_per_a = 1.5 * 3.0 * 0.305;
        let m = RefMotor {
            params: p,
            h5: 0.0,
            h7: 0.0,
        };
        let w = 200.0; // electrical rad/s
        let (vd, vq) = (-20.0, 80.0);
        let mut s = m.state([0.0, 0.0], 0.0, w / 3.0);
        let dt = 1e-4;
        for _ in 0..5000 {
            let th = s.theta_e_rad + 0.5 * w * dt;
            let v = [vd * th.cos() - vq * th.sin(), vd * th.sin() + vq * th.cos()];
            m.advance(&mut s, v, 0.0, dt, 1e-10);
        }
        // Steady state: vd = R id − ω Lq iq, vq = R iq + ω Ld id + ω ψ.
        let (r, ld, lq, psi) = (7.2, 0.025025, 0.04017, 0.305);
        let det = r * r + w * w * ld * lq;
        let id = (r * vd + w * lq * (vq - w * psi)) / det;
        let iq = (r * (vq - w * psi) - w * ld * vd) / det;
        let i = m.currents(&s);
        let th = s.theta_e_rad;
        let (gd, gq) = (
            i[0] * th.cos() + i[1] * th.sin(),
            -i[0] * th.sin() + i[1] * th.cos(),
        );
        // The voltage is piecewise constant over 0.1 ms steps, so allow the ZOH ripple.
        assert!(
            (gd - id).abs() < 0.01 * id.abs().max(iq.abs()),
            "{gd} vs {id}"
        );
        assert!(
            (gq - iq).abs() < 0.01 * id.abs().max(iq.abs()),
            "{gq} vs {iq}"
        );
    }
}
