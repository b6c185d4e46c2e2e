//! The background work (`f32`, off the per-sample path): the resistance fit, each burst's
//! inductance, the fine bursts' half periods, and handing out the result once.

use super::fit::{inductance_from_ripple, line};
use super::machine::{Identify, Phase, Q24};
use super::{Identified, IdentifyConfig, IdentifyError, Q16_COUNTS_PER_RAD, Stage};

/// The configuration's scales in `f32`, for the background work (see `fit.rs` for why
/// single precision).
#[derive(Clone, Copy, Debug)]
pub(super) struct Units {
    /// Amperes per `Pu` bit of current.
    pub(super) amps_per_bit: f32,
    /// Volts per `Pu` bit of voltage.
    pub(super) volts_per_bit: f32,
    /// The current base (the limit), A.
    pub(super) current_base_a: f32,
    /// The voltage that ends the spin's first ramp, V.
    pub(super) spin_voltage_v: f32,
    /// Control sample period, s.
    pub(super) sample_s: f32,
    /// Electrical rad/s per unit of a generator step (angle counts × 2¹⁶ per sample).
    pub(super) rad_s_per_q16: f32,
    /// Electrical rad/s per angle count per sample.
    pub(super) rad_s_per_count: f32,
    /// Joules per `Pu` bit of the summed `v·i` products (`1.5 V_b I_b T / 2²⁴`).
    pub(super) joules_per_bit: f32,
}

impl Units {
    /// Amperes of a current in `Pu` bits.
    pub(super) fn amps(&self, bits: f32) -> f32 {
        bits * self.amps_per_bit
    }

    /// Volts of a voltage in `Pu` bits.
    pub(super) fn volts(&self, bits: f32) -> f32 {
        bits * self.volts_per_bit
    }
}

impl IdentifyConfig {
    /// The scales of the background work.
    pub(super) fn units(&self) -> Units {
        let q24 = Q24 as f64;
        let ts = self.sample_s;
        Units {
            amps_per_bit: (self.current_base_a / q24) as f32,
            volts_per_bit: (self.voltage_base_v / q24) as f32,
            current_base_a: self.current_base_a as f32,
            spin_voltage_v: (self.design.spin_voltage_pu * self.voltage_base_v) as f32,
            sample_s: ts as f32,
            rad_s_per_q16: (1.0 / (Q16_COUNTS_PER_RAD * ts)) as f32,
            rad_s_per_count: (core::f64::consts::TAU / 4_294_967_296.0 / ts) as f32,
            joules_per_bit: (1.5 * self.voltage_base_v * self.current_base_a * ts / q24) as f32,
        }
    }
}

impl Identify {
    /// Background work: chooses the fine bursts' half periods and, once the sequence has
    /// ended, computes the result. Returns the result once (then `None`).
    pub fn poll(&mut self) -> Option<Result<Identified, IdentifyError>> {
        match self.phase {
            Phase::AwaitPoll(b) => {
                if let Err(e) = self.choose_burst(b) {
                    self.result = Some(Err(e));
                    self.phase = Phase::Done;
                }
                None
            }
            Phase::Finished => {
                self.result = Some(self.finish());
                self.phase = Phase::Done;
                self.report()
            }
            Phase::Done => self.report(),
            _ => None,
        }
    }

    /// What the resistance and inductance steps have measured so far (zero before):
    /// `(R Ω, distortion V, [L_d H, L_q H])`.
    pub fn measured(&self) -> (f64, f64, [f64; 2]) {
        (
            self.r_ohm as f64,
            self.v0_v as f64,
            self.inductance_h.map(|l| l as f64),
        )
    }

    fn report(&mut self) -> Option<Result<Identified, IdentifyError>> {
        if self.reported {
            None
        } else {
            self.reported = true;
            self.result
        }
    }

    fn resistance(&mut self) -> Result<(), IdentifyError> {
        let u = self.config.units();
        let mut pts = [(0.0, 0.0); 4];
        for (p, s) in pts.iter_mut().zip(self.levels.iter()) {
            let n = s.n.max(1) as f32;
            *p = (u.amps(s.i as f32 / n), u.volts(s.v as f32 / n));
        }
        let (r, v0, rms) = line(&pts).ok_or(IdentifyError::Noise(Stage::Resistance))?;
        // The line must explain the points to a small fraction of the voltage span.
        let span = pts[3].1 - pts[0].1;
        if r.is_nan() || r <= 0.0 || rms > 0.05 * span.abs() {
            return Err(IdentifyError::Noise(Stage::Resistance));
        }
        self.r_ohm = r;
        self.v0_v = v0;
        self.r_rms_v = rms;
        Ok(())
    }

    pub(super) fn burst_inductance(&self, b: u8) -> Result<f32, IdentifyError> {
        let u = self.config.units();
        let stage = if b < 2 {
            Stage::InductanceD
        } else {
            Stage::InductanceQ
        };
        let s = self.bursts.get(b as usize).copied().unwrap_or_default();
        let periods = (s.halves / 2).max(1) as f32;
        let d_a = u.amps(s.d as f32 / periods);
        let v_sq = u.volts(self.sq_bits as f32);
        if d_a < 2e-3 * u.current_base_a {
            return Err(IdentifyError::Noise(stage));
        }
        inductance_from_ripple(d_a, v_sq, s.n_half, u.sample_s, self.r_ohm)
            .ok_or(IdentifyError::Noise(stage))
    }

    fn choose_burst(&mut self, b: u8) -> Result<(), IdentifyError> {
        if b == 0 {
            self.resistance()?;
        }
        let c = self.config;
        let u = c.units();
        let l = self.burst_inductance(b)?;
        // D ≈ V_sq N T / L: the N for the wanted ripple, at least 1, at most 1/8 of a window
        // (max/min, not clamp: no panic path when the window is short).
        let v_sq = u.volts(self.sq_bits as f32);
        let want = c.design.ripple_pu as f32 * u.current_base_a;
        let n = (want * l / (v_sq * u.sample_s) + 0.5)
            .min((c.n_window / 8) as f32)
            .max(1.0);
        self.start_burst(b + 1, n as u32);
        self.phase = Phase::Burst(b + 1);
        Ok(())
    }
}
