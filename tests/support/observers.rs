//! Float64 references of the estimators of Solsona, Valla, Muravchik (2000) (docs/solsona2000.md), in SI units: the same
//! discrete algorithms as `pmsm_core::observer`, so that a comparison isolates the fixed-point
//! arithmetic and the per-unit scaling. Also: feeding a trajectory to either, and the
//! continuous-time AO errors of Solsona, Valla, Muravchik (2000) eq. 13–14.

use crate::trajectory::Sample;
use pmsm_core::MotorParams;
use pmsm_core::{AlphaBeta, InverterParams};
use pmsm_core::{Estimator, ObserverInput};
use pmsm_core::{PerUnit, to_f64};
use std::f64::consts::{FRAC_PI_2, PI};

/// An estimate in SI units.
#[derive(Clone, Copy, Debug, Default)]
pub struct Est {
    /// Electrical angle, rad.
    pub theta_rad: f64,
    /// Signed electrical speed, rad/s.
    pub omega_rad_s: f64,
    /// EMF estimate (α, β), V.
    pub emf_v: [f64; 2],
}

/// Mean EMF over an interval (the EMF meter inside `pmsm_core::Ao` and `pmsm_core::Nlo`).
#[derive(Clone, Debug)]
pub struct RefMeter {
    r: f64,
    l_over_ts: f64,
    prev: Option<[f64; 2]>,
}

impl RefMeter {
    fn new(m: &MotorParams, ts: f64) -> Self {
        Self {
            r: m.rs_ohm,
            l_over_ts: m.lq_h / ts,
            prev: None,
        }
    }

    fn update(&mut self, i: [f64; 2], v: [f64; 2]) -> Option<[f64; 2]> {
        let p = self.prev.replace(i)?;
        Some([0, 1].map(|k| v[k] - 0.5 * self.r * (p[k] + i[k]) - self.l_over_ts * (i[k] - p[k])))
    }
}

/// Direction of rotation from the mean angle step (the direction tracker inside `pmsm_core::Ao` and `pmsm_core::Nlo`).
#[derive(Clone, Debug)]
pub struct RefDirection {
    alpha: f64,
    threshold_rad: f64,
    forward: bool,
    prev: Option<f64>,
    mean: f64,
}

impl RefDirection {
    fn new(ts: f64, omega_b: f64) -> Self {
        let shift = (pmsm_core::tuning::DIRECTION_TIME_CONSTANT_S / ts)
            .log2()
            .round()
            .clamp(1.0, 16.0);
        Self {
            alpha: 0.5f64.powf(shift),
            threshold_rad: pmsm_core::tuning::DIRECTION_THRESHOLD_PU * omega_b * ts,
            forward: true,
            prev: None,
            mean: 0.0,
        }
    }

    fn update(&mut self, phi: f64, valid: bool, slow: bool) -> bool {
        if !valid {
            self.prev = None;
            return self.forward;
        }
        if let Some(p) = self.prev.replace(phi) {
            let step = crate::trajectory::wrap(phi - p);
            if step.abs() < FRAC_PI_2 {
                self.mean += self.alpha * (step - self.mean);
            }
        }
        if slow && self.forward && self.mean < -self.threshold_rad {
            self.forward = false;
        } else if slow && !self.forward && self.mean > self.threshold_rad {
            self.forward = true;
        }
        self.forward
    }
}

fn estimate_from_emf(emf: [f64; 2], psi: f64, min_emf: f64, dir: &mut RefDirection) -> Est {
    let phi = emf[1].atan2(emf[0]);
    let mag = emf[0].hypot(emf[1]);
    let flip = min_emf / pmsm_core::tuning::MIN_EMF_PU * pmsm_core::tuning::FLIP_SPEED_PU;
    let forward = dir.update(phi, mag > min_emf, mag < flip);
    let speed = emf[0].hypot(emf[1]) / psi;
    Est {
        theta_rad: if forward {
            phi - FRAC_PI_2
        } else {
            phi + FRAC_PI_2
        },
        omega_rad_s: if forward { speed } else { -speed },
        emf_v: emf,
    }
}

/// The AO (Solsona, Valla, Muravchik (2000) eq. 21–26), matched-pole discretisation.
#[derive(Clone, Debug)]
pub struct RefAo {
    meter: RefMeter,
    dir: RefDirection,
    kappa: f64,
    psi: f64,
    min_emf: f64,
    emf: [f64; 2],
}

impl RefAo {
    /// AO of gain `g` for `m` at sample period `ts`; `omega_b` sets the direction threshold.
    pub fn new(m: &MotorParams, ts: f64, g: f64, omega_b: f64) -> Self {
        Self {
            meter: RefMeter::new(m, ts),
            dir: RefDirection::new(ts, omega_b),
            kappa: 1.0 - (-g * ts).exp(),
            psi: m.flux_wb,
            min_emf: pmsm_core::tuning::MIN_EMF_PU * m.flux_wb * omega_b,
            emf: [0.0; 2],
        }
    }

    /// One sample: current at `t_k`, mean voltage over `[t_{k−1}, t_k]`.
    pub fn update(&mut self, i: [f64; 2], v: [f64; 2]) -> Est {
        if let Some(e) = self.meter.update(i, v) {
            for (x, m) in self.emf.iter_mut().zip(e) {
                *x += self.kappa * (m - *x);
            }
        }
        estimate_from_emf(self.emf, self.psi, self.min_emf, &mut self.dir)
    }
}

/// The NLO (Solsona, Valla, Muravchik (2000) eq. 15–20, docs/solsona2000.md §4) with exact rotation.
#[derive(Clone, Debug)]
pub struct RefNlo {
    meter: RefMeter,
    dir: RefDirection,
    kappa: f64,
    psi: f64,
    ts: f64,
    accel: f64,
    friction: f64,
    /// The load estimate's gain `κ²/(64a)`, its bound (2 `I_b`, as the core's) and the load,
    /// A along `û`.
    load_gain: f64,
    load_limit: f64,
    load: f64,
    emf: [f64; 2],
    u: [f64; 2],
    min_emf: f64,
    last_omega: f64,
}

impl RefNlo {
    /// NLO of gain `g` for `m` at sample period `ts`.
    pub fn new(m: &MotorParams, ts: f64, g: f64, omega_b: f64) -> Self {
        Self {
            meter: RefMeter::new(m, ts),
            dir: RefDirection::new(ts, omega_b),
            kappa: 1.0 - (-g * ts).exp(),
            psi: m.flux_wb,
            ts,
            accel: ts * m.p() * m.kt_nm_per_a * m.flux_wb / m.j_kg_m2,
            friction: ts * m.b_nm_s / m.j_kg_m2,
            // κ²/(4a) in A per V of innovation; the core's cap (2²⁰ per unit) binds on no
            // motor of the tests.
            load_gain: {
                let kappa = 1.0 - (-g * ts).exp();
                let a = ts * m.p() * m.kt_nm_per_a * m.flux_wb / m.j_kg_m2;
                kappa * kappa / (64.0 * a)
            },
            // I_b as `PerUnit` has it, with V_b = ψ ω_b.
            load_limit: 2.0
                * m.rated_current_a.map_or(
                    (m.flux_wb / m.ld_h).min(m.flux_wb * omega_b / m.rs_ohm),
                    |rms| std::f64::consts::SQRT_2 * rms,
                ),
            load: 0.0,
            emf: [0.0; 2],
            u: [1.0, 0.0],
            min_emf: pmsm_core::tuning::MIN_EMF_PU * m.flux_wb * omega_b,
            last_omega: 0.0,
        }
    }

    /// Started at the rotor's angle and speed (as the drive restarts the core's `Nlo` with
    /// `Estimator::reset` at its handover).
    pub fn start_at(mut self, theta_rad: f64, omega_rad_s: f64) -> Self {
        let (s, c) = theta_rad.sin_cos();
        self.emf = [-self.psi * omega_rad_s * s, self.psi * omega_rad_s * c];
        let mag = self.emf[0].hypot(self.emf[1]);
        if mag > 0.0 {
            self.u = [self.emf[0] / mag, self.emf[1] / mag];
        }
        self.dir.forward = omega_rad_s >= 0.0;
        self.last_omega = omega_rad_s;
        self
    }

    /// The load it estimates, A along `û`.
    pub fn load_a(&self) -> f64 {
        self.load
    }

    /// The paper's observer: no load estimate (its mechanical term lets the whole current
    /// accelerate the rotor).
    pub fn without_load(mut self) -> Self {
        self.load_gain = 0.0;
        self
    }

    /// One sample: current at `t_k`, mean voltage over `[t_{k−1}, t_k]`.
    pub fn update(&mut self, i: [f64; 2], v: [f64; 2]) -> Est {
        let half = 0.5 * self.last_omega * self.ts;
        let (s, c) = half.sin_cos();
        let rot = |x: [f64; 2]| [x[0] * c - x[1] * s, x[0] * s + x[1] * c];
        let prev = self.emf;
        let h = rot(prev);
        let mut e = rot(h);
        let along = i[0] * self.u[0] + i[1] * self.u[1] - self.load;
        for k in 0..2 {
            e[k] += self.accel * along * self.u[k] - self.friction * prev[k];
        }
        if let Some(m) = self.meter.update(i, v) {
            let sinc = if half.abs() < 1e-12 {
                1.0
            } else {
                half.sin() / half
            };
            let innovation = [m[0] - sinc * h[0], m[1] - sinc * h[1]];
            let along = innovation[0] * self.u[0] + innovation[1] * self.u[1];
            self.load =
                (self.load - self.load_gain * along).clamp(-self.load_limit, self.load_limit);
            for k in 0..2 {
                e[k] += self.kappa * innovation[k];
            }
        }
        self.emf = e;
        let mag = e[0].hypot(e[1]);
        if mag > self.min_emf {
            self.u = [e[0] / mag, e[1] / mag];
        }
        let est = estimate_from_emf(e, self.psi, self.min_emf, &mut self.dir);
        self.last_omega = est.omega_rad_s;
        est
    }
}

/// Tomita's MRAS on the AO (Solsona, Valla, Muravchik (2000) eq. 27–29).
#[derive(Clone, Debug)]
pub struct RefMras {
    ao: RefAo,
    c: [f64; 3],
    ts: f64,
    min_speed: f64,
    model: [f64; 2],
    integral: f64,
    last_omega: f64,
    /// Integrates `ε/ω̂_AO` (`MrasEmfConfig::normalised_integral`) instead of `ε`.
    normalised: bool,
}

impl RefMras {
    /// MRAS with constants `c` on an AO of gain `g`.
    pub fn new(m: &MotorParams, ts: f64, g: f64, omega_b: f64, c: [f64; 3]) -> Self {
        Self {
            normalised: false,
            ao: RefAo::new(m, ts, g, omega_b),
            c,
            ts,
            min_speed: pmsm_core::tuning::MRAS_EMF_MIN_SPEED_PU * omega_b,
            model: [0.0; 2],
            integral: 0.0,
            last_omega: 0.0,
        }
    }

    /// The same with `ε/ω̂_AO` integrated (`MrasEmfConfig::normalised_integral`).
    pub fn normalised(mut self) -> Self {
        self.normalised = true;
        self
    }

    /// One sample.
    pub fn update(&mut self, i: [f64; 2], v: [f64; 2]) -> Est {
        let ao = self.ao.update(i, v);
        let r = ao.emf_v;
        let w_ao = ao.omega_rad_s.abs().max(self.min_speed);
        let (s, c) = (self.last_omega * self.ts).sin_cos();
        let t = [
            self.model[0] * c - self.model[1] * s,
            self.model[0] * s + self.model[1] * c,
        ];
        let x = (w_ao * self.ts / self.c[2]).min(2.0);
        let pull = 1.0 - (-x).exp();
        self.model = [t[0] + pull * (r[0] - t[0]), t[1] + pull * (r[1] - t[1])];
        let d = [r[0] - self.model[0], r[1] - self.model[1]];
        let eps = d[1] * self.model[0] - d[0] * self.model[1];
        let w = if self.normalised {
            // ω̂ = c1 ε/ω̂_AO + c2 ∫ ε/ω̂_AO dt.
            self.integral += self.c[1] * eps / w_ao * self.ts;
            self.c[0] * eps / w_ao + self.integral
        } else {
            // ω̂ = (c1 ε + c2 ∫ ε dt)/ω̂_AO (Solsona, Valla, Muravchik (2000) eq. 29).
            self.integral += eps * self.ts;
            (self.c[0] * eps + self.c[1] * self.integral) / w_ao
        };
        self.last_omega = w;
        let phi = self.model[1].atan2(self.model[0]);
        Est {
            theta_rad: if w >= 0.0 {
                phi - FRAC_PI_2
            } else {
                phi + FRAC_PI_2
            },
            omega_rad_s: w,
            emf_v: self.model,
        }
    }
}

/// Solsona, Valla, Muravchik (2000) eq. 13–14: steady-state AO errors at electrical speed `omega` with gain `g`
/// (speed error rad/s, angle error rad).
pub fn ao_steady_errors(omega: f64, g: f64) -> (f64, f64) {
    (
        omega * (g / (g * g + omega * omega).sqrt() - 1.0),
        (-omega / g).atan(),
    )
}

/// Per-unit bases for motor `m` on a bus of `vdc_v` at `sample_hz`.
pub fn base(m: &MotorParams, vdc_v: f64, sample_hz: f64) -> PerUnit {
    let inv = InverterParams {
        vdc_v,
        pwm_hz: sample_hz,
        dead_time_s: 0.0,
        current_full_scale_a: 50.0,
    };
    PerUnit::new(m, &inv, sample_hz).expect("motor within the envelope")
}

/// The mean voltage over `[t_{k−1}, t_k]` from point samples (trapezoid), as `pmsm observe`
/// does; the first sample uses its own voltage.
pub fn mean_voltage(samples: &[Sample], k: usize) -> [f64; 2] {
    let cur = samples[k].v_v;
    match k.checked_sub(1).map(|j| samples[j].v_v) {
        Some(prev) => [0.5 * (prev[0] + cur[0]), 0.5 * (prev[1] + cur[1])],
        None => cur,
    }
}

/// Runs a fixed-point estimator over trajectory samples; estimates in SI.
pub fn run_fixed<E: Estimator>(est: &mut E, base: &PerUnit, samples: &[Sample]) -> Vec<Est> {
    (0..samples.len())
        .map(|k| {
            let v = mean_voltage(samples, k);
            let i = samples[k].i_a;
            let input = ObserverInput {
                i: AlphaBeta {
                    alpha: base.current_pu(i[0]),
                    beta: base.current_pu(i[1]),
                },
                v: AlphaBeta {
                    alpha: base.voltage_pu(v[0]),
                    beta: base.voltage_pu(v[1]),
                },
            };
            let e = est.update(&input);
            Est {
                theta_rad: e.theta.to_rad(),
                omega_rad_s: base.speed_rad_s(e.omega),
                emf_v: [
                    to_f64(e.emf.alpha) * base.voltage_v,
                    to_f64(e.emf.beta) * base.voltage_v,
                ],
            }
        })
        .collect()
}

/// Runs a reference estimator (closure over `update`) over trajectory samples.
pub fn run_ref(mut update: impl FnMut([f64; 2], [f64; 2]) -> Est, samples: &[Sample]) -> Vec<Est> {
    (0..samples.len())
        .map(|k| update(samples[k].i_a, mean_voltage(samples, k)))
        .collect()
}

/// Angle error (rad, wrapped) and speed error (rad/s) of each estimate against the truth.
pub fn errors(est: &[Est], truth: &[Sample]) -> Vec<(f64, f64)> {
    est.iter()
        .zip(truth)
        .map(|(e, s)| {
            (
                crate::trajectory::wrap(e.theta_rad - s.theta_e_rad),
                e.omega_rad_s - s.omega_e_rad_s,
            )
        })
        .collect()
}

/// Largest |value| of `f` over the samples `from..`.
pub fn max_abs(errs: &[(f64, f64)], from: usize, f: impl Fn(&(f64, f64)) -> f64) -> f64 {
    errs[from..].iter().map(|e| f(e).abs()).fold(0.0, f64::max)
}

/// Mean of `f` over the samples `from..`.
pub fn mean(errs: &[(f64, f64)], from: usize, f: impl Fn(&(f64, f64)) -> f64) -> f64 {
    errs[from..].iter().map(f).sum::<f64>() / (errs.len() - from) as f64
}

/// Degrees.
pub fn deg(rad: f64) -> f64 {
    rad * 180.0 / PI
}
