//! What a drive is designed from: SI units, with defaults computed from the motor and the
//! inverter ([`DriveDesign::default_for`]).

use super::TASK_PERIOD;
#[cfg(any(doc, test))]
use super::config::DriveConfig;
use crate::Angle;
use crate::control::current::CurrentDesign;
use crate::control::flux::FluxDesign;
use crate::control::light_load::LightLoadConfig;
use crate::control::low_speed::LowSpeedConfig;
use crate::control::speed::SpeedDesign;
use crate::deadtime::{CurrentSource, DeadTimeDesign, DeadTimeMode};
use crate::ipd::{IpdConfig, IpdDesign};
use crate::observer::{EstimatorKind, MrasCurrentGains, MrasEmfConfig, default_observer_gain};
use crate::params::{InverterParams, MotorParams};
use crate::units::PerUnit;

/// How the drive finds the rotor before it runs.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StartupMode {
    /// Voltage pulses, saliency and saturation (Khlaief, Boussak, Gossa (2012) §4). In a
    /// build with the feature `ipd` only; without it [`DriveConfig::new`] refuses it.
    Ipd,
    /// A d-axis current along the α axis pulls the rotor to `θ = 0` first.
    Align,
    /// The rotor angle is known (electrical).
    Known(Angle),
    /// [`StartupMode::Ipd`] where the motor's saliency allows it (and the build has the
    /// feature `ipd`), [`StartupMode::Align`] otherwise ([`StartupMode::resolve`]);
    /// [`DriveConfig::new`] resolves it, so a drive never runs in this mode.
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
    /// The saliency the initial position detection sees on a linear `motor`
    /// ([`MotorParams::saliency`]).
    pub fn saliency(motor: &MotorParams) -> f64 {
        motor.saliency()
    }

    /// `Auto` made concrete: the initial position detection when the motor's
    /// [`StartupMode::saliency`] is at least [`AUTO_SALIENCY_MARGIN`] times `ipd.min_saliency`
    /// and its pulses can be designed on this motor and bus (in a build with the feature
    /// `ipd`), the alignment otherwise. Other modes are returned unchanged.
    pub fn resolve(self, motor: &MotorParams, base: &PerUnit, ipd: &IpdDesign) -> Self {
        match self {
            StartupMode::Auto => {
                let salient = Self::saliency(motor) >= AUTO_SALIENCY_MARGIN * ipd.min_saliency;
                if salient && cfg!(feature = "ipd") && IpdConfig::new(motor, base, *ipd).is_ok() {
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
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
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
    /// that current makes, `0.2 p K_T I / J`, but none that reaches the handover speed in
    /// less than [`MIN_OPEN_LOOP_RAMP_S`]; handover at 10 % of the rated electrical speed
    /// (or of the base speed; [`DriveDesign::default_for`] raises it for the MRAS on the EMF
    /// to [`MrasEmfConfig::damped_speed_rad_s`] where that is higher); alignment over 0.5 s.
    pub fn default_for(motor: &MotorParams, base: &PerUnit) -> Self {
        let rated_e = rated_e_rad_s(motor, base);
        let handover_speed_rad_s = 0.1 * rated_e;
        let torque_accel = 0.2 * motor.p() * motor.kt_nm_per_a * base.current_a / motor.j_kg_m2;
        Self {
            current_a: base.current_a,
            accel_rad_s2: torque_accel.min(handover_speed_rad_s / MIN_OPEN_LOOP_RAMP_S),
            handover_speed_rad_s,
            align_time_s: 0.5,
        }
    }
}

/// The shortest default open-loop ramp from rest to the handover speed, s. A back-EMF
/// estimator starts from rest and sees an EMF that grows from zero with the speed; a light
/// rotor under a fifth of its rated torque reaches the handover speed in a millisecond or two
/// (the GM4108H gimbal motor in 1.6 ms, 40 samples at 25 kHz), while the estimate still swings
/// about the rotor, and the handover then took it or not as it happened to lie (docs/drive.md,
/// "OpenLoop"). Ten milliseconds, the least of the handover's wait.
pub const MIN_OPEN_LOOP_RAMP_S: f64 = 0.01;

/// The rated electrical speed, rad/s (the base speed for a motor without a rating).
pub(crate) fn rated_e_rad_s(motor: &MotorParams, base: &PerUnit) -> f64 {
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
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
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
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct DriveDesign {
    /// The estimator.
    pub estimator: EstimatorKind,
    /// Gain `g` of the estimators of Solsona, Valla, Muravchik (2000), rad/s.
    pub observer_gain_rad_s: f64,
    /// Adaptation gains of the current-model MRAS.
    pub mras_current: MrasCurrentGains,
    /// Current loops.
    pub current: CurrentDesign,
    /// Speed loop. Default: [`SpeedDesign::default_for`]'s, at 40 % with a back-EMF estimator,
    /// raised to a light rotor's `4/τ_b` within `0.005/T_s` (not the MRAS on the EMF), and
    /// with the current-model MRAS at most `1/(2ζ ε τ_m)`, `ε` =
    /// [`SPEED_LOOP_R_ERROR`](crate::tuning::SPEED_LOOP_R_ERROR) (docs/drive.md, "speed loop:
    /// the resistance's error").
    pub speed: SpeedDesign,
    /// Bandwidth of the speed loop above twice the open loop's handover speed, rad/s, where
    /// the back-EMF estimate is clean enough for a light rotor's stiff loop; `None`: `speed`'s
    /// everywhere. Default: a light rotor's `4/τ_b` (`τ_b` the time base torque takes it from
    /// rest to base speed) within `0.01/T_s`, for the NLO and the AO, where it exceeds
    /// `speed`'s (docs/khlaief2012.md, "stiffer above the handover").
    pub speed_stiff_rad_s: Option<f64>,
    /// Bandwidth of the load observer that feeds the load's current forward into the speed
    /// loop, rad/s; `None`: none. Default: ten times `1/τ_b` within half the task rate, for
    /// the back-EMF estimators on motors whose resistive drop is below a quarter of their EMF
    /// (docs/drive.md, "load observer").
    pub load_observer_rad_s: Option<f64>,
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
    /// [`crate::tuning::OVERMOD_SIX_STEP_REQUEST`] `V_DC` and field weakening holds the applied
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
    /// Track the motor's `R` and `ψ` while running and rewrite the drive's model with them
    /// (the task's [`super::Tracker`], docs/tracking.md). Default on with the current-model MRAS
    /// (whose model it rewrites) in a build with the feature `tracking`.
    pub tracking: bool,
    /// Learn the inverter's distortion voltage while running and rescale the dead-time
    /// compensation (the task's [`super::DistortionLearner`], docs/distortion.md). Default on
    /// in a build with the feature `distortion-learner` where the inverter has a dead time;
    /// it runs only while the compensation is on.
    pub deadtime_learning: bool,
    /// High-frequency injection at standstill and low speed on a salient motor
    /// (docs/injection.md): below [`crate::InjectionDesign::on_below`] of rated speed the angle comes
    /// from the saliency instead of the estimator, and while it holds the rotor there the
    /// low-speed d current is off. `None`
    /// for none. With the feature `injection` only, and then on by default where the motor
    /// allows it ([`crate::InjectionDesign::fallback`]): a firmware that does not inject
    /// carries neither its code nor its state.
    #[cfg(feature = "injection")]
    pub injection: Option<crate::observer::InjectionDesign>,
}

/// Speed-loop bandwidth that keeps a light rotor under a load step: `ω_n τ_b` with `τ_b` the
/// time base torque takes the rotor from rest to base speed. A step of base torque dips the
/// speed of a loop of natural frequency `ω_n` (`ζ = 1`) by `ω_b/(e ω_n τ_b)`, a tenth of base
/// speed at 3.7; a rotor without its load (a servo's 5–20 ms, a gimbal motor's 15 ms) would
/// otherwise stop and turn backwards under half its rated torque before the loop answered.
pub const SPEED_STIFFNESS: f64 = 4.0;
/// Largest default `ω_n T_s` of the speed loop: the current-model MRAS's default, two and a
/// half times the back-EMF estimators', a fifth of their estimated speed's filter. (At twice
/// that, the NLO's loop on the board's gimbal motor rang with the estimate's noise at its
/// 100 r/min handover, 0.4 V of EMF under 2.6 V of resistive drop, and the reversal's
/// handover tripped.)
pub const SPEED_BANDWIDTH_MAX_TS: f64 = 0.005;

/// Largest default `ω_n T_s` of the back-EMF estimators' stiff loop above twice their handover
/// speed ([`DriveDesign::speed_stiff_rad_s`]): twice [`SPEED_BANDWIDTH_MAX_TS`], where the
/// estimate's noise no longer rings the loop.
pub const SPEED_BANDWIDTH_STIFF_TS: f64 = 2.0 * SPEED_BANDWIDTH_MAX_TS;

/// The bandwidth [`SPEED_STIFFNESS`] asks for `motor`, rad/s.
pub fn stiff_bandwidth_rad_s(motor: &MotorParams, base: &PerUnit) -> f64 {
    // 4/τ_b, τ_b = J ω_b/(p K_T I_b).
    SPEED_STIFFNESS * motor.p() * motor.kt_nm_per_a * base.current_a
        / (motor.j_kg_m2 * base.omega_e_rad_s)
}

/// Relative error of the winding resistance the speed loop of a speed-adaptive estimator
/// stays stable with: copper's rise over 100 K (0.39 %/K), a winding measured cold and run hot.
/// The drive's default bandwidth with the current-model MRAS is at most `1/(2ζ ε τ_m)`,
/// `τ_m = J R/(K_T p ψ)` (docs/drive.md, "speed loop: the resistance's error").
pub const SPEED_LOOP_R_ERROR: f64 = 0.4;

/// Largest speed-loop bandwidth, rad/s, at which a resistance error of
/// [`SPEED_LOOP_R_ERROR`] leaves the loop stable, for `damping` `ζ`: `1/(2ζ ε τ_m)`,
/// `τ_m = J R/(K_T p ψ)` the motor's electromechanical time constant. An estimator that adapts
/// its speed to the voltage balance reads the q voltage `ΔR i_q` its model misses as a speed
/// `ΔR i_q/ψ`: a second path from the loop's current to its feedback, which turns the loop's
/// sign once `K_pΩ ΔR/ψ` reaches one (docs/drive.md, "speed loop: the resistance's error").
pub fn resistance_bandwidth_rad_s(motor: &MotorParams, damping: f64) -> f64 {
    let tau_m = motor.j_kg_m2 * motor.rs_ohm / (motor.kt_nm_per_a * motor.p() * motor.flux_wb);
    1.0 / (2.0 * damping * SPEED_LOOP_R_ERROR * tau_m)
}

/// Longest PWM update delay the drive compensates, control samples.
pub const MAX_PWM_DELAY_SAMPLES: u8 = 2;

impl DriveDesign {
    /// This design without the high-frequency injection (in a build without the feature
    /// `injection`, which has none, the design itself): the same drive on every build.
    #[must_use]
    pub fn without_injection(self) -> Self {
        #[cfg(feature = "injection")]
        let s = Self {
            injection: None,
            ..self
        };
        #[cfg(not(feature = "injection"))]
        let s = self;
        s
    }

    /// Defaults for `motor` on `inverter` with the bases `base`, running `estimator`.
    pub fn default_for(
        motor: &MotorParams,
        inverter: &InverterParams,
        base: &PerUnit,
        estimator: EstimatorKind,
    ) -> Self {
        let deadtime = DeadTimeDesign::default_for(motor, inverter);
        let speed = SpeedDesign {
            // The speed loop runs in the task.
            decimation: TASK_PERIOD,
            ..SpeedDesign::default_for(base)
        };
        Self {
            estimator,
            observer_gain_rad_s: default_observer_gain(motor, base),
            // A build without the current-model MRAS never reads its gains: none of their
            // design code in its image.
            mras_current: if cfg!(any(
                not(feature = "select-estimators"),
                feature = "mras-current"
            )) {
                MrasCurrentGains::default_for(motor, base)
            } else {
                MrasCurrentGains {
                    kp: 0.0,
                    ki: 0.0,
                    kl: 0.0,
                    low_speed_schedule: false,
                    d_weight: 0.0,
                }
            },
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
                // Not the MRAS on the EMF: its estimated speed is its adaptation's, whose slow
                // root a faster loop drives (on the random family's 30 seeds it lost 8 more
                // reversals under load with the light rotors' bandwidth, 596 → 588 of 612).
                if estimator != EstimatorKind::MrasEmf {
                    d.bandwidth_rad_s = d
                        .bandwidth_rad_s
                        .max(stiff_bandwidth_rad_s(motor, base))
                        .min(SPEED_BANDWIDTH_MAX_TS / base.sample_s);
                }
                // A speed adapted to the voltage balance reads the resistance's error as speed.
                // Not the MRAS on the EMF, whose own loop is slower still: bounded, it lost
                // motor A's start (its adaptation's slow root, above).
                if estimator == EstimatorKind::MrasCurrent {
                    d.bandwidth_rad_s = d
                        .bandwidth_rad_s
                        .min(resistance_bandwidth_rad_s(motor, d.damping));
                }
                d
            },
            speed_stiff_rad_s: Some(
                stiff_bandwidth_rad_s(motor, base).min(SPEED_BANDWIDTH_STIFF_TS / base.sample_s),
            )
            .filter(|&w| {
                matches!(estimator, EstimatorKind::Nlo | EstimatorKind::Ao)
                    && w > SPEED_BANDWIDTH_MAX_TS / base.sample_s
            }),
            load_observer_rad_s: crate::control::load_observer::default_bandwidth_rad_s(
                motor,
                base,
                base.sample_s * f64::from(TASK_PERIOD),
                estimator.needs_open_loop_start(),
            ),
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
            flux: FluxDesign::ON,
            overmodulation: false,
            pwm_delay_samples: 0,
            // The current-model MRAS runs from standstill, where the compensation's error is
            // its error; the back-EMF estimators hand over at a tenth of rated speed, where
            // the EMF dwarfs it. (`DriveConfig::new` runs it only with a compensated command.)
            deadtime_calibration: !estimator.needs_open_loop_start() && inverter.dead_time_s > 0.0,
            zero_crossing_hold: true,
            // The tracker rewrites the current-model MRAS's model; the back-EMF estimators
            // keep theirs (it would only move the current loops' feed-forward under them).
            tracking: estimator == EstimatorKind::MrasCurrent && cfg!(feature = "tracking"),
            // Wherever there is a compensation to scale (the task builds the learner only with
            // a compensated command), in a build with the learner.
            deadtime_learning: cfg!(feature = "distortion-learner") && inverter.dead_time_s > 0.0,
            #[cfg(feature = "injection")]
            injection: Some(crate::observer::InjectionDesign::default()),
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
/// IP form ([`crate::tuning::IP_FORM`]), whose reference is held at their least speed and whose rotor
/// must decelerate into the open-loop reversal.
pub const MRAS_REFERENCE_WEIGHT: f64 = 0.5;

/// The few choices a user makes about a drive; everything else is
/// [`DriveDesign::default_for`]'s (for more, change a [`DriveDesign`] and use
/// [`DriveConfig::new`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DriveOptions {
    /// The estimator; `None`: [`EstimatorKind::for_motor`] (the current-model MRAS on an
    /// interior motor, the NLO on a surface motor).
    pub estimator: Option<EstimatorKind>,
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

/// The fundamental voltage the drive can hold at the nominal bus, per unit of `V_b` (the
/// circle's radius): 1, or the six-step's `2√3/π` overmodulating.
pub(crate) fn voltage_limit_pu(design: &DriveDesign) -> f64 {
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
/// with `i_d = −I_d,lim` (`weakening_current_f64`) under field weakening, `i_d = 0` without
/// (where the EMF `ωψ` reaches `V_DC/√3`, the bus the diodes would rectify into). Never below
/// 1.2 pu.
pub(crate) fn overspeed_pu(motor: &MotorParams, base: &PerUnit, design: &DriveDesign) -> f64 {
    let i_max = design.speed.current_limit_a / base.current_a;
    let ld = motor.ld_h / base.inductance_h;
    let psi = motor.flux_wb / base.flux_wb;
    let r = motor.rs_ohm / base.impedance_ohm;
    let v_lim = voltage_limit_pu(design);
    let id_lim = if design.flux.field_weakening {
        crate::control::flux::weakening_current_f64(psi, ld, r, i_max, v_lim)
    } else {
        0.0
    };
    let cap = crate::control::flux::SPEED_CAP_PER_BASE;
    let w = crate::control::flux::max_speed_f64(psi, ld, r, id_lim, v_lim, cap);
    (OVERSPEED_FACTOR * w).max(1.2).min(cap)
}

#[cfg(test)]
mod tests;
