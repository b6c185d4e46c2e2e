//! The narrow hardware traits a board binding implements (embedded-hal has no motor-control
//! PWM or ADC traits), and one control interrupt's work over them.
//!
//! A binding (`pmsm-stm32` for the STM32G4) implements [`ThreePhasePwm`] for its timer and
//! [`PhaseCurrentSampler`] for its ADC; its control interrupt calls [`control_step`] (the
//! drive's interrupt side) and pends its task when [`DriveIsr::task_due`]. Neither
//! trait has an error path: a timer or an ADC that cannot do its job is a configuration
//! problem of the binding's constructor, and a bad sample is the drive's to judge (its
//! current-sensor checks).
//!
//! [`DutyCyclePwm`] implements [`ThreePhasePwm`] over three embedded-hal 1.0 `SetDutyCycle`
//! channels and an enable `OutputPin`, so any embedded-hal HAL's complementary PWM drives the
//! core.

mod embedded;
pub use embedded::{DutyCyclePwm, PwmErrors};

use crate::drive::{DriveInput, DriveIsr, DriveOutput, Handoff};
use crate::svpwm::Duties;

/// A three-phase inverter driven by complementary PWM.
pub trait ThreePhasePwm {
    /// Sets the leg duties for the next PWM period (preloaded: applied at the next update).
    fn set_duties(&mut self, duties: &Duties);
    /// Turns the outputs on (after a break or a `disable`).
    fn enable(&mut self);
    /// Turns every switch off.
    fn disable(&mut self);
    /// True while the outputs are switching.
    fn is_enabled(&self) -> bool;
}

/// The measurements of one control sample (phase currents and bus voltage, per unit), taken
/// at the PWM centre.
pub trait PhaseCurrentSampler {
    /// The sample that triggered this control interrupt.
    fn sample(&mut self) -> DriveInput;
}

/// One control interrupt: sample, step the drive's interrupt side, apply its output (duties
/// first, then the outputs on; or the outputs off). When [`DriveIsr::task_due`] after it,
/// the binding pends the task that runs [`crate::DriveTask::step`] on the same `handoff`.
pub fn control_step<P: ThreePhasePwm, S: PhaseCurrentSampler>(
    isr: &mut DriveIsr,
    handoff: &Handoff,
    pwm: &mut P,
    sampler: &mut S,
) -> DriveOutput {
    let input = sampler.sample();
    let out = isr.step(handoff, &input);
    apply(pwm, &out);
    out
}

/// Applies a drive output to the inverter.
pub fn apply<P: ThreePhasePwm>(pwm: &mut P, out: &DriveOutput) {
    if out.pwm_on {
        pwm.set_duties(&out.duties);
        if !pwm.is_enabled() {
            pwm.enable();
        }
    } else if pwm.is_enabled() {
        pwm.disable();
    }
}
