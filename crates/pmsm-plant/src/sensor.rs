//! Phase-current sensing: an ADC per phase (docs/khlaief2012.md §4).
//!
//! The measured current is `(1 + g_x) i_x + o_x + n_x` (gain error `g_x`, offset `o_x`,
//! Gaussian noise `n_x`), quantised by a bipolar ADC whose mid-scale code reads 0 A:
//! `code = round(i_meas / LSB) + 2^(bits−1)`, `LSB = 2 I_FS / 2^bits`, clamped to
//! `[0, 2^bits − 1]` (a real ADC saturates at its rails, it never wraps).

use pmsm_core::validate::{in_range, positive};
use pmsm_core::{InverterParams, ParamError, ParamReason};

use crate::noise::Rng;

/// ADC and analogue front-end of the three phase-current channels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdcParams {
    /// Resolution, bits, in `[2, 16]` (default 12).
    pub bits: u32,
    /// Full scale `I_FS`, A: the ADC spans `±I_FS`.
    pub full_scale_a: f64,
    /// Offset added to each phase, A.
    pub offset_a: [f64; 3],
    /// Relative gain error of each phase (0.01 reads 1 % high), in `[−0.5, 0.5]`.
    pub gain_error: [f64; 3],
    /// Standard deviation of the white Gaussian noise added to each phase, A.
    pub noise_rms_a: f64,
    /// Seed of the noise generator (same seed, same noise).
    pub seed: u64,
}

impl AdcParams {
    /// Ideal 12-bit channels spanning `±full_scale_a`: no offset, gain error or noise.
    pub fn new(full_scale_a: f64) -> Self {
        Self {
            bits: 12,
            full_scale_a,
            offset_a: [0.0; 3],
            gain_error: [0.0; 3],
            noise_rms_a: 0.0,
            seed: 0,
        }
    }

    /// [`AdcParams::new`] with the inverter's `current_full_scale_a`.
    pub fn from_inverter(params: &InverterParams) -> Self {
        Self::new(params.current_full_scale_a)
    }

    /// Checks every parameter; keys are prefixed `sensing.`.
    pub fn validate(&self) -> Result<(), ParamError> {
        if !(2..=16).contains(&self.bits) {
            return Err(ParamError {
                key: "sensing.bits",
                reason: ParamReason::OutOfRange {
                    min: 2.0,
                    max: 16.0,
                },
            });
        }
        let fs = positive("sensing.full_scale_a", self.full_scale_a)?;
        for o in self.offset_a {
            in_range("sensing.offset_a", o, -fs, fs)?;
        }
        for g in self.gain_error {
            in_range("sensing.gain_error", g, -0.5, 0.5)?;
        }
        in_range("sensing.noise_rms_a", self.noise_rms_a, 0.0, fs)?;
        Ok(())
    }

    /// Current step of one code, A: `2 I_FS / 2^bits`.
    pub fn lsb_a(&self) -> f64 {
        // ldexp: no shift overflow even for unvalidated `bits`.
        libm::ldexp(2.0 * self.full_scale_a, -(self.bits.min(1100) as i32))
    }
}

/// The three phase-current channels with their noise generator.
#[derive(Clone, Debug)]
pub struct CurrentSensor {
    params: AdcParams,
    rng: Rng,
}

impl CurrentSensor {
    /// Validated sensor; the noise generator is seeded from `params.seed`.
    pub fn new(params: AdcParams) -> Result<Self, ParamError> {
        params.validate()?;
        Ok(Self {
            rng: Rng::new(params.seed),
            params,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &AdcParams {
        &self.params
    }

    /// Code that reads 0 A, `2^(bits−1)`.
    pub fn mid_code(&self) -> u16 {
        (1u32 << (self.params.bits - 1)) as u16
    }

    /// Largest code, `2^bits − 1`.
    pub fn max_code(&self) -> u16 {
        ((1u32 << self.params.bits) - 1) as u16
    }

    /// Converts true phase currents `i_abc_a` (A) to ADC codes: gain error, offset and noise
    /// applied, then rounded and clamped to the rails. A NaN current reads as code 0.
    pub fn sample(&mut self, i_abc_a: [f64; 3]) -> [u16; 3] {
        let p = self.params;
        let lsb = p.lsb_a();
        let (mid, max) = (self.mid_code() as f64, self.max_code() as f64);
        let mut codes = [0u16; 3];
        for k in 0..3 {
            let noise = if p.noise_rms_a > 0.0 {
                p.noise_rms_a * self.rng.gaussian()
            } else {
                0.0
            };
            let i = (1.0 + p.gain_error[k]) * i_abc_a[k] + p.offset_a[k] + noise;
            let x = libm::floor(i / lsb + mid + 0.5);
            // NaN fails both comparisons and lands on 0.
            let x = if x >= 0.0 { x.min(max) } else { 0.0 };
            codes[k] = x as u16;
        }
        codes
    }

    /// Ideal inverse of the quantiser: the current a code stands for, A (offset and gain
    /// errors are not undone: that is the firmware's calibration).
    pub fn code_to_amps(&self, code: u16) -> f64 {
        (code as f64 - self.mid_code() as f64) * self.params.lsb_a()
    }

    /// Samples `i_abc_a` and returns the codes with the currents they read, A.
    pub fn measure(&mut self, i_abc_a: [f64; 3]) -> ([u16; 3], [f64; 3]) {
        let codes = self.sample(i_abc_a);
        (codes, codes.map(|c| self.code_to_amps(c)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantisation_within_half_lsb() {
        let mut s = CurrentSensor::new(AdcParams::new(10.0)).unwrap();
        let lsb = s.params().lsb_a();
        assert!((lsb - 20.0 / 4096.0).abs() < 1e-15);
        assert_eq!(s.sample([0.0; 3]), [2048; 3]);
        let mut worst: f64 = 0.0;
        for k in 0..20_001 {
            // Spans the whole representable range −FS .. FS − LSB.
            let i = -10.0 + (20.0 - lsb) * k as f64 / 20_000.0;
            let (_, m) = s.measure([i, -i * 0.5, 0.3 * i]);
            for (meas, truth) in m.iter().zip([i, -i * 0.5, 0.3 * i]) {
                worst = worst.max((meas - truth).abs());
            }
        }
        assert!(
            worst <= 0.5 * lsb * (1.0 + 1e-9),
            "worst {worst} vs ½ LSB {}",
            0.5 * lsb
        );
    }

    #[test]
    fn rails_clamp_and_never_wrap() {
        let mut s = CurrentSensor::new(AdcParams::new(10.0)).unwrap();
        assert_eq!(s.sample([1e9, -1e9, f64::INFINITY]), [4095, 0, 4095]);
        assert_eq!(s.sample([10.0, -10.0, f64::NEG_INFINITY]), [4095, 0, 0]);
        assert_eq!(s.sample([f64::NAN, 0.0, 0.0])[0], 0);
        let mut p = AdcParams::new(10.0);
        p.bits = 16;
        let mut s16 = CurrentSensor::new(p).unwrap();
        assert_eq!(s16.sample([100.0, -100.0, 0.0]), [65535, 0, 32768]);
    }

    #[test]
    fn offset_and_gain_applied() {
        let mut p = AdcParams::new(10.0);
        p.offset_a = [0.1, -0.2, 0.0];
        p.gain_error = [0.0, 0.0, 0.05];
        let lsb = p.lsb_a();
        let mut s = CurrentSensor::new(p).unwrap();
        let (_, m) = s.measure([2.0, 2.0, 2.0]);
        let expected = [2.1, 1.8, 2.1];
        for k in 0..3 {
            assert!(
                (m[k] - expected[k]).abs() <= 0.5 * lsb + 1e-12,
                "phase {k}: {}",
                m[k]
            );
        }
    }

    #[test]
    fn noise_standard_deviation() {
        let mut p = AdcParams::new(10.0);
        p.noise_rms_a = 0.05; // 10 LSB: quantisation adds only LSB²/12 to the variance
        p.seed = 42;
        let mut s = CurrentSensor::new(p).unwrap();
        let n = 10_000;
        let mut sum = [0.0; 3];
        let mut sum2 = [0.0; 3];
        for _ in 0..n {
            let (_, m) = s.measure([1.0, -0.5, -0.5]);
            for k in 0..3 {
                sum[k] += m[k];
                sum2[k] += m[k] * m[k];
            }
        }
        for k in 0..3 {
            let mean = sum[k] / n as f64;
            let std = libm::sqrt(sum2[k] / n as f64 - mean * mean);
            #[cfg(feature = "std")]
            std::eprintln!("phase {k}: noise std {std:.5} A (setting 0.05 A)");
            assert!((std - 0.05).abs() < 0.1 * 0.05, "phase {k}: std {std}");
        }
    }

    #[test]
    fn bad_parameters_named() {
        let mut p = AdcParams::new(10.0);
        p.bits = 17;
        assert_eq!(p.validate().map_err(|e| e.key), Err("sensing.bits"));
        let mut p = AdcParams::new(10.0);
        p.gain_error[1] = f64::NAN;
        assert_eq!(p.validate().map_err(|e| e.key), Err("sensing.gain_error"));
        assert_eq!(
            AdcParams::new(0.0).validate().map_err(|e| e.key),
            Err("sensing.full_scale_a")
        );
    }
}
