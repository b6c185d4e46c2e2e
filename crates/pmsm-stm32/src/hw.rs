//! Register-level set-up and run-time access of the STM32G4 peripherals (bare-metal ARM
//! only), in the order the reference manual (RM0440) asks for. Single fields are written
//! through the PAC's named fields and values; the computed words (ADC sequences and sampling
//! times, the PLL, the flash wait states) come from [`crate::regs`], host-tested.
//!
//! `unsafe` here is the PAC's `bits` writes: whole-register values from `regs`, plain
//! numeric fields the PAC leaves unchecked, and the clock set-up.

use crate::adc::{RawSample, Scaling};
use crate::regs;
use crate::timing::{DeadTime, PwmTiming};
use crate::{PhaseCurrentSampler, ThreePhasePwm};
use pmsm_core::DriveInput;
use pmsm_core::Duties;
use stm32g4::stm32g431 as pac;

/// The system clock after [`clock_170mhz`], Hz.
pub const SYSCLK_HZ: u32 = 170_000_000;

/// Where the system clock came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClockSource {
    /// The HSE crystal (8 MHz on the B-G431B-ESC1).
    Hse,
    /// HSI16: the crystal did not start.
    Hsi16,
}

/// 170 MHz from an 8 MHz HSE through the PLL (range 1 boost mode, 4 flash wait states,
/// AHB/APB1/APB2 = 170 MHz); from HSI16 if the crystal does not start. RM0440 §6.1.5 (boost
/// mode entry: AHB / 2 while switching, 1 µs, then / 1).
pub fn clock_170mhz(rcc: &pac::RCC, pwr: &pac::PWR, flash: &pac::FLASH) -> ClockSource {
    // PWR clock, range 1 boost mode (R1MODE = 0).
    rcc.apb1enr1()
        .modify(|r, w| unsafe { w.bits(r.bits() | (1 << 28)) });
    pwr.cr5()
        .modify(|r, w| unsafe { w.bits(r.bits() & !(1 << 8)) });
    // Flash: wait states, prefetch, instruction and data caches.
    let lat = regs::flash_latency(SYSCLK_HZ);
    flash.acr().modify(|r, w| unsafe {
        w.bits((r.bits() & !0xF) | lat | (1 << 8) | (1 << 9) | (1 << 10))
    });
    while flash.acr().read().bits() & 0xF != lat {}
    // HSE, with a time-out.
    rcc.cr()
        .modify(|r, w| unsafe { w.bits(r.bits() | (1 << 16)) });
    let mut hse = false;
    for _ in 0..200_000 {
        if rcc.cr().read().bits() & (1 << 17) != 0 {
            hse = true;
            break;
        }
    }
    let (pllcfgr, src) = if hse {
        (regs::RCC_PLLCFGR_170MHZ_FROM_8MHZ, ClockSource::Hse)
    } else {
        rcc.cr()
            .modify(|r, w| unsafe { w.bits(r.bits() & !(1 << 16)) });
        (regs::RCC_PLLCFGR_170MHZ_FROM_HSI16, ClockSource::Hsi16)
    };
    rcc.pllcfgr().write(|w| unsafe { w.bits(pllcfgr) });
    rcc.cr()
        .modify(|r, w| unsafe { w.bits(r.bits() | (1 << 24)) });
    while rcc.cr().read().bits() & (1 << 25) == 0 {}
    // AHB / 2 (HPRE = 1000), APB1 = APB2 = / 1, switch to the PLL.
    rcc.cfgr()
        .modify(|r, w| unsafe { w.bits((r.bits() & !0x3FF3) | (0b1000 << 4) | 0b11) });
    while (rcc.cfgr().read().bits() >> 2) & 0b11 != 0b11 {}
    // ≥ 1 µs at 85 MHz.
    cortex_m::asm::delay(200);
    rcc.cfgr()
        .modify(|r, w| unsafe { w.bits(r.bits() & !(0xF << 4)) });
    src
}

/// Enables the clocks of GPIOA/B/C, ADC1/2, TIM1 and SYSCFG (which also clocks the OPAMPs).
pub fn enable_peripheral_clocks(rcc: &pac::RCC) {
    rcc.ahb2enr()
        .modify(|r, w| unsafe { w.bits(r.bits() | 0b111 | (1 << 13)) });
    rcc.apb2enr()
        .modify(|r, w| unsafe { w.bits(r.bits() | 1 | (1 << 11)) });
    // Read back: the clock is on before the first register access.
    let _ = rcc.apb2enr().read().bits();
}

/// OPAMP1/2/3 as PGA gain stages: VINP0 in, PGA mode with the gain network's bottom on
/// VINM0 (bias/filtering, HAL's `OPAMP_PGA_CONNECT_INVERTINGINPUT_IO0_BIAS`), high-speed
/// mode, output routed internally to the ADC, factory trimming, enabled.
pub fn opamps_pga(opamp: &pac::OPAMP, gain: regs::PgaGain) {
    macro_rules! pga {
        ($csr:ident) => {
            opamp.$csr().write(|w| {
                w.vp_sel().vinp0().vm_sel().pga().opahsm().set_bit();
                w.opaintoen().set_bit().opaen().set_bit();
                match gain {
                    regs::PgaGain::X2 => w.pga_gain().gain2_filtering_vinm0(),
                    regs::PgaGain::X4 => w.pga_gain().gain4_filtering_vinm0(),
                    regs::PgaGain::X8 => w.pga_gain().gain8_filtering_vinm0(),
                    regs::PgaGain::X16 => w.pga_gain().gain16_filtering_vinm0(),
                    regs::PgaGain::X32 => w.pga_gain().gain32_filtering_vinm0(),
                    regs::PgaGain::X64 => w.pga_gain().gain64_filtering_vinm0(),
                }
            })
        };
    }
    pga!(opamp1_csr);
    pga!(opamp2_csr);
    pga!(opamp3_csr);
}

/// TIM1 as a centre-aligned complementary three-phase PWM.
pub struct Tim1Pwm {
    tim: pac::TIM1,
    arr: u16,
}

impl Tim1Pwm {
    /// Configures TIM1 (outputs off: MOE = 0), sets TRGO2 to fire one clock before the
    /// counter peak, and starts the counter, so the ADC triggers run from now on.
    pub fn new(
        tim: pac::TIM1,
        timing: PwmTiming,
        dead: DeadTime,
        brk: regs::BreakSource,
        break_active_high: bool,
    ) -> Self {
        // Centre-aligned mode 1, auto-reload preload, dead-time clock; counter still off.
        tim.cr1().write(|w| {
            w.cms().center_aligned1().arpe().set_bit();
            match dead.ckd {
                0 => w.ckd().div1(),
                1 => w.ckd().div2(),
                _ => w.ckd().div4(),
            }
        });
        // TRGO2 = OC4REF; idle states low (OISx = OISxN = 0, the reset value).
        tim.cr2()
            .write(|w| unsafe { w.mms2().bits(regs::MMS2_OC4REF) });
        tim.psc().write(|w| w.psc().set(timing.psc));
        tim.arr().write(|w| w.arr().set(timing.arr as u32));
        // RCR = 1: in centre-aligned mode, one update (preload transfer) per PWM period.
        // Written before CEN, so the update falls on the overflow, the counter's peak where
        // the ADC samples (RM0440 §28.3.3): the compare values written by the interrupt after
        // sample k act from peak k + 1, one period late (`crate::PWM_UPDATE_DELAY_SAMPLES`,
        // docs/drive.md, PWM update delay). Keep this write before `cen` below.
        tim.rcr().write(|w| w.rep().set(1));
        // Legs in PWM mode 1 with preload; channel 4 in PWM mode 2 with preload, so that
        // OC4REF (TRGO2) rises when the counter passes CCR4 on its way up: with
        // CCR4 = ARR − 1, one timer clock before the peak, the centre of the low-side
        // conduction.
        tim.ccmr1_output().write(|w| {
            w.oc1m().pwm_mode1().oc1pe().set_bit();
            w.oc2m().pwm_mode1().oc2pe().set_bit()
        });
        tim.ccmr2_output().write(|w| {
            w.oc3m().pwm_mode1().oc3pe().set_bit();
            w.oc4m().pwm_mode2().oc4pe().set_bit()
        });
        let half = timing.arr as u32 / 2;
        tim.ccr1().write(|w| w.ccr().set(half));
        tim.ccr2().write(|w| w.ccr().set(half));
        tim.ccr3().write(|w| w.ccr().set(half));
        tim.ccr4()
            .write(|w| w.ccr().set((timing.arr as u32).saturating_sub(1)));
        // Break sources (input polarities left at reset: not inverted).
        let cmp = |k: u8| match brk {
            regs::BreakSource::Comparators(mask) => mask & (1 << k) != 0,
            _ => false,
        };
        tim.af1().write(|w| {
            w.bkine().bit(brk == regs::BreakSource::Pin);
            w.bkcmp1e()
                .bit(cmp(0))
                .bkcmp2e()
                .bit(cmp(1))
                .bkcmp3e()
                .bit(cmp(2));
            w.bkcmp4e()
                .bit(cmp(3))
                .bkcmp5e()
                .bit(cmp(4))
                .bkcmp6e()
                .bit(cmp(5));
            w.bkcmp7e().bit(cmp(6))
        });
        // Dead time; off-state outputs driven to the idle level, low (OSSR = OSSI = 1: both
        // switches of a leg off); break enabled with its polarity; no automatic output enable
        // (after a break the outputs stay off until software sets MOE again); break filter 3.
        tim.bdtr().write(|w| {
            w.dtg().set(dead.dtg).ossi().set_bit().ossr().set_bit();
            w.bke()
                .set_bit()
                .bkp()
                .bit(break_active_high)
                .aoe()
                .clear_bit();
            unsafe { w.bkf().bits(regs::BREAK_FILTER) }
        });
        // Both switches of each leg, active high (the L6387 inputs). CH4 drives no pin.
        tim.ccer().write(|w| {
            w.cc1e().set_bit().cc1ne().set_bit();
            w.cc2e().set_bit().cc2ne().set_bit();
            w.cc3e().set_bit().cc3ne().set_bit()
        });
        // Load the preloaded registers (UG), clear the flags (the UG update and a stale break).
        tim.egr().write(|w| w.ug().set_bit());
        tim.sr().write(|w| unsafe { w.bits(0) });
        tim.cr1().modify(|_, w| w.cen().set_bit());
        Self {
            tim,
            arr: timing.arr,
        }
    }

    /// The compare value of a 100 % duty.
    pub fn period(&self) -> u16 {
        self.arr
    }

    /// Software break: the outputs off in hardware, as the break input does.
    pub fn trip(&mut self) {
        self.tim.egr().write(|w| w.bg().set_bit());
    }

    /// A break (hardware or software) occurred since the last call; clears the flag.
    pub fn take_break(&mut self) -> bool {
        let brk = self.tim.sr().read().bif().bit_is_set();
        if brk {
            // rc_w0: the other flags are written 1, unchanged.
            self.tim.sr().write(|w| w.bif().clear_bit());
        }
        brk
    }
}

impl ThreePhasePwm for Tim1Pwm {
    #[inline]
    fn set_duties(&mut self, duties: &Duties) {
        let [a, b, c] = duties.to_compare(self.arr);
        self.tim.ccr1().write(|w| w.ccr().set(a as u32));
        self.tim.ccr2().write(|w| w.ccr().set(b as u32));
        self.tim.ccr3().write(|w| w.ccr().set(c as u32));
    }

    fn enable(&mut self) {
        // A break that is still active keeps MOE at 0: the hardware wins.
        self.tim.bdtr().modify(|_, w| w.moe().set_bit());
    }

    fn disable(&mut self) {
        self.tim.bdtr().modify(|_, w| w.moe().clear_bit());
    }

    #[inline]
    fn is_enabled(&self) -> bool {
        self.tim.bdtr().read().moe().bit_is_set()
    }
}

/// Enables, calibrates (single-ended) and readies one ADC (RM0440 §21.4.6–21.4.9).
fn adc_power_up<const A: usize>(adc: &stm32g4::Periph<pac::adc1::RegisterBlock, A>) {
    // Leave deep power-down, enable the regulator, wait t_ADCVREG_STUP (20 µs).
    adc.cr().write(|w| unsafe { w.bits(0) });
    adc.cr().write(|w| unsafe { w.bits(1 << 28) });
    cortex_m::asm::delay(SYSCLK_HZ / 50_000 + 1);
    // Calibrate.
    adc.cr()
        .modify(|r, w| unsafe { w.bits(r.bits() | (1 << 31)) });
    while adc.cr().read().bits() & (1 << 31) != 0 {}
    cortex_m::asm::delay(100);
    // Enable, wait ADRDY, clear it.
    adc.isr().write(|w| unsafe { w.bits(1) });
    adc.cr().modify(|r, w| unsafe { w.bits(r.bits() | 1) });
    while adc.isr().read().bits() & 1 == 0 {}
    adc.isr().write(|w| unsafe { w.bits(1) });
}

/// The channels of the injected conversions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InjectedChannels {
    /// ADC1: phase a current, then the bus voltage.
    pub adc1: [u8; 2],
    /// ADC2: phase b, then phase c current.
    pub adc2: [u8; 2],
    /// ADC1 channel read by [`InjectedAdc::read_regular`] (software-started), e.g. a
    /// potentiometer.
    pub regular: u8,
}

/// ADC1 and ADC2: two injected conversions each on TIM1 TRGO2; ADC1's end of injected
/// sequence raises the control interrupt (`ADC1_2`).
pub struct InjectedAdc {
    adc1: pac::ADC1,
    adc2: pac::ADC2,
    /// Codes to per unit; set the offsets after calibration.
    pub scaling: Scaling,
}

impl InjectedAdc {
    /// Powers both ADCs up, programs the injected sequences and the regular channel, arms
    /// the hardware trigger and enables the end-of-injected-sequence interrupt of ADC1 (the
    /// NVIC line is left to the caller).
    pub fn new(
        adc1: pac::ADC1,
        adc2: pac::ADC2,
        common: &pac::ADC12_COMMON,
        ch: InjectedChannels,
        scaling: Scaling,
    ) -> Self {
        // Synchronous clock HCLK / 4 = 42.5 MHz (the ADC clock must stay ≤ 60 MHz),
        // independent mode.
        common.ccr().write(|w| w.ckmode().sync_div4());
        adc_power_up(&adc1);
        adc_power_up(&adc2);
        let (s1, s2) = regs::adc_smpr(&[ch.adc1[0], ch.adc1[1], ch.regular], regs::SMP_12_5);
        adc1.smpr1().write(|w| unsafe { w.bits(s1) });
        adc1.smpr2().write(|w| unsafe { w.bits(s2) });
        let (s1, s2) = regs::adc_smpr(&ch.adc2, regs::SMP_12_5);
        adc2.smpr1().write(|w| unsafe { w.bits(s1) });
        adc2.smpr2().write(|w| unsafe { w.bits(s2) });
        // Regular sequence of ADC1: one conversion of `regular` (SQ1 at bits 6..10).
        adc1.sqr1()
            .write(|w| unsafe { w.bits((ch.regular as u32) << 6) });
        let j1 = regs::adc_jsqr(regs::JEXTSEL_TIM1_TRGO2, &ch.adc1).unwrap_or(0);
        let j2 = regs::adc_jsqr(regs::JEXTSEL_TIM1_TRGO2, &ch.adc2).unwrap_or(0);
        adc1.jsqr().write(|w| unsafe { w.bits(j1) });
        adc2.jsqr().write(|w| unsafe { w.bits(j2) });
        // Clear the flags, enable JEOS on ADC1, arm the injected triggers (JADSTART).
        adc1.isr().write(|w| unsafe { w.bits(0x7FF) });
        adc2.isr().write(|w| unsafe { w.bits(0x7FF) });
        adc1.ier().write(|w| w.jeosie().enabled());
        adc1.cr().modify(|_, w| w.jadstart().start_conversion());
        adc2.cr().modify(|_, w| w.jadstart().start_conversion());
        Self {
            adc1,
            adc2,
            scaling,
        }
    }

    /// The codes of the sequence that raised the interrupt; clears the flags (waits for
    /// ADC2, which converts in parallel and finishes at the same time).
    #[inline]
    pub fn read_raw(&mut self) -> RawSample {
        self.adc1.isr().write(|w| w.jeoc().clear().jeos().clear());
        let mut spin = 0u32;
        while self.adc2.isr().read().jeos().bit_is_clear() && spin < 1000 {
            spin += 1;
        }
        self.adc2.isr().write(|w| w.jeoc().clear().jeos().clear());
        RawSample {
            i: [
                self.adc1.jdr1().read().bits() as u16,
                self.adc2.jdr1().read().bits() as u16,
                self.adc2.jdr2().read().bits() as u16,
            ],
            vdc: self.adc1.jdr2().read().bits() as u16,
        }
    }

    /// A blocking software-started conversion of the regular channel (injected
    /// conversions interrupt it and take priority).
    pub fn read_regular(&mut self) -> u16 {
        self.adc1.isr().write(|w| w.eoc().clear());
        self.adc1.cr().modify(|_, w| w.adstart().start_conversion());
        while self.adc1.isr().read().eoc().bit_is_clear() {}
        self.adc1.dr().read().rdata().bits()
    }
}

impl PhaseCurrentSampler for InjectedAdc {
    #[inline]
    fn sample(&mut self) -> DriveInput {
        let raw = self.read_raw();
        self.scaling.input(&raw)
    }
}

/// Starts the DWT cycle counter (for the control interrupt's own timing).
pub fn start_cycle_counter(
    dcb: &mut cortex_m::peripheral::DCB,
    dwt: &mut cortex_m::peripheral::DWT,
) {
    dcb.enable_trace();
    dwt.enable_cycle_counter();
}
