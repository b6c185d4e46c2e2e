//! The background work (`f64`, off the per-sample path): the resistance fit, each burst's
//! inductance, the fine bursts' half periods, and handing out the result once.

use super::fit::{inductance_from_ripple, line};
use super::machine::{Identify, Phase};
use super::{Identified, IdentifyError, Stage};

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
        (self.r_ohm, self.v0_v, self.inductance_h)
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
        let c = self.config;
        let mut pts = [(0.0, 0.0); 4];
        for (p, s) in pts.iter_mut().zip(self.levels.iter()) {
            let n = s.n.max(1) as f64;
            *p = (c.amps(s.i as f64 / n), c.volts(s.v as f64 / n));
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

    pub(super) fn burst_inductance(&self, b: u8) -> Result<f64, IdentifyError> {
        let c = self.config;
        let stage = if b < 2 {
            Stage::InductanceD
        } else {
            Stage::InductanceQ
        };
        let s = self.bursts.get(b as usize).copied().unwrap_or_default();
        let periods = (s.halves / 2).max(1) as f64;
        let d_a = c.amps(s.d as f64 / periods);
        let v_sq = c.volts(self.sq_bits as f64);
        if d_a < 2e-3 * c.current_base_a {
            return Err(IdentifyError::Noise(stage));
        }
        inductance_from_ripple(d_a, v_sq, s.n_half, c.sample_s, self.r_ohm)
            .ok_or(IdentifyError::Noise(stage))
    }

    fn choose_burst(&mut self, b: u8) -> Result<(), IdentifyError> {
        if b == 0 {
            self.resistance()?;
        }
        let c = self.config;
        let l = self.burst_inductance(b)?;
        // D ≈ V_sq N T / L: the N for the wanted ripple, at least 1, at most 1/4 of a window.
        let v_sq = c.volts(self.sq_bits as f64);
        let want = c.design.ripple_pu * c.current_base_a;
        let n = libm::round(want * l / (v_sq * c.sample_s)).clamp(1.0, (c.n_window / 8) as f64);
        self.start_burst(b + 1, n as u32);
        self.phase = Phase::Burst(b + 1);
        Ok(())
    }
}
