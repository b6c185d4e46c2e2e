//! Float64 references of the fixed-point drive blocks of `pmsm-core` (Khlaief, Boussak, Gossa (2012), docs/khlaief2012.md):
//! the current-model MRAS, the PI and IP loops, SVPWM, dead-time compensation and the
//! initial-position arithmetic. Each is written from the equations, in SI units, as plainly as
//! possible, so that a test can bound the fixed-point result against it.

use core::f64::consts::{PI, TAU};

use pmsm_core::MotorParams;

/// `√3`.
pub const SQRT3: f64 = 1.732_050_807_568_877_2;

/// Park transform of `[α, β]` at `theta` (docs/algorithms.md (conventions)).
pub fn park(ab: [f64; 2], theta: f64) -> [f64; 2] {
    let (s, c) = theta.sin_cos();
    [ab[0] * c + ab[1] * s, -ab[0] * s + ab[1] * c]
}

/// Inverse Park transform of `[d, q]` at `theta`.
pub fn inverse_park(dq: [f64; 2], theta: f64) -> [f64; 2] {
    let (s, c) = theta.sin_cos();
    [dq[0] * c - dq[1] * s, dq[0] * s + dq[1] * c]
}

/// The frame at `theta` as the fixed-point drive's transforms take it (sin and cos floored to
/// 2⁻¹⁴): its angle and length.
pub fn frame_q14(theta: f64) -> (f64, f64) {
    let (s, c) = theta.sin_cos();
    let q = |x: f64| (x * 16384.0).floor() / 16384.0;
    let (s, c) = (q(s), q(c));
    (s.atan2(c), s.hypot(c))
}

/// Angle wrapped to [−π, π).
pub fn wrap(x: f64) -> f64 {
    (x + PI).rem_euclid(TAU) - PI
}

// ---------------------------------------------------------------------------------------------
// MRAS current-model estimator (Khlaief, Boussak, Gossa (2012) eq. 14–23, docs/khlaief2012.md §2)
// ---------------------------------------------------------------------------------------------

/// Float64 current-model MRAS, SI units (A, V, rad, rad/s), with the same discretisation as
/// `pmsm_core::MrasCurrent`: Strang splitting of the adjustable model into an exact
/// R–L half step (ZOH), an exact rotation of the flux vector `(L_d î_d + ψ, L_q î_q)` by
/// `−ω̂ T_s` (the frame turning), and a second R–L half step.
#[derive(Clone, Copy, Debug)]
pub struct MrasRef {
    /// `R`, Ω.
    pub r: f64,
    /// `L_d`, H.
    pub ld: f64,
    /// `L_q`, H.
    pub lq: f64,
    /// `ψ`, Wb.
    pub psi: f64,
    /// Sample period, s.
    pub ts: f64,
    /// `K_p` of eq. 22, (rad/s)/A².
    pub kp: f64,
    /// `K_i` of eq. 22, (rad/s²)/A².
    pub ki: f64,
    /// Model current `[î_d, î_q]`, A, in the estimated frame.
    pub i_hat: [f64; 2],
    /// Estimated angle, rad (continuous).
    pub theta: f64,
    /// Estimated electrical speed, rad/s.
    pub omega: f64,
    /// Integral part of the speed, rad/s.
    pub integ: f64,
    /// Last `ξ`, A².
    pub xi: f64,
    /// The next update seeds the model with the measured current (after a reset).
    pub seed: bool,
    /// Mechanical model `a = p K_T/J` (rad/s² per A) and `B/J` (1/s).
    pub accel: f64,
    /// See `accel`.
    pub friction: f64,
    /// Gain `K_L` of the load-current estimate, A/(A²·s); zero: no mechanical model.
    pub kl: f64,
    /// Load-current estimate, A.
    pub i_load: f64,
    /// The low-speed schedule (`pmsm_core::MrasCurrent::schedule`): `(above_rad_s, factor)`
    /// per level, fastest first; all `(0, 1)`: the gains stay as given.
    pub levels: [(f64, f64); 5],
    /// The factor of the level in use.
    pub boost: f64,
    /// The d-axis error's weight in `ξ`, relative to eq. 21's (`pmsm_core::MrasCurrentGains::
    /// d_weight`; 1: the paper's).
    pub d_weight: f64,
}

impl MrasRef {
    /// Estimator for `m` sampled every `ts` with gains `kp`, `ki`.
    pub fn new(m: &MotorParams, ts: f64, kp: f64, ki: f64) -> Self {
        Self::with_load(m, ts, kp, ki, 0.0)
    }

    /// With the mechanical model and load-estimate gain `kl` (zero: none).
    pub fn with_load(m: &MotorParams, ts: f64, kp: f64, ki: f64, kl: f64) -> Self {
        Self {
            r: m.rs_ohm,
            ld: m.ld_h,
            lq: m.lq_h,
            psi: m.flux_wb,
            ts,
            kp,
            ki,
            i_hat: [0.0; 2],
            theta: 0.0,
            omega: 0.0,
            integ: 0.0,
            xi: 0.0,
            seed: true,
            accel: m.p() * m.kt_nm_per_a / m.j_kg_m2,
            friction: m.b_nm_s / m.j_kg_m2,
            kl,
            i_load: 0.0,
            levels: [(0.0, 1.0); 5],
            boost: 1.0,
            d_weight: 1.0,
        }
    }

    /// With the d-axis error weighed by `w` in `ξ` (`w (L_q/L_d) i_q ε_d`).
    pub fn with_d_weight(mut self, w: f64) -> Self {
        self.d_weight = w;
        self
    }

    /// The low-speed schedule of the crate's current-model MRAS, from its definition: the
    /// factors `b = (1, 3/2, 2, 3, 4)`, level `j` above `ω_c/√(√(b_j b_{j+1}) − 1)`,
    /// `ω_c = R/√(L_d L_q)` (the corner of ξ's sensitivity `ω²/(ω² + ω_c²)` at zero current).
    pub fn with_schedule(mut self) -> Self {
        let corner = self.r / (self.ld * self.lq).sqrt();
        let b = |j: usize| [1.0f64, 1.5, 2.0, 3.0, 4.0][j];
        self.levels = core::array::from_fn(|j| {
            let mid = if j < 4 { (b(j) * b(j + 1)).sqrt() } else { 1.0 };
            let above = if mid > 1.0 {
                corner / (mid - 1.0).sqrt()
            } else {
                0.0
            };
            (above, b(j))
        });
        self
    }

    /// Takes the level for the speed `omega` (rad/s electrical).
    pub fn schedule(&mut self, omega: f64) {
        if let Some(&(_, b)) = self.levels.iter().find(|(above, _)| omega.abs() >= *above) {
            self.boost = b;
        }
    }

    /// Restart at `theta`, `omega`; the next update seeds the model with the measured current.
    pub fn reset(&mut self, theta: f64, omega: f64) {
        self.theta = theta;
        self.omega = omega;
        self.integ = omega;
        self.i_hat = [0.0; 2];
        self.xi = 0.0;
        self.i_load = 0.0;
        self.seed = true;
        self.schedule(omega);
    }

    fn half_step(&mut self, v_dq: [f64; 2]) {
        let h = 0.5 * self.ts;
        let ad = (-self.r * h / self.ld).exp();
        let aq = (-self.r * h / self.lq).exp();
        self.i_hat[0] = ad * self.i_hat[0] + (1.0 - ad) / self.r * v_dq[0];
        self.i_hat[1] = aq * self.i_hat[1] + (1.0 - aq) / self.r * v_dq[1];
    }

    /// One sample: `i_ab` sampled now (A), `v_ab` applied over the last period (V).
    /// Returns `(θ̂, ω̂)`.
    pub fn update(&mut self, i_ab: [f64; 2], v_ab: [f64; 2]) -> (f64, f64) {
        let delta = self.omega * self.ts;
        let th0 = self.theta;
        let th1 = th0 + delta;
        // The frames as the fixed-point estimator takes them: sin and cos floored to 2⁻¹⁴, a
        // rotation by φ scaled by ρ; the measured currents come scaled by ρ₁, and the model
        // (in the frame at φ, unscaled here) is compared scaled the same.
        let (phi0, _) = frame_q14(th0);
        let (phi1, rho1) = frame_q14(th1);
        if self.seed {
            self.seed = false;
            self.theta = th1;
            self.i_hat = park(i_ab, phi1);
            self.xi = 0.0;
            return (self.theta, self.omega);
        }
        self.half_step(park(v_ab, phi0));
        // Flux vector in the estimated frame turns by −Δφ as the frame advances by Δφ.
        let (s, c) = (phi1 - phi0).sin_cos();
        let ld_ = self.ld * self.i_hat[0] + self.psi;
        let lq_ = self.lq * self.i_hat[1];
        let (nd, nq) = (c * ld_ + s * lq_, -s * ld_ + c * lq_);
        self.i_hat = [(nd - self.psi) / self.ld, nq / self.lq];
        self.half_step(park(v_ab, phi1));
        self.theta = th1;
        let i = park(i_ab, phi1).map(|x| rho1 * x);
        let (ed, eq) = (i[0] - rho1 * self.i_hat[0], i[1] - rho1 * self.i_hat[1]);
        // Khlaief, Boussak, Gossa (2012) eq. 22, the d-axis error weighed by `d_weight`
        // (docs/khlaief2012.md §2).
        let xi = self.d_weight * (self.lq / self.ld) * i[1] * ed
            - (self.ld / self.lq) * i[0] * eq
            - (self.psi / self.lq) * eq;
        self.xi = xi;
        let g = self.boost;
        if self.kl > 0.0 {
            self.i_load -= self.ts * g * self.kl * xi;
            self.integ +=
                self.ts * (self.accel * (i[1] - self.i_load) - self.friction * self.omega);
        }
        self.integ += g * self.ki * self.ts * xi;
        self.omega = self.integ + g * self.kp * xi;
        (self.theta, self.omega)
    }
}

// ---------------------------------------------------------------------------------------------
// PI, current loops, IP speed loop (docs/khlaief2012.md §6–7)
// ---------------------------------------------------------------------------------------------

/// Float64 PI with output clamp and anti-windup, the algorithm of `pmsm_core::Pi`:
/// `u_raw = ff + K_p e + I`; with `K_p > 0` back-calculation
/// `I += K_i T_s e + k_t (clamp(u_raw) − u_raw)`, `k_t = min(1, K_i T_s/K_p)`; with `K_p = 0`
/// conditional integration (no integration while `u_raw` is at a limit and `e` pushes
/// further); `hold` stops integration that pushes `|u_raw|` outward; then
/// `I = clamp(I, lo − ff, hi − ff)` and `u = clamp(ff + K_p e + I, lo, hi)`.
#[derive(Clone, Copy, Debug, Default)]
pub struct PiRef {
    /// Proportional gain.
    pub kp: f64,
    /// Integral gain times the sample period.
    pub ki_ts: f64,
    /// Integral state.
    pub integ: f64,
}

impl PiRef {
    /// One step; returns `(u, saturated)`.
    pub fn step(&mut self, e: f64, ff: f64, lo: f64, hi: f64, hold: bool) -> (f64, bool) {
        let p = self.kp * e;
        let raw = ff + p + self.integ;
        let (up, down) = (e > 0.0, e < 0.0);
        let outward = hold && ((raw > 0.0 && up) || (raw < 0.0 && down));
        let back_calc = self.kp > 0.0;
        let stop = outward || (!back_calc && ((raw >= hi && up) || (raw <= lo && down)));
        if !stop {
            self.integ += self.ki_ts * e;
        }
        if back_calc && !outward {
            let kt = (self.ki_ts / self.kp).min(1.0);
            self.integ += kt * (raw.clamp(lo, hi) - raw);
        }
        let (i_lo, i_hi) = (lo - ff, (hi - ff).max(lo - ff));
        let clamped = self.integ > i_hi || self.integ < i_lo;
        self.integ = self.integ.clamp(i_lo, i_hi);
        let raw = ff + p + self.integ;
        let on_limit = (raw >= hi && up) || (raw <= lo && down);
        (
            raw.clamp(lo, hi),
            raw > hi || raw < lo || on_limit || clamped,
        )
    }
}

/// Float64 field-oriented current control with the true angle and speed (for open-loop tests
/// of the estimators): two [`PiRef`] with `K_p = ω_c L`, `K_i = ω_c R` and the decoupling
/// feed-forward, limited to `±v_max` per axis.
#[derive(Clone, Copy, Debug)]
pub struct FocRef {
    /// d controller.
    pub d: PiRef,
    /// q controller.
    pub q: PiRef,
    /// `L_d`, `L_q`, `ψ`.
    pub ld: f64,
    /// See `ld`.
    pub lq: f64,
    /// See `ld`.
    pub psi: f64,
    /// Per-axis voltage limit, V.
    pub v_max: f64,
}

impl FocRef {
    /// Controllers of bandwidth `wc` (rad/s) for `m` sampled every `ts`.
    pub fn new(m: &MotorParams, ts: f64, wc: f64, v_max: f64) -> Self {
        Self {
            d: PiRef {
                kp: wc * m.ld_h,
                ki_ts: wc * m.rs_ohm * ts,
                integ: 0.0,
            },
            q: PiRef {
                kp: wc * m.lq_h,
                ki_ts: wc * m.rs_ohm * ts,
                integ: 0.0,
            },
            ld: m.ld_h,
            lq: m.lq_h,
            psi: m.flux_wb,
            v_max,
        }
    }

    /// Voltage `[v_α, v_β]` for the reference `i_ref` (dq, A) from `i_ab` (A) at the true
    /// angle `theta` and electrical speed `omega`.
    pub fn step(&mut self, i_ab: [f64; 2], theta: f64, omega: f64, i_ref: [f64; 2]) -> [f64; 2] {
        let i = park(i_ab, theta);
        let ffd = -omega * self.lq * i[1];
        let ffq = omega * (self.ld * i[0] + self.psi);
        let (vd, _) = self
            .d
            .step(i_ref[0] - i[0], ffd, -self.v_max, self.v_max, false);
        let (vq, _) = self
            .q
            .step(i_ref[1] - i[1], ffq, -self.v_max, self.v_max, false);
        inverse_park([vd, vq], theta)
    }
}

// ---------------------------------------------------------------------------------------------
// Motors and inverters of the tests
// ---------------------------------------------------------------------------------------------

pub use pmsm_core::fixtures::{inverter_b, motor_b};

/// Rated torque current of motor B, A peak: 4 N·m / K_T.
pub fn motor_b_rated_iq_a() -> f64 {
    4.0 / motor_b().kt_nm_per_a
}

/// r/min (mechanical) to electrical rad/s for `p` pole pairs.
pub fn rpm_to_omega_e(rpm: f64, p: u32) -> f64 {
    rpm * TAU / 60.0 * p as f64
}

// ---------------------------------------------------------------------------------------------
// SVPWM (docs/khlaief2012.md §5)
// ---------------------------------------------------------------------------------------------

/// Float64 SVPWM by min–max injection: `v` (V or pu) on bus `vdc` (same unit) with margin `m`.
/// Returns the duties, the vector after the hexagon's limit (the legs' span `max − min` at
/// most `m V_DC`, beyond it the vector scaled onto it keeping its angle), and whether it was
/// limited.
pub fn svpwm_ref(v: [f64; 2], vdc: f64, m: f64) -> ([f64; 3], [f64; 2], bool) {
    let span = |v: [f64; 2]| {
        let ph = pmsm_plant::inverse_clarke(v);
        ph[0].max(ph[1]).max(ph[2]) - ph[0].min(ph[1]).min(ph[2])
    };
    let s = span(v);
    let (v, sat) = if s > m * vdc {
        let k = m * vdc / s;
        ([v[0] * k, v[1] * k], true)
    } else {
        (v, false)
    };
    let ph = pmsm_plant::inverse_clarke(v);
    let hi = ph[0].max(ph[1]).max(ph[2]);
    let lo = ph[0].min(ph[1]).min(ph[2]);
    let v0 = -(hi + lo) / 2.0;
    (ph.map(|x| 0.5 + (x + v0) / vdc), v, sat)
}

/// The hexagon's radius in the direction `phi` (rad) for bus `vdc` and margin `m`: the length
/// at which the legs' span reaches `m V_DC` (`m V_DC/√3` at the sides' midpoints, `2 m V_DC/3`
/// at the vertices).
pub fn hexagon_radius(phi: f64, vdc: f64, m: f64) -> f64 {
    // Angle from the nearest side's normal (30° + k 60°), in [−30°, 30°].
    let sixth = std::f64::consts::FRAC_PI_3;
    let off = phi.rem_euclid(sixth) - sixth / 2.0;
    m * vdc / (SQRT3 * off.cos())
}

/// The αβ voltage an ideal inverter makes from duties `d` on bus `vdc` (Clarke of `d_x V_DC`).
pub fn duties_to_alpha_beta(d: [f64; 3], vdc: f64) -> [f64; 2] {
    pmsm_plant::clarke(d.map(|x| x * vdc))
}

// ---------------------------------------------------------------------------------------------
// Dead-time compensation (Khlaief, Boussak, Gossa (2012) eq. 7–9, docs/khlaief2012.md §4)
// ---------------------------------------------------------------------------------------------

/// Float64 dead-time voltage (Khlaief, Boussak, Gossa (2012) eq. 8), V.
pub fn v_dead_ref(
    dead_time_s: f64,
    t_on_s: f64,
    t_off_s: f64,
    pwm_hz: f64,
    vdc_v: f64,
    v_sat_v: f64,
    v_f_v: f64,
) -> f64 {
    (dead_time_s + t_on_s - t_off_s) * pwm_hz * (vdc_v - v_sat_v + v_f_v) + 0.5 * (v_sat_v + v_f_v)
}

/// Float64 dead-time error vector (Khlaief, Boussak, Gossa (2012) eq. 7) with the signs `sat(i_x/band)`, computed as
/// the complex sum `(2/3) V_dead [s_a + a s_b + a² s_c]`.
pub fn dead_time_vector_ref(v_dead: f64, i_abc: [f64; 3], band: f64) -> [f64; 2] {
    let s = i_abc.map(|i| (i / band).clamp(-1.0, 1.0));
    let a = TAU / 3.0;
    let re = s[0] + s[1] * a.cos() + s[2] * (2.0 * a).cos();
    let im = s[1] * a.sin() + s[2] * (2.0 * a).sin();
    [2.0 / 3.0 * v_dead * re, 2.0 / 3.0 * v_dead * im]
}

// ---------------------------------------------------------------------------------------------
// Initial position detection (Khlaief, Boussak, Gossa (2012) §4, docs/khlaief2012.md §3)
// ---------------------------------------------------------------------------------------------

/// Float64 arithmetic of the initial-position detector from the five peaks (A or pu): three
/// short pulses along 0, 2π/3, 4π/3, then the long pulses along `θ̂` and `θ̂ + π`. Returns
/// `(θ mod π in [−π/2, π/2), θ_0 in [0, 2π), saliency ΔI/I_0, polarity contrast)`.
pub fn ipd_ref(peaks: [f64; 5], ld_gt_lq: bool) -> (f64, f64, f64, f64) {
    let [i1, i2, i3, i4, i5] = peaks;
    let x = i1 - 0.5 * (i2 + i3);
    let y = 0.5 * SQRT3 * (i3 - i2);
    let mut th = 0.5 * y.atan2(x);
    if th >= 0.5 * PI {
        th -= PI;
    }
    if ld_gt_lq {
        th += 0.5 * PI;
    }
    let saliency = (2.0 / 3.0) * x.hypot(y) / ((i1 + i2 + i3) / 3.0);
    let contrast = (i4 - i5) / (0.5 * (i4 + i5));
    let th0 = if i4 > i5 { th } else { th + PI };
    (th, th0.rem_euclid(TAU), saliency, contrast)
}

/// Pulse length of the detector, control samples: an R–L step of `v` reaching `i`
/// (`T = −(L/R) ln(1 − R i/v)`), rounded, at least 2.
pub fn ipd_pulse_samples_ref(l: f64, r: f64, i: f64, v: f64, ts: f64) -> u32 {
    ((-(l / r) * (1.0 - r * i / v).ln()) / ts).round().max(2.0) as u32
}
