//! Register values that the `hw` module writes, as pure functions (bit positions from RM0440
//! rev 8 and the `stm32g4` 0.16 PAC's field documentation), tested on the host.

// Zero-valued fields are spelled out (`0b00 << 2 // VP_SEL = VINP0`): they document the choice.
#![allow(clippy::identity_op)]

/// TIM1_CR1: centre-aligned mode 1 (CMS = 01), auto-reload preload (ARPE), `CKD`; counter
/// off (CEN is set separately).
pub fn tim1_cr1(ckd: u8) -> u32 {
    (0b01 << 5) | (1 << 7) | ((ckd as u32 & 0b11) << 8)
}

/// TIM1_CR2: MMS2 = 0111 (TRGO2 = OC4REF), idle states low (OISx = OISxN = 0).
pub const TIM1_CR2: u32 = 0b0111 << 20;

/// Output-compare mode PWM 1 (`0110`): active while CNT < CCR.
const OCM_PWM1: u32 = 0b0110;
/// Output-compare mode PWM 2 (`0111`): inactive while CNT < CCR.
const OCM_PWM2: u32 = 0b0111;

/// TIM1_CCMR1: channels 1 and 2 in PWM mode 1 with preload (OCxPE).
pub const TIM1_CCMR1: u32 = (OCM_PWM1 << 4) | (1 << 3) | (OCM_PWM1 << 12) | (1 << 11);

/// TIM1_CCMR2: channel 3 in PWM mode 1 with preload; channel 4 in PWM mode 2 with preload,
/// so that OC4REF (TRGO2) rises when the counter passes CCR4 on its way up: with
/// CCR4 = ARR − 1, one timer clock before the peak, the centre of the low-side conduction.
pub const TIM1_CCMR2: u32 = (OCM_PWM1 << 4) | (1 << 3) | (OCM_PWM2 << 12) | (1 << 11);

/// TIM1_CCER: CC1E, CC1NE, CC2E, CC2NE, CC3E, CC3NE, all active high (the L6387 inputs are
/// active high). CH4 drives no pin.
pub const TIM1_CCER: u32 = (1 << 0) | (1 << 2) | (1 << 4) | (1 << 6) | (1 << 8) | (1 << 10);

/// TIM1_BDTR without MOE: dead time `dtg`, OSSR = OSSI = 1 (off-state outputs driven to the
/// idle level, low: both switches of a leg off), break enabled (BKE) with polarity
/// `break_active_high`, automatic output enable off (after a break the outputs stay off until
/// software sets MOE again), break filter `bkf` (0–15).
pub fn tim1_bdtr(dtg: u8, break_active_high: bool, bkf: u8) -> u32 {
    dtg as u32
        | (1 << 10)
        | (1 << 11)
        | (1 << 12)
        | ((break_active_high as u32) << 13)
        | ((bkf as u32 & 0xF) << 16)
}

/// TIMx_BDTR.MOE.
pub const BDTR_MOE: u32 = 1 << 15;

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

/// TIM1_AF1 for a break source (BKINE bit 0, BKCMPxE bits 1–7; input polarities left at
/// reset: not inverted).
pub fn tim1_af1(src: BreakSource) -> u32 {
    match src {
        BreakSource::SoftwareOnly => 0,
        BreakSource::Pin => 1,
        BreakSource::Comparators(m) => ((m as u32) & 0x7F) << 1,
    }
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

/// ADC12_CCR: CKMODE = 11 (synchronous, HCLK / 4 = 42.5 MHz at 170 MHz; the ADC clock
/// must stay ≤ 60 MHz), independent mode.
pub const ADC12_CCR: u32 = 0b11 << 16;

/// PGA gain codes (OPAMPx_CSR.PGA_GAIN\[2:0\]): non-inverting gain 2, 4, 8, 16, 32, 64 (or
/// inverting −1 ... −63).
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

/// OPAMPx_CSR for PGA mode on VINP0 with the gain network's bottom on VINM0 (bias/filtering:
/// PGA_GAIN\[4:3\] = 10, HAL's `OPAMP_PGA_CONNECT_INVERTINGINPUT_IO0_BIAS`), high-speed mode,
/// output routed internally to the ADC (OPAINTOEN), factory trimming, enabled.
pub fn opamp_csr_pga(gain: PgaGain) -> u32 {
    let pga = (0b10 << 3) | gain as u32;
    1 // OPAEN
        | (0b00 << 2) // VP_SEL = VINP0
        | (0b10 << 5) // VM_SEL = PGA mode
        | (1 << 7) // OPAHSM
        | (1 << 8) // OPAINTOEN
        | (pga << 14)
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
    fn timer_registers() {
        assert_eq!(tim1_cr1(0), 0x00A0);
        assert_eq!(tim1_cr1(1), 0x01A0);
        assert_eq!(TIM1_CR2, 0x0070_0000);
        assert_eq!(TIM1_CCMR1, 0x6868);
        assert_eq!(TIM1_CCMR2, 0x7868);
        assert_eq!(TIM1_CCER, 0x0555);
        // DTG 85, OSSI, OSSR, BKE, active low, no filter.
        assert_eq!(tim1_bdtr(85, false, 0), 0x1C55);
        assert_eq!(tim1_bdtr(85, true, 3), 0x0003_3C55);
        assert_eq!(tim1_bdtr(0, false, 0) & BDTR_MOE, 0);
        assert_eq!(tim1_af1(BreakSource::SoftwareOnly), 0);
        assert_eq!(tim1_af1(BreakSource::Pin), 1);
        assert_eq!(tim1_af1(BreakSource::Comparators(0b101)), 0b1010);
    }

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
        assert_eq!(ADC12_CCR, 0x0003_0000);
    }

    #[test]
    fn opamp_register() {
        // HAL: PGA mode (VM_SEL = 10), VINP0, high speed, internal output, gain 16 with
        // VINM0 bias: PGA_GAIN = 0b10011.
        let v = opamp_csr_pga(PgaGain::X16);
        assert_eq!(v, 1 | (0b10 << 5) | (1 << 7) | (1 << 8) | (0b10011 << 14));
        assert_eq!(v, 0x0004_C1C1);
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
