//! Sensorless PMSM drive on ST's B-G431B-ESC1, as an RTIC app: 170 MHz, TIM1 20 kHz
//! centre-aligned PWM with 0.5 µs dead time, injected ADC conversions at the PWM centre;
//! initial position by voltage pulses, current-model MRAS.
//!
//! | task | priority | owns | does |
//! |---|---|---|---|
//! | `control` (ADC1_2, every PWM period) | 3 | the drive, TIM1, the injected ADCs | offset calibration, the drive step, the fault recorder |
//! | `ui` (SPI1 vector, pended by `control` every 10 ms) | 2 | the knob, the button | speed reference, start/stop/clear fault |
//! | `idle` | 0 | the logger | defmt logs: state, speed, cycles; the recorder after a fault |
//!
//! No `static mut` and no shared flags: the tasks talk through two `heapless::spsc::Queue`s,
//! commands `ui` → `control` and reports `control` → `idle`, and share the fault recorder,
//! which `control` writes and the logger reads sample by sample once it is frozen. All three
//! are RTIC resources: `control`'s locks cost nothing (top priority), the others' mask it
//! for one enqueue, dequeue or copy. (The queues are not split into producer and consumer
//! halves: the halves compute the ring position modulo a length they only know at run time,
//! a panic path that CI's check of the image rejects; a whole `Queue` knows its length.)
//!
//! `cargo run --release` (in this folder) flashes and runs it through probe-rs.
#![no_std]
#![no_main]

mod board;
mod motor;

use defmt_rtt as _;
use panic_probe as _;

/// A configuration the firmware cannot run: say so and stop here, outputs never enabled. No
/// panic machinery (the release image has no panic path; CI checks its symbols).
fn halt(why: &str) -> ! {
    defmt::error!("cannot start: {=str}", why);
    loop {
        cortex_m::asm::wfi();
    }
}

#[rtic::app(device = stm32g4::stm32g431, peripherals = true)]
mod app {
    use super::{board, halt, motor};
    use cortex_m::peripheral::DWT;
    use heapless::spsc::Queue;
    use pmsm_core::{Drive, DriveConfig, DriveOptions, DriveState, FaultRecorder, Pu};
    use pmsm_stm32::adc::{KnobCommand, OffsetCalibration, Scaling, SpeedKnob};
    use pmsm_stm32::hw::{self, InjectedAdc, Tim1Pwm};
    use pmsm_stm32::timing::{DeadTime, PwmTiming};
    use pmsm_stm32::{PhaseCurrentSampler, ThreePhasePwm, apply};
    use stm32g4::stm32g431 as pac;

    /// Samples kept before a fault: 3.2 ms at 20 kHz (44 bytes each).
    const RECORD: usize = 64;
    /// Control samples between two runs of `ui` (10 ms).
    const UI_PERIOD: u32 = motor::PWM_HZ / 100;
    /// Control samples between two periodic reports (100 ms).
    const REPORT_PERIOD: u32 = motor::PWM_HZ / 10;

    /// `ui` → `control`.
    #[derive(Clone, Copy)]
    pub enum Command {
        /// Start from `Idle` (ignored elsewhere).
        Start,
        /// Outputs off, back to `Idle`; re-arms after a hardware break.
        Stop,
        /// Button: clear a fault (and re-arm the recorder), else start from `Idle`, else stop.
        Button,
        /// Speed reference, per unit of `ω_b` (Q8.24).
        Speed(Pu),
    }

    /// Something that happened once, for the logger.
    #[derive(Clone, Copy, PartialEq, Eq, defmt::Format)]
    pub enum Event {
        /// A periodic report or a state change.
        None,
        /// The current offsets are measured: the drive accepts commands.
        Calibrated,
        /// The offsets are outside their window: the drive stays off.
        CalibrationFailed,
        /// The break input turned the outputs off in hardware.
        Break,
    }

    /// `control` → `idle`: on a state change, an event, and every 100 ms.
    #[derive(Clone, Copy)]
    pub struct Report {
        state: DriveState,
        /// Estimated speed, per unit (Q8.24).
        speed_est: Pu,
        /// Speed reference, per unit (Q8.24).
        speed_ref: Pu,
        /// Worst control interrupt so far, CPU cycles.
        max_cycles: u32,
        event: Event,
    }

    /// What the control interrupt owns.
    pub struct Control {
        drive: Drive,
        pwm: Tim1Pwm,
        adc: InjectedAdc,
        calibration: Option<OffsetCalibration>,
        /// Cycles per PWM period: a step longer than this overran.
        budget: u32,
        /// A hardware break turned the outputs off: no restart before a stop.
        latched: bool,
        speed_ref: Pu,
        max_cycles: u32,
        tick: u32,
        last_state: DriveState,
    }

    /// The knob (ADC1 regular channel) and the button.
    pub struct Ui {
        adc1: pac::ADC1,
        gpioc: pac::GPIOC,
        knob: SpeedKnob,
        knob_running: bool,
        /// Consecutive polls with the button down (debounce: 3 polls, 30 ms).
        pressed_polls: u8,
    }

    /// The logger's state.
    pub struct Logger {
        rpm_per_pu: f32,
        last_state: Option<DriveState>,
        /// Samples of the frozen recorder already logged.
        dumped: usize,
    }

    #[shared]
    struct Shared {
        recorder: FaultRecorder<RECORD>,
        /// `ui` → `control`.
        commands: Queue<Command, 8>,
        /// `control` → `idle`.
        reports: Queue<Report, 16>,
    }

    #[local]
    struct Local {
        control: Control,
        ui: Ui,
        logger: Logger,
    }

    #[init]
    fn init(cx: init::Context) -> (Shared, Local) {
        let mut cp = cx.core;
        let dp = cx.device;
        let src = hw::clock_170mhz(&dp.RCC, &dp.PWR, &dp.FLASH);
        if src == hw::ClockSource::Hsi16 {
            defmt::warn!("HSE did not start: 170 MHz from HSI16");
        }
        hw::start_cycle_counter(&mut cp.DCB, &mut cp.DWT);
        hw::enable_peripheral_clocks(&dp.RCC);

        // Configuration (floating point, once).
        let (m, inv) = (motor::motor(), motor::inverter());
        let sample_hz = motor::PWM_HZ as f64;
        let config = match DriveConfig::from_params(&m, &inv, sample_hz, DriveOptions::default()) {
            Ok(c) => c,
            Err(e) => {
                defmt::error!("drive configuration: {}", e);
                halt("motor.rs: the drive configuration failed");
            }
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
        let mut adc =
            InjectedAdc::new(dp.ADC1, dp.ADC2, &dp.ADC12_COMMON, board::CHANNELS, scaling);
        let pwm = Tim1Pwm::new(dp.TIM1, timing, dead, board::BREAK, false);
        board::pwm_pins(&dp.GPIOA, &dp.GPIOB, &dp.GPIOC);
        board::button_pin(&dp.GPIOC);
        let _ = adc.read_regular();

        // SAFETY: `ui` touches only ADC1's regular conversion (start bit, EOC flag, data
        // register) and `control` only its injected flags and data (InjectedAdc::read_raw).
        let adc1 = unsafe { pac::ADC1::steal() };
        let max_speed = base.speed_pu(0.8 * base.omega_e_rad_s);
        let control = Control {
            drive: Drive::new(config),
            pwm,
            adc,
            // 1024 samples (51 ms) with the outputs off; offsets within 1.65 V ± 15 %.
            calibration: Some(OffsetCalibration::new(1024, (1741, 2355))),
            budget: hw::SYSCLK_HZ / motor::PWM_HZ,
            latched: false,
            speed_ref: Pu::ZERO,
            max_cycles: 0,
            tick: 0,
            last_state: DriveState::Idle,
        };
        let ui = Ui {
            adc1,
            gpioc: dp.GPIOC,
            knob: SpeedKnob::new(150, 300, 4000, max_speed),
            knob_running: false,
            pressed_polls: 0,
        };
        let logger = Logger {
            rpm_per_pu: (base.omega_e_rad_s / m.p() * 60.0 / core::f64::consts::TAU) as f32,
            last_state: None,
            dumped: 0,
        };
        // RTIC unmasks ADC1_2 after `init` returns.
        (
            Shared {
                recorder: FaultRecorder::new(),
                commands: Queue::new(),
                reports: Queue::new(),
            },
            Local {
                control,
                ui,
                logger,
            },
        )
    }

    /// The control interrupt: ADC1's end of injected sequence, once per PWM period.
    #[task(binds = ADC1_2, priority = 3, local = [control], shared = [recorder, commands, reports])]
    fn control(mut cx: control::Context) {
        let start = DWT::cycle_count();
        let c = cx.local.control;
        c.tick = c.tick.wrapping_add(1);
        if c.tick.is_multiple_of(UI_PERIOD) {
            // SPI1 is unused on the board: its vector runs `ui`, pended from here.
            rtic::pend(pac::Interrupt::SPI1);
        }
        if let Some(cal) = c.calibration.as_mut() {
            let raw = c.adc.read_raw();
            let event = match cal.add(&raw) {
                None => return,
                Some(Ok(offsets)) => {
                    c.adc.scaling.offsets = offsets;
                    c.calibration = None;
                    Event::Calibrated
                }
                // Stays here with the outputs off; said once a second.
                Some(Err(_)) if c.tick.is_multiple_of(motor::PWM_HZ) => Event::CalibrationFailed,
                Some(Err(_)) => return,
            };
            cx.shared.reports.lock(|q| report(q, c, event));
            return;
        }
        let mut event = Event::None;
        while let Some(cmd) = cx.shared.commands.lock(|q| q.dequeue()) {
            match cmd {
                Command::Speed(w) => c.speed_ref = w,
                // `start` acts only from Idle: a fault needs the button first.
                Command::Start if !c.latched => c.drive.start(),
                Command::Start => {}
                Command::Stop => {
                    c.latched = false;
                    c.drive.stop();
                }
                Command::Button => match c.drive.state() {
                    DriveState::Fault(_) => {
                        c.latched = false;
                        c.drive.clear_fault();
                        cx.shared.recorder.lock(|r| r.rearm());
                    }
                    DriveState::Idle if !c.latched => c.drive.start(),
                    _ => c.drive.stop(),
                },
            }
        }
        c.drive.set_speed_ref(c.speed_ref);
        if c.pwm.take_break() {
            c.latched = true;
            c.drive.stop();
            event = Event::Break;
        }
        let input = c.adc.sample();
        let out = c.drive.step(&input);
        apply(&mut c.pwm, &out);
        cx.shared.recorder.lock(|r| r.record(&c.drive, &input));
        let cycles = DWT::cycle_count().wrapping_sub(start);
        c.max_cycles = c.max_cycles.max(cycles);
        if cycles > c.budget {
            c.drive.report_overrun();
            c.pwm.disable();
        }
        let state = c.drive.state();
        if state != c.last_state || event != Event::None || c.tick.is_multiple_of(REPORT_PERIOD) {
            c.last_state = state;
            cx.shared.reports.lock(|q| report(q, c, event));
        }
    }

    /// Queues a report for the logger (dropped if the logger is behind: the next one tells).
    fn report(q: &mut Queue<Report, 16>, c: &Control, event: Event) {
        let _ = q.enqueue(Report {
            state: c.drive.state(),
            speed_est: c.drive.telemetry().estimate.omega,
            speed_ref: c.speed_ref,
            max_cycles: c.max_cycles,
            event,
        });
    }

    /// Knob and button, every 10 ms (a hardware task on the unused SPI1 vector, pended by
    /// `control`: no executor, no timer).
    #[task(binds = SPI1, priority = 2, local = [ui], shared = [commands])]
    fn ui(mut cx: ui::Context) {
        let u = cx.local.ui;
        let mut send = |cmd: Command| {
            // Full only if `control` stopped taking commands: nothing better to do.
            let _ = cx.shared.commands.lock(|q| q.enqueue(cmd));
        };
        let pot = read_pot(&u.adc1);
        let cmd = u.knob.update(pot);
        let running = matches!(cmd, KnobCommand::Run(_));
        // The knob starts and stops on its edges only, so the button can stop a drive that
        // the knob keeps at speed.
        match cmd {
            KnobCommand::Run(w) => {
                send(Command::Speed(w));
                if !u.knob_running {
                    send(Command::Start);
                }
            }
            KnobCommand::Stop if u.knob_running => send(Command::Stop),
            KnobCommand::Stop => {}
        }
        u.knob_running = running;
        if board::button_down(&u.gpioc) {
            u.pressed_polls = u.pressed_polls.saturating_add(1);
            if u.pressed_polls == 3 {
                send(Command::Button);
            }
        } else {
            u.pressed_polls = 0;
        }
    }

    /// A software-started conversion of the pot (ADC1 regular channel).
    fn read_pot(adc1: &pac::ADC1) -> u16 {
        adc1.isr().write(|w| w.eoc().clear());
        adc1.cr().modify(|_, w| w.adstart().start_conversion());
        while adc1.isr().read().eoc().bit_is_clear() {}
        adc1.dr().read().rdata().bits()
    }

    /// The logger: reports as they come, and the recorder's samples once a fault froze it.
    #[idle(local = [logger], shared = [recorder, reports])]
    fn idle(mut cx: idle::Context) -> ! {
        let l = cx.local.logger;
        loop {
            while let Some(r) = cx.shared.reports.lock(|q| q.dequeue()) {
                log(l, &r);
            }
            // One sample per lock: the control interrupt waits at most one copy.
            let n = l.dumped;
            let next = cx.shared.recorder.lock(|rec| {
                if rec.is_frozen() {
                    rec.sample(n).map(|s| (s, rec.len()))
                } else {
                    None
                }
            });
            match next {
                Some((s, len)) => {
                    if n == 0 {
                        defmt::warn!("fault recorder: {=usize} samples before the fault", len);
                    }
                    defmt::info!("rec {=usize}: {}", n, s);
                    l.dumped += 1;
                }
                None => {
                    if l.dumped > 0 && !cx.shared.recorder.lock(|rec| rec.is_frozen()) {
                        l.dumped = 0; // re-armed: the next fault dumps again
                    }
                    cortex_m::asm::delay(hw::SYSCLK_HZ / 1000);
                }
            }
        }
    }

    fn log(l: &mut Logger, r: &Report) {
        match r.event {
            Event::None => {}
            Event::Calibrated => defmt::info!("current offsets measured: ready"),
            Event::CalibrationFailed => {
                defmt::error!("current offsets out of range: check the OPAMPs and the motor wiring")
            }
            Event::Break => defmt::warn!(
                "break input: outputs off in hardware; stop (knob or button) to re-arm"
            ),
        }
        if l.last_state != Some(r.state) {
            l.last_state = Some(r.state);
            match r.state {
                DriveState::Fault(f) => defmt::warn!("state: fault {}", f),
                s => defmt::info!("state: {}", s),
            }
        } else if r.event == Event::None {
            defmt::info!(
                "speed {=f32} r/min (ref {=f32}), control max {=u32} cycles",
                r.speed_est.to_num::<f32>() * l.rpm_per_pu,
                r.speed_ref.to_num::<f32>() * l.rpm_per_pu,
                r.max_cycles
            );
        }
    }
}
