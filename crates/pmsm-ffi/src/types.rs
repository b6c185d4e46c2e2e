//! The C types of `pmsm.h`: status codes, enumerations, configuration, per-sample data and
//! the storage of a drive.
//!
//! Sign and timing conventions (stated once here and in every type they concern):
//! - a phase current is positive when it flows from the inverter leg into the motor winding;
//! - angles are electrical, measured from the axis of phase a, positive in the direction
//!   a → b → c (positive sequence), `2^32` = one turn;
//! - the duties returned by a step apply over the PWM period that starts at the sample whose
//!   currents were given to that step.

/// Status returned by every function that can fail. `PMSM_OK` (0) is success; errors are
/// negative. `pmsm_status_message` gives a one-line description of each.
#[repr(i32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum pmsm_status_t {
    /// Success.
    PMSM_OK = 0,
    /// A required pointer argument is NULL.
    PMSM_ERR_NULL = -1,
    /// The storage is smaller than `pmsm_drive_size()` bytes.
    PMSM_ERR_BUFFER_TOO_SMALL = -2,
    /// A pointer is not aligned for its type (storage: `pmsm_drive_align()` bytes).
    PMSM_ERR_MISALIGNED = -3,
    /// The handle does not point to a drive initialised by `pmsm_drive_init`.
    PMSM_ERR_NOT_INITIALIZED = -4,
    /// An enumerated code or integer argument is out of range.
    PMSM_ERR_INVALID_ARGUMENT = -5,
    /// A physical parameter of the configuration is invalid (not finite, not positive, out of
    /// its physical range); `pmsm_config_error_message` names it.
    PMSM_ERR_CONFIG_PARAM = -6,
    /// The motor, bus and sample rate fall outside the fixed-point envelope.
    PMSM_ERR_CONFIG_ENVELOPE = -7,
    /// A controller or estimator gain is outside its stable, representable range.
    PMSM_ERR_CONFIG_GAIN = -8,
    /// The image passed to `pmsm_drive_init_image` was written by another build of the
    /// library (sources, compiler, estimator features), has another size, or is corrupted.
    PMSM_ERR_IMAGE = -9,
}

/// The drive's rotor-position estimator (`pmsm_config_t.estimator`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum pmsm_estimator_t {
    /// Current-model MRAS of Khlaief, Boussak, Gossa (2012); works from standstill after IPD.
    /// The default (0). Cargo feature `mras-current`.
    PMSM_ESTIMATOR_MRAS_CURRENT = 0,
    /// Nonlinear reduced-order back-EMF observer of Solsona, Valla, Muravchik (2000); open-loop
    /// start. Cargo feature `nlo`.
    PMSM_ESTIMATOR_NLO = 1,
    /// Linear reduced-order back-EMF observer of Solsona, Valla, Muravchik (2000); open-loop
    /// start. Cargo feature `ao`.
    PMSM_ESTIMATOR_AO = 2,
    /// MRAS speed estimator on the back-EMF observer (Solsona, Valla, Muravchik (2000));
    /// open-loop start. Cargo feature `mras-emf`.
    PMSM_ESTIMATOR_MRAS_EMF = 3,
    /// The one the defaults choose for the motor, as `pmsm simulate`'s `observer = "auto"`:
    /// the current-model MRAS when `|L_q − L_d|/(L_q + L_d)` ≥ 0.04 (an interior motor), the
    /// NLO otherwise (a surface motor). A library built without the chosen one refuses it.
    PMSM_ESTIMATOR_AUTO = 4,
}

/// How the drive finds the rotor on `pmsm_start` (`pmsm_config_t.startup`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum pmsm_startup_t {
    /// Automatic: IPD where the saliency |L_q - L_d|/(L_q + L_d) reaches 10 %, alignment otherwise (0).
    PMSM_STARTUP_DEFAULT = 0,
    /// Initial position detection from voltage pulses (needs saliency, L_d < L_q).
    PMSM_STARTUP_IPD = 1,
    /// Pull the rotor to electrical angle 0 with a d-axis current first.
    PMSM_STARTUP_ALIGN = 2,
    /// The rotor is at `pmsm_config_t.startup_angle`.
    PMSM_STARTUP_KNOWN = 3,
}

/// Dead-time compensation (`pmsm_config_t.deadtime_compensation`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum pmsm_deadtime_t {
    /// The default: both (0).
    PMSM_DEADTIME_DEFAULT = 0,
    /// No compensation.
    PMSM_DEADTIME_OFF = 1,
    /// Added to the voltage command only.
    PMSM_DEADTIME_COMMAND = 2,
    /// Removed from the voltage the estimator sees only.
    PMSM_DEADTIME_ESTIMATOR = 3,
    /// Both.
    PMSM_DEADTIME_BOTH = 4,
}

/// The high-frequency injection at standstill and low speed (`pmsm_config_t.injection`,
/// docs/injection.md): below 6 % of rated speed the angle comes from the saliency (`L_q/L_d`
/// of at least 1.1) instead of the back-EMF, so that an interior motor holds full torque at
/// 0 r/min without the low-speed d current. Cargo feature `injection` (on by default).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum pmsm_injection_t {
    /// On where the motor allows it, off on a surface motor or in a library built without
    /// the feature; `pmsm_injection_message` says which and why (0).
    PMSM_INJECTION_DEFAULT = 0,
    /// Off: the low-speed d current holds the rotor at standstill.
    PMSM_INJECTION_OFF = 1,
    /// On, and a motor it cannot serve (or a library without it) is refused.
    PMSM_INJECTION_ON = 2,
}

/// A learner of the drive's task left to its default, turned off or asked for
/// (`pmsm_config_t.tracking`, `pmsm_config_t.deadtime_learning`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum pmsm_option_t {
    /// The library's default for the motor and inverter (0).
    PMSM_OPTION_DEFAULT = 0,
    /// Off.
    PMSM_OPTION_OFF = 1,
    /// On; refused (`PMSM_ERR_INVALID_ARGUMENT`) by a library built without it.
    PMSM_OPTION_ON = 2,
}

/// What the drive is doing (`pmsm_state_info_t.state`, `pmsm_output_t.state`). The values
/// are the core's `DriveState::code()`; new states get new values, none is renumbered.
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum pmsm_state_t {
    /// Outputs off, waiting for `pmsm_start`.
    PMSM_STATE_IDLE = 0,
    /// Detecting the initial rotor position.
    PMSM_STATE_IPD = 1,
    /// Aligning the rotor to angle 0.
    PMSM_STATE_ALIGN = 2,
    /// Open-loop current-vector start (back-EMF estimators).
    PMSM_STATE_OPEN_LOOP = 3,
    /// Sensorless closed loop.
    PMSM_STATE_RUN = 4,
    /// Outputs off after a fault, latched until `pmsm_clear_fault` or `pmsm_stop`.
    PMSM_STATE_FAULT = 5,
}

/// Why the drive stopped switching (`pmsm_state_info_t.fault`), with the meaning of
/// `pmsm_state_info_t.fault_value`. The values are the core's `Fault::code()`; new faults get
/// new values, none is renumbered. `pmsm_fault_name` gives a short name of each.
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum pmsm_fault_t {
    /// No fault (the state is not `PMSM_STATE_FAULT`); value 0.
    PMSM_FAULT_NONE = 0,
    /// A phase current beyond the trip threshold; value: the current, Q8.24 pu.
    PMSM_FAULT_OVERCURRENT = 1,
    /// The bus voltage below its minimum; value: the bus, Q8.24 pu.
    PMSM_FAULT_BUS_UNDERVOLTAGE = 2,
    /// The bus voltage above its maximum; value: the bus, Q8.24 pu.
    PMSM_FAULT_BUS_OVERVOLTAGE = 3,
    /// The initial position detection failed; value: which check, a `pmsm_ipd_fault_t`
    /// (`pmsm_get_ipd` gives its measurements).
    PMSM_FAULT_INITIAL_POSITION = 4,
    /// The estimator disagreed with the open-loop frame at handover; value: the angle
    /// difference, turn (2^32 = one electrical turn).
    PMSM_FAULT_HANDOVER = 5,
    /// A current sensor is broken; value: the channel stuck while the others move (0 = a,
    /// 1 = b, 2 = c), or -1 when the three currents do not add up to zero.
    PMSM_FAULT_CURRENT_SENSOR = 6,
    /// A phase carries no current while the others do (open winding, cable or switch); value:
    /// the phase (0 = a, 1 = b, 2 = c).
    PMSM_FAULT_PHASE_LOSS = 7,
    /// The speed loop is at its current limit with the rotor far below the reference:
    /// stalled or locked; value 0.
    PMSM_FAULT_STALL = 8,
    /// The estimated speed changed faster than the motor can accelerate, the estimator's
    /// health figure passed its limit, or the current loops lost their references in the
    /// estimated frame: the estimator lost its lock; value 0.
    PMSM_FAULT_LOSS_OF_LOCK = 9,
    /// The firmware reported a control step that did not finish within its period
    /// (`pmsm_report_overrun`); value 0.
    PMSM_FAULT_OVERRUN = 10,
    /// The estimated speed is beyond what the drive can hold within the bus; value: the
    /// speed, Q8.24 pu. The outputs short the motor (every duty 0, low-side switches on).
    PMSM_FAULT_OVERSPEED = 11,
    /// The speed loop pushes at its current limit in the reference's direction while the rotor
    /// turns the other way without slowing (a load stronger than the drive); value 0.
    PMSM_FAULT_DRIVEN_BACKWARDS = 12,
}

/// Which check of the initial position detection failed (`pmsm_state_info_t.fault_value` of
/// `PMSM_FAULT_INITIAL_POSITION`, `pmsm_ipd_t.fault`). The values are the core's
/// `IpdFault::code()`; `pmsm_ipd_fault_name` gives the core's `IpdFault::name()`.
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum pmsm_ipd_fault_t {
    /// No detection failed.
    PMSM_IPD_FAULT_NONE = 0,
    /// A phase current exceeded the detector's limit; `pmsm_ipd_t.fault_value[0]`: that
    /// current, Q8.24 pu.
    PMSM_IPD_FAULT_OVERCURRENT = 1,
    /// A short pulse produced less than a quarter of its design peak (open phase, no motor);
    /// `fault_value[0]`: its peak, Q8.24 pu.
    PMSM_IPD_FAULT_NO_CURRENT = 2,
    /// The saliency was below the minimum (a surface motor, or noise): no angle;
    /// `fault_value`: the modulation `(3/2) dI` and the sum `3 I_0` of the short peaks, pu.
    PMSM_IPD_FAULT_LOW_SALIENCY = 3,
    /// The two long pulses were too close to tell north from south; `fault_value`: the peaks
    /// along the candidate and opposite it, pu.
    PMSM_IPD_FAULT_NO_POLARITY = 4,
    /// The bus voltage was too low to modulate the pulses.
    PMSM_IPD_FAULT_BUS_LOW = 5,
}

/// Configuration of a drive: motor, inverter and control, SI units. Zero-initialise it
/// (`pmsm_config_t c = {0};`), then set the motor and inverter: every optional field left at 0
/// takes the library's default, computed from the motor and inverter.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct pmsm_config_t {
    /// Pole pairs `p` (1..100).
    pub pole_pairs: u32,
    /// A `pmsm_estimator_t` (0: current-model MRAS).
    pub estimator: u32,
    /// A `pmsm_startup_t` (0: the estimator's default).
    pub startup: u32,
    /// A `pmsm_deadtime_t` (0: compensation on, both command and estimator).
    pub deadtime_compensation: u32,
    /// Rotor electrical angle for `PMSM_STARTUP_KNOWN`, turn (2^32 = one turn, signed).
    pub startup_angle: i32,
    /// Period of the centre-aligned PWM timer in counts (the compare value of duty 1), in the
    /// range 0 to 65535, for `pmsm_output_t.compare` (0: the compare values are 0).
    pub pwm_period_ticks: u32,
    /// Stator phase resistance `R`, ohm.
    pub rs_ohm: f64,
    /// Direct-axis inductance `L_d`, H.
    pub ld_h: f64,
    /// Quadrature-axis inductance `L_q`, H (`L_d = L_q`: surface motor).
    pub lq_h: f64,
    /// Peak magnet flux linkage `psi`, V*s/rad electrical.
    pub flux_wb: f64,
    /// Torque constant, N*m/A peak (optional; 0: `1.5 p psi`).
    pub kt_nm_per_a: f64,
    /// Rotor and load inertia, kg*m^2.
    pub j_kg_m2: f64,
    /// Viscous friction, N*m*s/rad (0 allowed).
    pub b_nm_s: f64,
    /// Rated phase current, A RMS (optional; 0: from the envelope). 1 pu current = sqrt(2)
    /// times this.
    pub rated_current_a: f64,
    /// Rated mechanical speed, r/min (optional).
    pub rated_speed_rpm: f64,
    /// Nominal DC bus voltage, V. 1 pu voltage = `vdc_v / sqrt(3)`.
    pub vdc_v: f64,
    /// PWM switching frequency, Hz.
    pub pwm_hz: f64,
    /// Dead time, s.
    pub dead_time_s: f64,
    /// Full scale of the current sensing, A peak (optional; 0: 4 pu).
    pub current_full_scale_a: f64,
    /// Control sample rate (calls of `pmsm_step` per second), Hz (optional; 0: `pwm_hz`).
    pub sample_hz: f64,
    /// Current-loop bandwidth, Hz (optional).
    pub current_bandwidth_hz: f64,
    /// Speed-loop bandwidth, Hz (optional).
    pub speed_bandwidth_hz: f64,
    /// Current limit of the speed loop (and of the open-loop start), A peak (optional).
    pub current_limit_a: f64,
    /// Gain of the back-EMF observers, rad/s (optional).
    pub observer_gain_rad_s: f64,
    /// Control samples between a step's return and the PWM period its duties act over (0, 1
    /// or 2): 1 for a timer whose compare registers are preloaded and load at the next update
    /// (an STM32 TIM1 with OCxPE set), 0 when the duties act over the coming period. The drive
    /// turns its voltage further and gives its estimator the voltage that acted.
    pub pwm_delay_samples: u32,
    /// A `pmsm_injection_t` (0: on where the motor's saliency allows it, in a library built
    /// with the cargo feature `injection`).
    pub injection: u32,
    /// A `pmsm_option_t` for the tracker of `R` and `psi` in the drive's task (docs/tracking.md;
    /// 0: on with the current-model MRAS, whose model it rewrites, in a library built with the
    /// cargo feature `tracking`).
    pub tracking: u32,
    /// A `pmsm_option_t` for the learner of the inverter's distortion voltage in the drive's
    /// task (docs/distortion.md; 0: on wherever `dead_time_s` is above 0 and the dead time is
    /// compensated, in a library built with the cargo feature `distortion-learner`).
    pub deadtime_learning: u32,
}

/// The measurements of one control sample, Q8.24 per unit (`2^24` = 1.0 pu).
///
/// Sign: a phase current is positive when it flows from the inverter leg into the motor
/// winding. Convert ADC codes with a `pmsm_scale_t` whose sign makes this so
/// (`pmsm_scale_current`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct pmsm_input_t {
    /// Phase current a sampled at the PWM centre (the sample instant `t_k`), per unit of
    /// `I_b` (`pmsm_get_bases`); positive into the motor.
    pub i_a: i32,
    /// Phase current b, per unit of `I_b`; positive into the motor.
    pub i_b: i32,
    /// Phase current c, per unit of `I_b`; positive into the motor.
    pub i_c: i32,
    /// DC bus voltage, per unit of `V_b = vdc_v / sqrt(3)` (the nominal bus is 1.7320508 pu
    /// = 29058991).
    pub vdc: i32,
}

/// What to apply over the next PWM period: the duties returned by the step of sample `t_k`
/// apply over the period `[t_k, t_k + T_s)` that starts at that sample. Write them to the
/// timer's preloaded compare registers before its next update event (the interrupt's
/// computation is taken to finish before the period's first switching edge).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct pmsm_output_t {
    /// Leg duties a, b, c (high-side on-time over the period), Q2.30 in [0, 2^30].
    pub duty: [i32; 3],
    /// The same as compare values of a centre-aligned timer counting to
    /// `pmsm_config_t.pwm_period_ticks`: `round(duty * period)`.
    pub compare: [u16; 3],
    /// 1: switch with these duties (main output enabled); 0: turn every switch off (duties
    /// are 0.5 then). It changes from step to step: set and clear the timer's main output
    /// enable from it at every step.
    pub pwm_on: u8,
    /// The state after this step, a `pmsm_state_t`.
    pub state: u8,
    /// 1 when this step ended a task period: pend the task that calls `pmsm_task`.
    pub task_due: u8,
}

/// The state and the latched fault.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct pmsm_state_info_t {
    /// A `pmsm_state_t`.
    pub state: u32,
    /// A `pmsm_fault_t` (`PMSM_FAULT_NONE` unless `state` is `PMSM_STATE_FAULT`).
    pub fault: u32,
    /// The fault's value (see `pmsm_fault_t`), 0 if none.
    pub fault_value: i32,
}

/// The rotor estimate of the last step.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct pmsm_estimate_t {
    /// Electrical angle of the rotor d axis (magnet north) from the axis of phase a,
    /// positive towards b then c; turn (2^32 = one turn, wrapping; signed).
    pub theta: i32,
    /// Signed electrical speed, Q8.24 per unit of `omega_b` (`pmsm_get_bases`); positive:
    /// `theta` increasing (rotation a → b → c).
    pub omega: i32,
}

/// What the last step computed, for logs and plots (`pmsm_get_telemetry`). Currents Q8.24 per
/// unit of `I_b`, voltages Q8.24 per unit of `V_b`, angles turn (2^32 = one electrical turn,
/// from the axis of phase a, positive towards b).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct pmsm_telemetry_t {
    /// The angle of the frame the current loops used (the estimate, or the imposed frame
    /// while aligning or starting open loop).
    pub theta: i32,
    /// The estimator's rotor angle.
    pub theta_est: i32,
    /// The estimator's electrical speed, Q8.24 per unit of `omega_b`.
    pub omega_est: i32,
    /// Measured d-axis current in the frame `theta`.
    pub i_d: i32,
    /// Measured q-axis current in the frame `theta` (positive: motoring torque forwards).
    pub i_q: i32,
    /// d-axis current reference.
    pub i_d_ref: i32,
    /// q-axis current reference.
    pub i_q_ref: i32,
    /// Voltage commanded to the modulator after its limit, alpha (along phase a).
    pub v_alpha: i32,
    /// Voltage commanded to the modulator after its limit, beta (90 degrees ahead of alpha).
    pub v_beta: i32,
    /// The estimator's health figure, filtered over 10 ms (0 outside the closed loop;
    /// growing as its model stops explaining the measurements): per unit of `V_b` for the
    /// back-EMF estimators, of `I_b` for the current-model MRAS.
    pub health: i32,
    /// 1 when the modulator limited the voltage at the last step.
    pub saturated: u32,
}

/// The last initial position detection (`pmsm_get_ipd`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct pmsm_ipd_t {
    /// 1 when a detection has completed since `pmsm_drive_init` (the fields below hold its
    /// result), 0 otherwise.
    pub found: u32,
    /// The detected electrical angle of the magnet's north pole from the axis of phase a,
    /// turn (2^32 = one turn; read as `uint32_t` it is in [0, 2^32)).
    pub theta: i32,
    /// The angle modulo pi from the short pulses, turn, in [-2^30, 2^30).
    pub theta_mod_pi: i32,
    /// Starting sector of Khlaief, Boussak, Gossa (2012) Table 2: 1 for [0, 60) degrees,
    /// ..., 6 for [300, 360).
    pub sector: u32,
    /// The five pulse peaks, Q8.24 pu: the short pulses along a, b, c, then the long ones
    /// along `theta_mod_pi` and opposite it.
    pub peaks: [i32; 5],
    /// A `pmsm_ipd_fault_t` while the drive is in `PMSM_FAULT_INITIAL_POSITION`, 0 otherwise.
    pub fault: u32,
    /// The measurements of that check, Q8.24 pu (see `pmsm_ipd_fault_t`), 0 if none.
    pub fault_value: [i32; 2],
}

/// What the drive's task has learnt (`pmsm_get_learned`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct pmsm_learned_t {
    /// 1 when the drive runs the tracker of `R` and `psi` (`pmsm_config_t.tracking`).
    pub tracking: u32,
    /// `R/R_0` as the drive's model is given it (`R_0` the configured `rs_ohm`), Q8.24 (1.0
    /// without the tracker).
    pub rs_ratio: i32,
    /// `psi/psi_0` likewise (`psi_0` the configured `flux_wb`), Q8.24.
    pub flux_ratio: i32,
    /// The tracker's updates that learnt since `pmsm_drive_init`.
    pub tracker_updates: u32,
    /// 1 when the drive runs the learner of the inverter's distortion
    /// (`pmsm_config_t.deadtime_learning`).
    pub deadtime_learning: u32,
    /// The dead-time compensation's `V_dead` over the configured one, Q8.24 (1.0 until a
    /// calibration or the learner measured it).
    pub deadtime_scale: i32,
}

/// Per-unit bases of a drive, SI (for logs and conversions outside the ISR).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct pmsm_bases_t {
    /// 1 pu current `I_b`, A peak.
    pub current_a: f64,
    /// 1 pu voltage `V_b = vdc / sqrt(3)`, V.
    pub voltage_v: f64,
    /// 1 pu speed `omega_b`, electrical rad/s.
    pub omega_e_rad_s: f64,
    /// Control sample period, s.
    pub sample_s: f64,
}

/// An integer conversion to Q8.24 per unit: `pu = (x * gain) >> shift`, rounded to nearest
/// and saturated (`pmsm_scale_apply`). For ADC codes, subtract the offset first.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct pmsm_scale_t {
    /// Multiplier.
    pub gain: i32,
    /// Right shift, 0..62.
    pub shift: u32,
}

/// Samples per task period: `pmsm_step` sets `pmsm_output_t.task_due` once per this many
/// steps, and `pmsm_task` must return within as many sample periods.
pub const PMSM_TASK_PERIOD: u32 = 8;
const _: () = assert!(PMSM_TASK_PERIOD == pmsm_core::TASK_PERIOD);

/// Depth of the fault recorder every drive carries, samples (`pmsm_fault_record_get`).
///
/// 64 samples: 4.6 ms at 14 kHz, 6.4 ms at 10 kHz: the trip and the few milliseconds before
/// it, several current-loop rise times, enough to tell a current spike from a loop gone
/// unstable or an estimate running away. A sample is 44 bytes, so the recorder takes 2.8 KiB
/// beside the drive's 3.4 KiB (both rates) in `PMSM_STORAGE_SIZE`; one electrical period at
/// low speed (a thousand samples and more) would not fit the RAM of the small parts this
/// library targets.
pub const PMSM_FAULT_RECORD_DEPTH: usize = 64;

/// One sample of the fault recorder (`pmsm_fault_record_get`): what a `pmsm_step` was given
/// and what it computed, as the drive's own integer words (a record replays bit for bit
/// through the same fixed-point code on the host).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct pmsm_fault_sample_t {
    /// Phase current a given to the step (`pmsm_input_t.i_a`), Q8.24 per unit of `I_b`.
    pub i_a: i32,
    /// Phase current b given to the step, Q8.24 per unit of `I_b`.
    pub i_b: i32,
    /// Phase current c given to the step, Q8.24 per unit of `I_b`.
    pub i_c: i32,
    /// Bus voltage given to the step, Q8.24 per unit of `V_b`.
    pub vdc: i32,
    /// Voltage the step commanded (applied over the next period), alpha (along phase a),
    /// Q8.24 per unit of `V_b`. A step that computes none (idle, fault, and the one that
    /// trips) leaves the last one commanded; the outputs are off then.
    pub v_alpha: i32,
    /// Voltage the step commanded, beta (90 degrees ahead of alpha), Q8.24 per unit of `V_b`.
    pub v_beta: i32,
    /// The estimator's rotor angle after the step, turn (2^32 = one electrical turn).
    pub theta_est: i32,
    /// The estimator's electrical speed after the step, Q8.24 per unit of `omega_b`.
    pub omega_est: i32,
    /// The `pmsm_state_t` after the step (`PMSM_STATE_FAULT` in the last sample of a frozen
    /// record).
    pub state: u32,
}

/// Size of static storage that holds a drive and its fault recorder on every supported
/// target, bytes. The C firmware can declare `static pmsm_storage_t storage;` (`sizeof` =
/// this, aligned to 8).
pub const PMSM_STORAGE_SIZE: usize = 8192;

/// `PMSM_STORAGE_SIZE / 8`: the `uint64_t` words of `pmsm_storage_t`.
pub const PMSM_STORAGE_WORDS: usize = 1024;

/// Statically allocatable storage for one drive: `static pmsm_storage_t storage;` then
/// `pmsm_drive_init(&storage, sizeof storage, &config, &drive)`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct pmsm_storage_t {
    /// The bytes, as `uint64_t` for 8-byte alignment.
    pub words: [u64; PMSM_STORAGE_WORDS],
}
