//! What goes in and out of a [`Drive`]: a sample's measurements and the duties for the next
//! period, what the drive is doing and why it stopped, and what it computed (telemetry).

#[cfg(doc)]
use super::{ACTIVE_SHORT, Drive, DriveConfig, OpenLoopDesign};
use crate::angle::Angle;
use crate::frames::{Abc, AlphaBeta, Dq};
use crate::ipd::IpdFault;
use crate::num::Pu;
use crate::observer::Estimate;
use crate::svpwm::Duties;

/// Why the drive stopped switching. Latched until [`Drive::clear_fault`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    /// A phase current beyond the protection threshold (its value, per unit).
    OverCurrent(Pu),
    /// The bus voltage below its minimum (per unit).
    BusUnderVoltage(Pu),
    /// The bus voltage above its maximum (per unit).
    BusOverVoltage(Pu),
    /// The initial position detection failed.
    InitialPosition(IpdFault),
    /// At the end of the open-loop start the estimator disagreed with the imposed frame
    /// (angle difference, speed per unit).
    Handover(Angle, Pu),
    /// The three phase currents do not add up to zero (`None`), or one channel (0 = a, 1 = b,
    /// 2 = c) reads the same value while the others move: a current sensor is broken.
    CurrentSensor(Option<u8>),
    /// A phase (0 = a, 1 = b, 2 = c) carries no current while the others do: open winding,
    /// cable or switch.
    PhaseLoss(u8),
    /// The speed loop is at its current limit and the rotor far below the reference: stalled
    /// or locked.
    Stall,
    /// The estimator lost its lock: its speed changes faster than the motor can accelerate,
    /// its health figure is beyond its limit in steady state, the current loops no longer
    /// hold their references in the estimated frame, or its angle turns against its speed
    /// (docs/drive.md §3).
    LossOfLock,
    /// The control step did not finish within its period (reported by the binding).
    Overrun,
    /// The estimated speed is beyond what the drive can hold within the bus
    /// ([`DriveConfig::overspeed`]): a load drives the rotor so fast that its EMF would
    /// rectify into the bus. The inverter short-circuits the motor (all low-side switches
    /// on, [`ACTIVE_SHORT`]) until [`Drive::clear_fault`] or [`Drive::stop`].
    Overspeed(Pu),
    /// The speed loop pushes at its current limit in the reference's direction while the
    /// rotor turns the other way without slowing as that torque would make it: a load
    /// stronger than the drive (or an estimate of the wrong sign).
    DrivenBackwards,
}

impl Fault {
    /// A short name (CSV files, logs).
    pub fn name(&self) -> &'static str {
        match self {
            Fault::OverCurrent(_) => "overcurrent",
            Fault::BusUnderVoltage(_) => "bus_undervoltage",
            Fault::BusOverVoltage(_) => "bus_overvoltage",
            Fault::InitialPosition(_) => "initial_position",
            Fault::Handover(_, _) => "handover",
            Fault::CurrentSensor(_) => "current_sensor",
            Fault::PhaseLoss(_) => "phase_loss",
            Fault::Stall => "stall",
            Fault::LossOfLock => "loss_of_lock",
            Fault::Overrun => "overrun",
            Fault::Overspeed(_) => "overspeed",
            Fault::DrivenBackwards => "driven_backwards",
        }
    }
}

/// Why the closed loop does not run at the speed reference set ([`Drive::speed_ref_limit`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpeedRefLimit {
    /// The reference is below the least speed the back-EMF estimator can run at (the NLO, AO
    /// and MRAS on the EMF see no EMF at standstill; the least speed is the handover speed,
    /// [`OpenLoopDesign::handover_speed_rad_s`]): the closed loop holds `held`, that speed in
    /// the reference's direction, instead of `requested` (both electrical, per unit of `ω_b`).
    BelowEstimatorMinimum {
        /// The reference set.
        requested: Pu,
        /// The reference the speed loop gets.
        held: Pu,
    },
    /// The reference is beyond the drive's maximum speed ([`crate::FluxConfig::max_speed`],
    /// computed from the motor and the bus): the closed loop runs at `used`, that speed with
    /// the reference's sign, instead of `requested` (electrical, per unit of `ω_b`).
    AboveMaxSpeed {
        /// The reference set.
        requested: Pu,
        /// The reference used.
        used: Pu,
    },
    /// The speed loop gives all the current it may (its current limit, or the room the
    /// current circle leaves with field weakening): the rotor turns at what that torque
    /// allows against the load, `estimated` by the drive, not necessarily at `requested`
    /// (electrical, per unit of `ω_b`). A rotor far from `estimated` is a lost lock, not this.
    AtCurrentLimit {
        /// The reference set.
        requested: Pu,
        /// The estimated speed the speed loop sees.
        estimated: Pu,
    },
}

impl SpeedRefLimit {
    /// The reason, for logs: `below_estimator_minimum`, `above_max_speed` or
    /// `at_current_limit`.
    pub const fn name(&self) -> &'static str {
        match self {
            SpeedRefLimit::BelowEstimatorMinimum { .. } => "below_estimator_minimum",
            SpeedRefLimit::AboveMaxSpeed { .. } => "above_max_speed",
            SpeedRefLimit::AtCurrentLimit { .. } => "at_current_limit",
        }
    }
}

/// What the drive is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DriveState {
    /// Outputs off, waiting for [`Drive::start`].
    Idle,
    /// Detecting the initial position.
    Ipd,
    /// Pulling the rotor to `θ = 0`.
    Align,
    /// Open-loop current-vector start (back-EMF estimators).
    OpenLoop,
    /// Sensorless closed loop.
    Run,
    /// Outputs off after a fault.
    Fault(Fault),
}

/// One control sample's measurements, per unit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DriveInput {
    /// Phase currents sampled at the PWM centre, per unit of `I_b`.
    pub i_abc: Abc,
    /// DC bus voltage, per unit of `V_b` (√3 at the nominal bus).
    pub vdc: Pu,
}

/// What to do over the next PWM period.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriveOutput {
    /// Leg duties (meaningless when `pwm_on` is false).
    pub duties: Duties,
    /// Switch (true) or turn every switch off (false).
    pub pwm_on: bool,
}

/// What the drive computed at the last sample, for logs and plots.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Telemetry {
    /// The estimate.
    pub estimate: Estimate,
    /// The angle the controller used (the estimate, or the imposed frame while starting).
    pub theta: Angle,
    /// Measured current in the controller's frame.
    pub i_dq: Dq,
    /// Current reference.
    pub i_ref: Dq,
    /// Voltage commanded to the modulator after its limit, αβ.
    pub v: AlphaBeta,
    /// The modulator limited the voltage.
    pub saturated: bool,
    /// The estimator's health figure as the loss-of-lock check sees it (filtered over 10 ms by
    /// the task, zero outside the closed loop), per unit ([`crate::Estimator::health`]).
    pub health: Pu,
}
