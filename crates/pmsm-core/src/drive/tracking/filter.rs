//! The tracker's filter (docs/tracking.md, "Estimation"): an update in three parts, the
//! gates and the drift on the sample, the measurement, and the Kalman correction, so that the
//! drive's task spreads one update over three task periods (module docs, "Cost").

use super::{Frozen, SPEED_HYSTERESIS, Tracker, TrackerInput, pu, sin_cos_f32, toward};
use crate::angle::Angle;

/// What the gates pass on to the measurement: the sample's angle, speed (per unit), current
/// in the estimated frame and voltage (αβ, per unit).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Sample {
    theta: Angle,
    w_hat: f32,
    i: [f32; 2],
    v: [f32; 2],
}

/// What the measurement gives the correction: `y`, the regressor `φ` and the noise the
/// current's motion and the speed's swing add to the measurement's variance (per unit).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Measurement {
    y: f32,
    phi: [f32; 2],
    extra: f32,
}

impl Tracker {
    /// The first part of an update: the filters, the drift and the gates on `input`; the
    /// sample the measurement takes, if every gate is open.
    pub(super) fn begin(&mut self, input: &TrackerInput) -> Option<Sample> {
        self.status.learning = false;
        let w_hat = pu(input.omega);
        if !input.running {
            self.run_updates = 0;
            self.status.frozen = Frozen::NotRunning;
            return None;
        }
        let (id, iq) = (pu(input.i_dq.d), pu(input.i_dq.q));
        if self.run_updates == 0 {
            (self.w_f, self.dw_f) = (w_hat, 0.0);
            (self.i_last, self.motion) = ([id, iq], 0.0);
        }
        self.run_updates = self.run_updates.saturating_add(1);
        let w_prev = self.w_f;
        self.w_f = toward(self.w_f, w_hat, self.filter);
        self.dw_f = toward(self.dw_f, self.w_f - w_prev, self.filter);
        // The current through a short low-pass first: the sampling noise of a steady current is
        // no motion.
        let pre = self.motion_pre;
        let i_f = [
            toward(self.i_last[0], id, pre),
            toward(self.i_last[1], iq, pre),
        ];
        let step = self.ld * libm::fabsf(i_f[0] - self.i_last[0])
            + self.lq * libm::fabsf(i_f[1] - self.i_last[1]);
        self.motion = toward(self.motion, step, self.filter);
        self.i_last = i_f;
        // The drift goes on whether or not this update learns (bounded by the prior).
        self.predict();
        // The inverter's residual: whole within the band of zero current, then band/|i|.
        let i_abs = libm::sqrtf(id * id + iq * iq);
        let residual = if i_abs > self.band {
            self.inv_v * self.band / i_abs
        } else {
            self.inv_v
        };
        let speed = libm::fabsf(w_hat);
        self.slow = if self.slow {
            speed <= self.min_speed * (1.0 + SPEED_HYSTERESIS)
        } else {
            speed < self.min_speed
        };
        let frozen = if self.run_updates <= self.settle_updates {
            Some(Frozen::Settling)
        } else if self.slow {
            Some(Frozen::LowSpeed)
        } else if residual > self.inv_ratio * self.psi0 * speed {
            Some(Frozen::Inverter)
        } else if input.saturated {
            Some(Frozen::Saturated)
        } else if libm::fabsf(self.dw_f) > self.max_dw
            || libm::fabsf(id - pu(input.i_ref.d)) > self.max_di
            || libm::fabsf(iq - pu(input.i_ref.q)) > self.max_di
        {
            Some(Frozen::Transient)
        } else {
            None
        };
        if let Some(f) = frozen {
            self.status.frozen = f;
            return None;
        }
        Some(Sample {
            theta: input.theta,
            w_hat,
            i: [id, iq],
            v: [pu(input.v.alpha), pu(input.v.beta)],
        })
    }

    /// The update's measurement on `sample`: `y`, the regressor and the extra noise (module
    /// docs, "Measurement"); none where the EMF's direction is undefined.
    pub(super) fn measure(&self, sample: &Sample) -> Option<Measurement> {
        let (w_hat, [id, iq]) = (sample.w_hat, sample.i);
        // The voltage acts over the coming period: its frame is at the mid-period angle.
        let turn = self.half_turn * w_hat * (4_294_967_296.0 / core::f32::consts::TAU);
        let (s, c) = sin_cos_f32(sample.theta + Angle(turn as i32));
        let [va, vb] = sample.v;
        let (vd, vq) = (va * c + vb * s, vb * c - va * s);
        let (wd, wq) = (vd + w_hat * self.lq * iq, vq - w_hat * self.ld * id);
        let r_hat = self.r0 * self.x[0];
        let (ed, eq) = (wd - r_hat * id, wq - r_hat * iq);
        let norm = libm::sqrtf(ed * ed + eq * eq);
        if norm.is_nan() || norm <= 0.0 {
            return None;
        }
        let (nd, nq) = (ed / norm, eq / norm);
        let phi = [
            self.r0 * (nd * id + nq * iq),
            self.psi0 * libm::fabsf(w_hat),
        ];
        let motion_v = self.motion_gain * self.motion;
        // The regressor's speed is the estimate: its swing about the filtered speed is an
        // error of the EMF term, counted as noise.
        let swing_v = self.psi0 * (w_hat - self.w_f);
        Some(Measurement {
            y: nd * wd + nq * wq,
            phi,
            extra: motion_v * motion_v + swing_v * swing_v,
        })
    }

    /// The update's Kalman correction on `m`.
    pub(super) fn learn_from(&mut self, m: &Measurement) {
        // `R` learns only where its drop is a fair share of the EMF: elsewhere a bias of a
        // percent of the EMF would read as a resistance error many times larger.
        let learn_r = libm::fabsf(m.phi[0]) >= self.drop_ratio * m.phi[1];
        self.correct(m.y, m.phi, m.extra, learn_r);
        self.status.learning = true;
        self.status.learnt = self.status.learnt.saturating_add(1);
    }

    /// The random walk of one update, the variances held within the prior's.
    fn predict(&mut self) {
        let p = &mut self.p;
        p[0] = (p[0] + self.q[0]).min(self.p_max[0]);
        p[2] = (p[2] + self.q[2]).min(self.p_max[1]);
        let c = libm::sqrtf(p[0] * p[2]);
        p[1] = (p[1] + self.q[1]).max(-c).min(c);
    }

    /// The Kalman correction on `y = φ · x` (per unit of `V_b`), the measurement's variance
    /// raised by `extra`; without `learn_r`, on `ψ` alone with `R̂` taken as known (its
    /// variance kept, its correlation with `ψ` shrunk as `ψ`'s variance is).
    fn correct(&mut self, y: f32, phi: [f32; 2], extra: f32, learn_r: bool) {
        let p = self.p;
        let (pf, s) = if learn_r {
            let pf = [p[0] * phi[0] + p[1] * phi[1], p[1] * phi[0] + p[2] * phi[1]];
            (pf, phi[0] * pf[0] + phi[1] * pf[1] + self.noise2 + extra)
        } else {
            let pf = [0.0, p[2] * phi[1]];
            (pf, phi[1] * pf[1] + self.noise2 + extra)
        };
        let k = [pf[0] / s, pf[1] / s];
        let nu = y - (phi[0] * self.x[0] + phi[1] * self.x[1]);
        let mut dx = [k[0] * nu, k[1] * nu];
        // A step beyond the limit is shortened and the covariance kept: the rest of the
        // innovation comes back at the next updates.
        let big = libm::fabsf(dx[0]).max(libm::fabsf(dx[1]));
        if big > self.max_step {
            let scale = self.max_step / big;
            dx = [dx[0] * scale, dx[1] * scale];
        } else {
            self.p = if learn_r {
                [
                    p[0] - k[0] * pf[0],
                    p[1] - k[0] * pf[1],
                    p[2] - k[1] * pf[1],
                ]
            } else {
                [p[0], p[1] * (1.0 - k[1] * phi[1]), p[2] - k[1] * pf[1]]
            };
        }
        self.x = [
            (self.x[0] + dx[0]).max(self.lo[0]).min(self.hi[0]),
            (self.x[1] + dx[1]).max(self.lo[1]).min(self.hi[1]),
        ];
        self.status.rs_at_bound = self.x[0] <= self.lo[0] || self.x[0] >= self.hi[0];
        self.status.flux_at_bound = self.x[1] <= self.lo[1] || self.x[1] >= self.hi[1];
    }
}
