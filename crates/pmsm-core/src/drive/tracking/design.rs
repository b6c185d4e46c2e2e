//! The tracker's design in SI units and its defaults from the drive (docs/tracking.md).

use crate::drive::DriveConfig;
use crate::units::PerUnit;

/// How the tracker is designed, SI units; [`TrackerDesign::default_for`] gives the defaults.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackerDesign {
    /// Control samples between two calls of [`Tracker::update`](super::Tracker::update).
    pub interval_samples: u32,
    /// Least electrical speed at which the tracker learns, rad/s.
    pub min_speed_rad_s: f64,
    /// Largest distance of the measured current from its reference at which the tracker
    /// learns, A (either axis).
    pub max_current_error_a: f64,
    /// Time in `Run` before the tracker learns, s.
    pub settle_s: f64,
    /// Relative standard deviation of the model's `R` (prior).
    pub rs_sigma: f64,
    /// Relative standard deviation of the model's `ψ` (prior).
    pub flux_sigma: f64,
    /// `R̂/R₀` is kept within this range.
    pub rs_range: (f64, f64),
    /// `ψ̂/ψ₀` is kept within this range.
    pub flux_range: (f64, f64),
    /// Temperature coefficient of the winding's resistance, 1/K (copper 0.00393).
    pub rs_per_k: f64,
    /// Temperature coefficient of the magnet's flux, 1/K (NdFeB about −0.001, ferrite −0.002).
    pub flux_per_k: f64,
    /// Random walk of the temperature, K/√s.
    pub drift_k_per_sqrt_s: f64,
    /// Random walk of `R/R₀` and `ψ/ψ₀` apart from the temperature, 1/√s.
    pub independent_per_sqrt_s: f64,
    /// Noise of one measurement `y`, V.
    pub noise_v: f64,
    /// Largest electrical acceleration at which the tracker learns, rad/s² (of the speed
    /// estimate filtered over [`SPEED_FILTER_S`](super::SPEED_FILTER_S)): a ramp is not a steady state.
    pub max_accel_rad_s2: f64,
    /// Time constant of the low-pass from the filter's estimates to the values written to the
    /// drive, s: the estimates jitter at the update rate, and each write moves the MRAS's
    /// model current, which its adaptation reads as a speed error.
    pub apply_time_s: f64,
    /// Largest relative change of `R̂` or `ψ̂` per update (keeps the estimator's frame smooth
    /// while a large model error is learnt).
    pub max_step: f64,
    /// The voltage error the inverter may leave near zero current after the dead-time
    /// compensation, V: the dead-time voltage `V_dead` at the nominal bus (0: no such gate).
    pub inverter_error_v: f64,
    /// The dead-time compensation's current band, A: beyond it the residual error falls as
    /// `band/|i|` (the share of the period a phase spends near zero); `None` when the drive
    /// does not compensate (the whole `V_dead` everywhere).
    pub current_band_a: Option<f64>,
    /// Largest ratio of that residual to the EMF `|ω̂| ψ₀` at which the tracker learns.
    pub max_inverter_ratio: f64,
    /// Weight of the current's motion in the measurement noise: the noise grows by this many
    /// times the voltage `L_d |Δi_d| + L_q |Δi_q|` per update (over [`SPEED_FILTER_S`](super::SPEED_FILTER_S)).
    pub transient_weight: f64,
    /// Time constant of the low-pass on the current before its motion is taken, s (longer
    /// than the update interval, so that the sampling noise of a steady current does not
    /// count; shorter than a limit cycle's period).
    pub motion_filter_s: f64,
    /// Least ratio of the resistive drop `R₀ |n·î|` to the EMF `|ω̂| ψ₀` at which `R` is
    /// learnt (elsewhere only `ψ`): a bias of 1 % of the EMF in the measurement reads as an
    /// error of `R` of 1 %/ratio.
    pub rs_min_drop_ratio: f64,
}

impl TrackerDesign {
    /// An update every twice [`TRACKER_STAGES`](super::TRACKER_STAGES) task periods (the
    /// drive's [`Tracker::task_step`](super::Tracker::task_step) works in the first half of
    /// each cycle: half the task's mean cost of a working cycle on a Cortex-M0, whose `f32` is
    /// software); learning above 10 % of `ω_b`, the current within 0.2 `I_b` of its reference,
    /// the speed changing by less than `2 ω_b` per second, 10 ms after entering `Run`; the model's `R` within ±50 %, `ψ` within ±30 %
    /// (one standard deviation), kept within ×0.5…×2 and ±40 %; copper and NdFeB; 10 K/√s; 1 %
    /// of the base voltage of noise; 1 % per update at most; 20 ms of low-pass to the drive;
    /// the current's motion (low-passed over 4 ms) weighted 10 times; no inverter gate (see
    /// [`TrackerDesign::for_drive`]).
    pub fn default_for(base: &PerUnit) -> Self {
        Self {
            interval_samples: 2 * super::TRACKER_STAGES * crate::drive::TASK_PERIOD,
            min_speed_rad_s: 0.1 * base.omega_e_rad_s,
            max_current_error_a: 0.2 * base.current_a,
            max_accel_rad_s2: 2.0 * base.omega_e_rad_s,
            settle_s: 0.01,
            rs_sigma: 0.5,
            flux_sigma: 0.3,
            rs_range: (0.5, 2.0),
            flux_range: (0.6, 1.4),
            rs_per_k: 0.00393,
            flux_per_k: -0.001,
            drift_k_per_sqrt_s: 10.0,
            independent_per_sqrt_s: 0.003,
            noise_v: 0.01 * base.voltage_v,
            max_step: 0.01,
            apply_time_s: 0.02,
            inverter_error_v: 0.0,
            current_band_a: None,
            max_inverter_ratio: 0.1,
            transient_weight: 10.0,
            motion_filter_s: 0.004,
            rs_min_drop_ratio: 0.2,
        }
    }

    /// [`TrackerDesign::default_for`] the drive's bases, with the inverter gate from its
    /// dead-time compensation: the residual is its `V_dead` at the nominal bus, fading beyond
    /// its current band (or everywhere, without compensation); learning where it exceeds 10 %
    /// of the EMF. (Without the gate, 31 of the 200 healthy scenarios of `cargo xtask sweep`
    /// lost the lock with tracking on: the start's light-load ramps taught the filter the
    /// dead-time residue as a resistance and a flux.) Nor below the speed where the drive's
    /// low-speed d current has faded out (docs/drive.md, "low-speed current"): that current
    /// saturates the d axis, which the model does not know, and motor B's start with ψ 20 %
    /// high in the model taught the filter an `R̂` 22 % high there and lost its lock.
    pub fn for_drive(config: &DriveConfig) -> Self {
        let default = Self::default_for(&config.base);
        let low_speed = if config.design.low_speed_id_a > 0.0 {
            config.design.low_speed_fade_rad_s
        } else {
            0.0
        };
        Self {
            inverter_error_v: config.v_dead_nominal_v(),
            current_band_a: config
                .deadtime_compensation()
                .then_some(config.design.deadtime.band_a),
            min_speed_rad_s: default.min_speed_rad_s.max(low_speed),
            ..default
        }
    }
}
