//! Initial rotor position detection at standstill by voltage pulses (Khlaief, Boussak, Gossa (2012) §4, eq. 10–13,
//! Tables 1–2; docs/khlaief2012.md §3).
//!
//! # Sequence
//!
//! Five pulses, each three stages long, stepped once per control sample:
//!
//! | pulse | direction `φ` | length | purpose |
//! |---|---|---|---|
//! | 1, 2, 3 | `0, 2π/3, 4π/3` (U1: a+ b− c−, U2, U3) | `N_s` samples | saliency: `θ` mod π |
//! | 4, 5 | `θ̂`, `θ̂ + π` | `N_l` samples | saturation: north or south |
//!
//! A pulse applies `V_p (cos φ, sin φ)` for its length, then `−V_p (cos φ, sin φ)` for as long
//! (the current ramps back to about zero, and the pulse pair leaves no net flux or torque
//! impulse), then the zero vector (all low sides on) for `N_off` samples while what remains
//! decays. The **peak** of pulse `k` is the current along `φ` at the end of its first stage
//! minus the current along `φ` at its start.
//!
//! # Angle modulo π (Khlaief, Boussak, Gossa (2012) eq. 10–13, restated in docs/khlaief2012.md §3)
//!
//! For a locked rotor and a short pulse, the current along `φ` grows as
//! `V t [Σ + Δ cos 2(θ − φ)]`, `Σ = (1/L_d + 1/L_q)/2`, `Δ = (1/L_d − 1/L_q)/2`
//! (docs/khlaief2012.md §1), so the peaks are `I_k = I_0 + ΔI cos(2θ − 2φ_k)` and
//!
//! ```text
//! 2θ = atan2(√3/2 (I_3 − I_2), I_1 − (I_2 + I_3)/2)
//! ```
//!
//! (both arguments are `(3/2) ΔI` times `sin 2θ`, `cos 2θ`). The saliency is
//! `ΔI/I_0 = (2/3)|(…)| / I_0`, `Δ/Σ = (L_q − L_d)/(L_q + L_d)` for a linear motor: 0.23 on
//! motor B. Below [`IpdDesign::min_saliency`] the angle is noise and the detector stops with
//! [`IpdFault::LowSaliency`] instead of returning a wrong angle (a surface motor). A motor with
//! `L_d > L_q` has its largest current along q: the result is turned by π/2.
//!
//! # Polarity (Khlaief, Boussak, Gossa (2012) §4, Fig. 4)
//!
//! Long pulses along the two candidates: the one along the magnet's north pole adds to the
//! magnet flux, saturates the d axis, lowers its incremental inductance and gives the larger
//! peak. `θ_0 = θ̂` if `I_4 > I_5`, else `θ̂ + π`. A relative difference below
//! [`IpdDesign::min_polarity`] is [`IpdFault::NoPolarity`]. (Khlaief, Boussak, Gossa's (2012) Table 1 variant, long
//! pulses along the three phase axes, needs one more pulse and resolves only the 120° sector;
//! the two candidates of the short pulses are enough.)
//!
//! # Pulse design
//!
//! With the pulse voltage `V_p` (a fraction of the nominal `V_DC/√3`, default 0.9) and the
//! peak wanted `I`, the duration is that of an R–L step reaching `I`:
//! `T = −(L/R) ln(1 − R I/V_p)`, with `L = 2/(1/L_d + 1/L_q)` (the mean `Σ`) for the short
//! pulses and `L = L_d` for the long ones (they point along d), rounded to whole control
//! samples. Defaults: short peak 0.5 `I_b` (half the rated peak current), long peak 2 `I_b`
//! (Khlaief, Boussak, Gossa (2012): "approximately twice the nominal current"). On motor B at 540 V and 14 kHz this
//! gives 3 samples (214 µs; seed: 200 µs) and 10 samples (714 µs; seed: 700 µs); on a 24 V,
//! 0.6/1.0 mH, 5 A motor at 20 kHz, 4 and 17 samples. `N_off` lets what the ramp back leaves
//! decay to [`IpdDesign::off_residual`] (0.67 %, about `e⁻⁵`) of the peak with the time constant
//! `τ = max(L_d, L_q)/R`. An R–L ramp of length `T` and its mirror leave `(T/τ)` of the peak
//! (to first order), and the dead time and the iron's saturation make the two ramps unequal by
//! up to a tenth of it: `N_off = τ ln(min(1, T_l/τ + 0.1)/0.0067)`, from 2.7 `τ` on a motor
//! whose pulses are short against `τ` to the five `τ` of a remainder as large as the peak (a
//! 540 V motor with 0.2 H and 4 Ω: 0.14 s per pulse instead of 0.24 s).
//!
//! Measured on the plant (switching inverter with dead time, 12-bit ADC, default saturation;
//! `tests/drive_parts_ipd.rs`): worst error over 72 angles 2.0° on motor B at 14 kHz, 2.7°
//! at 7 kHz, 1.4° on the small motor, polarity always right; Khlaief, Boussak, Gossa (2012) reports 15°.
//!
//! # Safety
//!
//! Every sample the three phase currents are checked against
//! [`IpdDesign::current_limit_pu`]: beyond it the sequence stops with
//! [`IpdFault::OverCurrent`] and `pwm_on = false`. A pulse peak below a quarter of the design
//! (open phase, no motor) is [`IpdFault::NoCurrent`]; a bus the modulator cannot use is
//! [`IpdFault::BusLow`].
//!
//! # Formats
//!
//! Currents and voltages [`Pu`] Q8.24; angles [`Angle`]; duties from [`SvpwmConfig`] (Q2.30).
//! The arithmetic is an `atan2` (`polar`) and comparisons scaled by [`Gain`]s: no division.

use crate::angle::{Angle, SinCos};
use crate::cordic::polar;
use crate::error::ConfigError;
use crate::frames::{AlphaBeta, inverse_clarke};
use crate::num::{Gain, Pu, mul_unit, pu_from_f64};
use crate::params::{MotorParams, ParamError, ParamReason, in_range};
use crate::svpwm::{Duties, SvpwmConfig};
use crate::units::PerUnit;

/// How the detector is set up; [`IpdDesign::default`] gives the defaults.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct IpdDesign {
    /// Pulse voltage as a fraction of the nominal `V_DC/√3`, in (0, 1].
    pub voltage_fraction: f64,
    /// Design peak of the short pulses, per unit of `I_b`.
    pub short_current_pu: f64,
    /// Design peak of the long pulses, per unit of `I_b`.
    pub long_current_pu: f64,
    /// Smallest accepted saliency `ΔI/I_0`.
    pub min_saliency: f64,
    /// Smallest accepted relative difference of the two long peaks.
    pub min_polarity: f64,
    /// Phase current that aborts the sequence, per unit of `I_b`.
    pub current_limit_pu: f64,
    /// Share of a pulse's peak the current may keep when the next pulse starts (the zero
    /// vector's time is designed from it, see the module's "Pulse design").
    pub off_residual: f64,
}

impl Default for IpdDesign {
    /// 0.9 of the bus, 0.5 and 2 pu peaks, saliency ≥ 5 %, polarity ≥ 1 %, limit 3 pu,
    /// 0.67 % (about `e⁻⁵`) of the peak left between pulses.
    fn default() -> Self {
        Self {
            voltage_fraction: 0.9,
            short_current_pu: 0.5,
            long_current_pu: 2.0,
            min_saliency: 0.05,
            min_polarity: 0.01,
            current_limit_pu: 3.0,
            off_residual: 0.0067,
        }
    }
}

/// Share of a pulse's peak by which its ramp back may miss zero through the dead time and the
/// iron's saturation (the ramps' own R–L remainder `T/τ` comes on top).
const RAMP_BACK_ASYMMETRY: f64 = 0.1;

/// Longest pulse or off time accepted, control samples.
pub const MAX_SAMPLES: u32 = 1 << 20;

/// Configuration of the [`Ipd`].
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct IpdConfig {
    /// Short pulse length, control samples.
    pub n_short: u32,
    /// Long pulse length, control samples.
    pub n_long: u32,
    /// Zero-vector time after each pulse, control samples.
    pub n_off: u32,
    /// Pulse voltage, per unit.
    v_p: Pu,
    /// Current limit, per unit.
    i_limit: Pu,
    /// Peak below which a short pulse is "no current" (a quarter of the design).
    i_short_min: Pu,
    /// `min_saliency / 2`: fault when `|(X, Y)| = (3/2) ΔI < this · (I_1 + I_2 + I_3)`, i.e.
    /// `ΔI/I_0 < min_saliency` (the sum is `3 I_0`).
    saliency_k: Gain,
    /// `min_polarity`: fault when `|I_4 − I_5| < this · (I_4 + I_5)/2`.
    polarity_k: Gain,
    /// Turn the saliency angle by π/2 (`L_d > L_q`).
    inverse_saliency: bool,
    svpwm: SvpwmConfig,
}

fn samples(key: &'static str, t_s: f64, ts: f64) -> Result<u32, ConfigError> {
    let n = libm::round(t_s / ts).max(2.0);
    if n.is_finite() && n <= MAX_SAMPLES as f64 {
        Ok(n as u32)
    } else {
        Err(ConfigError::OutOfEnvelope {
            quantity: key,
            value: n,
            min: 2.0,
            max: MAX_SAMPLES as f64,
            fit: crate::error::Fit::Other,
        })
    }
}

/// Time for an R–L step of `v` to reach `i`: `−(L/R) ln(1 − R i/v)`, or an error naming `key`
/// when `R i ≥ v` (the voltage cannot drive that current).
fn rise_time(key: &'static str, l: f64, r: f64, i: f64, v: f64) -> Result<f64, ConfigError> {
    let x = r * i / v;
    if x < 0.95 {
        Ok(-(l / r) * libm::log(1.0 - x))
    } else {
        Err(ParamError {
            key,
            reason: ParamReason::Inconsistent("rs_ohm and the pulse voltage (R·I near V)"),
        }
        .into())
    }
}

impl IpdConfig {
    /// Detector for `motor` with the bases (and control sample period) of `base`.
    ///
    /// Errors: [`ConfigError::Param`] naming `ipd.*` for a design value out of range or a
    /// peak the pulse voltage cannot reach; [`ConfigError::OutOfEnvelope`] for a pulse longer
    /// than 2²⁰ samples.
    pub fn new(
        motor: &MotorParams,
        base: &PerUnit,
        design: IpdDesign,
    ) -> Result<Self, ConfigError> {
        motor.validate()?;
        in_range("ipd.voltage_fraction", design.voltage_fraction, 0.05, 1.0)?;
        in_range("ipd.short_current_pu", design.short_current_pu, 0.01, 10.0)?;
        in_range("ipd.long_current_pu", design.long_current_pu, 0.01, 20.0)?;
        in_range("ipd.min_saliency", design.min_saliency, 1e-3, 0.9)?;
        in_range("ipd.min_polarity", design.min_polarity, 1e-4, 0.9)?;
        in_range(
            "ipd.current_limit_pu",
            design.current_limit_pu,
            1.1 * design.long_current_pu.max(design.short_current_pu),
            60.0,
        )?;
        in_range("ipd.off_residual", design.off_residual, 1e-4, 0.5)?;
        let ts = base.sample_s;
        let v = design.voltage_fraction * base.voltage_v;
        let r = motor.rs_ohm;
        let l_mean = 2.0 / (1.0 / motor.ld_h + 1.0 / motor.lq_h);
        let i_s = design.short_current_pu * base.current_a;
        let i_l = design.long_current_pu * base.current_a;
        let t_s = rise_time("ipd.short_current_pu", l_mean, r, i_s, v)?;
        let t_l = rise_time("ipd.long_current_pu", motor.ld_h, r, i_l, v)?;
        let tau = motor.ld_h.max(motor.lq_h) / r;
        let left = (t_l / tau + RAMP_BACK_ASYMMETRY).min(1.0);
        let t_off = tau * libm::log(left / design.off_residual).max(0.0);
        let gain = |key, value: f64| {
            Gain::new(value).ok_or(ConfigError::Gain {
                key,
                value,
                min: 1e-4,
                max: 1.0,
            })
        };
        Ok(Self {
            n_short: samples("ipd short pulse samples", t_s, ts)?,
            n_long: samples("ipd long pulse samples", t_l, ts)?,
            n_off: samples("ipd off samples", t_off, ts)?,
            v_p: pu_from_f64(design.voltage_fraction),
            i_limit: pu_from_f64(design.current_limit_pu),
            i_short_min: pu_from_f64(0.25 * design.short_current_pu),
            saliency_k: gain("ipd.min_saliency", 0.5 * design.min_saliency)?,
            polarity_k: gain("ipd.min_polarity", design.min_polarity)?,
            inverse_saliency: motor.ld_h > motor.lq_h,
            svpwm: SvpwmConfig::default(),
        })
    }

    /// The configuration of a drive that does not start by IPD: no design is checked (its
    /// pulses need not be reachable on this motor and bus). Should a detection run on it
    /// anyway, its zero current limit stops it at the first sample with
    /// [`IpdFault::OverCurrent`] or, with no current at all, [`IpdFault::NoCurrent`].
    pub(crate) fn unused() -> Self {
        Self {
            n_short: 2,
            n_long: 2,
            n_off: 2,
            v_p: Pu::ZERO,
            i_limit: Pu::ZERO,
            i_short_min: Pu::MAX,
            saliency_k: Gain::ZERO,
            polarity_k: Gain::ZERO,
            inverse_saliency: false,
            svpwm: SvpwmConfig::default(),
        }
    }

    /// Control samples the whole sequence takes (if it does not stop early).
    pub fn total_samples(&self) -> u32 {
        3 * (2 * self.n_short + self.n_off) + 2 * (2 * self.n_long + self.n_off)
    }
}

/// Why the detection failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IpdFault {
    /// A phase current exceeded the limit (the current at that sample, per unit).
    OverCurrent(Pu),
    /// A short pulse produced less than a quarter of its design peak (open phase or no
    /// motor); its peak, per unit.
    NoCurrent(Pu),
    /// The saliency `ΔI/I_0` was below the minimum: a surface motor, or too much noise. The
    /// measured `(3/2) ΔI` and `3 I_0`, per unit.
    LowSaliency {
        /// `|(I_1 − (I_2+I_3)/2, √3/2 (I_3 − I_2))|` = `(3/2) ΔI`.
        modulation: Pu,
        /// `I_1 + I_2 + I_3` = `3 I_0`.
        sum: Pu,
    },
    /// The long peaks along `θ̂` and `θ̂ + π` were too close to tell north from south.
    NoPolarity {
        /// Peak along `θ̂`.
        along: Pu,
        /// Peak along `θ̂ + π`.
        opposite: Pu,
    },
    /// The bus voltage is too low to modulate.
    BusLow,
}

/// The detected initial position.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IpdResult {
    /// Electrical angle of the magnet's north pole. Read as `theta.0 as u32` it is in
    /// [0, 2π) (2³² per turn).
    pub theta: Angle,
    /// Starting sector of Khlaief, Boussak, Gossa (2012) Table 2: 1 for [0°, 60°), …, 6 for [300°, 360°).
    pub sector: u8,
    /// Angle modulo π from the short pulses, in [−π/2, π/2).
    pub theta_mod_pi: Angle,
    /// The five peaks `I_1 … I_5`, per unit (short pulses along the phase axes, then the long
    /// pulses along `θ̂` and `θ̂ + π`).
    pub peaks: [Pu; 5],
}

impl IpdResult {
    /// The angle in degrees, [0, 360) (host code and reports).
    pub fn theta_deg_0_360(&self) -> f64 {
        self.theta.0 as u32 as f64 * (360.0 / 4_294_967_296.0)
    }
}

/// Starting sector (Khlaief, Boussak, Gossa (2012) Table 2) of an angle: 1 + ⌊θ/60°⌋ with θ in [0°, 360°).
pub fn sector(theta: Angle) -> u8 {
    (((theta.0 as u32 as u64) * 6) >> 32) as u8 + 1
}

/// Output of one [`Ipd::step`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IpdOutput {
    /// Duties for the next control period.
    pub duties: Duties,
    /// The voltage vector those duties command, αβ per unit.
    pub v: AlphaBeta,
    /// Keep the inverter switching (false once done or faulted).
    pub pwm_on: bool,
    /// `Some` once the sequence has ended, with the result or the fault.
    pub done: Option<Result<IpdResult, IpdFault>>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    /// `+V_p` along φ.
    On,
    /// `−V_p` along φ.
    Return,
    /// Zero vector.
    Off,
}

/// The detector's state machine; step it once per control sample from standstill.
#[derive(Clone, Copy, Debug)]
pub struct Ipd {
    config: IpdConfig,
    pulse: u8,
    stage: Stage,
    count: u32,
    dir: SinCos,
    baseline: Pu,
    peaks: [Pu; 5],
    theta_mod_pi: Angle,
    done: Option<Result<IpdResult, IpdFault>>,
}

impl Ipd {
    /// A detector ready to start.
    pub fn new(config: IpdConfig) -> Self {
        Self {
            config,
            pulse: 0,
            stage: Stage::On,
            count: 0,
            dir: Angle::ZERO.sin_cos(),
            baseline: Pu::ZERO,
            peaks: [Pu::ZERO; 5],
            theta_mod_pi: Angle::ZERO,
            done: None,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &IpdConfig {
        &self.config
    }

    /// Restart from the first pulse.
    pub fn restart(&mut self) {
        *self = Self::new(self.config);
    }

    /// Direction of pulse `k`.
    fn direction(&self, k: u8) -> Angle {
        match k {
            0 => Angle::ZERO,
            1 => THIRD_TURN,
            2 => -THIRD_TURN,
            3 => self.theta_mod_pi,
            _ => self.theta_mod_pi + Angle::PI,
        }
    }

    fn stop(&mut self, r: Result<IpdResult, IpdFault>) -> IpdOutput {
        self.done = Some(r);
        Self::idle(self.done)
    }

    fn idle(done: Option<Result<IpdResult, IpdFault>>) -> IpdOutput {
        IpdOutput {
            duties: Duties::HALF,
            v: AlphaBeta::default(),
            pwm_on: false,
            done,
        }
    }

    /// One control sample: `i` is the current measured at this sample (αβ, per unit: the end
    /// of the period commanded by the previous output), `vdc` the bus (per unit of `V_b`).
    /// Returns the duties for the next period. Integer only; never panics.
    pub fn step(&mut self, i: AlphaBeta, vdc: Pu) -> IpdOutput {
        if self.done.is_some() {
            return Self::idle(self.done);
        }
        let sign = match self.measure(i) {
            Ok(sign) => sign,
            Err(f) => return self.stop(Err(f)),
        };
        if let Some(done) = self.advance() {
            return self.stop(done);
        }
        self.output(sign, vdc)
    }

    /// What this sample measures: the overcurrent check, then the current along the pulse's
    /// direction at the start of a pulse (baseline) and at the end of its first stage (peak).
    /// Returns the sign of this sample's voltage (`None`: zero vector).
    #[inline(always)]
    fn measure(&mut self, i: AlphaBeta) -> Result<Option<bool>, IpdFault> {
        let ph = inverse_clarke(i);
        let worst =
            ph.a.saturating_abs()
                .max(ph.b.saturating_abs())
                .max(ph.c.saturating_abs());
        if worst > self.config.i_limit {
            return Err(IpdFault::OverCurrent(worst));
        }
        match self.stage {
            Stage::On => {
                if self.count == 0 {
                    self.dir = self.direction(self.pulse).sin_cos();
                    self.baseline = mul_unit(i.alpha, self.dir.cos)
                        .saturating_add(mul_unit(i.beta, self.dir.sin));
                }
                Ok(Some(true))
            }
            Stage::Return => {
                if self.count == 0 {
                    let along = mul_unit(i.alpha, self.dir.cos)
                        .saturating_add(mul_unit(i.beta, self.dir.sin));
                    let peak = along.saturating_sub(self.baseline);
                    if let Some(p) = self.peaks.get_mut(self.pulse as usize) {
                        *p = peak;
                    }
                    if self.pulse < 3 && peak < self.config.i_short_min {
                        return Err(IpdFault::NoCurrent(peak));
                    }
                }
                Ok(Some(false))
            }
            Stage::Off => Ok(None),
        }
    }

    /// Counts the sample and moves to the next stage or pulse; after the third pulse the
    /// angle mod π, after the fifth the result (`Some`: the detection is over).
    #[inline(always)]
    fn advance(&mut self) -> Option<Result<IpdResult, IpdFault>> {
        self.count += 1;
        let limit = match self.stage {
            Stage::On | Stage::Return if self.pulse < 3 => self.config.n_short,
            Stage::On | Stage::Return => self.config.n_long,
            Stage::Off => self.config.n_off,
        };
        if self.count >= limit {
            self.count = 0;
            match self.stage {
                Stage::On => self.stage = Stage::Return,
                Stage::Return => self.stage = Stage::Off,
                Stage::Off => {
                    if self.pulse == 2
                        && let Err(f) = self.saliency()
                    {
                        return Some(Err(f));
                    }
                    if self.pulse >= 4 {
                        return Some(self.polarity());
                    }
                    self.pulse += 1;
                    self.stage = Stage::On;
                }
            }
        }
        None
    }

    /// The duties of the next period: the pulse's voltage of sign `sign` along its direction,
    /// or the zero vector (all legs low) between pulses.
    #[inline(always)]
    fn output(&mut self, sign: Option<bool>, vdc: Pu) -> IpdOutput {
        let Some(positive) = sign else {
            return IpdOutput {
                duties: Duties::LOW,
                v: AlphaBeta::default(),
                pwm_on: true,
                done: None,
            };
        };
        let m = if positive {
            self.config.v_p
        } else {
            -self.config.v_p
        };
        let v = AlphaBeta {
            alpha: mul_unit(m, self.dir.cos),
            beta: mul_unit(m, self.dir.sin),
        };
        let out = self.config.svpwm.modulate(v, vdc);
        if out.bus_low {
            return self.stop(Err(IpdFault::BusLow));
        }
        IpdOutput {
            duties: out.duties,
            v: out.v,
            pwm_on: true,
            done: None,
        }
    }

    /// `θ` mod π from the three short peaks (eq. 12–13 as restated in docs/khlaief2012.md §3).
    fn saliency(&mut self) -> Result<(), IpdFault> {
        let [i1, i2, i3, _, _] = self.peaks;
        // X = I_1 − (I_2 + I_3)/2, Y = √3/2 (I_3 − I_2), in i64 then back to Pu (exact halves).
        let x = i1.to_bits() as i64 - ((i2.to_bits() as i64 + i3.to_bits() as i64) >> 1);
        let y = mul_unit(i3.saturating_sub(i2), SQRT3_2);
        let x = Pu::from_bits(crate::num::sat_i32(x));
        let p = polar(x, y);
        let sum = i1.saturating_add(i2).saturating_add(i3);
        if p.magnitude < self.config.saliency_k.apply(sum) || sum <= Pu::ZERO {
            return Err(IpdFault::LowSaliency {
                modulation: p.magnitude,
                sum,
            });
        }
        // 2θ → θ mod π: halve the angle (arithmetic shift keeps [−π/2, π/2)).
        let mut theta = Angle(p.angle.0 >> 1);
        if self.config.inverse_saliency {
            theta = theta + Angle::HALF_PI;
        }
        self.theta_mod_pi = theta;
        Ok(())
    }

    /// North or south from the two long peaks.
    fn polarity(&self) -> Result<IpdResult, IpdFault> {
        let [_, _, _, a, b] = self.peaks;
        let mean = Pu::from_bits(((a.to_bits() as i64 + b.to_bits() as i64) >> 1) as i32);
        let diff = a.saturating_sub(b).saturating_abs();
        if diff < self.config.polarity_k.apply(mean) || mean <= Pu::ZERO {
            return Err(IpdFault::NoPolarity {
                along: a,
                opposite: b,
            });
        }
        let theta = if a > b {
            self.theta_mod_pi
        } else {
            self.theta_mod_pi + Angle::PI
        };
        Ok(IpdResult {
            theta,
            sector: sector(theta),
            theta_mod_pi: self.theta_mod_pi,
            peaks: self.peaks,
        })
    }
}

/// √3/2 in Q2.30.
const SQRT3_2: crate::num::Unit = crate::num::Unit::from_bits(929_887_697);

/// 2π/3 (round(2³²/3) counts); −2π/3 is 4π/3.
const THIRD_TURN: Angle = Angle(1_431_655_765);

#[cfg(test)]
mod tests;
