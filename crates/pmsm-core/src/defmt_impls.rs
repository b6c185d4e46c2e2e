//! `defmt::Format` for the types that hold fixed-point words (feature `defmt`).
//!
//! The other public value types derive it. These are written by hand because `fixed`'s own
//! defmt support formats through `core::fmt` on the target (several KiB of flash and panic
//! paths in a firmware image); here every fixed-point field goes out as an `f32` that the
//! host formats (`{=f32}`: four bytes on the wire, one conversion on the target), angles as
//! their integer turn word, so a log costs what defmt is meant to cost.

use defmt::{Format, Formatter, write};

use crate::angle::SinCos;
use crate::drive::{DriveInput, Fault, Telemetry};
use crate::frames::{Abc, AlphaBeta, Dq};
use crate::ipd::{IpdFault, IpdResult};
use crate::num::{Pu, Unit};
use crate::observer::Estimate;
use crate::recorder::FaultSample;
use crate::svpwm::Duties;

fn pu(x: Pu) -> f32 {
    x.to_num()
}

fn unit(x: Unit) -> f32 {
    x.to_num()
}

impl Format for Fault {
    fn format(&self, f: Formatter<'_>) {
        // The faults without a payload, and those with one per-unit value, share one format
        // string each under their `Fault::name`: a string and its encoder per variant cost
        // the board's flash more than the name sent as text costs the link.
        match *self {
            Fault::OverCurrent(x)
            | Fault::BusUnderVoltage(x)
            | Fault::BusOverVoltage(x)
            | Fault::Overspeed(x) => write!(f, "{=str} ({=f32} pu)", self.name(), pu(x)),
            Fault::InitialPosition(e) => write!(f, "initial_position ({})", e),
            Fault::Handover(theta, w) => write!(
                f,
                "handover (θ {=i32} turn/2^32, ω {=f32} pu)",
                theta.0,
                pu(w)
            ),
            Fault::CurrentSensor(phase) => write!(f, "current_sensor (phase {})", phase),
            Fault::PhaseLoss(phase) => write!(f, "phase_loss (phase {=u8})", phase),
            Fault::Stall | Fault::LossOfLock | Fault::Overrun | Fault::DrivenBackwards => {
                write!(f, "{=str}", self.name())
            }
        }
    }
}

impl Format for Telemetry {
    fn format(&self, f: Formatter<'_>) {
        write!(
            f,
            "Telemetry {{ estimate: {}, theta: {=i32}, i_dq: {}, i_ref: {}, v: {}, saturated: {=bool}, health: {=f32} }}",
            self.estimate,
            self.theta.0,
            self.i_dq,
            self.i_ref,
            self.v,
            self.saturated,
            pu(self.health)
        )
    }
}

impl Format for IpdFault {
    fn format(&self, f: Formatter<'_>) {
        match *self {
            IpdFault::OverCurrent(i) => write!(f, "overcurrent ({=f32} pu)", pu(i)),
            IpdFault::NoCurrent(i) => write!(f, "no_current ({=f32} pu)", pu(i)),
            IpdFault::LowSaliency { modulation, sum } => write!(
                f,
                "low_saliency (modulation {=f32}, sum {=f32} pu)",
                pu(modulation),
                pu(sum)
            ),
            IpdFault::NoPolarity { along, opposite } => write!(
                f,
                "no_polarity (along {=f32}, opposite {=f32} pu)",
                pu(along),
                pu(opposite)
            ),
            IpdFault::BusLow => write!(f, "bus_low"),
        }
    }
}

impl Format for IpdResult {
    fn format(&self, f: Formatter<'_>) {
        let [a, b, c, d, e] = self.peaks.map(pu);
        write!(
            f,
            "IpdResult {{ θ {=i32}, sector {=u8}, θ mod π {=i32}, peaks [{=f32}, {=f32}, {=f32}, {=f32}, {=f32}] pu }}",
            self.theta.0, self.sector, self.theta_mod_pi.0, a, b, c, d, e
        )
    }
}

impl Format for Abc {
    fn format(&self, f: Formatter<'_>) {
        write!(
            f,
            "abc({=f32}, {=f32}, {=f32})",
            pu(self.a),
            pu(self.b),
            pu(self.c)
        )
    }
}

impl Format for AlphaBeta {
    fn format(&self, f: Formatter<'_>) {
        write!(f, "αβ({=f32}, {=f32})", pu(self.alpha), pu(self.beta))
    }
}

impl Format for Dq {
    fn format(&self, f: Formatter<'_>) {
        write!(f, "dq({=f32}, {=f32})", pu(self.d), pu(self.q))
    }
}

impl Format for SinCos {
    fn format(&self, f: Formatter<'_>) {
        write!(
            f,
            "SinCos {{ sin {=f32}, cos {=f32} }}",
            unit(self.sin),
            unit(self.cos)
        )
    }
}

impl Format for Estimate {
    fn format(&self, f: Formatter<'_>) {
        write!(
            f,
            "Estimate {{ θ {=i32}, ω {=f32}, emf {} }}",
            self.theta.0,
            pu(self.omega),
            self.emf
        )
    }
}

impl Format for DriveInput {
    fn format(&self, f: Formatter<'_>) {
        write!(
            f,
            "DriveInput {{ i {}, vdc {=f32} }}",
            self.i_abc,
            pu(self.vdc)
        )
    }
}

impl Format for Duties {
    fn format(&self, f: Formatter<'_>) {
        write!(
            f,
            "duties({=f32}, {=f32}, {=f32})",
            unit(self.a),
            unit(self.b),
            unit(self.c)
        )
    }
}

/// The raw words (bit-exact replay on the host), in the recorder's field order.
impl Format for FaultSample {
    fn format(&self, f: Formatter<'_>) {
        write!(
            f,
            "i {=i32} {=i32} {=i32} vdc {=i32} v {=i32} {=i32} θ {=i32} ω {=i32} state {=u8}",
            self.i_abc.a.to_bits(),
            self.i_abc.b.to_bits(),
            self.i_abc.c.to_bits(),
            self.vdc.to_bits(),
            self.v.alpha.to_bits(),
            self.v.beta.to_bits(),
            self.estimate.theta.0,
            self.estimate.omega.to_bits(),
            self.state
        )
    }
}

impl Format for crate::SpeedRefLimit {
    fn format(&self, f: Formatter) {
        match *self {
            crate::SpeedRefLimit::BelowEstimatorMinimum { requested, held } => write!(
                f,
                "below_estimator_minimum ({=f32} pu held at {=f32} pu)",
                pu(requested),
                pu(held)
            ),
            crate::SpeedRefLimit::AboveMaxSpeed { requested, used } => write!(
                f,
                "above_max_speed ({=f32} pu clamped to {=f32} pu)",
                pu(requested),
                pu(used)
            ),
            crate::SpeedRefLimit::AtCurrentLimit {
                requested,
                estimated,
            } => write!(
                f,
                "at_current_limit ({=f32} pu requested, {=f32} pu estimated)",
                pu(requested),
                pu(estimated)
            ),
        }
    }
}
