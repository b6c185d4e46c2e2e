//! Register values that the `hw` module writes and that are computed rather than named: ADC
//! sequences and sampling times, the PLL, flash wait states, and the two TIM1 codes the PAC
//! leaves numeric (bit positions from RM0440 rev 8), tested on the host. Single named fields
//! are written in `hw` through the `stm32g4` PAC's field API.

// Zero-valued fields are spelled out (`0b00 << 25 // PLLR = 2`): they document the choice.
#![allow(clippy::identity_op)]

/// TIM1_CR2.MMS2 = 0111: TRGO2 = OC4REF (the ADC trigger; no named value in the PAC).
pub const MMS2_OC4REF: u8 = 0b0111;

/// TIM1_BDTR.BKF: break filter `f_CK_INT`, N = 8 (RM0440 "BKF"): a glitch shorter than eight
/// timer clocks (47 ns) does not trip.
pub const BREAK_FILTER: u8 = 3;

/// Where TIM1's break (BRK) comes from (TIM1_AF1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BreakSource {
    /// Only the software break (EGR.BG) and the core's trips.
    SoftwareOnly,
    /// The TIM1_BKIN pin.
    Pin,
    /// Comparator outputs COMP1..COMP7 (bit 0 = COMP1), e.g. an over-current threshold.
    Comparators(u8),
}

/// ADC_JSQR: `channels` (1 to 4) converted in order on the rising edge of external trigger
/// `jextsel`. Returns `None` for an empty or too long sequence or a channel above 18.
pub fn adc_jsqr(jextsel: u8, channels: &[u8]) -> Option<u32> {
    if channels.is_empty() || channels.len() > 4 || jextsel > 31 {
        return None;
    }
    let mut v = (channels.len() as u32 - 1) | ((jextsel as u32) << 2) | (0b01 << 7);
    for (k, &ch) in channels.iter().enumerate() {
        if ch > 18 {
            return None;
        }
        v |= (ch as u32) << (9 + 6 * k);
    }
    Some(v)
}

/// JEXTSEL of TIM1_TRGO2 for ADC1/ADC2 (RM0440 table "ADC1 and ADC2 - External triggers for
/// injected channels": EXT8; HAL's `ADC_EXTERNALTRIGINJEC_T1_TRGO2` = JEXTSEL_3).
pub const JEXTSEL_TIM1_TRGO2: u8 = 8;

/// ADC_SMPR1/SMPR2 field value for 12.5 ADC clocks of sampling (`010`); at 42.5 MHz ADC
/// clock, 294 ns: enough for the OPAMP's low-impedance outputs and the bus divider.
pub const SMP_12_5: u32 = 0b010;

/// ADC_SMPRx values setting sampling time `smp` for `channels` (0–18): (SMPR1, SMPR2).
pub fn adc_smpr(channels: &[u8], smp: u32) -> (u32, u32) {
    let (mut r1, mut r2) = (0u32, 0u32);
    for &ch in channels {
        if ch < 10 {
            r1 |= (smp & 7) << (3 * ch as u32);
        } else if ch <= 18 {
            r2 |= (smp & 7) << (3 * (ch as u32 - 10));
        }
    }
    (r1, r2)
}

/// PGA gains (OPAMPx_CSR.PGA_GAIN\[2:0\], non-inverting 2 … 64 or inverting −1 … −63); `hw`
/// sets them with the network's bottom on VINM0.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PgaGain {
    /// 2 or −1.
    X2 = 0,
    /// 4 or −3.
    X4 = 1,
    /// 8 or −7.
    X8 = 2,
    /// 16 or −15.
    X16 = 3,
    /// 32 or −31.
    X32 = 4,
    /// 64 or −63.
    X64 = 5,
}

/// The main PLL of a 170 MHz system clock from an 8 MHz HSE: `/M = 2` (4 MHz in),
/// `×N = 85` (340 MHz VCO), `/R = 2` (170 MHz), R output enabled; source HSE.
pub const RCC_PLLCFGR_170MHZ_FROM_8MHZ: u32 = 0b11 // PLLSRC = HSE
    | ((2 - 1) << 4) // PLLM = 2
    | (85 << 8) // PLLN = 85
    | (1 << 24) // PLLREN
    | (0b00 << 25); // PLLR = 2

/// The same 170 MHz from HSI16 (fallback when the crystal does not start): `/M = 4`,
/// `×N = 85`, `/R = 2`; source HSI16.
pub const RCC_PLLCFGR_170MHZ_FROM_HSI16: u32 = 0b10 // PLLSRC = HSI16
    | ((4 - 1) << 4) // PLLM = 4
    | (85 << 8) // PLLN = 85
    | (1 << 24) // PLLREN
    | (0b00 << 25); // PLLR = 2

/// The system clock a PLLCFGR value makes from `hse_hz` (R output), Hz.
pub fn pll_r_hz(hse_hz: u32, pllcfgr: u32) -> u32 {
    let m = ((pllcfgr >> 4) & 0xF) + 1;
    let n = (pllcfgr >> 8) & 0x7F;
    let r = 2 * (((pllcfgr >> 25) & 0b11) + 1);
    (hse_hz as u64 * n as u64 / (m as u64 * r as u64)) as u32
}

/// Flash wait states for `hclk_hz` in range 1 boost mode (RM0440 table 9: 34 MHz per wait
/// state).
pub fn flash_latency(hclk_hz: u32) -> u32 {
    hclk_hz.saturating_sub(1) / 34_000_000
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adc_registers() {
        // Two conversions (L = 1), JEXTSEL 8, rising edge, IN13 then IN1.
        let v = adc_jsqr(JEXTSEL_TIM1_TRGO2, &[13, 1]).unwrap();
        assert_eq!(v, 1 | (8 << 2) | (1 << 7) | (13 << 9) | (1 << 15));
        assert_eq!(adc_jsqr(8, &[]), None);
        assert_eq!(adc_jsqr(8, &[1, 2, 3, 4, 5]), None);
        assert_eq!(adc_jsqr(8, &[19]), None);
        assert_eq!(adc_smpr(&[1, 13], SMP_12_5), (0b010 << 3, 0b010 << 9));
        assert_eq!(adc_smpr(&[16, 18], 7), (0, (7 << 18) | (7 << 24)));
    }

    #[test]
    fn clock_tree() {
        assert_eq!(
            pll_r_hz(8_000_000, RCC_PLLCFGR_170MHZ_FROM_8MHZ),
            170_000_000
        );
        assert_eq!(
            pll_r_hz(16_000_000, RCC_PLLCFGR_170MHZ_FROM_HSI16),
            170_000_000
        );
        assert_eq!(RCC_PLLCFGR_170MHZ_FROM_8MHZ & 0b11, 0b11);
        assert_eq!(RCC_PLLCFGR_170MHZ_FROM_HSI16 & 0b11, 0b10);
        // VCO 340 MHz within 96–344 MHz; PLL input 4 MHz within 2.66–8 MHz.
        assert_eq!(flash_latency(170_000_000), 4);
        assert_eq!(flash_latency(16_000_000), 0);
        assert_eq!(flash_latency(34_000_000), 0);
        assert_eq!(flash_latency(34_000_001), 1);
    }
}
