//! ADC codes to per unit: phase currents through shunts and amplifiers, the bus voltage
//! through a divider; the current channels' offset calibration; a potentiometer as a speed
//! knob. Coefficients are computed once in floating point; the conversions are integer.

use pmsm_core::Abc;
use pmsm_core::DriveInput;
use pmsm_core::PU_FRAC;
use pmsm_core::Pu;

/// Why a scaling cannot be made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScalingError {
    /// A parameter is zero, negative or not finite.
    Invalid(&'static str),
    /// One ADC count is worth more than 2^15 or less than 2^−16 LSB of per unit: the base is
    /// far from the sensor's range.
    OutOfRange,
}

/// Finite and above zero.
fn positive(x: f64) -> bool {
    x.is_finite() && x > 0.0
}

/// A linear map `code → (code − offset) · k`, `k` in Q8.24 LSB per ADC count as a
/// Q47.16 integer: one 32 × 32 → 64-bit multiply and a shift, saturating.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinearScale {
    /// Q8.24 LSB per ADC count, times 2^16.
    k: i64,
}

impl LinearScale {
    /// `pu_per_count` per unit per ADC count (may be negative).
    pub fn new(pu_per_count: f64) -> Result<Self, ScalingError> {
        if !pu_per_count.is_finite() || pu_per_count == 0.0 {
            return Err(ScalingError::Invalid("pu_per_count"));
        }
        let k = pu_per_count * (1u64 << (PU_FRAC + 16)) as f64;
        let mag = if k < 0.0 { -k } else { k };
        if !(1.0..=(1u64 << 31) as f64 * 65536.0).contains(&mag) {
            return Err(ScalingError::OutOfRange);
        }
        // Round half away from zero without libm.
        let k = if k < 0.0 { k - 0.5 } else { k + 0.5 } as i64;
        Ok(Self { k })
    }

    /// `(code − offset) · k`, saturating to the range of [`Pu`].
    #[inline]
    pub fn apply(&self, code: u16, offset: u16) -> Pu {
        let x = (code as i64 - offset as i64) * self.k;
        let bits = (x >> 16).clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        Pu::from_bits(bits)
    }
}

/// The ADC: reference voltage and resolution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdcSpec {
    /// VREF+, V.
    pub vref_v: f64,
    /// Resolution, bits (12 on the STM32G4).
    pub bits: u32,
}

impl AdcSpec {
    /// Volts per ADC count.
    pub fn volts_per_count(&self) -> f64 {
        self.vref_v / (1u64 << self.bits) as f64
    }
}

/// Phase-current sensing: shunt, amplifier gain (signed: negative when a positive phase
/// current, out of the leg into the motor, lowers the ADC reading, as with low-side shunts
/// and non-inverting amplifiers), and the per-unit base current.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurrentSensing {
    /// The ADC.
    pub adc: AdcSpec,
    /// Shunt resistance, Ω.
    pub shunt_ohm: f64,
    /// Voltage gain from the shunt to the ADC pin (signed).
    pub gain: f64,
}

impl CurrentSensing {
    /// Amperes per ADC count (signed).
    pub fn amps_per_count(&self) -> f64 {
        self.adc.volts_per_count() / (self.gain * self.shunt_ohm)
    }

    /// The largest current measurable around a mid-scale offset, A.
    pub fn full_scale_a(&self) -> f64 {
        let a = self.amps_per_count() * (1u64 << (self.adc.bits - 1)) as f64;
        if a < 0.0 { -a } else { a }
    }

    /// The scale to per unit of `base_current_a`.
    pub fn scale(&self, base_current_a: f64) -> Result<LinearScale, ScalingError> {
        if !positive(self.shunt_ohm) || !self.gain.is_finite() || self.gain == 0.0 {
            return Err(ScalingError::Invalid("shunt_ohm or gain"));
        }
        if !positive(base_current_a) {
            return Err(ScalingError::Invalid("base_current_a"));
        }
        LinearScale::new(self.amps_per_count() / base_current_a)
    }
}

/// Bus-voltage sensing through a divider.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoltageSensing {
    /// The ADC.
    pub adc: AdcSpec,
    /// Divider ratio `V_pin / V_bus`.
    pub divider: f64,
}

impl VoltageSensing {
    /// The scale to per unit of `base_voltage_v` (the core's `V_b = V_DC,nominal / √3`).
    pub fn scale(&self, base_voltage_v: f64) -> Result<LinearScale, ScalingError> {
        if !positive(self.divider) || self.divider > 1.0 {
            return Err(ScalingError::Invalid("divider"));
        }
        if !positive(base_voltage_v) {
            return Err(ScalingError::Invalid("base_voltage_v"));
        }
        LinearScale::new(self.adc.volts_per_count() / self.divider / base_voltage_v)
    }
}

/// One sample's raw ADC codes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RawSample {
    /// Phase currents a, b, c.
    pub i: [u16; 3],
    /// Bus voltage.
    pub vdc: u16,
}

/// Raw codes to the drive's input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Scaling {
    /// Per-unit current per count.
    pub current: LinearScale,
    /// Per-unit voltage per count.
    pub voltage: LinearScale,
    /// Zero-current codes of the three channels.
    pub offsets: [u16; 3],
}

impl Scaling {
    /// The drive's input for a raw sample.
    #[inline]
    pub fn input(&self, raw: &RawSample) -> DriveInput {
        DriveInput {
            i_abc: Abc {
                a: self.current.apply(raw.i[0], self.offsets[0]),
                b: self.current.apply(raw.i[1], self.offsets[1]),
                c: self.current.apply(raw.i[2], self.offsets[2]),
            },
            vdc: self.voltage.apply(raw.vdc, 0),
        }
    }
}

/// An offset out of its plausible window: a broken amplifier or a current flowing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OffsetError {
    /// Channel (0 = a).
    pub channel: u8,
    /// Its mean code.
    pub code: u16,
}

/// Averages `samples` raw samples with the outputs off into the current offsets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OffsetCalibration {
    sum: [u32; 3],
    n: u32,
    samples: u32,
    window: (u16, u16),
}

impl OffsetCalibration {
    /// Over `samples` (1 to 65 536) samples, accepting offsets within `window` (codes).
    pub fn new(samples: u32, window: (u16, u16)) -> Self {
        Self {
            sum: [0; 3],
            n: 0,
            samples: samples.clamp(1, 1 << 16),
            window,
        }
    }

    /// Adds a sample; returns the offsets once enough samples are in.
    pub fn add(&mut self, raw: &RawSample) -> Option<Result<[u16; 3], OffsetError>> {
        if self.n >= self.samples {
            return Some(self.result());
        }
        for (s, &c) in self.sum.iter_mut().zip(raw.i.iter()) {
            *s += c as u32;
        }
        self.n += 1;
        (self.n >= self.samples).then(|| self.result())
    }

    fn result(&self) -> Result<[u16; 3], OffsetError> {
        let n = self.n.max(1);
        let mut out = [0u16; 3];
        for (k, (o, &s)) in out.iter_mut().zip(self.sum.iter()).enumerate() {
            *o = ((s + n / 2) / n) as u16;
            if *o < self.window.0 || *o > self.window.1 {
                return Err(OffsetError {
                    channel: k as u8,
                    code: *o,
                });
            }
        }
        Ok(out)
    }
}

/// What the speed knob asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KnobCommand {
    /// Stop the drive.
    Stop,
    /// Run at this speed reference (per unit, electrical).
    Run(Pu),
}

/// A potentiometer as a speed knob: the bottom of its travel stops the drive (with
/// hysteresis, so a noisy reading at the threshold does not start and stop it), above that
/// the speed rises linearly to `max` at full scale.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SpeedKnob {
    stop_below: u16,
    run_above: u16,
    full_scale: u16,
    max: Pu,
    running: bool,
}

impl SpeedKnob {
    /// Stops below `stop_below`, runs above `run_above` (> `stop_below`), at `max` for
    /// `full_scale` (> `run_above`).
    pub fn new(stop_below: u16, run_above: u16, full_scale: u16, max: Pu) -> Self {
        let run_above = run_above.max(stop_below.saturating_add(1));
        Self {
            stop_below,
            run_above,
            full_scale: full_scale.max(run_above.saturating_add(1)),
            max,
            running: false,
        }
    }

    /// The command for a reading.
    pub fn update(&mut self, code: u16) -> KnobCommand {
        if self.running && code < self.stop_below {
            self.running = false;
        } else if !self.running && code > self.run_above {
            self.running = true;
        }
        if !self.running {
            return KnobCommand::Stop;
        }
        // `new` keeps full_scale > stop_below; the `max(1)` shows the compiler that the
        // division cannot fail (no panic path in a firmware image). ⌊max x/span⌋ in 32 bits
        // (x ≤ span < 2¹⁶: the remainder's product fits), without a 64-bit division.
        let span = u32::from(self.full_scale.saturating_sub(self.stop_below)).max(1);
        let x = u32::from(code.min(self.full_scale).saturating_sub(self.stop_below));
        let max = self.max.to_bits().max(0) as u32;
        let (q, r) = (max / span, max % span);
        KnobCommand::Run(Pu::from_bits((q * x + r * x / span) as i32))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ADC: AdcSpec = AdcSpec {
        vref_v: 3.3,
        bits: 12,
    };

    fn to_f64(x: Pu) -> f64 {
        x.to_bits() as f64 / (1u64 << PU_FRAC) as f64
    }

    #[test]
    fn board_current_scaling() {
        // B-G431B-ESC1: 3 mΩ, gain −64/7 (≈ −9.14): 29.4 mA per count, ±60 A.
        let s = CurrentSensing {
            adc: ADC,
            shunt_ohm: 0.003,
            gain: -64.0 / 7.0,
        };
        assert!((s.amps_per_count() + 0.029_37).abs() < 1e-4);
        assert!((s.full_scale_a() - 60.16).abs() < 0.01);
        let base = 5.0 * core::f64::consts::SQRT_2;
        let k = s.scale(base).unwrap();
        for code in [0u16, 1, 100, 2000, 2048, 2100, 4095] {
            let got = to_f64(k.apply(code, 2048));
            let want = (code as f64 - 2048.0) * s.amps_per_count() / base;
            assert!((got - want).abs() < 1e-6, "{code}: {got} vs {want}");
        }
        // Positive phase current lowers the code.
        assert!(k.apply(2000, 2048) > Pu::ZERO);
        assert_eq!(k.apply(2048, 2048), Pu::ZERO);
    }

    #[test]
    fn board_voltage_scaling() {
        let v = VoltageSensing {
            adc: ADC,
            divider: 18.0 / (169.0 + 18.0),
        };
        let vb = 24.0 / libm_sqrt3();
        let k = v.scale(vb).unwrap();
        // 24 V on the bus reads 24 · ratio / 3.3 · 4096 counts and is √3 per unit.
        let code = (24.0 * 18.0 / 187.0 / 3.3 * 4096.0 + 0.5) as u16;
        let got = to_f64(k.apply(code, 0));
        assert!((got - 3f64.sqrt()).abs() < 1e-3, "{got}");
    }

    fn libm_sqrt3() -> f64 {
        3f64.sqrt()
    }

    #[test]
    fn scaling_saturates_and_rejects_nonsense() {
        let k = LinearScale::new(-30.0).unwrap();
        assert_eq!(k.apply(0, 4095), Pu::MAX);
        assert_eq!(k.apply(4095, 0), Pu::MIN);
        assert!(LinearScale::new(0.0).is_err());
        assert!(LinearScale::new(f64::NAN).is_err());
        assert_eq!(LinearScale::new(1e-15), Err(ScalingError::OutOfRange));
        assert_eq!(LinearScale::new(1e9), Err(ScalingError::OutOfRange));
        let bad = CurrentSensing {
            adc: ADC,
            shunt_ohm: 0.0,
            gain: 9.0,
        };
        assert!(bad.scale(1.0).is_err());
        let bad = VoltageSensing {
            adc: ADC,
            divider: 2.0,
        };
        assert!(bad.scale(1.0).is_err());
    }

    #[test]
    fn drive_input_from_raw() {
        let s = Scaling {
            current: LinearScale::new(0.01).unwrap(),
            voltage: LinearScale::new(0.001).unwrap(),
            offsets: [2000, 2048, 2100],
        };
        let i = s.input(&RawSample {
            i: [2100, 2048, 2000],
            vdc: 1732,
        });
        assert!((to_f64(i.i_abc.a) - 1.0).abs() < 1e-6);
        assert_eq!(i.i_abc.b, Pu::ZERO);
        assert!((to_f64(i.i_abc.c) + 1.0).abs() < 1e-6);
        assert!((to_f64(i.vdc) - 1.732).abs() < 1e-6);
    }

    #[test]
    fn offset_calibration() {
        let mut c = OffsetCalibration::new(4, (1800, 2300));
        let raw = |a, b, c| RawSample {
            i: [a, b, c],
            vdc: 0,
        };
        assert_eq!(c.add(&raw(2040, 2050, 2000)), None);
        assert_eq!(c.add(&raw(2042, 2050, 2001)), None);
        assert_eq!(c.add(&raw(2040, 2052, 2001)), None);
        assert_eq!(c.add(&raw(2042, 2052, 2002)), Some(Ok([2041, 2051, 2001])));
        assert_eq!(c.add(&raw(0, 0, 0)), Some(Ok([2041, 2051, 2001])));
        let mut c = OffsetCalibration::new(1, (1800, 2300));
        assert_eq!(
            c.add(&raw(2000, 100, 2000)),
            Some(Err(OffsetError {
                channel: 1,
                code: 100
            }))
        );
    }

    #[test]
    fn speed_knob_with_hysteresis() {
        let max = Pu::from_num(1);
        let mut k = SpeedKnob::new(100, 200, 4000, max);
        assert_eq!(k.update(0), KnobCommand::Stop);
        assert_eq!(k.update(150), KnobCommand::Stop);
        let KnobCommand::Run(s) = k.update(201) else {
            panic!()
        };
        assert!(s > Pu::ZERO && s < Pu::from_num(0.03));
        // Stays running down to the stop threshold.
        assert!(matches!(k.update(150), KnobCommand::Run(_)));
        assert_eq!(k.update(100), KnobCommand::Run(Pu::ZERO));
        assert_eq!(k.update(99), KnobCommand::Stop);
        assert_eq!(k.update(150), KnobCommand::Stop);
        assert_eq!(k.update(4095), KnobCommand::Run(max));
        assert_eq!(k.update(4000), KnobCommand::Run(max));
    }
}
