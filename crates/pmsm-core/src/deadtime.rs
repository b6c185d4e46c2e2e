//! Dead-time compensation of Khlaief, Boussak, Gossa (2012) §3 (eq. 7–9; docs/khlaief2012.md §4).
//!
//! During the dead time of each switching edge a leg's output follows its current, not its
//! command; averaged over a period the leg loses `V_dead sgn(i_x)` (Khlaief, Boussak, Gossa (2012) eq. 8, the
//! numbering of the paper's own text):
//!
//! ```text
//! V_dead = (T_dead + T_on − T_off)/T_PWM · (V_DC − V_sat + V_f) + (V_sat + V_f)/2     (eq. 8)
//! V_dt   = (2/3) V_dead [s_a + a s_b + a² s_c],  a = e^{j2π/3}                        (eq. 7)
//! applied voltage = commanded voltage − V_dt                                        (eq. 9)
//! ```
//!
//! `(2/3)[s_a + a s_b + a² s_c]` is the amplitude-invariant Clarke transform of
//! `(s_a, s_b, s_c)`, so `V_dt = clarke(V_dead · s)`; with no current near zero it has length
//! `(4/3) V_dead` and points at the sector of the current vector.
//!
//! # Near zero crossings
//!
//! `s_x = sat(i_x / i_band)` (linear within `±i_band`, ±1 outside) instead of `sgn i_x`: the
//! leg error fades over the band where the PWM ripple makes the instantaneous current change
//! sign, and a noisy measured current near zero does not toggle ±V_dead every sample. Default
//! `i_band` is the ripple amplitude of a leg at half duty, `V_DC/(8 L_min f_PWM)` (0.19 A for
//! motor B at 540 V, 14 kHz). The current used can be the measurement or the current
//! reference (smooth, and known before the period it compensates): [`CurrentSource`] tells
//! the drive which one to pass.
//!
//! # Where it applies ([`DeadTimeMode`])
//!
//! | mode | command sent to the PWM | voltage given to the estimator |
//! |---|---|---|
//! | `Off` | `v_ref` | the command |
//! | `Command` | `v_ref + V_dt` | the command (the estimator is not told) |
//! | `Estimator` | `v_ref` | the command `− V_dt` (Khlaief, Boussak, Gossa (2012) eq. 9) |
//! | `Both` | `v_ref + V_dt` | the command `− V_dt` (= `v_ref` when nothing limits) |
//!
//! `V_dead` is scaled by the measured bus at run time (it is affine in `V_DC`).
//!
//! # Formats
//!
//! Currents, voltages, bus: [`Pu`] (Q8.24) of `I_b`, `V_b`. `T_eff f_PWM`:
//! [`Coef<31>`](crate::num::Coef) (below 0.1); `1/i_band`: [`Reciprocal`]. `s_x`: Q4.28 in [−1, 1]
//! (a current more than `i_band` from zero is ±1 without a product). `V_dt` is formed as the
//! Clarke transform of the signs, scaled once: `α = V_dead (2s_a − s_b − s_c)/3`,
//! `β = V_dead (s_b − s_c)/√3` (the sign sums exact in Q4.28, `V_dead/3` and `V_dead/√3` in
//! Q8.26, computed once per bus reading by [`DeadTimeBus`], one rounding to [`Pu`]); within
//! 2 LSB of the f64 formula.

use crate::error::ConfigError;
use crate::frames::{Abc, AlphaBeta, Dq, inverse_clarke};
use crate::num::{Coef, Pu, Reciprocal, pu_from_f64, round_shift_sat, wmul};
use crate::params::{InverterParams, MotorParams, ParamError, ParamReason, in_range, non_negative};
use crate::units::PerUnit;

/// Where the compensation is applied (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, crate::image::Words)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DeadTimeMode {
    /// No compensation.
    Off,
    /// Added to the voltage command only.
    Command,
    /// Subtracted from the voltage the estimator uses only (Khlaief, Boussak, Gossa (2012) eq. 9).
    Estimator,
    /// Both.
    #[default]
    Both,
}

impl DeadTimeMode {
    /// The command gets `+V_dt`.
    pub fn compensates_command(self) -> bool {
        matches!(self, Self::Command | Self::Both)
    }

    /// The estimator's voltage gets `−V_dt`.
    pub fn corrects_estimator(self) -> bool {
        matches!(self, Self::Estimator | Self::Both)
    }
}

/// Which current the drive passes to [`DeadTimeConfig::error_vector`] (docs/drive.md,
/// "dead-time compensation: which current's sign").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, crate::image::Words)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CurrentSource {
    /// The measured current, in the controller's frame turned to the middle of the period the
    /// command acts over, while the current vector lies beyond the band (`|i_d| + |i_q| >
    /// i_band`); within it, the reference.
    Measured,
    /// The measured current while the q current the loop is expected to carry lies beyond
    /// [`MEASURED_SIGN_BANDS`] bands of zero and the estimated speed's EMF beyond `V_dead`
    /// (under load, where the reference's signs sustain a cycle at the electrical frequency on
    /// a strongly salient motor); the reference otherwise (at light load the measured signs
    /// chatter with the ripple, and near standstill the distortion outweighs the EMF).
    MeasuredUnderLoad,
    /// The current reference through the current loop's lag, turned likewise.
    #[default]
    Reference,
}

/// The q current, in bands `i_band`, from which [`CurrentSource::MeasuredUnderLoad`] takes the
/// measured current (docs/drive.md, "dead-time compensation: which current's sign"). On the
/// random family 4 held one run more than 6 but doubled motor B's no-load oscillation on the
/// averaged inverter with a hard sign; 8 held three fewer.
pub const MEASURED_SIGN_BANDS: u32 = 6;

/// Switching-device parameters beyond [`InverterParams`] (SI; zero for ideal devices).
#[derive(Clone, Copy, Debug, Default, PartialEq, crate::image::Words)]
pub struct DeviceParams {
    /// Switch turn-on delay `T_on`, s.
    pub t_on_s: f64,
    /// Switch turn-off delay `T_off`, s.
    pub t_off_s: f64,
    /// On-state drop of a switch `V_sat`, V.
    pub v_sat_v: f64,
    /// Forward drop of a diode `V_f`, V.
    pub v_f_v: f64,
}

/// How the compensation is set up; [`DeadTimeDesign::default_for`] gives the defaults.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct DeadTimeDesign {
    /// Device delays and drops.
    pub device: DeviceParams,
    /// Half-width of the linear band of the current sign, A.
    pub band_a: f64,
    /// Where it applies.
    pub mode: DeadTimeMode,
    /// Which current to use.
    pub source: CurrentSource,
}

impl DeadTimeDesign {
    /// Ideal devices, band `V_DC/(8 L_min f_PWM)`, mode [`DeadTimeMode::Both`], current
    /// reference.
    pub fn default_for(motor: &MotorParams, inverter: &InverterParams) -> Self {
        let l_min = motor.ld_h.min(motor.lq_h);
        Self {
            device: DeviceParams::default(),
            band_a: inverter.vdc_v / (8.0 * l_min * inverter.pwm_hz),
            mode: DeadTimeMode::Both,
            source: CurrentSource::Reference,
        }
    }

    /// The distortion voltage `V_dead` this design compensates on `inverter` at its nominal
    /// bus, V: `T_eff f_PWM V_DC + (V_sat + V_f)/2 − T_eff f_PWM (V_sat − V_f)` (docs/khlaief2012.md §4).
    pub fn v_dead_v(&self, inverter: &InverterParams) -> f64 {
        let (k, v_const) = self.terms(inverter);
        k * inverter.vdc_v + v_const
    }

    /// `T_eff f_PWM` and the bus-independent part of `V_dead` (V).
    fn terms(&self, inverter: &InverterParams) -> (f64, f64) {
        let d = self.device;
        let k = (inverter.dead_time_s + d.t_on_s - d.t_off_s) * inverter.pwm_hz;
        (k, 0.5 * (d.v_sat_v + d.v_f_v) - k * (d.v_sat_v - d.v_f_v))
    }
}

/// Configuration of the compensation.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct DeadTimeConfig {
    /// `T_eff f_PWM` (dimensionless): the part of `V_dead` proportional to the bus.
    k_bus: Coef<31>,
    /// `[(V_sat + V_f)/2 − T_eff f_PWM (V_sat − V_f)] / V_b`.
    v_const: Pu,
    /// `1/i_band` (the band in LSB of [`Pu`], not rounded): `sat(i/i_band)` of a current inside
    /// the band is one product.
    inv_band: Reciprocal,
    /// `i_band` in LSB of [`Pu`], rounded up: beyond it the sign is ±1 exactly.
    band_bits: i32,
    /// The q current beyond which the drive may take the measured current in place of the
    /// reference, LSB of [`Pu`]: [`MEASURED_SIGN_BANDS`] bands with
    /// [`CurrentSource::MeasuredUnderLoad`], never (`u32::MAX`) otherwise (one comparison
    /// serves both sources; computing it at run time cost the Cortex-M0 8 instructions).
    loaded_bits: u32,
    /// Where it applies.
    mode: DeadTimeMode,
    /// Which current's signs it takes.
    source: CurrentSource,
}

impl DeadTimeConfig {
    /// Compensation for `inverter` in the bases `base`.
    ///
    /// Errors ([`ConfigError::Param`]): `deadtime.t_on_s`, `deadtime.t_off_s`,
    /// `deadtime.v_sat_v`, `deadtime.v_f_v` negative or not finite, drops above 50 V, an
    /// effective dead time `T_dead + T_on − T_off` negative or above 10 % of the period, or
    /// `deadtime.band_a` outside `(0, 10 I_b]` (at least 1e−6 I_b).
    pub fn new(
        inverter: &InverterParams,
        base: &PerUnit,
        design: DeadTimeDesign,
    ) -> Result<Self, ConfigError> {
        inverter.validate()?;
        let d = design.device;
        non_negative("deadtime.t_on_s", d.t_on_s)?;
        non_negative("deadtime.t_off_s", d.t_off_s)?;
        in_range("deadtime.v_sat_v", d.v_sat_v, 0.0, 50.0)?;
        in_range("deadtime.v_f_v", d.v_f_v, 0.0, 50.0)?;
        let (k, v_const) = design.terms(inverter);
        if !(0.0..0.1).contains(&k) {
            return Err(ParamError {
                key: "deadtime.t_off_s",
                reason: ParamReason::Inconsistent(
                    "dead_time_s + t_on_s (effective dead time outside [0, 10 %) of the period)",
                ),
            }
            .into());
        }
        let band = in_range(
            "deadtime.band_a",
            design.band_a,
            1e-6 * base.current_a,
            10.0 * base.current_a,
        )?;
        // band ≤ 10 I_b: at most 10·2²⁴ + 1 LSB, rounded up.
        let band_bits = libm::ceil(band / base.current_a * (1u64 << 24) as f64) as u32;
        Ok(Self {
            // k ∈ [0, 0.1) (checked above): Q1.31 holds it to 4.7e−10.
            k_bus: Coef::new(k).ok_or(ConfigError::Gain {
                key: "dead_time_s",
                value: k,
                min: 0.0,
                max: 0.1,
            })?,
            v_const: pu_from_f64(v_const / base.voltage_v),
            inv_band: Reciprocal::from_f64(band / base.current_a * (1u64 << 24) as f64).ok_or(
                ConfigError::Gain {
                    key: "deadtime.band_a",
                    value: band,
                    min: 1e-6 * base.current_a,
                    max: 10.0 * base.current_a,
                },
            )?,
            band_bits: band_bits as i32,
            // At most 6·(10·2²⁴ + 1) < 2³² LSB.
            loaded_bits: match design.source {
                CurrentSource::MeasuredUnderLoad => MEASURED_SIGN_BANDS * band_bits,
                CurrentSource::Measured | CurrentSource::Reference => u32::MAX,
            },
            mode: design.mode,
            source: design.source,
        })
    }

    /// The same compensation with `V_dead` scaled by `scale` (Q4.28, `1 << 28` is one; within
    /// `[0, 4]`, saturated): what the drive uses once it has measured the inverter's
    /// distortion voltage at standstill (docs/drive.md, "dead-time calibration").
    pub fn scaled(&self, scale: i32) -> Self {
        let apply = |x: i32| crate::num::scale_q28(x, scale.clamp(0, 4 << 28));
        Self {
            // k < 0.1 (checked by `new`) times at most 4: below 1, inside Q1.31.
            k_bus: Coef::from_bits(apply(self.k_bus.bits())),
            v_const: Pu::from_bits(apply(self.v_const.to_bits())),
            ..*self
        }
    }

    /// The compensation's bus terms as bits (`k_bus`, `v_const`): what the calibration and
    /// the learner scale, sent from the drive's task to its interrupt side.
    pub(crate) fn bus_terms(&self) -> (i32, i32) {
        (self.k_bus.bits(), self.v_const.to_bits())
    }

    /// The same compensation with the bus terms of [`DeadTimeConfig::bus_terms`].
    pub(crate) fn with_bus_terms(&self, (k_bus, v_const): (i32, i32)) -> Self {
        Self {
            k_bus: Coef::from_bits(k_bus),
            v_const: Pu::from_bits(v_const),
            ..*self
        }
    }

    /// Whose current's signs the compensation takes.
    #[inline(always)]
    pub(crate) fn source(&self) -> CurrentSource {
        self.source
    }

    /// `V_dead` (eq. 8) for the measured bus `vdc`, per unit of `V_b`; zero for a bus at or
    /// below zero.
    pub fn v_dead(&self, vdc: Pu) -> Pu {
        if vdc <= Pu::ZERO {
            return Pu::ZERO;
        }
        self.k_bus.apply(vdc).saturating_add(self.v_const)
    }

    /// `i_band` in [`Pu`] bits, rounded up.
    pub(crate) fn band_bits(&self) -> u32 {
        self.band_bits.unsigned_abs()
    }

    /// Whether the current vector `i` lies beyond the band, `|i_d| + |i_q| > i_band` (the sum
    /// is at least the vector's length): where [`CurrentSource::Measured`] takes the measured
    /// current's signs (docs/drive.md, "dead-time compensation: which current's sign").
    #[inline(always)]
    pub(crate) fn beyond_band(&self, i: Dq) -> bool {
        let (d, q) = (i.d.to_bits(), i.q.to_bits());
        d.saturating_abs().saturating_add(q.saturating_abs()) > self.band_bits
    }

    /// Whether the q current `i_q` lies beyond [`MEASURED_SIGN_BANDS`] bands with
    /// [`CurrentSource::MeasuredUnderLoad`] (where the drive may take the measured current);
    /// false with the other sources.
    #[inline(always)]
    pub(crate) fn loaded(&self, i_q: Pu) -> bool {
        i_q.to_bits().unsigned_abs() > self.loaded_bits
    }

    /// `sat(i/i_band)` in [−1, 1], Q4.28. Beyond `band_bits` (the band rounded up to an
    /// LSB) ±1 without the product; inside, `i/i_band` from the reciprocal (within one LSB of
    /// Q4.28), clamped.
    #[inline(always)]
    fn sign(&self, i: Pu) -> i32 {
        let x = i.to_bits();
        if x > self.band_bits {
            SIGN_ONE
        } else if x < -self.band_bits {
            -SIGN_ONE
        } else {
            self.inv_band.fraction_q28(x).clamp(-SIGN_ONE, SIGN_ONE)
        }
    }

    /// The dead-time error vector `V_dt` (eq. 7) for the current `i` (αβ, per unit: the
    /// measurement or the reference, see [`CurrentSource`]) on the bus `vdc`.
    pub fn error_vector(&self, i: AlphaBeta, vdc: Pu) -> AlphaBeta {
        self.error_vector_abc(inverse_clarke(i), vdc)
    }

    /// [`DeadTimeConfig::error_vector`] from the phase currents (what a drive measuring three
    /// phases already has): `V_dt = clarke(V_dead · s)` written as the Clarke transform of the
    /// signs, `α = V_dead (2s_a − s_b − s_c)/3`, `β = V_dead (s_b − s_c)/√3`.
    pub fn error_vector_abc(&self, i: Abc, vdc: Pu) -> AlphaBeta {
        self.error_vector_abc_cached(i, vdc, &mut DeadTimeBus::default())
    }

    /// [`DeadTimeConfig::error_vector_abc`], bit for bit, with the bus terms `V_dead/3` and
    /// `V_dead/√3` taken from `cache` when `vdc` is the reading they were computed for.
    pub(crate) fn error_vector_abc_cached(
        &self,
        i: Abc,
        vdc: Pu,
        cache: &mut DeadTimeBus,
    ) -> AlphaBeta {
        let bits = vdc.to_bits();
        // The empty cache (reading 0) holds what a reading of 0 gives: V_dead = 0.
        if bits != cache.vdc {
            let v = self.v_dead(vdc).to_bits();
            // V_dead/3 and V_dead/√3 in Q8.26 (the bits of 4/3 and 4/√3 times V_dead).
            *cache = DeadTimeBus {
                vdc: bits,
                third: round_shift_sat(wmul(v, FOUR_THIRDS_Q30), 30),
                inv_sqrt3: round_shift_sat(wmul(v, FOUR_INV_SQRT3_Q29), 29),
            };
        }
        let (sa, sb, sc) = (self.sign(i.a), self.sign(i.b), self.sign(i.c));
        // Q4.28, |s| ≤ 2²⁸: the sums are exact, |2s_a − s_b − s_c| ≤ 2³⁰, |s_b − s_c| ≤ 2²⁹.
        let s_alpha = 2 * sa - sb - sc;
        let s_beta = sb - sc;
        // Q4.28 · Q8.26 = Q.54 → Q8.24: one product and one rounding per component.
        AlphaBeta {
            alpha: Pu::from_bits(round_shift_sat(wmul(s_alpha, cache.third), 30)),
            beta: Pu::from_bits(round_shift_sat(wmul(s_beta, cache.inv_sqrt3), 30)),
        }
    }

    /// The command to send to the PWM for the reference `v_ref`: `v_ref + V_dt` when the mode
    /// compensates the command, else `v_ref`.
    pub fn command(&self, v_ref: AlphaBeta, v_dt: AlphaBeta) -> AlphaBeta {
        if self.mode.compensates_command() {
            v_ref.saturating_add(v_dt)
        } else {
            v_ref
        }
    }

    /// The voltage the estimator should use, from the command `v_cmd` actually sent (after
    /// the modulator's limit) over the period: `v_cmd − V_dt` when the mode corrects the
    /// estimator (eq. 9), else `v_cmd`.
    pub fn estimator_voltage(&self, v_cmd: AlphaBeta, v_dt: AlphaBeta) -> AlphaBeta {
        if self.mode.corrects_estimator() {
            v_cmd.saturating_sub(v_dt)
        } else {
            v_cmd
        }
    }
}

/// The bus terms of the dead-time vector for the last bus reading seen (see
/// [`DeadTimeConfig::error_vector_abc_cached`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct DeadTimeBus {
    vdc: i32,
    /// `V_dead/3`, Q8.26.
    third: i32,
    /// `V_dead/√3`, Q8.26.
    inv_sqrt3: i32,
}

/// One in Q4.28 (the format of the signs).
const SIGN_ONE: i32 = 1 << 28;
/// `4/3` in Q2.30 (Q4.28 sign sum to Q2.30, divided by 3).
const FOUR_THIRDS_Q30: i32 = 1_431_655_765;
/// `4/√3` in Q3.29 (Q4.28 sign difference to Q2.30, divided by √3): the bits of `1/√3` in
/// Q1.31.
const FOUR_INV_SQRT3_Q29: i32 = crate::num::INV_SQRT3_Q31;

#[cfg(test)]
mod tests {
    use super::*;

    /// Motor B's default design in `mode`.
    fn design(mode: DeadTimeMode) -> DeadTimeDesign {
        let (m, inv) = (crate::fixtures::motor_b(), crate::fixtures::inverter_b());
        DeadTimeDesign {
            mode,
            ..DeadTimeDesign::default_for(&m, &inv)
        }
    }

    fn setup(mode: DeadTimeMode) -> (DeadTimeConfig, PerUnit) {
        let inv = crate::fixtures::inverter_b();
        let base = crate::fixtures::base_b();
        (
            DeadTimeConfig::new(&inv, &base, design(mode)).unwrap(),
            base,
        )
    }

    #[test]
    fn papers_inverter_value_and_modes() {
        let (c, base) = setup(DeadTimeMode::Both);
        // 2 µs at 14 kHz on 540 V: 15.12 V (docs/khlaief2012.md §4: "about 15 V").
        let (m, inv) = (crate::fixtures::motor_b(), crate::fixtures::inverter_b());
        let v = DeadTimeDesign::default_for(&m, &inv).v_dead_v(&inv);
        assert!((v - 15.12).abs() < 1e-9);
        let vd = c.v_dead(base.voltage_pu(540.0));
        assert!((base.voltage_v(vd) - 15.12).abs() < 1e-5);
        assert_eq!(c.v_dead(Pu::ZERO), Pu::ZERO);
        let v = AlphaBeta {
            alpha: Pu::from_num(0.5),
            beta: Pu::ZERO,
        };
        let dt = AlphaBeta {
            alpha: Pu::from_num(0.03125),
            beta: Pu::ZERO,
        };
        for (mode, cmd, est) in [
            (DeadTimeMode::Off, 0.5, 0.5),
            (DeadTimeMode::Command, 0.53125, 0.53125),
            (DeadTimeMode::Estimator, 0.5, 0.46875),
            (DeadTimeMode::Both, 0.53125, 0.5),
        ] {
            let (c, _) = setup(mode);
            let command = c.command(v, dt);
            assert_eq!(command.alpha, Pu::from_num(cmd), "{mode:?}");
            assert_eq!(
                c.estimator_voltage(command, dt).alpha,
                Pu::from_num(est),
                "{mode:?}"
            );
        }
    }

    /// The band's test on the current vector against the f64 sum: motor B's band is
    /// 0.1929 A; the sum of the components' magnitudes decides, in either quadrant.
    #[test]
    fn beyond_band_is_the_sum_of_magnitudes_against_the_band() {
        let (c, base) = setup(DeadTimeMode::Both);
        let band = design(DeadTimeMode::Both).band_a;
        assert!((band - 540.0 / (8.0 * 0.025025 * 14000.0)).abs() < 1e-12);
        for (d, q) in [
            (0.1, 0.1),
            (0.09, 0.09),
            (-0.2, 0.0),
            (0.0, -0.19),
            (0.05, -0.15),
        ] {
            let i = Dq {
                d: base.current_pu(d),
                q: base.current_pu(q),
            };
            let want = f64::abs(d) + f64::abs(q) > band;
            assert_eq!(c.beyond_band(i), want, "({d}, {q}) A against {band} A");
        }
    }

    /// A scaled compensation's `V_dead` against the f64 product, within 2 LSB, at 0, 0.5,
    /// 0.998, 1, 1.5 and beyond the limit of 4.
    #[test]
    fn scaled_v_dead() {
        let (c, base) = setup(DeadTimeMode::Both);
        let vdc = base.voltage_pu(540.0);
        let v = c.v_dead(vdc).to_bits() as f64;
        for s in [0.0, 0.5, 0.998, 1.0, 1.5, 9.0] {
            let bits = (s * (1u64 << 28) as f64).min(i32::MAX as f64) as i32;
            let got = c.scaled(bits).v_dead(vdc).to_bits() as f64;
            let want = v * s.min(4.0);
            assert!((got - want).abs() <= 2.0, "{s}: {got} {want}");
        }
        assert_eq!(c.scaled(1 << 28), c);
    }

    #[test]
    fn bad_device_parameters_are_named() {
        let base = crate::fixtures::base_b();
        let inv = InverterParams {
            vdc_v: 540.0,
            pwm_hz: 14e3,
            dead_time_s: 2e-6,
            current_full_scale_a: 10.0,
        };
        let mut d = design(DeadTimeMode::Both);
        d.device.t_off_s = 3e-6;
        assert!(matches!(
            DeadTimeConfig::new(&inv, &base, d),
            Err(ConfigError::Param(ParamError {
                key: "deadtime.t_off_s",
                ..
            }))
        ));
        let mut d = design(DeadTimeMode::Both);
        d.band_a = 0.0;
        assert!(matches!(
            DeadTimeConfig::new(&inv, &base, d),
            Err(ConfigError::Param(ParamError {
                key: "deadtime.band_a",
                ..
            }))
        ));
    }
}
