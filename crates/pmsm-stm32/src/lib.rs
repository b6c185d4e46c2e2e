//! Thin binding of `pmsm-core` to STM32G4 peripherals (register level, `stm32g4` PAC):
//!
//! - TIM1 centre-aligned complementary PWM at a configured frequency, dead time from the
//!   configured dead time ([`timing`]), break input turning the outputs off in hardware;
//! - ADC1/ADC2 injected conversions of the three phase currents and the bus voltage,
//!   triggered by TIM1 (TRGO2 = OC4REF just before the counter peak, the centre of the
//!   low-side conduction where low-side shunts carry the phase currents);
//! - OPAMP1/2/3 as PGA gain stages of the shunts;
//! - [`control_step`]: one control interrupt's work over the narrow traits
//!   [`ThreePhasePwm`] and [`PhaseCurrentSampler`].
//!
//! Everything except the `hw` module (bare-metal ARM only) is pure and tested on the host:
//! prescaler and period for a frequency, dead-time register encoding, ADC scaling to per unit,
//! offset calibration, the speed knob, and the register values the `hw` module writes.
//!
//! The traits are the core's ([`ThreePhasePwm`], [`PhaseCurrentSampler`], re-exported here);
//! this crate implements them for TIM1 and the ADCs.
#![no_std]

pub mod adc;
pub mod regs;
pub mod timing;

#[cfg(all(target_arch = "arm", target_os = "none"))]
#[allow(unsafe_code)]
pub mod hw;

pub use pmsm_core::{PhaseCurrentSampler, ThreePhasePwm, apply, control_step};

/// Control samples between a control step and the PWM period its duties act over on this
/// binding's TIM1: its drive wants `DriveOptions::pwm_delay_samples = Some(1)`.
///
/// The ADC samples at the counter's peak (TRGO2) and the interrupt writes the compare
/// registers a few µs later; they are preloaded (`OCxPE`), and the preload is transferred at
/// the update event, which with `RCR = 1` in centre-aligned mode comes once per period, at the
/// overflow (the peak), because RCR is written before the counter is started (RM0440 §28.3.3,
/// repetition counter: for odd RCR the update falls on the overflow if RCR was written
/// before the counter was launched, on the underflow otherwise). So the duties computed from
/// the sample at peak `k` load at peak `k + 1` and act over `[t_{k+1}, t_{k+2})`: one period
/// after the `[t_k, t_{k+1})` the drive assumes without delay (docs/drive.md, PWM update
/// delay).
pub const PWM_UPDATE_DELAY_SAMPLES: u8 = 1;

#[cfg(test)]
mod tests {
    use super::*;
    use pmsm_core::Abc;
    use pmsm_core::Pu;
    use pmsm_core::{
        Drive, DriveConfig, DriveInput, DriveIsr, DriveOptions, DriveState, DriveTask, Duties,
        Handoff, InverterParams, MotorParams, TASK_PERIOD,
    };

    #[derive(Default)]
    struct MockPwm {
        duties: Option<Duties>,
        on: bool,
        enables: u32,
        disables: u32,
    }

    impl ThreePhasePwm for MockPwm {
        fn set_duties(&mut self, d: &Duties) {
            self.duties = Some(*d);
        }
        fn enable(&mut self) {
            self.on = true;
            self.enables += 1;
        }
        fn disable(&mut self) {
            self.on = false;
            self.disables += 1;
        }
        fn is_enabled(&self) -> bool {
            self.on
        }
    }

    struct Fixed(DriveInput);

    impl PhaseCurrentSampler for Fixed {
        fn sample(&mut self) -> DriveInput {
            self.0
        }
    }

    /// The two sides of a drive and their handoff, as a firmware holds them.
    struct Parts {
        isr: DriveIsr,
        task: DriveTask,
        handoff: Handoff,
    }

    impl Parts {
        /// One control interrupt, and the task when it is due.
        fn step(&mut self, pwm: &mut MockPwm, s: &mut Fixed) -> pmsm_core::DriveOutput {
            let out = control_step(&mut self.isr, &self.handoff, pwm, s);
            if self.isr.task_due() {
                self.task.step(&self.handoff);
            }
            out
        }
    }

    fn parts() -> Parts {
        let (isr, task) = drive().into_parts();
        Parts {
            isr,
            task,
            handoff: Handoff::new(),
        }
    }

    fn drive() -> Drive {
        let mut m = MotorParams::new(4, 0.3, 0.6e-3, 1.0e-3, 0.01, 2e-5, 1e-5);
        m.rated_current_a = Some(5.0);
        let inv = InverterParams {
            vdc_v: 24.0,
            pwm_hz: 20e3,
            dead_time_s: 0.5e-6,
            current_full_scale_a: 60.0,
        };
        Drive::new(DriveConfig::from_params(&m, &inv, 20e3, DriveOptions::default()).unwrap())
    }

    /// Samples from a task-side call to the interrupt side's acting on it, at most.
    const FOLLOW: u32 = 2 * TASK_PERIOD;

    #[test]
    fn idle_drive_keeps_outputs_off_and_running_drive_switches() {
        let mut d = parts();
        let mut pwm = MockPwm::default();
        let vdc = Pu::from_num(1.732);
        let mut s = Fixed(DriveInput {
            i_abc: Abc::default(),
            vdc,
        });
        let out = d.step(&mut pwm, &mut s);
        assert!(!out.pwm_on);
        assert!(!pwm.on);
        assert_eq!(pwm.enables, 0);
        d.task.start();
        assert_ne!(d.task.state(), DriveState::Idle);
        // Started: the outputs switch (the detection's pulses, off between them).
        let mut switched = 0;
        for _ in 0..FOLLOW {
            let out = d.step(&mut pwm, &mut s);
            assert_eq!(out.pwm_on, pwm.on);
            switched += u32::from(pwm.on);
        }
        assert!(switched > 0 && d.isr.state() != DriveState::Idle);
        d.task.stop();
        for _ in 0..FOLLOW {
            d.step(&mut pwm, &mut s);
        }
        assert!(!pwm.on);
    }

    #[test]
    fn overcurrent_turns_outputs_off() {
        let mut d = parts();
        let mut pwm = MockPwm::default();
        let mut idle = Fixed(DriveInput {
            i_abc: Abc::default(),
            vdc: Pu::from_num(1.732),
        });
        d.task.start();
        for _ in 0..FOLLOW {
            d.step(&mut pwm, &mut idle);
        }
        let big = Pu::from_num(10);
        let mut s = Fixed(DriveInput {
            i_abc: Abc {
                a: big,
                b: -big,
                c: Pu::ZERO,
            },
            vdc: Pu::from_num(1.732),
        });
        pwm.on = true;
        let out = d.step(&mut pwm, &mut s);
        assert!(!out.pwm_on);
        assert!(!pwm.on);
        assert!(matches!(d.isr.state(), DriveState::Fault(_)));
    }
}
