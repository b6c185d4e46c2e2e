//! One numeric code per state and per fault, shared by every interface that has to put them in
//! a word: the C library, the board firmware's logs and the processor-in-the-loop records.
//! The values are part of those interfaces: never renumber, only add.

use super::{DriveState, Fault};
use crate::ipd::IpdFault;

impl DriveState {
    /// `Idle` 0, `Ipd` 1, `Align` 2, `OpenLoop` 3, `Run` 4, `Fault` 5.
    pub const fn code(&self) -> u8 {
        match self {
            DriveState::Idle => 0,
            DriveState::Ipd => 1,
            DriveState::Align => 2,
            DriveState::OpenLoop => 3,
            DriveState::Run => 4,
            DriveState::Fault(_) => 5,
        }
    }

    /// The fault's code ([`Fault::code`]) in `Fault`, 0 in every other state.
    pub const fn fault_code(&self) -> u8 {
        match self {
            DriveState::Fault(f) => f.code(),
            _ => 0,
        }
    }
}

impl Fault {
    /// 0 is "no fault"; `OverCurrent` 1, `BusUnderVoltage` 2, `BusOverVoltage` 3,
    /// `InitialPosition` 4, `Handover` 5, `CurrentSensor` 6, `PhaseLoss` 7, `Stall` 8,
    /// `LossOfLock` 9, `Overrun` 10, `Overspeed` 11, `DrivenBackwards` 12.
    pub const fn code(&self) -> u8 {
        match self {
            Fault::OverCurrent(_) => 1,
            Fault::BusUnderVoltage(_) => 2,
            Fault::BusOverVoltage(_) => 3,
            Fault::InitialPosition(_) => 4,
            Fault::Handover(_, _) => 5,
            Fault::CurrentSensor(_) => 6,
            Fault::PhaseLoss(_) => 7,
            Fault::Stall => 8,
            Fault::LossOfLock => 9,
            Fault::Overrun => 10,
            Fault::Overspeed(_) => 11,
            Fault::DrivenBackwards => 12,
        }
    }
}

impl IpdFault {
    /// Which check of the initial position detection failed: `OverCurrent` 1, `NoCurrent` 2,
    /// `LowSaliency` 3, `NoPolarity` 4, `BusLow` 5.
    pub const fn code(&self) -> u8 {
        match self {
            IpdFault::OverCurrent(_) => 1,
            IpdFault::NoCurrent(_) => 2,
            IpdFault::LowSaliency { .. } => 3,
            IpdFault::NoPolarity { .. } => 4,
            IpdFault::BusLow => 5,
        }
    }

    /// A short name (logs, CSV files).
    pub const fn name(&self) -> &'static str {
        match self {
            IpdFault::OverCurrent(_) => "overcurrent",
            IpdFault::NoCurrent(_) => "no_current",
            IpdFault::LowSaliency { .. } => "low_saliency",
            IpdFault::NoPolarity { .. } => "no_polarity",
            IpdFault::BusLow => "bus_low",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::angle::Angle;
    use crate::num::Pu;

    #[test]
    fn codes_are_distinct_and_nonzero() {
        let faults = [
            Fault::OverCurrent(Pu::ZERO),
            Fault::BusUnderVoltage(Pu::ZERO),
            Fault::BusOverVoltage(Pu::ZERO),
            Fault::InitialPosition(IpdFault::BusLow),
            Fault::Handover(Angle::ZERO, Pu::ZERO),
            Fault::CurrentSensor(None),
            Fault::PhaseLoss(0),
            Fault::Stall,
            Fault::LossOfLock,
            Fault::Overrun,
            Fault::Overspeed(Pu::ZERO),
            Fault::DrivenBackwards,
        ];
        for (k, f) in faults.iter().enumerate() {
            assert_eq!(usize::from(f.code()), k + 1, "{}", f.name());
            assert_eq!(DriveState::Fault(*f).fault_code(), f.code());
        }
        assert_eq!(DriveState::Run.fault_code(), 0);
        let states = [
            DriveState::Idle,
            DriveState::Ipd,
            DriveState::Align,
            DriveState::OpenLoop,
            DriveState::Run,
            DriveState::Fault(Fault::Stall),
        ];
        for (k, s) in states.iter().enumerate() {
            assert_eq!(usize::from(s.code()), k);
        }
        let ipd = [
            IpdFault::OverCurrent(Pu::ZERO),
            IpdFault::NoCurrent(Pu::ZERO),
            IpdFault::LowSaliency {
                modulation: Pu::ZERO,
                sum: Pu::ZERO,
            },
            IpdFault::NoPolarity {
                along: Pu::ZERO,
                opposite: Pu::ZERO,
            },
            IpdFault::BusLow,
        ];
        for (k, f) in ipd.iter().enumerate() {
            assert_eq!(usize::from(f.code()), k + 1, "{}", f.name());
        }
    }
}
