//! B-G431B-ESC1 facts. Sources: ST UM2516 (the kit's user manual: pinout, 8 MHz crystal,
//! L6387 drivers, 3 mΩ shunts); the STM32G431 datasheet (DS12589, alternate functions) and
//! RM0440 (ADC channels of the OPAMP outputs); ST's and SimpleFOC's published board support
//! for this kit (OPAMPs in PGA mode, gain 16 with the external network on VINM0, overall
//! shunt-to-ADC gain −64/7 ≈ −9.14, potentiometer on PB12, bus divider on PA0). Where a value
//! could not be checked against the schematic it says so.
//!
//! | signal | pin | peripheral |
//! |---|---|---|
//! | U high / low | PA8 / PC13 | TIM1_CH1 (AF6) / TIM1_CH1N (AF4) |
//! | V high / low | PA9 / PA12 | TIM1_CH2 (AF6) / TIM1_CH2N (AF6) |
//! | W high / low | PA10 / PB15 | TIM1_CH3 (AF6) / TIM1_CH3N (AF4) |
//! | shunt U, V, W | PA1, PA7, PB0 | OPAMP1/2/3 VINP0 → ADC1_IN13, ADC2_IN16, ADC2_IN18 |
//! | bus voltage | PA0 | ADC1_IN1 |
//! | potentiometer | PB12 | ADC1_IN11 |
//! | user button | PC10 | GPIO input, pull-up, pressed = low (NOT VERIFIED against the schematic) |

pub use crate::sensing::{CURRENT, VBUS};
use pmsm_stm32::hw::InjectedChannels;
use pmsm_stm32::regs::{BreakSource, PgaGain};
use stm32g4::stm32g431 as pac;

/// The OPAMPs' PGA gain (the board's resistor network makes the overall −64/7).
pub const PGA_GAIN: PgaGain = PgaGain::X16;

/// ADC channels.
pub const CHANNELS: InjectedChannels = InjectedChannels {
    adc1: [13, 1],
    adc2: [16, 18],
    regular: 11,
};

/// The break input: software break only. The kit's over-current protection (ST's firmware
/// uses the internal comparators on the OPAMP outputs with a DAC threshold) is not set up
/// yet; `BreakSource::Comparators` is ready for it. The core's over-current trip (3 × rated
/// peak) turns the outputs off within one PWM period.
pub const BREAK: BreakSource = BreakSource::SoftwareOnly;

/// Sets `pin` of a GPIO port to alternate function `af`, very high speed.
macro_rules! alternate {
    ($gpio:expr, $pin:expr, $af:expr) => {{
        let (pin, af): (u32, u32) = ($pin, $af);
        // SAFETY (for the whole-register writes): only the bits of `pin` change.
        unsafe {
            $gpio
                .ospeedr()
                .modify(|r, w| w.bits(r.bits() | (0b11 << (2 * pin))));
            if pin < 8 {
                $gpio
                    .afrl()
                    .modify(|r, w| w.bits((r.bits() & !(0xF << (4 * pin))) | (af << (4 * pin))));
            } else {
                let s = 4 * (pin - 8);
                $gpio
                    .afrh()
                    .modify(|r, w| w.bits((r.bits() & !(0xF << s)) | (af << s)));
            }
            $gpio
                .moder()
                .modify(|r, w| w.bits((r.bits() & !(0b11 << (2 * pin))) | (0b10 << (2 * pin))));
        }
    }};
}

/// The six gate-driver inputs to TIM1. The analog inputs (PA0, PA1, PA7, PB0, PB12 and the
/// OPAMP VINM0 pins PA3, PA5, PB2) stay in their reset state, analog.
pub fn pwm_pins(gpioa: &pac::GPIOA, gpiob: &pac::GPIOB, gpioc: &pac::GPIOC) {
    // TIM1 is configured first, so with MOE = 0 (OSSI = 1) the pins drive the idle level,
    // low (both switches of each leg off), from the moment they switch over.
    alternate!(gpioa, 8, 6);
    alternate!(gpioa, 9, 6);
    alternate!(gpioa, 10, 6);
    alternate!(gpioa, 12, 6);
    alternate!(gpiob, 15, 4);
    alternate!(gpioc, 13, 4);
}

/// The user button's pin as an input with its pull-up.
pub fn button_pin(gpioc: &pac::GPIOC) {
    gpioc.pupdr().modify(|_, w| w.pupdr10().pull_up());
    gpioc.moder().modify(|_, w| w.moder10().input());
}

/// The user button is held down.
pub fn button_down(gpioc: &pac::GPIOC) -> bool {
    gpioc.idr().read().idr10().is_low()
}

/// Current limit of the commissioning run (A peak): the base of the identification's per
/// unit, its resistance levels are 30 to 60 % of it and it trips at 150 %. The board stands
/// 40 A peak; 1 A suits the kit's gimbal motor (rated 1.13 A peak) and keeps the current
/// well above the ADC's step (29 mA). Raise it for a larger motor (4 A for one rated near
/// 3 A RMS), never above the motor's rated peak current.
pub const COMMISSION_CURRENT_A: f64 = 1.0;

/// Polls (10 ms each) the button must be held for a long press (2 s): commissioning.
pub const LONG_PRESS_POLLS: u8 = 200;
