//! What a drive is made of: a design in SI units with defaults from the motor and inverter,
//! and the fixed-point configuration computed from it once.

use crate::Angle;
use crate::control::current::{CurrentConfig, CurrentDesign};
use crate::control::flux::{FluxConfig, FluxDesign};
use crate::control::light_load::LightLoadConfig;
use crate::control::low_speed::LowSpeedConfig;
use crate::control::speed::{SpeedConfig, SpeedDesign};
use crate::deadtime::{CurrentSource, DeadTimeConfig, DeadTimeDesign, DeadTimeMode};
use crate::error::ConfigError;
use crate::ipd::{IpdConfig, IpdDesign};
use crate::num::{Pu, follow_shift, pu_from_f64};
#[cfg_attr(feature = "select-estimators", allow(unused_imports))]
use crate::observer::{
    AoConfig, EstimatorConfig, EstimatorKind, MrasCurrentConfig, MrasCurrentGains, MrasEmfConfig,
    NloConfig, default_observer_gain,
};
use crate::params::{InverterParams, MotorParams, ParamError, ParamReason, in_range, positive};
use crate::svpwm::SvpwmConfig;
use crate::units::PerUnit;

/// How the drive finds the rotor before it runs.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StartupMode {
    /// Voltage pulses, saliency and saturation (Khlaief, Boussak, Gossa (2012) §4).
    Ipd,
    /// A d-axis current along the α axis pulls the rotor to `θ = 0` first.
    Align,
    /// The rotor angle is known (electrical).
    Known(Angle),
    /// [`StartupMode::Ipd`] where the motor's saliency allows it, [`StartupMode::Align`]
    /// otherwise ([`StartupMode::resolve`]); [`DriveConfig::new`] resolves it, so a drive never
    /// runs in this mode.
    Auto,
}

/// How far above the detector's least accepted saliency ([`IpdDesign::min_saliency`]) a
/// motor's `|L_q − L_d|/(L_q + L_d)` must be for [`StartupMode::Auto`] to choose the initial
/// position detection. The detector measures `ΔI/I_0`, which equals that ratio for linear
/// magnetics at a locked rotor; the dead time, the ADC's steps and the d axis' saturation by
/// the pulses take part of it away, so the margin is a factor of two: with the default 5 %
/// minimum a motor needs 10 % (motor B has 23 %, a surface motor 0).
pub const AUTO_SALIENCY_MARGIN: f64 = 2.0;

impl StartupMode {
    /// The saliency the initial position detection sees on a linear `motor`,
    /// `|L_q − L_d|/(L_q + L_d)` (Khlaief, Boussak, Gossa (2012) eq. 10–13, `Δ/Σ`;
    /// docs/khlaief2012.md §3).
    pub fn saliency(motor: &MotorParams) -> f64 {
        libm::fabs(motor.lq_h - motor.ld_h) / (motor.lq_h + motor.ld_h)
    }

    /// `Auto` made concrete: the initial position detection when the motor's
    /// [`StartupMode::saliency`] is at least [`AUTO_SALIENCY_MARGIN`] times `ipd.min_saliency`
    /// and its pulses can be designed on this motor and bus, the alignment otherwise. Other
    /// modes are returned unchanged.
    pub fn resolve(self, motor: &MotorParams, base: &PerUnit, ipd: &IpdDesign) -> Self {
        match self {
            StartupMode::Auto => {
                let salient = Self::saliency(motor) >= AUTO_SALIENCY_MARGIN * ipd.min_saliency;
                if salient && IpdConfig::new(motor, base, *ipd).is_ok() {
                    StartupMode::Ipd
                } else {
                    StartupMode::Align
                }
            }
            other => other,
        }
    }
}

/// The open-loop current-vector start of the back-EMF estimators, and the alignment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OpenLoopDesign {
    /// Current of the alignment and of the open-loop start, A peak.
    pub current_a: f64,
    /// Acceleration of the imposed frame, electrical rad/s².
    pub accel_rad_s2: f64,
    /// Speed at which the estimator takes over, electrical rad/s.
    pub handover_speed_rad_s: f64,
    /// Duration of the alignment, s.
    pub align_time_s: f64,
}

impl OpenLoopDesign {
    /// Rated peak current (the per-unit base); an acceleration that takes 20 % of the torque
    /// that current makes, `0.2 p K_T I / J`; handover at 10 % of the rated electrical speed
    /// (or of the base speed; [`DriveDesign::default_for`] raises it for the MRAS on the EMF
    /// to [`MrasEmfConfig::damped_speed_rad_s`] where that is higher); alignment over 0.5 s.
    pub fn default_for(motor: &MotorParams, base: &PerUnit) -> Self {
        let rated_e = rated_e_rad_s(motor, base);
        Self {
            current_a: base.current_a,
            accel_rad_s2: 0.2 * motor.p() * motor.kt_nm_per_a * base.current_a / motor.j_kg_m2,
            handover_speed_rad_s: 0.1 * rated_e,
            align_time_s: 0.5,
        }
    }
}

/// The light-load and the low-speed d-axis currents' configurations (both updated every
/// eighth sample, `Drive::speed_loop`).
#[inline(always)]
fn d_axis_currents(
    design: &DriveDesign,
    base: &PerUnit,
    flux_wb: f64,
    v_dead_v: f64,
) -> Result<(LightLoadConfig, LowSpeedConfig), ConfigError> {
    let limit_a = design.speed.current_limit_a;
    Ok((
        LightLoadConfig::new(
            design.light_load_id_a,
            LightLoadConfig::default_fade_rad_s(flux_wb, v_dead_v),
            crate::control::LIGHT_LOAD_RAISED_PER_LIMIT * limit_a,
            base,
            8,
        )?,
        LowSpeedConfig::new(
            design.low_speed_id_a,
            design.low_speed_fade_rad_s,
            pu_from_f64(limit_a / base.current_a),
            base,
        )?,
    ))
}

/// The rated electrical speed, rad/s (the base speed for a motor without a rating).
fn rated_e_rad_s(motor: &MotorParams, base: &PerUnit) -> f64 {
    motor.rated_speed_rpm.map_or(base.omega_e_rad_s, |n| {
        n * core::f64::consts::TAU / 60.0 * motor.p()
    })
}

/// Default [`Protection::health_limit_pu`]: 1.0 pu, about five times the largest steady-state
/// figure of a healthy current-model MRAS on the sweep (0.21 pu) and within the figures of a
/// lost lock (0.9–2.2 pu). A drive whose model of the motor is off (ψ ±20 %, L ±30 %) explains
/// the currents worse while still holding the angle: at 0.5 pu 7 of the 27 combinations of
/// `cargo xtask robustness` that held tripped, at 1.0 pu 2 do, and every combination that
/// loses the lock ends in a named fault (docs/drive.md, loss of lock).
pub const DEFAULT_HEALTH_LIMIT_PU: f64 = 1.0;

/// Protection thresholds checked every sample (the reliability work extends this list).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Protection {
    /// Phase current that trips the drive, A.
    pub overcurrent_a: f64,
    /// Bus voltage below which the drive trips, V.
    pub vdc_min_v: f64,
    /// Bus voltage above which the drive trips, V.
    pub vdc_max_v: f64,
    /// Limit of the estimator's health figure ([`crate::observer::Estimator::health`]),
    /// filtered over 10 ms, above which the drive trips on loss of lock: per unit of `V_b`
    /// for the EMF estimators, of `I_b` for the current-model MRAS (so the limit scales with
    /// the motor's bases). Judged only in steady state (40 ms at a constant reference with the
    /// estimate within 0.02 pu of it throughout, until the reference changes), because a healthy drive's
    /// figure depends on the manoeuvre: on the 200-scenario sweep the current-model MRAS
    /// reaches 1.3 pu while accelerating, but at most 0.21 pu in steady state including load
    /// steps, while a lost lock shows 0.9–2.2 pu (the 24 V servo driven backwards) or
    /// 0.5–1.3 pu (model `R` three times the motor's). Default [`DEFAULT_HEALTH_LIMIT_PU`];
    /// `None`: reported ([`crate::drive::Drive::health`]) but never tripped on.
    pub health_limit_pu: Option<f64>,
}

impl Protection {
    /// Three times the rated peak current (the detector's pulses reach two), the bus within
    /// 50–125 % of nominal.
    pub fn default_for(inverter: &InverterParams, base: &PerUnit) -> Self {
        Self {
            overcurrent_a: 3.0 * base.current_a,
            vdc_min_v: 0.5 * inverter.vdc_v,
            vdc_max_v: 1.25 * inverter.vdc_v,
            health_limit_pu: Some(DEFAULT_HEALTH_LIMIT_PU),
        }
    }
}

/// Everything a drive is designed from, SI units. [`DriveDesign::default_for`] computes every
/// default from the motor and the inverter; change fields to override.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveDesign {
    /// The estimator.
    pub estimator: EstimatorKind,
    /// Gain `g` of the estimators of Solsona, Valla, Muravchik (2000), rad/s.
    pub observer_gain_rad_s: f64,
    /// Adaptation gains of the current-model MRAS.
    pub mras_current: MrasCurrentGains,
    /// Current loops.
    pub current: CurrentDesign,
    /// Speed loop.
    pub speed: SpeedDesign,
    /// Bandwidth of the first-order filter on the estimated speed that the speed loop uses,
    /// rad/s, its time constant rounded to a power of two of samples (the filter is a shift);
    /// `None` for none. Default: five times the default speed-loop bandwidth for the back-EMF
    /// estimators (their speed carries the dead time's 6th-harmonic ripple), three times for
    /// the current-model MRAS (docs/drive.md, "speed filter": its proportional adaptation
    /// passes every voltage error the model sees into the speed, and a speed loop whose gain
    /// grows with the inertia turned those steps into a limit cycle through the current
    /// limit).
    pub speed_filter_rad_s: Option<f64>,
    /// Dead-time compensation ([`DeadTimeMode::Off`] disables it). Default
    /// [`DeadTimeDesign::default_for`], with the signs of the measured currents
    /// ([`CurrentSource::Measured`]) for the back-EMF estimators and of the measured currents
    /// under load only ([`CurrentSource::MeasuredUnderLoad`]) for the current-model MRAS.
    pub deadtime: DeadTimeDesign,
    /// Initial position detection.
    pub ipd: IpdDesign,
    /// How the drive starts. Default [`StartupMode::Auto`]; the design a [`DriveConfig`] keeps
    /// has it resolved.
    pub startup: StartupMode,
    /// Open-loop start and alignment.
    pub open_loop: OpenLoopDesign,
    /// Trip thresholds.
    pub protection: Protection,
    /// The d-axis reference: MTPA and field weakening (docs/field-weakening.md).
    pub flux: FluxDesign,
    /// Overmodulation up to six-step beyond the modulator's circle (docs/overmodulation.md;
    /// default off). On, the current loops' voltage limit becomes
    /// [`crate::OVERMOD_SIX_STEP_REQUEST`] `V_DC` and field weakening holds the applied
    /// vector's length within `2 V_DC/3`, the hexagon's vertex.
    pub overmodulation: bool,
    /// Control samples between a step's return and the period its duties act over: 0 when
    /// they act over the coming period (a loop that applies them at once), 1 on pmsm-stm32's
    /// TIM1, whose compare preload loads them one period later (docs/drive.md, PWM update
    /// delay). The drive advances the voltage's angle by `ω̂ T_s` per sample of delay and
    /// gives the estimator the voltage that acted over the period that just ended. At most
    /// [`MAX_PWM_DELAY_SAMPLES`]; default 0.
    pub pwm_delay_samples: u8,
    /// The d-axis current held at light load, A peak (docs/drive.md, "light load";
    /// [`LightLoadConfig`]); 0 turns it off. Default
    /// [`LightLoadConfig::default_current_a`]: three times the dead-time compensation's band,
    /// at most a sixth of the speed loop's current limit, for the current-model MRAS; 0 for
    /// the back-EMF estimators and for an inverter without dead
    /// time.
    pub light_load_id_a: f64,
    /// The positive d-axis current held at low speed in the closed loop, A peak, faded out at
    /// [`DriveDesign::low_speed_fade_rad_s`] (docs/drive.md, "low-speed current";
    /// [`LowSpeedConfig`]); 0 turns it off. Default [`LowSpeedConfig::default_current_a`]: the
    /// speed loop's current limit, at most `ψ/(2 (L_q − L_d))` on a salient motor, for the
    /// current-model MRAS; 0 for the back-EMF estimators, which pass through zero speed in
    /// their open loop.
    pub low_speed_id_a: f64,
    /// Electrical speed where the low-speed current has faded out, rad/s. Default
    /// [`LowSpeedConfig::default_fade_rad_s`]: a fifth of the rated speed (twice the
    /// back-EMF estimators' handover speed).
    pub low_speed_fade_rad_s: f64,
    /// Measure the inverter's distortion voltage at standstill, between the rotor's angle
    /// found (detection or alignment) and the run, and scale the dead-time compensation to it
    /// (docs/drive.md, "dead-time calibration"; 40 ms); it runs only when the compensation acts
    /// on the command. Default: on for the current-model MRAS and an inverter with a dead time.
    pub deadtime_calibration: bool,
    /// Hold the current-model MRAS's adaptation through a phase current's zero crossing at
    /// low speed and light load, where the inverter's distortion there is as large as the EMF
    /// (docs/drive.md, "Zero crossings at low speed"). Default on; it acts only while the
    /// dead-time compensation does, and the other estimators ignore it.
    pub zero_crossing_hold: bool,
}

/// Longest PWM update delay the drive compensates, control samples.
pub const MAX_PWM_DELAY_SAMPLES: u8 = 2;

impl DriveDesign {
    /// Defaults for `motor` on `inverter` with the bases `base`, running `estimator`.
    pub fn default_for(
        motor: &MotorParams,
        inverter: &InverterParams,
        base: &PerUnit,
        estimator: EstimatorKind,
    ) -> Self {
        let deadtime = DeadTimeDesign::default_for(motor, inverter);
        let speed = SpeedDesign::default_for(base);
        Self {
            estimator,
            observer_gain_rad_s: default_observer_gain(motor, base),
            mras_current: MrasCurrentGains::default_for(motor, base),
            current: CurrentDesign::default_for(base),
            speed: {
                // A back-EMF estimator's speed carries the ripple of every voltage error the
                // dead time leaves (6th harmonic): its loop gets 40 % of the default bandwidth.
                // The current-model MRAS's weighs the reference by a half in the proportional
                // action: a ramp followed with half the IP's lag (a load that changes with the
                // reference finds the rotor where it should be) and a fraction of the PI's
                // overshoot at its end (docs/drive.md, "speed loop: the reference's weight").
                let mut d = speed;
                if estimator.needs_open_loop_start() {
                    d.bandwidth_rad_s *= 0.4;
                } else {
                    d.reference_weight = MRAS_REFERENCE_WEIGHT;
                }
                d
            },
            speed_filter_rad_s: Some(
                if estimator.needs_open_loop_start() {
                    5.0
                } else {
                    3.0
                } * crate::control::speed::DEFAULT_BANDWIDTH_TS
                    / base.sample_s,
            ),
            // The back-EMF estimators take the signs of the measured currents: their voltage
            // model reads every volt the signs get wrong, and where the current leaves its
            // reference (the open-loop reversal, a loaded handover) the reference's signs are
            // wrong. On the random family, seeds 1–14, the NLO then holds 301 of 301 runs
            // against 282, the AO 294 against 269. The current-model MRAS keeps the
            // reference's at light load, where the measured sign chatters with the ripple, and
            // takes the measured under load, where the reference's sustain a cycle on strongly
            // salient motors: 537 of 560 runs against 524 (docs/drive.md, "dead-time
            // compensation: which current's sign").
            deadtime: DeadTimeDesign {
                source: if estimator.needs_open_loop_start() {
                    CurrentSource::Measured
                } else {
                    CurrentSource::MeasuredUnderLoad
                },
                ..deadtime
            },
            ipd: IpdDesign::default(),
            startup: StartupMode::Auto,
            open_loop: {
                // The MRAS on the EMF hands over where its adaptation is damped ½: at a
                // tenth of rated speed on a motor of two pole pairs rated near 1000 r/min its
                // estimate swung about the rotor's until the speed loop drove it through zero
                // (docs/solsona2000.md §5).
                let mut d = OpenLoopDesign::default_for(motor, base);
                if estimator == EstimatorKind::MrasEmf {
                    d.handover_speed_rad_s = d
                        .handover_speed_rad_s
                        .max(MrasEmfConfig::damped_speed_rad_s(base));
                }
                d
            },
            protection: Protection::default_for(inverter, base),
            flux: FluxDesign::default(),
            overmodulation: false,
            pwm_delay_samples: 0,
            // The current-model MRAS runs from standstill, where the compensation's error is
            // its error; the back-EMF estimators hand over at a tenth of rated speed, where
            // the EMF dwarfs it. (`DriveConfig::new` runs it only with a compensated command.)
            deadtime_calibration: !estimator.needs_open_loop_start() && inverter.dead_time_s > 0.0,
            zero_crossing_hold: true,
            // The back-EMF estimators' speed loops run at 40 % of the bandwidth and do not
            // oscillate at no load; a d current switched in at their handover disturbed an NLO
            // start of the random family.
            light_load_id_a: if estimator.needs_open_loop_start() {
                0.0
            } else {
                LightLoadConfig::default_current_a(
                    deadtime.band_a,
                    speed.current_limit_a,
                    inverter.dead_time_s,
                )
            },
            // The back-EMF estimators pass through zero speed in their open loop's current
            // vector, the same spring; in their closed loop, above the handover speed, the
            // current changed nothing measurable on the random family.
            low_speed_id_a: if estimator.needs_open_loop_start() {
                0.0
            } else {
                LowSpeedConfig::default_current_a(motor, speed.current_limit_a)
            },
            low_speed_fade_rad_s: LowSpeedConfig::default_fade_rad_s(rated_e_rad_s(motor, base)),
        }
    }
}

/// [`SpeedDesign::reference_weight`] of the drive's default speed loop with the current-model
/// MRAS (docs/drive.md, "speed loop: the reference's weight"); the back-EMF estimators keep the
/// IP form ([`crate::IP_FORM`]), whose reference is held at their least speed and whose rotor
/// must decelerate into the open-loop reversal.
pub const MRAS_REFERENCE_WEIGHT: f64 = 0.5;

/// The few choices a user makes about a drive; everything else is
/// [`DriveDesign::default_for`]'s (for more, change a [`DriveDesign`] and use
/// [`DriveConfig::new`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveOptions {
    /// The estimator (default: the current-model MRAS, which starts from standstill).
    pub estimator: EstimatorKind,
    /// How the drive starts; `None`: [`StartupMode::Auto`] (initial position detection on a
    /// salient motor, alignment otherwise).
    pub startup: Option<StartupMode>,
    /// Dead-time compensation; `None`: the default of [`DeadTimeDesign::default_for`].
    pub deadtime: Option<DeadTimeMode>,
    /// Overmodulation up to six-step ([`DriveDesign::overmodulation`]; default off).
    pub overmodulation: bool,
    /// [`DriveDesign::pwm_delay_samples`]; `None`: 0.
    pub pwm_delay_samples: Option<u8>,
}

impl Default for DriveOptions {
    fn default() -> Self {
        Self {
            estimator: EstimatorKind::MrasCurrent,
            startup: None,
            deadtime: None,
            overmodulation: false,
            pwm_delay_samples: None,
        }
    }
}

/// The fixed-point configuration of a drive.
#[derive(Clone, Copy, Debug)]
pub struct DriveConfig {
    /// Per-unit bases and sample period.
    pub base: PerUnit,
    /// The design it was computed from.
    pub design: DriveDesign,
    /// The estimator's coefficients ([`Drive::new`](super::Drive::new) builds its state).
    pub estimator: EstimatorConfig,
    pub(crate) current: CurrentConfig,
    pub(crate) speed: SpeedConfig,
    /// The speed loop runs in the slots `k` with `k & speed_mask == 0` (mask 0, 1 or 3: every
    /// 1, 2 or 4 samples, [`SpeedDesign::decimation`]).
    pub(crate) speed_mask: u8,
    /// The speed filter's pole as a shift, `y += (x − y)·2^−k`: `k = round(log2(1/(ω_f T_s)))`
    /// in 0..=20 (its time constant `2^k` samples, longer than any decimation, so a
    /// decimated loop sees the mean of its period); 0 passes the speed through.
    pub(crate) speed_filter_shift: u32,
    /// The closed current loop's lag as a shift, `k = round(log2(1/(ω_c T_s)))` (0..=20): the
    /// dead-time compensation's signs follow the q reference through it (the current the loop
    /// will carry). 0 (the reference itself) when overmodulating: beyond the circle the loops
    /// are voltage-limited and the current does not follow their first-order response.
    pub(crate) deadtime_lag_shift: u32,
    pub(crate) deadtime: DeadTimeConfig,
    pub(crate) svpwm: SvpwmConfig,
    pub(crate) ipd: IpdConfig,
    pub(crate) open_loop: OpenLoopConfig,
    pub(crate) protection: ProtectionConfig,
    pub(crate) monitor: super::monitor::MonitorConfig,
    /// [`super::RECTIFY_GRACE_S`] in samples.
    pub(crate) rectify_grace_samples: u32,
    /// [`DriveDesign::pwm_delay_samples`].
    pub(crate) pwm_delay: u8,
    /// Half sample steps from a sample's angle to the middle of the period its voltage acts
    /// in: `2 pwm_delay + 1`.
    pub(crate) mid_turns: i32,
    /// `mid_turns − 2`, for the estimator's frames (`drive::mid_frame`).
    pub(crate) mid_frame_k: i32,
    /// The light-load d-axis current ([`DriveDesign::light_load_id_a`]).
    pub(crate) light_load: LightLoadConfig,
    /// The low-speed d-axis current ([`DriveDesign::low_speed_id_a`]).
    pub(crate) low_speed: LowSpeedConfig,
    /// The dead-time calibration at the alignment's end ([`DriveDesign::deadtime_calibration`]).
    pub(crate) calibration: super::calibrate::CalibrationConfig,
    /// Declared last: declared before the fields above, its growth by two words moved them
    /// past the Cortex-M0's short load offsets (15 instructions more in the step's worst case).
    pub(crate) flux: FluxConfig,
}

/// [`OpenLoopDesign`] in per unit and samples.
#[derive(Clone, Copy, Debug)]
pub(crate) struct OpenLoopConfig {
    pub current: Pu,
    /// Speed increment per sample, per unit.
    pub accel: Pu,
    pub handover_speed: Pu,
    /// Samples the open loop may hold the handover speed while the estimate does not yet
    /// agree with it: as long as the ramp took, within 10–50 ms.
    pub handover_wait: u32,
    pub align_samples: u32,
    /// Rotation per sample, angle LSB per LSB of per-unit speed (`ω_b T_s 2⁸/(2π)`, below
    /// 128 for any `ω_b T_s < π`).
    pub turn_per_speed: crate::num::Coef<24>,
}

/// [`Protection`] in per unit.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ProtectionConfig {
    pub overcurrent: Pu,
    pub vdc_min: Pu,
    pub vdc_max: Pu,
}

impl DriveConfig {
    /// The drive for `motor` on `inverter` sampled at `sample_hz`, with every default of
    /// [`DriveDesign::default_for`] but the choices of `options`. Inlined, as
    /// [`DriveConfig::new`].
    #[inline(always)]
    pub fn from_params(
        motor: &MotorParams,
        inverter: &InverterParams,
        sample_hz: f64,
        options: DriveOptions,
    ) -> Result<Self, ConfigError> {
        let base = PerUnit::new(motor, inverter, sample_hz)?;
        let mut design = DriveDesign::default_for(motor, inverter, &base, options.estimator);
        if let Some(startup) = options.startup {
            design.startup = startup;
        }
        if let Some(mode) = options.deadtime {
            design.deadtime.mode = mode;
        }
        design.overmodulation = options.overmodulation;
        if let Some(d) = options.pwm_delay_samples {
            design.pwm_delay_samples = d;
        }
        Self::new(motor, inverter, sample_hz, design)
    }

    /// Computes and checks every coefficient of `design` for `motor` on `inverter` at
    /// `sample_hz`. Inlined (the board firmware calls it once with its motor's constants, which
    /// then fold: out of line it costs 7 KB more flash than the 64 KiB image holds); a caller
    /// that builds drives in several places wraps it once.
    #[inline(always)]
    pub fn new(
        motor: &MotorParams,
        inverter: &InverterParams,
        sample_hz: f64,
        design: DriveDesign,
    ) -> Result<Self, ConfigError> {
        let base = PerUnit::new(motor, inverter, sample_hz)?;
        let mut design = design;
        design.startup = design.startup.resolve(motor, &base, &design.ipd);
        // Built first: a fallible call late in the literal below makes the compiler keep
        // every field before it in temporaries (kilobytes of stack on ARMv6-M).
        let deadtime = DeadTimeConfig::new(inverter, &base, design.deadtime)?;
        let flux = FluxConfig::new(
            motor,
            &base,
            design.speed.current_limit_a,
            design.flux,
            voltage_limit_pu(&design),
            overspeed_pu(motor, &base, &design),
        )?;
        #[cfg_attr(feature = "select-estimators", allow(unused_variables))]
        let g = design.observer_gain_rad_s;
        let estimator = match design.estimator {
            #[cfg(any(not(feature = "select-estimators"), feature = "nlo"))]
            EstimatorKind::Nlo => EstimatorConfig::Nlo(NloConfig::new(motor, &base, g)?),
            #[cfg(any(not(feature = "select-estimators"), feature = "ao"))]
            EstimatorKind::Ao => {
                EstimatorConfig::Ao(AoConfig::new(motor, &base, g)?.lag_compensated(&base)?)
            }
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-emf"))]
            EstimatorKind::MrasEmf => {
                EstimatorConfig::MrasEmf(MrasEmfConfig::default_for(motor, &base, g)?)
            }
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
            EstimatorKind::MrasCurrent => EstimatorConfig::MrasCurrent(MrasCurrentConfig::new(
                motor,
                &base,
                design.mras_current,
            )?),
            #[allow(unreachable_patterns)] // every estimator is built without the feature
            _ => {
                return Err(crate::params::ParamError {
                    key: "estimator",
                    reason: crate::params::ParamReason::Inconsistent(
                        "the estimators built in (feature select-estimators)",
                    ),
                }
                .into());
            }
        };
        let ol = design.open_loop;
        let ts = base.sample_s;
        positive("open_loop.current_a", ol.current_a)?;
        positive("open_loop.accel_rad_s2", ol.accel_rad_s2)?;
        in_range(
            "open_loop.handover_speed_rad_s",
            ol.handover_speed_rad_s,
            1e-3 * base.omega_e_rad_s,
            base.omega_e_rad_s,
        )?;
        in_range("open_loop.align_time_s", ol.align_time_s, 0.0, 100.0)?;
        // The drive runs the speed loop on its even slots (every 2 or 4 samples), or on every
        // sample.
        let speed_mask = match design.speed.decimation {
            1 => 0,
            2 => 1,
            4 => 3,
            d => {
                return Err(ConfigError::Param(ParamError {
                    key: "speed.decimation",
                    reason: if d == 0 || d > 4 {
                        ParamReason::OutOfRange { min: 1.0, max: 4.0 }
                    } else {
                        ParamReason::Inconsistent("the drive's outer-loop slots (1, 2 or 4)")
                    },
                }));
            }
        };
        let p = design.protection;
        positive("protection.overcurrent_a", p.overcurrent_a)?;
        in_range(
            "pwm_delay_samples",
            design.pwm_delay_samples as f64,
            0.0,
            MAX_PWM_DELAY_SAMPLES as f64,
        )?;
        positive("protection.vdc_min_v", p.vdc_min_v)?;
        in_range("protection.vdc_max_v", p.vdc_max_v, p.vdc_min_v, 1e4)?;
        let (light_load, low_speed) =
            d_axis_currents(&design, &base, motor.flux_wb, deadtime.v_dead_nominal_v)?;
        Ok(Self {
            estimator,
            current: CurrentConfig::new(motor, &base, {
                // Overmodulating, the current loops may ask up to six-step's request.
                let mut c = design.current;
                if design.overmodulation {
                    c.modulation *= crate::svpwm::OVERMOD_SIX_STEP_REQUEST * libm::sqrt(3.0);
                }
                c
            })?,
            speed: SpeedConfig::new(motor, &base, design.speed)?,
            speed_mask,
            deadtime_lag_shift: if design.overmodulation {
                0
            } else {
                follow_shift(1.0 / (design.current.bandwidth_rad_s * ts)).unwrap_or(0)
            },
            speed_filter_shift: match design.speed_filter_rad_s {
                None => 0,
                Some(w) => {
                    let w = in_range("speed_filter_rad_s", w, 1e-3, 2.0 / ts)?;
                    follow_shift(1.0 / (w * ts)).unwrap_or(0)
                }
            },
            deadtime,
            svpwm: svpwm_config(inverter, &design)?,
            // Only an IPD start-up needs pulses this motor and bus can drive.
            ipd: match design.startup {
                StartupMode::Ipd => IpdConfig::new(motor, &base, design.ipd)?,
                _ => IpdConfig::unused(design.ipd),
            },
            open_loop: OpenLoopConfig {
                current: pu_from_f64(ol.current_a / base.current_a),
                accel: pu_from_f64(ol.accel_rad_s2 * ts / base.omega_e_rad_s),
                handover_speed: pu_from_f64(ol.handover_speed_rad_s / base.omega_e_rad_s),
                handover_wait: libm::round(
                    (ol.handover_speed_rad_s / ol.accel_rad_s2).clamp(0.01, 0.05) / ts,
                ) as u32,
                align_samples: libm::round(ol.align_time_s / ts) as u32,
                turn_per_speed: crate::num::Coef::new(
                    base.omega_e_rad_s * ts / (Angle::RAD_PER_LSB * (1u64 << 24) as f64),
                )
                .ok_or(ConfigError::Gain {
                    key: "sample_hz",
                    value: sample_hz,
                    // The rotation per sample at 1 pu must stay below 128 LSB per LSB.
                    min: base.omega_e_rad_s / (128.0 * Angle::RAD_PER_LSB * (1u64 << 24) as f64),
                    max: f64::INFINITY,
                })?,
            },
            monitor: {
                let accel =
                    motor.p() * motor.kt_nm_per_a * design.speed.current_limit_a / motor.j_kg_m2;
                let limit = design.speed.current_limit_a / base.current_a;
                let health = match p.health_limit_pu {
                    Some(h) => pu_from_f64(in_range("protection.health_limit_pu", h, 1e-6, 100.0)?),
                    None => Pu::MAX,
                };
                super::monitor::MonitorConfig::new(ts, base.omega_e_rad_s, accel, limit, health)
                    .ok_or(ConfigError::Gain {
                        key: "sample_hz",
                        value: sample_hz,
                        min: 0.0,
                        max: 0.0,
                    })?
            },
            protection: ProtectionConfig {
                overcurrent: pu_from_f64(p.overcurrent_a / base.current_a),
                vdc_min: pu_from_f64(p.vdc_min_v / base.voltage_v),
                vdc_max: pu_from_f64(p.vdc_max_v / base.voltage_v),
            },
            flux,
            // I/2 then I (the alignment's and the open loop's current last: a rotor just
            // pulled into place and held at half of it for 20 ms settles again), each 10 ms to
            // settle (seven time constants of the default current loops) and 10 ms to average.
            calibration: if design.deadtime_calibration
                && design.deadtime.mode.compensates_command()
            {
                let i = ol.current_a / base.current_a;
                super::calibrate::CalibrationConfig {
                    levels: [pu_from_f64(0.5 * i), pu_from_f64(i)],
                    settle: libm::ceil(0.01 / ts) as u32,
                    average: (libm::ceil(0.01 / ts) as u32).min(super::calibrate::MAX_AVERAGE),
                }
            } else {
                super::calibrate::CalibrationConfig::default()
            },
            light_load,
            low_speed,
            rectify_grace_samples: libm::ceil(super::RECTIFY_GRACE_S / ts) as u32,
            pwm_delay: design.pwm_delay_samples,
            mid_turns: 2 * design.pwm_delay_samples as i32 + 1,
            mid_frame_k: 2 * design.pwm_delay_samples as i32 - 1,
            base,
            design,
        })
    }

    /// The d-axis reference's configuration (MTPA, field weakening, maximum speed).
    pub fn flux(&self) -> &FluxConfig {
        &self.flux
    }

    /// Estimated speed beyond which the drive trips on [`super::Fault::Overspeed`], per unit.
    pub fn overspeed(&self) -> Pu {
        self.flux.overspeed
    }

    /// The dead-time compensation, as designed for the inverter the drive was told.
    pub fn deadtime(&self) -> &DeadTimeConfig {
        &self.deadtime
    }

    /// Whether dead-time compensation is on.
    pub fn deadtime_compensation(&self) -> bool {
        self.design.deadtime.mode != DeadTimeMode::Off
    }
}

/// The modulator: the linear one, or overmodulating with pulses shorter than the dead time
/// dropped (docs/overmodulation.md); overmodulation asked of a build without it is an error.
fn svpwm_config(
    inverter: &InverterParams,
    design: &DriveDesign,
) -> Result<SvpwmConfig, ConfigError> {
    if !design.overmodulation {
        return Ok(SvpwmConfig::default());
    }
    #[cfg(feature = "overmodulation")]
    return SvpwmConfig::overmodulating()
        .with_min_pulse((inverter.dead_time_s * inverter.pwm_hz).clamp(0.0, 0.1));
    #[cfg(not(feature = "overmodulation"))]
    {
        let _ = inverter;
        Err(crate::params::ParamError {
            key: "overmodulation",
            reason: crate::params::ParamReason::Inconsistent(
                "a build with overmodulation (feature overmodulation)",
            ),
        }
        .into())
    }
}

/// The fundamental voltage the drive can hold at the nominal bus, per unit of `V_b` (the
/// circle's radius): 1, or the six-step's `2√3/π` overmodulating.
fn voltage_limit_pu(design: &DriveDesign) -> f64 {
    if design.overmodulation {
        crate::control::flux::SIX_STEP_PER_CIRCLE
    } else {
        1.0
    }
}

/// Times the highest controllable speed at which the drive trips on overspeed.
pub const OVERSPEED_FACTOR: f64 = 1.15;

/// The overspeed threshold, per unit: [`OVERSPEED_FACTOR`] times the highest speed at which
/// the drive can still hold the no-load voltage within the circle at the nominal bus, i.e.
/// with `i_d = −min(I_max, ψ/L_d)` under field weakening, `i_d = 0` without (where the EMF
/// `ωψ` reaches `V_DC/√3`, the bus the diodes would rectify into). Never below 1.2 pu.
fn overspeed_pu(motor: &MotorParams, base: &PerUnit, design: &DriveDesign) -> f64 {
    let i_max = design.speed.current_limit_a / base.current_a;
    let ld = motor.ld_h / base.inductance_h;
    let psi = motor.flux_wb / base.flux_wb;
    let r = motor.rs_ohm / base.impedance_ohm;
    let id_lim = if design.flux.field_weakening {
        i_max.min(psi / ld)
    } else {
        0.0
    };
    let cap = crate::control::flux::SPEED_CAP_PER_BASE;
    let w = crate::control::flux::max_speed_f64(psi, ld, r, id_lim, voltage_limit_pu(design), cap);
    (OVERSPEED_FACTOR * w).max(1.2).min(cap)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::{inverter_b, motor_b};

    fn resolved(ld_h: f64, lq_h: f64) -> (f64, StartupMode) {
        let mut m = motor_b();
        m.ld_h = ld_h;
        m.lq_h = lq_h;
        let base = PerUnit::new(&m, &inverter_b(), 14e3).unwrap();
        let design = DriveDesign::default_for(&m, &inverter_b(), &base, EstimatorKind::MrasCurrent);
        assert_eq!(design.startup, StartupMode::Auto);
        let config = DriveConfig::new(&m, &inverter_b(), 14e3, design).unwrap();
        (StartupMode::saliency(&m), config.design.startup)
    }

    #[test]
    fn auto_start_up_follows_the_saliency() {
        // Motor B: (40.17 − 25)/(40.17 + 25) mH = 0.233, far above 2 × 5 %: detection.
        let b = motor_b();
        let (s, mode) = resolved(b.ld_h, b.lq_h);
        assert!((s - 0.233).abs() < 0.001, "{s}");
        assert_eq!(mode, StartupMode::Ipd);
        // A surface motor: alignment.
        assert_eq!(resolved(0.03, 0.03), (0.0, StartupMode::Align));
        // Either side of the threshold 2 × 5 % = 10 %: 8 % aligns, 12 % detects.
        let (s, mode) = resolved(0.0230, 0.0270);
        assert!((s - 0.08).abs() < 1e-9 && mode == StartupMode::Align, "{s}");
        let (s, mode) = resolved(0.0220, 0.0280);
        assert!((s - 0.12).abs() < 1e-9 && mode == StartupMode::Ipd, "{s}");
        // L_d > L_q counts by its magnitude.
        assert_eq!(resolved(b.lq_h, b.ld_h).1, StartupMode::Ipd);
        // A mode given explicitly is kept.
        let base = PerUnit::new(&b, &inverter_b(), 14e3).unwrap();
        let ipd = IpdDesign::default();
        assert_eq!(
            StartupMode::Align.resolve(&b, &base, &ipd),
            StartupMode::Align
        );
        assert_eq!(
            StartupMode::Known(Angle::ZERO).resolve(&b, &base, &ipd),
            StartupMode::Known(Angle::ZERO)
        );
    }

    /// The MRAS on the EMF hands over where its adaptation's loop `s² + (|ω|/c3) s + ψ² c2 |ω|`
    /// (the constants `MrasEmfConfig::default_for` designs) is damped at least ½: at a tenth of
    /// rated speed where that is fast enough (motor B at 14 kHz: ζ = 0.82), at the damped
    /// speed on a slow motor (two pole pairs, 1055 r/min: ζ = 0.40 at a tenth); the other
    /// estimators hand over at a tenth.
    #[test]
    fn the_mras_on_the_emf_hands_over_where_its_adaptation_is_damped() {
        let handover = |m: &MotorParams, inv: &InverterParams, kind| {
            let base = PerUnit::new(m, inv, inv.pwm_hz).unwrap();
            let d = DriveDesign::default_for(m, inv, &base, kind);
            let w = d.open_loop.handover_speed_rad_s;
            let c = MrasEmfConfig::default_for(m, &base, default_observer_gain(m, &base)).unwrap();
            let [_, c2, c3] = c.constants;
            let zeta = (w / c3) / (2.0 * (m.flux_wb * m.flux_wb * c2 * w).sqrt());
            (w / rated_e_rad_s(m, &base), zeta)
        };
        let (b, inv_b) = (motor_b(), inverter_b());
        let (share, zeta) = handover(&b, &inv_b, EstimatorKind::MrasEmf);
        assert!(
            (share - 0.1).abs() < 1e-12 && (zeta - 0.82).abs() < 0.01,
            "{share} {zeta}"
        );
        let mut slow = MotorParams::new(2, 0.5822, 0.016699, 0.016699, 0.51839, 0.0076614, 0.0034);
        slow.rated_speed_rpm = Some(1055.0);
        slow.rated_current_a = Some(8.24);
        let inv = InverterParams {
            vdc_v: 320.0,
            pwm_hz: 14e3,
            dead_time_s: 1.06e-6,
            current_full_scale_a: 30.0,
        };
        let (share, zeta) = handover(&slow, &inv, EstimatorKind::MrasEmf);
        assert!((zeta - crate::MRAS_EMF_MIN_DAMPING).abs() < 1e-9, "{zeta}");
        assert!(share > 0.15 && share < 0.17, "{share}");
        for kind in [EstimatorKind::Ao, EstimatorKind::Nlo] {
            let (share, zeta) = handover(&slow, &inv, kind);
            assert!(
                (share - 0.1).abs() < 1e-12 && zeta < 0.41,
                "{kind:?}: {share} {zeta}"
            );
        }
    }
}
