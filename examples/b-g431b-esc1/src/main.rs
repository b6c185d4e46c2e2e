//! Sensorless PMSM drive on ST's B-G431B-ESC1: 170 MHz, TIM1 20 kHz centre-aligned PWM with
//! 0.5 µs dead time, injected ADC conversions at the PWM centre, the control step in the ADC
//! interrupt; initial position by voltage pulses, current-model MRAS, speed from the
//! potentiometer (bottom of its travel: stop). defmt logs state, speed, faults and the
//! control interrupt's worst cycle count (DWT).
//!
//! `cargo run --release` (in this folder) flashes and runs it through probe-rs.
#![no_std]
#![no_main]

mod board;
mod motor;

use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicBool, AtomicI32, AtomicU8, AtomicU32, Ordering::Relaxed};

use cortex_m::peripheral::{DWT, NVIC};
use cortex_m_rt::entry;
use defmt_rtt as _;
use panic_probe as _;
use pmsm_core::{Drive, DriveConfig, DriveOptions, DriveState, Pu};
use pmsm_stm32::adc::{KnobCommand, OffsetCalibration, Scaling, SpeedKnob};
use pmsm_stm32::hw::{self, InjectedAdc, Tim1Pwm};
use pmsm_stm32::timing::{DeadTime, PwmTiming};
use pmsm_stm32::{ThreePhasePwm, control_step};
use stm32g4::stm32g431::{self as pac, interrupt};

/// What the control interrupt owns.
struct Control {
    drive: Drive,
    pwm: Tim1Pwm,
    adc: InjectedAdc,
    calibration: Option<OffsetCalibration>,
    /// Cycles per PWM period: a step longer than this overran.
    budget: u32,
    /// A hardware break turned the outputs off: no restart until the knob asks for a stop.
    latched: bool,
}

/// The interrupt's state: written once by `main` before the interrupt is unmasked, then
/// owned by the interrupt alone. In `.uninit` (not `.data`): an initialised `static` of this
/// size (2.7 KiB) would also cost its image in flash.
#[unsafe(link_section = ".uninit.CONTROL")]
static mut CONTROL: MaybeUninit<Control> = MaybeUninit::uninit();

// Main → interrupt.
const CMD_NONE: u8 = 0;
const CMD_START: u8 = 1;
const CMD_STOP: u8 = 2;
static COMMAND: AtomicU8 = AtomicU8::new(CMD_NONE);
static SPEED_REF: AtomicI32 = AtomicI32::new(0);

// Interrupt → main.
static STATE: AtomicU8 = AtomicU8::new(0);
static FAULT: AtomicU8 = AtomicU8::new(0);
static SPEED_EST: AtomicI32 = AtomicI32::new(0);
static MAX_CYCLES: AtomicU32 = AtomicU32::new(0);
static CALIBRATED: AtomicBool = AtomicBool::new(false);
static CAL_FAILED: AtomicBool = AtomicBool::new(false);
static BREAK_SEEN: AtomicBool = AtomicBool::new(false);

fn state_code(s: DriveState) -> u8 {
    match s {
        DriveState::Idle => 0,
        DriveState::Ipd => 1,
        DriveState::Align => 2,
        DriveState::OpenLoop => 3,
        DriveState::Run => 4,
        DriveState::Fault(_) => 5,
    }
}

const STATE_NAMES: [&str; 6] = ["idle", "ipd", "align", "open-loop", "run", "fault"];
const FAULT_NAMES: [&str; 11] = [
    "none",
    "overcurrent",
    "bus_undervoltage",
    "bus_overvoltage",
    "initial_position",
    "handover",
    "current_sensor",
    "phase_loss",
    "stall",
    "loss_of_lock",
    "overrun",
];

fn fault_code(s: DriveState) -> u8 {
    match s {
        DriveState::Fault(f) => FAULT_NAMES
            .iter()
            .position(|n| *n == f.name())
            .map_or(0, |k| k as u8),
        _ => 0,
    }
}

/// A configuration the firmware cannot run: say so and stop here, outputs never enabled. No
/// panic machinery (the release image has no panic path; CI checks its symbols).
fn halt(why: &str) -> ! {
    defmt::error!("cannot start: {=str}", why);
    loop {
        cortex_m::asm::wfi();
    }
}

#[entry]
fn main() -> ! {
    let (Some(mut cp), Some(dp)) = (cortex_m::Peripherals::take(), pac::Peripherals::take()) else {
        halt("peripherals taken");
    };
    let src = hw::clock_170mhz(&dp.RCC, &dp.PWR, &dp.FLASH);
    if src == hw::ClockSource::Hsi16 {
        defmt::warn!("HSE did not start: 170 MHz from HSI16");
    }
    hw::start_cycle_counter(&mut cp.DCB, &mut cp.DWT);
    hw::enable_peripheral_clocks(&dp.RCC);

    // Configuration (floating point, once).
    let (m, inv) = (motor::motor(), motor::inverter());
    let sample_hz = motor::PWM_HZ as f64;
    let Ok(config) = DriveConfig::from_params(&m, &inv, sample_hz, DriveOptions::default()) else {
        halt(
            "motor.rs: the drive configuration failed (run `pmsm simulate` on the host for the message)",
        );
    };
    let base = config.base;
    let (Ok(current), Ok(voltage)) = (
        board::CURRENT.scale(base.current_a),
        board::VBUS.scale(base.voltage_v),
    ) else {
        halt("ADC scaling out of range");
    };
    let Ok(timing) = PwmTiming::centre_aligned(hw::SYSCLK_HZ, motor::PWM_HZ) else {
        halt("PWM frequency");
    };
    let Ok(dead) = DeadTime::at_least(hw::SYSCLK_HZ, motor::DEAD_TIME_NS) else {
        halt("dead time");
    };
    defmt::info!(
        "PWM {=u32} Hz: PSC {=u16} ARR {=u16}; dead time {=u32} ns (DTG {=u8:#x}, CKD {=u8})",
        motor::PWM_HZ,
        timing.psc,
        timing.arr,
        dead.nanoseconds(hw::SYSCLK_HZ),
        dead.dtg,
        dead.ckd
    );

    // Peripherals: OPAMPs, ADCs armed on TIM1 TRGO2, TIM1 running with its outputs off.
    hw::opamps_pga(&dp.OPAMP, board::PGA_GAIN);
    let scaling = Scaling {
        current,
        voltage,
        offsets: [2048; 3],
    };
    let mut adc = InjectedAdc::new(dp.ADC1, dp.ADC2, &dp.ADC12_COMMON, board::CHANNELS, scaling);
    let pwm = Tim1Pwm::new(dp.TIM1, timing, dead, board::BREAK, false);
    board::pwm_pins(&dp.GPIOA, &dp.GPIOB, &dp.GPIOC);
    let _ = adc.read_regular();

    // SAFETY: the interrupt that reads CONTROL is still masked; it is unmasked below, after
    // this write, and `main` never touches CONTROL again.
    unsafe {
        (*core::ptr::addr_of_mut!(CONTROL)).write(Control {
            drive: Drive::new(config),
            pwm,
            adc,
            // 1024 samples (51 ms) with the outputs off; offsets within 1.65 V ± 15 %.
            calibration: Some(OffsetCalibration::new(1024, (1741, 2355))),
            budget: hw::SYSCLK_HZ / motor::PWM_HZ,
            latched: false,
        });
    }
    // SAFETY: the interrupt's state is in place; no critical section relies on it masked.
    unsafe { NVIC::unmask(pac::Interrupt::ADC1_2) };

    // The pot is read by ADC1 regular conversions from here on, between control samples;
    // `InjectedAdc` is owned by the interrupt, so main reads the regular data register.
    // SAFETY: main only touches ADC1's regular conversion (ISR: injected flags and data).
    let adc1 = unsafe { pac::ADC1::steal() };
    let max_speed = base.speed_pu(0.8 * base.omega_e_rad_s);
    let mut knob = SpeedKnob::new(150, 300, 4000, max_speed);
    let rpm_per_pu = (base.omega_e_rad_s / m.p() * 60.0 / core::f64::consts::TAU) as f32;
    let mut tick: u32 = 0;
    let mut last_state = u8::MAX;
    loop {
        cortex_m::asm::delay(hw::SYSCLK_HZ / 100); // ~10 ms
        tick = tick.wrapping_add(1);
        if CAL_FAILED.load(Relaxed) {
            if tick.is_multiple_of(100) {
                defmt::error!(
                    "current offsets out of range: check the OPAMPs and the motor wiring"
                );
            }
            continue;
        }
        if !CALIBRATED.load(Relaxed) {
            continue;
        }
        let pot = read_pot(&adc1);
        match knob.update(pot) {
            KnobCommand::Stop => COMMAND.store(CMD_STOP, Relaxed),
            KnobCommand::Run(w) => {
                SPEED_REF.store(w.to_bits(), Relaxed);
                COMMAND.store(CMD_START, Relaxed);
            }
        }
        if BREAK_SEEN.swap(false, Relaxed) {
            defmt::warn!("break input: outputs off in hardware; turn the knob to stop to re-arm");
        }
        let state = STATE.load(Relaxed);
        if state != last_state {
            last_state = state;
            let name = STATE_NAMES.get(state as usize).copied().unwrap_or("?");
            if state == 5 {
                let f = FAULT.load(Relaxed) as usize;
                defmt::warn!(
                    "state: fault {=str}",
                    FAULT_NAMES.get(f).copied().unwrap_or("?")
                );
            } else {
                defmt::info!("state: {=str}", name);
            }
        }
        if tick.is_multiple_of(50) {
            let est = SPEED_EST.load(Relaxed) as f32 / (1u32 << 24) as f32 * rpm_per_pu;
            let reference = SPEED_REF.load(Relaxed) as f32 / (1u32 << 24) as f32 * rpm_per_pu;
            defmt::info!(
                "speed {=f32} r/min (ref {=f32}), pot {=u16}, control max {=u32} cycles",
                est,
                reference,
                pot,
                MAX_CYCLES.load(Relaxed)
            );
        }
    }
}

/// A software-started conversion of the pot (ADC1 regular channel 11).
fn read_pot(adc1: &pac::ADC1) -> u16 {
    // SAFETY: EOC (bit 2) is write-1-to-clear; ADSTART (bit 2 of CR) starts one conversion.
    unsafe {
        adc1.isr().write(|w| w.bits(1 << 2));
        adc1.cr().modify(|r, w| w.bits(r.bits() | (1 << 2)));
    }
    while adc1.isr().read().bits() & (1 << 2) == 0 {}
    adc1.dr().read().bits() as u16
}

/// The control interrupt: ADC1's end of injected sequence, once per PWM period.
#[interrupt]
fn ADC1_2() {
    let start = DWT::cycle_count();
    // SAFETY: `main` initialised CONTROL before unmasking this interrupt, which is its only
    // user from then on (and does not nest in itself).
    let c = unsafe { (*core::ptr::addr_of_mut!(CONTROL)).assume_init_mut() };
    if let Some(cal) = c.calibration.as_mut() {
        let raw = c.adc.read_raw();
        match cal.add(&raw) {
            None => {}
            Some(Ok(offsets)) => {
                c.adc.scaling.offsets = offsets;
                c.calibration = None;
                CALIBRATED.store(true, Relaxed);
            }
            Some(Err(_)) => CAL_FAILED.store(true, Relaxed),
        }
        return;
    }
    match COMMAND.swap(CMD_NONE, Relaxed) {
        // `start` acts only from Idle: after a fault the knob must go to its stop first.
        CMD_START if !c.latched => c.drive.start(),
        CMD_STOP => {
            c.latched = false;
            c.drive.stop();
        }
        _ => {}
    }
    c.drive
        .set_speed_ref(Pu::from_bits(SPEED_REF.load(Relaxed)));
    if c.pwm.take_break() {
        c.latched = true;
        c.drive.stop();
        BREAK_SEEN.store(true, Relaxed);
    }
    control_step(&mut c.drive, &mut c.pwm, &mut c.adc);
    let s = c.drive.state();
    STATE.store(state_code(s), Relaxed);
    FAULT.store(fault_code(s), Relaxed);
    SPEED_EST.store(c.drive.telemetry().estimate.omega.to_bits(), Relaxed);
    let cycles = DWT::cycle_count().wrapping_sub(start);
    if cycles > MAX_CYCLES.load(Relaxed) {
        MAX_CYCLES.store(cycles, Relaxed);
    }
    if cycles > c.budget {
        c.drive.report_overrun();
        c.pwm.disable();
    }
}
