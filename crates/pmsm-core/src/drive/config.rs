//! The fixed-point configuration of a drive, computed once from its design: the interrupt
//! side's part ([`IsrConfig`], fixed point only) and the task's ([`TaskConfig`]).

use super::TASK_PERIOD;
use super::design::{
    DriveDesign, DriveOptions, MAX_PWM_DELAY_SAMPLES, StartupMode, overspeed_pu, voltage_limit_pu,
};
use crate::Angle;
use crate::control::current::CurrentConfig;
use crate::control::flux::FluxConfig;
use crate::control::light_load::LightLoadConfig;
#[cfg(feature = "load-observer")]
use crate::control::load_observer::LoadObserverConfig;
use crate::control::low_speed::LowSpeedConfig;
use crate::control::speed::{SpeedConfig, SpeedGains};
use crate::deadtime::{DeadTimeConfig, DeadTimeMode};
use crate::error::ConfigError;
use crate::ipd::IpdConfig;
use crate::num::{Pu, follow_shift, pu_from_f64};
#[cfg_attr(feature = "select-estimators", allow(unused_imports))]
use crate::observer::{
    AoConfig, EstimatorConfig, EstimatorKind, MrasCurrentConfig, MrasEmfConfig, NloConfig,
};
use crate::params::{InverterParams, MotorParams, ParamError, ParamReason, in_range, positive};
use crate::svpwm::SvpwmConfig;
use crate::units::PerUnit;

mod features;
mod schedule;

/// The fixed-point configuration of a drive: the interrupt side's part, the task's, and what
/// they were computed from.
#[derive(Clone, Copy, Debug, crate::image::Words)]
pub struct DriveConfig {
    /// Per-unit bases and sample period.
    pub base: PerUnit,
    /// The design it was computed from.
    pub design: DriveDesign,
    /// The motor as the drive was told it (the task's learners start from it).
    pub motor: MotorParams,
    /// The distortion voltage `V_dead` of the inverter as the drive was told it, at its
    /// nominal bus, V ([`crate::DeadTimeDesign::v_dead_v`]).
    v_dead_nominal_v: f64,
    /// The estimator's coefficients ([`super::DriveIsr`] builds its state).
    pub estimator: EstimatorConfig,
    /// The current loops', the detector's (the interrupt side's controllers hold them) and
    /// the speed loop's (the task's).
    pub(crate) current: CurrentConfig,
    pub(crate) ipd: IpdConfig,
    pub(crate) speed: SpeedConfig,
    pub(crate) isr: IsrConfig,
    pub(crate) task: TaskConfig,
    /// Why the default injection was left out ([`crate::InjectionDesign::fallback`]).
    #[cfg(feature = "injection")]
    #[words(skip)] // a diagnostic (names, text): the image holds none
    injection_declined: Option<ConfigError>,
    /// The injection's design in figures (not the interrupt side's: `f64`).
    #[cfg(feature = "injection")]
    injection_figures: Option<crate::observer::InjectionFigures>,
}

/// What the interrupt side works with: fixed point only, no design data.
#[derive(Clone, Copy, Debug, crate::image::Words)]
pub(crate) struct IsrConfig {
    pub deadtime: DeadTimeConfig,
    /// [`StartupMode::Auto`] chose the detection: one that finds the axis but not the
    /// magnet's polarity ([`IpdFault::NoPolarity`](crate::IpdFault)) waits for the task, which
    /// falls back to the alignment, instead of tripping.
    #[cfg_attr(not(feature = "ipd"), allow(dead_code))] // the detection's step reads it
    pub ipd_fallback: bool,
    /// The closed current loop's lag as a shift, `k = round(log2(1/(ω_c T_s)))` (0..=20): the
    /// dead-time compensation's signs follow the q reference through it (the current the loop
    /// will carry). 0 (the reference itself) when overmodulating: beyond the circle the loops
    /// are voltage-limited and the current does not follow their first-order response.
    pub deadtime_lag_shift: u32,
    pub svpwm: SvpwmConfig,
    pub open_loop: OpenLoopConfig,
    pub protection: ProtectionConfig,
    /// [`super::RECTIFY_GRACE_S`] in samples.
    pub rectify_grace_samples: u32,
    /// [`DriveDesign::pwm_delay_samples`].
    pub pwm_delay: u8,
    /// Half sample steps from a sample's angle to the middle of the period its voltage acts
    /// in: `2 pwm_delay + 1`.
    pub mid_turns: i32,
    /// `mid_turns − 2`, for the estimator's frames (`isr::mid_frame`).
    pub mid_frame_k: i32,
    /// [`DriveDesign::injection`], designed.
    #[cfg(feature = "injection")]
    pub injection: Option<crate::observer::InjectionConfig>,
}

/// What the task works with, per unit and in task periods ([`TASK_PERIOD`] samples).
#[derive(Clone, Copy, Debug, crate::image::Words)]
pub(crate) struct TaskConfig {
    pub estimator: EstimatorKind,
    /// How the drive starts ([`DriveDesign::startup`], resolved).
    pub startup: StartupMode,
    /// The speed filter's pole as a shift per task period, `y += (x − y)·2^−k` on the period's
    /// mean estimated speed: its time constant `2^k` periods (0: the mean itself).
    pub speed_filter_shift: u32,
    pub flux: FluxConfig,
    pub light_load: LightLoadConfig,
    pub low_speed: LowSpeedConfig,
    /// The dead-time compensation as designed (the calibration's and the learner's reference,
    /// scaled with them).
    pub deadtime: DeadTimeConfig,
    pub svpwm: SvpwmConfig,
    pub calibration: super::calibrate::CalibrationConfig,
    pub monitor: super::monitor::MonitorConfig,
    /// The open loop's current and handover speed, per unit.
    pub open_loop_current: Pu,
    /// The open loop's damping: the frame's lead per unit of its speed over the estimated
    /// one, angle LSB per 2¹⁶ [`Pu`] LSB (`startup`, "Damping").
    pub open_loop_damping: i32,
    pub handover_speed: Pu,
    /// Task periods the handover may wait for an estimate that does not agree yet.
    pub handover_wait: u32,
    /// [`DriveDesign::zero_crossing_hold`] where the compensation acts.
    pub zero_crossing_hold: bool,
    /// The speed loop's own gains, which the task's schedule switches back to.
    pub speed_own: SpeedGains,
    /// [`DriveDesign::load_observer_rad_s`].
    #[cfg(feature = "load-observer")]
    pub load_observer: Option<LoadObserverConfig>,
    /// The speed loop while the injection gives the angle, and the speed reference below
    /// which it applies.
    #[cfg(feature = "injection")]
    pub speed_injecting: Option<(SpeedGains, Pu)>,
    /// The stiff speed loop of [`DriveDesign::speed_stiff_rad_s`], and the speed above which it
    /// applies.
    pub speed_stiff: Option<(SpeedGains, Pu)>,
    /// The polarity check when the drive comes back to zero speed on the injection.
    #[cfg(feature = "injection")]
    pub polarity: Option<crate::observer::PolarityConfig>,
}

/// [`super::design::OpenLoopDesign`] in per unit and samples.
#[derive(Clone, Copy, Debug, crate::image::Words)]
pub(crate) struct OpenLoopConfig {
    pub current: Pu,
    /// Speed increment per sample, per unit.
    pub accel: Pu,
    pub handover_speed: Pu,
    pub align_samples: u32,
    /// The alignment's current steps per sample over its two ramps ([`Pu`] bits with 16
    /// more fractional bits): `I/(n/8)` and `I/(n/2 − n/8)`.
    pub align_steps: [i64; 2],
    /// Rotation per sample, angle LSB per LSB of per-unit speed (`ω_b T_s 2⁸/(2π)`, below
    /// 128 for any `ω_b T_s < π`).
    pub turn_per_speed: crate::num::Coef<24>,
}

/// The trips of every sample, per unit.
#[derive(Clone, Copy, Debug, crate::image::Words)]
pub(crate) struct ProtectionConfig {
    pub overcurrent: Pu,
    pub vdc_min: Pu,
    pub vdc_max: Pu,
    /// Estimated speed beyond which the closed loop trips on overspeed.
    pub overspeed: Pu,
    /// `|i_a + i_b + i_c|` filtered over 1 ms above 0.15 `I_b` trips a broken current sensor:
    /// the limit in quarters of [`Pu`]'s bits (as the filtered sum) and the filter's shift.
    pub sum_limit: i32,
    pub sum_shift: u32,
}

/// The light-load and the low-speed d-axis currents' configurations (both updated once per
/// task period).
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
            TASK_PERIOD,
        )?,
        LowSpeedConfig::new(
            design.low_speed_id_a,
            design.low_speed_fade_rad_s,
            pu_from_f64(limit_a / base.current_a),
            base,
        )?,
    ))
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
        let estimator = options
            .estimator
            .unwrap_or_else(|| EstimatorKind::for_motor(motor));
        let mut design = DriveDesign::default_for(motor, inverter, &base, estimator);
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
    /// `sample_hz`. Inlined: a firmware that designs on the target calls it once, often with
    /// its motor's constants, which then fold (out of line the B-G431B-ESC1 image was 7 KB
    /// larger when it designed there; it loads a drive image now, docs/image.md); a caller
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
        let auto_startup = design.startup == StartupMode::Auto;
        design.startup = design.startup.resolve(motor, &base, &design.ipd);
        // Built first: a fallible call late in the literal below makes the compiler keep
        // every field before it in temporaries (kilobytes of stack on ARMv6-M).
        let deadtime = DeadTimeConfig::new(inverter, &base, design.deadtime)?;
        let v_dead_nominal_v = design.deadtime.v_dead_v(inverter);
        features::check(&design)?;
        #[cfg(feature = "injection")]
        let (injection, injection_figures, injection_declined) = match design.injection.map(|d| {
            let c = crate::observer::InjectionConfig::new(
                motor,
                inverter,
                &base,
                d,
                design.pwm_delay_samples,
            );
            (c, d.fallback)
        }) {
            None => (None, None, None),
            Some((Ok((c, f)), _)) => (Some(c), Some(f), None),
            Some((Err(e), true)) => {
                design.injection = None;
                (None, None, Some(e))
            }
            Some((Err(e), false)) => return Err(e),
        };
        if design.speed.decimation != TASK_PERIOD {
            return Err(ParamError {
                key: "speed.decimation",
                reason: ParamReason::Inconsistent("the task's period (TASK_PERIOD samples)"),
            }
            .into());
        }
        let overspeed = overspeed_pu(motor, &base, &design);
        let flux = FluxConfig::new(
            motor,
            &base,
            design.speed.current_limit_a,
            design.flux,
            voltage_limit_pu(&design),
            overspeed,
        )?;
        #[cfg_attr(feature = "select-estimators", allow(unused_variables))]
        let g = design.observer_gain_rad_s;
        let estimator = match design.estimator {
            #[cfg(any(not(feature = "select-estimators"), feature = "nlo"))]
            EstimatorKind::Nlo => EstimatorConfig::Nlo(NloConfig::new(motor, &base, g)?),
            #[cfg(any(not(feature = "select-estimators"), feature = "ao"))]
            EstimatorKind::Ao => EstimatorConfig::Ao(AoConfig::lag_compensated(motor, &base, g)?),
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
        let tt = ts * f64::from(TASK_PERIOD);
        positive("open_loop.current_a", ol.current_a)?;
        positive("open_loop.accel_rad_s2", ol.accel_rad_s2)?;
        in_range(
            "open_loop.handover_speed_rad_s",
            ol.handover_speed_rad_s,
            1e-3 * base.omega_e_rad_s,
            base.omega_e_rad_s,
        )?;
        in_range("open_loop.align_time_s", ol.align_time_s, 0.0, 100.0)?;
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
            d_axis_currents(&design, &base, motor.flux_wb, v_dead_nominal_v)?;
        let svpwm = svpwm_config(inverter, &design)?;
        let align_samples = libm::round(ol.align_time_s / ts) as u32;
        let open_loop_current = pu_from_f64(ol.current_a / base.current_a);
        let align_step = |len: u32| {
            libm::round(f64::from(open_loop_current.to_bits()) * 65536.0 / f64::from(len.max(1)))
                as i64
        };
        let align_first = (align_samples / 8).max(1);
        let open_loop = OpenLoopConfig {
            current: open_loop_current,
            accel: pu_from_f64(ol.accel_rad_s2 * ts / base.omega_e_rad_s),
            handover_speed: pu_from_f64(ol.handover_speed_rad_s / base.omega_e_rad_s),
            align_samples,
            align_steps: [
                align_step(align_first),
                align_step((align_samples / 2).saturating_sub(align_first)),
            ],
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
        };
        let monitor = {
            let accel =
                motor.p() * motor.kt_nm_per_a * design.speed.current_limit_a / motor.j_kg_m2;
            let limit = design.speed.current_limit_a / base.current_a;
            let health = match p.health_limit_pu {
                Some(h) => pu_from_f64(in_range("protection.health_limit_pu", h, 1e-6, 100.0)?),
                None => Pu::MAX,
            };
            super::monitor::MonitorConfig::new(tt, base.omega_e_rad_s, accel, limit, health).ok_or(
                ConfigError::Gain {
                    key: "sample_hz",
                    value: sample_hz,
                    min: 0.0,
                    max: 0.0,
                },
            )?
        };
        let current = CurrentConfig::new(motor, &base, {
            // Overmodulating, the current loops may ask up to six-step's request.
            let mut c = design.current;
            if design.overmodulation {
                c.modulation *= crate::svpwm::OVERMOD_SIX_STEP_REQUEST * libm::sqrt(3.0);
            }
            c
        })?;
        // Only an IPD start-up needs pulses this motor and bus can drive.
        let ipd = match design.startup {
            // (`features::check` refused it in a build without it.)
            #[cfg(feature = "ipd")]
            StartupMode::Ipd => IpdConfig::new(motor, &base, design.ipd)?,
            _ => IpdConfig::unused(),
        };
        let speed = SpeedConfig::new(motor, &base, design.speed)?;
        #[cfg(feature = "injection")]
        let speed_injecting =
            schedule::injecting(motor, &base, &design, &injection, &injection_figures)?;
        let speed_stiff = schedule::stiff(motor, &base, &design, open_loop.handover_speed)?;
        let isr = IsrConfig {
            deadtime,
            ipd_fallback: auto_startup && design.startup == StartupMode::Ipd,
            deadtime_lag_shift: if design.overmodulation {
                0
            } else {
                follow_shift(1.0 / (design.current.bandwidth_rad_s * ts)).unwrap_or(0)
            },
            svpwm,
            open_loop,
            protection: ProtectionConfig {
                overcurrent: pu_from_f64(p.overcurrent_a / base.current_a),
                vdc_min: pu_from_f64(p.vdc_min_v / base.voltage_v),
                vdc_max: pu_from_f64(p.vdc_max_v / base.voltage_v),
                overspeed: pu_from_f64(overspeed),
                sum_limit: pu_from_f64(0.15).to_bits() >> 2,
                sum_shift: follow_shift(1e-3 / ts).ok_or(ConfigError::Gain {
                    key: "sample_hz",
                    value: sample_hz,
                    min: 1.0,
                    max: 1e9,
                })?,
            },
            rectify_grace_samples: libm::ceil(super::RECTIFY_GRACE_S / ts) as u32,
            pwm_delay: design.pwm_delay_samples,
            mid_turns: 2 * design.pwm_delay_samples as i32 + 1,
            mid_frame_k: 2 * design.pwm_delay_samples as i32 - 1,
            #[cfg(feature = "injection")]
            injection,
        };
        let task = TaskConfig {
            estimator: design.estimator,
            startup: design.startup,
            speed_filter_shift: match design.speed_filter_rad_s {
                None => 0,
                Some(w) => {
                    let w = in_range("speed_filter_rad_s", w, 1e-3, 2.0 / ts)?;
                    follow_shift(1.0 / (w * tt)).unwrap_or(0)
                }
            },
            flux,
            light_load,
            low_speed,
            deadtime,
            svpwm,
            // I/2 then I (the alignment's and the open loop's current last: a rotor just
            // pulled into place and held at half of it for 20 ms settles again), each 10 ms to
            // settle (seven time constants of the default current loops) and 10 ms to average,
            // in task periods.
            calibration: if design.deadtime_calibration
                && design.deadtime.mode.compensates_command()
            {
                let i = ol.current_a / base.current_a;
                super::calibrate::CalibrationConfig {
                    levels: [pu_from_f64(0.5 * i), pu_from_f64(i)],
                    settle: libm::ceil(0.01 / tt) as u32,
                    average: (libm::ceil(0.01 / tt) as u32).min(super::calibrate::MAX_AVERAGE),
                }
            } else {
                super::calibrate::CalibrationConfig::default()
            },
            monitor,
            open_loop_current: open_loop.current,
            open_loop_damping: super::startup::damping(motor, &base, ol.current_a),
            handover_speed: open_loop.handover_speed,
            handover_wait: libm::ceil(
                (ol.handover_speed_rad_s / ol.accel_rad_s2).clamp(0.01, 0.05) / tt,
            ) as u32,
            speed_own: speed.gains(),
            #[cfg(feature = "load-observer")]
            load_observer: LoadObserverConfig::of_design(
                motor,
                &base,
                tt,
                design.load_observer_rad_s,
            )?,
            #[cfg(feature = "injection")]
            speed_injecting,
            speed_stiff,
            // Half the detection's polarity pulse, within the speed loop's current limit.
            #[cfg(feature = "injection")]
            polarity: injection.is_some().then(|| {
                crate::observer::PolarityConfig::new(
                    (0.5 * design.ipd.long_current_pu)
                        .min(design.speed.current_limit_a / base.current_a),
                )
            }),
            zero_crossing_hold: design.zero_crossing_hold,
        };
        Ok(Self {
            base,
            design,
            motor: *motor,
            v_dead_nominal_v,
            estimator,
            current,
            ipd,
            speed,
            isr,
            task,
            #[cfg(feature = "injection")]
            injection_declined,
            #[cfg(feature = "injection")]
            injection_figures,
        })
    }

    /// The d-axis reference's configuration (MTPA, field weakening, maximum speed).
    pub fn flux(&self) -> &FluxConfig {
        &self.task.flux
    }

    /// Estimated speed beyond which the drive trips on [`super::Fault::Overspeed`], per unit.
    pub fn overspeed(&self) -> Pu {
        self.isr.protection.overspeed
    }

    /// The dead-time compensation, as designed for the inverter the drive was told.
    pub fn deadtime(&self) -> &DeadTimeConfig {
        &self.task.deadtime
    }

    /// The inverter's distortion voltage `V_dead` at the nominal bus, V, as the compensation
    /// was designed for it (whether or not the compensation is on).
    pub fn v_dead_nominal_v(&self) -> f64 {
        self.v_dead_nominal_v
    }

    /// Whether dead-time compensation is on.
    pub fn deadtime_compensation(&self) -> bool {
        self.design.deadtime.mode != DeadTimeMode::Off
    }

    /// The high-frequency injection as designed, `None` without it: its amplitude (V), its
    /// frequency (Hz, half the sampling rate), the current it moves across the axis at 45° of
    /// error (`K`, A) and the peak-to-peak ripple it makes along the d axis (A).
    #[cfg(feature = "injection")]
    pub fn injection(&self) -> Option<crate::observer::InjectionFigures> {
        self.injection_figures
    }

    /// Why the injection the design asked for with [`crate::InjectionDesign::fallback`] was
    /// left out (a surface motor, a gain out of range); `None` if it is in or was not asked,
    /// and in a configuration read from an image (a diagnostic, which images do not hold).
    #[cfg(feature = "injection")]
    pub fn injection_declined(&self) -> Option<ConfigError> {
        self.injection_declined
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
