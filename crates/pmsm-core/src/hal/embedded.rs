//! [`ThreePhasePwm`] over embedded-hal 1.0: three [`SetDutyCycle`] channels (the high sides of
//! a complementary timer; the HAL drives the low sides and inserts the dead time) and an
//! [`OutputPin`] that enables the gate driver (or the timer's main output).
//!
//! | quantity | unit, format | range |
//! |---|---|---|
//! | leg duty in ([`Duties`]) | Q2.30, fraction of the period | [0, 1] (outside: saturated) |
//! | duty out (`set_duty_cycle`) | timer ticks | [0, `max_duty_cycle()`] |
//!
//! Scaling: `ticks = round(d · max_duty_cycle())` with halves rounded up, computed exactly in
//! 64-bit integers ([`Duties::to_compare`]), so a tick is within ½ tick of the exact product;
//! a duty below 0 gives 0 ticks and one above 1 gives `max_duty_cycle()` (saturation, never a
//! wrap). `max_duty_cycle()` is read at each update, so a HAL that changes its period stays
//! right.
//!
//! Errors: [`ThreePhasePwm`] has no error path (the control step cannot stop to handle one),
//! so the adapter never panics and never drops an error silently: it counts each failed call
//! per channel and for the enable pin ([`PwmErrors`], saturating counters), and remembers the
//! enable state it could not reach: a failed `disable` leaves [`is_enabled`] true, so the
//! next [`apply`] tries again, and a failed `enable` leaves it false. The caller reads
//! [`DutyCyclePwm::errors`] outside the control step and decides (for instance stops the
//! drive or latches a fault).
//!
//! [`is_enabled`]: ThreePhasePwm::is_enabled
//! [`apply`]: super::apply

use embedded_hal::digital::OutputPin;
use embedded_hal::pwm::SetDutyCycle;

use super::ThreePhasePwm;
use crate::svpwm::Duties;

/// Failed embedded-hal calls since the last [`DutyCyclePwm::clear_errors`] (saturating).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PwmErrors {
    /// `set_duty_cycle` failures of legs a, b, c.
    pub duty: [u32; 3],
    /// `set_high`/`set_low` failures of the enable pin.
    pub enable: u32,
}

impl PwmErrors {
    /// True if any call failed.
    pub fn any(&self) -> bool {
        self.enable != 0 || self.duty.iter().any(|&n| n != 0)
    }
}

/// Three embedded-hal PWM channels (legs a, b, c) and an active-high enable pin as one
/// [`ThreePhasePwm`]. Starts disabled: [`DutyCyclePwm::new`] drives the pin low.
#[derive(Debug)]
pub struct DutyCyclePwm<A, B, C, E> {
    a: A,
    b: B,
    c: C,
    enable: E,
    enabled: bool,
    errors: PwmErrors,
}

impl<A, B, C, E> DutyCyclePwm<A, B, C, E>
where
    A: SetDutyCycle,
    B: SetDutyCycle,
    C: SetDutyCycle,
    E: OutputPin,
{
    /// Takes the channels and the enable pin, and drives the pin low (outputs off); a failure
    /// of that first `set_low` is counted like any other.
    pub fn new(a: A, b: B, c: C, enable: E) -> Self {
        let mut pwm = Self {
            a,
            b,
            c,
            enable,
            enabled: true,
            errors: PwmErrors::default(),
        };
        pwm.disable();
        pwm
    }

    /// The failed calls counted so far.
    pub fn errors(&self) -> PwmErrors {
        self.errors
    }

    /// Resets the error counters.
    pub fn clear_errors(&mut self) {
        self.errors = PwmErrors::default();
    }

    /// Gives the channels and the pin back.
    pub fn release(self) -> (A, B, C, E) {
        (self.a, self.b, self.c, self.enable)
    }
}

/// `d · max_duty_cycle()` in ticks, rounded and saturated.
fn set_leg<P: SetDutyCycle>(ch: &mut P, duty: crate::num::Unit, errors: &mut u32) {
    let max = ch.max_duty_cycle();
    let d = Duties {
        a: duty,
        ..Duties::LOW
    };
    let [ticks, _, _] = d.to_compare(max);
    if ch.set_duty_cycle(ticks).is_err() {
        *errors = errors.saturating_add(1);
    }
}

impl<A, B, C, E> ThreePhasePwm for DutyCyclePwm<A, B, C, E>
where
    A: SetDutyCycle,
    B: SetDutyCycle,
    C: SetDutyCycle,
    E: OutputPin,
{
    fn set_duties(&mut self, duties: &Duties) {
        let [ea, eb, ec] = &mut self.errors.duty;
        set_leg(&mut self.a, duties.a, ea);
        set_leg(&mut self.b, duties.b, eb);
        set_leg(&mut self.c, duties.c, ec);
    }

    fn enable(&mut self) {
        match self.enable.set_high() {
            Ok(()) => self.enabled = true,
            Err(_) => self.errors.enable = self.errors.enable.saturating_add(1),
        }
    }

    fn disable(&mut self) {
        match self.enable.set_low() {
            Ok(()) => self.enabled = false,
            Err(_) => self.errors.enable = self.errors.enable.saturating_add(1),
        }
    }

    fn is_enabled(&self) -> bool {
        self.enabled
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drive::DriveOutput;
    use crate::hal::apply;
    use crate::num::Unit;
    use embedded_hal::digital::{self, ErrorType as PinErrorType};
    use embedded_hal::pwm::{self, ErrorType};

    /// A PWM channel that keeps the last duty, or fails every call while `fail` is set.
    struct Channel {
        max: u16,
        duty: u16,
        fail: bool,
    }

    impl ErrorType for Channel {
        type Error = pwm::ErrorKind;
    }

    impl SetDutyCycle for Channel {
        fn max_duty_cycle(&self) -> u16 {
            self.max
        }
        fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Self::Error> {
            if self.fail {
                return Err(pwm::ErrorKind::Other);
            }
            assert!(duty <= self.max, "duty {duty} above max {}", self.max);
            self.duty = duty;
            Ok(())
        }
    }

    /// An enable pin that logs its levels (1 high, 0 low) in order.
    struct Pin {
        log: [u8; 16],
        n: usize,
        fail: bool,
    }

    impl PinErrorType for Pin {
        type Error = digital::ErrorKind;
    }

    impl OutputPin for Pin {
        fn set_low(&mut self) -> Result<(), Self::Error> {
            self.level(0)
        }
        fn set_high(&mut self) -> Result<(), Self::Error> {
            self.level(1)
        }
    }

    impl Pin {
        fn level(&mut self, l: u8) -> Result<(), digital::ErrorKind> {
            if self.fail {
                return Err(digital::ErrorKind::Other);
            }
            self.log[self.n] = l;
            self.n += 1;
            Ok(())
        }
        fn levels(&self) -> &[u8] {
            &self.log[..self.n]
        }
    }

    fn ch(max: u16) -> Channel {
        Channel {
            max,
            duty: u16::MAX,
            fail: false,
        }
    }

    fn pin() -> Pin {
        Pin {
            log: [9; 16],
            n: 0,
            fail: false,
        }
    }

    #[test]
    fn duties_scale_to_ticks_within_half_a_tick() {
        // 4250: TIM1 centre-aligned at 20 kHz from 170 MHz; 1 and u16::MAX: the extremes.
        for max in [1u16, 7, 1000, 4250, 65535] {
            let mut p = DutyCyclePwm::new(ch(max), ch(max), ch(max), pin());
            let mut worst = 0.0f64;
            for k in 0..=2000u32 {
                let bits = ((1u64 << 30) * u64::from(k) / 2000) as i32 + (k as i32 % 7) - 3;
                let d = Unit::from_bits(bits.clamp(0, 1 << 30));
                let third = Unit::from_bits((1 << 30) - d.to_bits());
                p.set_duties(&Duties {
                    a: d,
                    b: third,
                    c: Unit::from_bits(1 << 29),
                });
                let exact = d.to_num::<f64>() * f64::from(max);
                let exact_b = third.to_num::<f64>() * f64::from(max);
                worst = worst
                    .max((f64::from(p.a.duty) - exact).abs())
                    .max((f64::from(p.b.duty) - exact_b).abs());
                assert!(p.c.duty == max / 2 || p.c.duty == max.div_ceil(2));
            }
            assert!(worst <= 0.5 + 1e-9, "max {max}: worst error {worst} ticks");
        }
        assert_eq!(
            PwmErrors::default(),
            PwmErrors {
                duty: [0; 3],
                enable: 0
            }
        );
    }

    #[test]
    fn duties_outside_zero_one_saturate() {
        let mut p = DutyCyclePwm::new(ch(4250), ch(4250), ch(4250), pin());
        p.set_duties(&Duties {
            a: Unit::from_num(-0.25),
            b: Unit::from_num(1.5),
            c: Unit::MAX,
        });
        assert_eq!([p.a.duty, p.b.duty, p.c.duty], [0, 4250, 4250]);
        assert!(!p.errors().any());
    }

    #[test]
    fn apply_sets_duties_before_enable_and_disables_once() {
        let mut p = DutyCyclePwm::new(ch(100), ch(100), ch(100), pin());
        assert!(!p.is_enabled());
        let on = DriveOutput {
            duties: Duties {
                a: Unit::from_num(0.25),
                b: Unit::from_num(0.5),
                c: Unit::from_num(0.75),
            },
            pwm_on: true,
        };
        let off = DriveOutput {
            duties: Duties::LOW,
            pwm_on: false,
        };
        apply(&mut p, &off); // already off: no pin write
        apply(&mut p, &on);
        assert_eq!([p.a.duty, p.b.duty, p.c.duty], [25, 50, 75]);
        apply(&mut p, &on); // already on: duties only
        apply(&mut p, &off);
        apply(&mut p, &off);
        apply(&mut p, &on);
        assert!(p.is_enabled());
        // new() low; enable; disable; enable.
        assert_eq!(p.enable.levels(), &[0, 1, 0, 1]);
        assert!(!p.errors().any());
    }

    #[test]
    fn failures_are_counted_and_the_enable_state_is_retried() {
        let mut p = DutyCyclePwm::new(ch(100), ch(100), ch(100), pin());
        p.b.fail = true;
        p.set_duties(&Duties::HALF);
        p.set_duties(&Duties::HALF);
        assert_eq!(p.errors().duty, [0, 2, 0]);
        assert_eq!((p.a.duty, p.c.duty), (50, 50));

        p.enable.fail = true;
        p.enable();
        assert!(
            !p.is_enabled(),
            "a failed enable must not report the outputs on"
        );
        p.enable.fail = false;
        p.enable();
        assert!(p.is_enabled());
        p.enable.fail = true;
        p.disable();
        assert!(
            p.is_enabled(),
            "a failed disable keeps the outputs reported on, so apply retries"
        );
        assert_eq!(p.errors().enable, 2);
        p.enable.fail = false;
        apply(
            &mut p,
            &DriveOutput {
                duties: Duties::LOW,
                pwm_on: false,
            },
        );
        assert!(!p.is_enabled());
        assert_eq!(p.enable.levels(), &[0, 1, 0]);
        assert!(p.errors().any());
        p.clear_errors();
        assert_eq!(p.errors(), PwmErrors::default());
    }
}
