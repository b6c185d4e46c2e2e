//! The board's analog front end: what its ADC readings mean in amperes and volts. Apart from
//! `board.rs` (pins and peripherals) because `build.rs` reads it too, with `motor.rs`, to
//! design the drive on the host: the current's full scale is the inverter's.

use pmsm_stm32::adc::{AdcSpec, CurrentSensing, VoltageSensing};

/// The ADC: 12 bits, VREF+ = VDDA = 3.3 V.
pub const ADC: AdcSpec = AdcSpec {
    vref_v: 3.3,
    bits: 12,
};

/// Phase-current sensing: 3 mΩ low-side shunts, overall gain −64/7 (OPAMP PGA ×16 behind
/// the board's input network; negative: a positive phase current lowers the reading).
pub const CURRENT: CurrentSensing = CurrentSensing {
    adc: ADC,
    shunt_ohm: 0.003,
    gain: -64.0 / 7.0,
};

/// Bus voltage divider. NOT VERIFIED against the schematic: 169 kΩ over 18 kΩ (ratio
/// 0.0963, 34 V full scale, enough for the 6S battery the board is made for); check R and
/// correct this value, or the drive trips on bus under/over-voltage.
pub const VBUS: VoltageSensing = VoltageSensing {
    adc: ADC,
    divider: 18.0 / (169.0 + 18.0),
};
