//! Sensorless PMSM drive on ST's B-G431B-ESC1, as an RTIC app: 170 MHz, TIM1 20 kHz
//! centre-aligned PWM with 0.5 µs dead time, injected ADC conversions at the PWM centre; the
//! estimator the defaults choose for the motor of `motor.rs` (the kit's surface motor: the
//! alignment, an open-loop start and the NLO); with the feature `commissioning`,
//! a mode that identifies the motor connected (`pmsm_core::Identify`,
//! `docs/identification.md`; README.md says why it is not in the default image).
//!
//! | task | priority | owns | does |
//! |---|---|---|---|
//! | `control` (ADC1_2, every PWM period) | 3 | the drive's interrupt side, TIM1, the injected ADCs | offset calibration, the interrupt step or the identification's step, the fault recorder; pends `motion` when a task period ends |
//! | `motion` (SPI1 vector, pended by `control` every task period) | 2 | the drive's task side, the knob, the button | the task step (state machine, speed loop, slow checks, learners); every 10 ms the knob and the button: speed reference, start/stop/clear fault, commissioning (long press) |
//! | `idle` | 0 | the logger | defmt logs: state, speed, cycles; the recorder after a fault; the identification's `f32` fits (`Identify::poll`), the identified motor and the drive rebuilt from it |
//!
//! The two sides of the drive meet in `HANDOFF`, a `static` of lock-free mailboxes (atomic
//! words: the task's command, the interrupt's window of each task period); `motion` must
//! finish its step within the task period (`pmsm_core::TASK_PERIOD` PWM periods), else the
//! drive trips `overrun`. No `static mut`: the other tasks talk through RTIC resources, the
//! reports `control` → `idle` a `heapless::spsc::Queue`, the fault recorder (which `control`
//! writes and the logger reads sample by sample once it is frozen), the identification
//! (stepped by `control`, polled by `idle`), the drive configuration that `idle` builds from
//! an identified motor, and a few flags between `control` and `motion` (the break input's
//! latch, commissioning's request and state, the speed reference for the reports). Every lock
//! that `control` takes costs it nothing (top priority); the others mask it for one enqueue,
//! dequeue or copy, except `Identify::poll`, which masks it for its fits (up to about 20 000
//! instructions, three times per identification, while the identification holds its voltage
//! or has turned the outputs off: the samples it delays change nothing). (The queue is not
//! split into producer and consumer halves: the halves compute the ring position modulo a
//! length they only know at run time, a panic path that CI's check of the image rejects; a
//! whole `Queue` knows its length.)
//!
//! `cargo run --release` (in this folder) flashes and runs it through probe-rs.
#![no_std]
#![no_main]

mod board;
mod motor;
mod sensing;

/// The drive designed by build.rs for `motor.rs` (`DRIVE_IMAGE`, `DRIVE_IMAGE_SCHEMA`).
mod image {
    include!(concat!(env!("OUT_DIR"), "/drive_image.rs"));
}

// build.rs designed the drive with pmsm-core built for the host with the build-dependency's
// features: they must be the firmware's (Cargo.toml).
const _: () = assert!(
    image::DRIVE_IMAGE_SCHEMA == pmsm_core::DriveConfig::IMAGE_SCHEMA
        && image::DRIVE_IMAGE.len() == pmsm_core::DriveConfig::IMAGE_WORDS,
    "the drive image is of another pmsm-core build: give pmsm-core the same features under \
     [dependencies] and [build-dependencies] in Cargo.toml"
);

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
    use heapless::Vec;
    use heapless::spsc::Queue;
    use pmsm_core::{
        DriveConfig, DriveInput, DriveIsr, DriveState, DriveTask, FaultRecorder, Handoff, Pu,
        TASK_PERIOD,
    };
    use pmsm_core::{
        Identified, Identify, IdentifyConfig, IdentifyDesign, IdentifyError, IdentifyOutput, Stage,
        clarke,
    };
    use pmsm_stm32::adc::{KnobCommand, OffsetCalibration, Scaling, SpeedKnob};
    use pmsm_stm32::hw::{self, InjectedAdc, Tim1Pwm};
    use pmsm_stm32::timing::{DeadTime, PwmTiming};
    use pmsm_stm32::{PhaseCurrentSampler, ThreePhasePwm, apply};
    use rtic::Mutex;
    use stm32g4::stm32g431 as pac;

    /// Where the drive's two sides meet: lock-free mailboxes of atomic words, the interrupt's
    /// window of each task period and the task's command.
    static HANDOFF: Handoff = Handoff::new();

    /// Samples kept before a fault: 3.2 ms at 20 kHz (44 bytes each).
    const RECORD: usize = 64;
    /// The commissioning mode is built in (feature `commissioning`: with it the image
    /// exceeds the 64 KiB budget, see the README). Without it every commissioning path is
    /// dead code (the compiler drops it) and its slots hold nothing.
    const COMMISSIONING: bool = cfg!(feature = "commissioning");
    /// Capacity of the identification's and the rebuilt drive's slots: 1 with the mode,
    /// 0 (no RAM) without.
    const SLOTS: usize = COMMISSIONING as usize;
    /// Task periods between two polls of the knob and the button (10 ms).
    const UI_PERIOD: u32 = motor::PWM_HZ / 100 / TASK_PERIOD;
    /// Control samples between two periodic reports (100 ms).
    const REPORT_PERIOD: u32 = motor::PWM_HZ / 10;

    /// What the knob and the button ask for.
    #[derive(Clone, Copy)]
    pub enum Command {
        /// Start from `Idle` (ignored elsewhere).
        Start,
        /// Outputs off, back to `Idle`; re-arms after a hardware break.
        Stop,
        /// Button (short press): clear a fault (and re-arm the recorder), else start from
        /// `Idle`, else stop (or abort a commissioning run).
        Button,
        /// Button (long press): identify the motor, from `Idle` only.
        Commission,
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
        /// Commissioning started (outputs on, identification stepping).
        CommissionStarted,
        /// Commissioning asked for outside `Idle` (or without an identification
        /// configuration): nothing done.
        CommissionRefused,
        /// Commissioning stopped by the button, the knob or the break input.
        CommissionAborted,
        /// The identification's sequence ended (outputs off); `idle` reports the result.
        CommissionEnded,
        /// The drive was rebuilt from the identified motor.
        DriveRebuilt,
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
        /// The identification's stage while commissioning.
        stage: Option<Stage>,
    }

    /// A drive built by `idle` from an identified motor: `motion` takes it in `Idle` and
    /// hands it on to `control`.
    pub struct Rebuilt {
        config: DriveConfig,
        /// The ADC scaling to its bases (offsets are kept).
        scaling: Scaling,
    }

    /// `motion` ↔ `control`, besides the handoff.
    #[derive(Clone, Copy, Default)]
    pub struct Flags {
        /// A hardware break turned the outputs off: no restart before a stop (`control` sets
        /// it, `motion` clears it on a stop).
        latched: bool,
        /// `motion` asks for commissioning (in `Idle`), or to abort it.
        commission: bool,
        abort: bool,
        /// Commissioning runs (`control`'s).
        commissioning: bool,
        /// The speed reference, for the reports.
        speed_ref: Pu,
    }

    /// What the control interrupt owns.
    pub struct Control {
        isr: DriveIsr,
        pwm: Tim1Pwm,
        adc: InjectedAdc,
        calibration: Option<OffsetCalibration>,
        /// Cycles per PWM period: a step longer than this overran.
        budget: u32,
        max_cycles: u32,
        tick: u32,
        last_state: DriveState,
        /// The ADC scaling to the drive's bases (offsets set by the calibration).
        drive_scaling: Scaling,
        /// The identification's configuration and its ADC scaling (current per unit of the
        /// commissioning limit, voltage per unit of `V_DC/√3`); `None`: commissioning
        /// unavailable (logged at start-up).
        commission: Option<(IdentifyConfig, Scaling)>,
        /// Commissioning runs: the identification, not the drive, drives the outputs.
        commissioning: bool,
        last_stage: Option<Stage>,
    }

    /// What the motion task owns: the drive's task side, the knob (ADC1 regular channel) and
    /// the button.
    pub struct Motion {
        task: DriveTask,
        /// Task periods since the last poll of the knob and the button.
        polls: u32,
        adc1: pac::ADC1,
        gpioc: pac::GPIOC,
        knob: SpeedKnob,
        knob_running: bool,
        /// Consecutive polls with the button down (debounce: 3 polls, 30 ms; a long press:
        /// [`board::LONG_PRESS_POLLS`]).
        pressed_polls: u8,
        /// The break latch last seen (a new one stops the task).
        latched: bool,
    }

    /// The logger's state.
    pub struct Logger {
        /// Mechanical r/min per unit of speed (changes with a rebuilt drive).
        rpm_per_pu: f32,
        last_state: Option<DriveState>,
        /// Samples of the frozen recorder already logged.
        dumped: usize,
    }

    #[shared]
    struct Shared {
        recorder: FaultRecorder<RECORD>,
        /// `control` → `idle`.
        reports: Queue<Report, 16>,
        flags: Flags,
        /// The commissioning run: `control` steps it, `idle` polls it (at most one).
        identify: Vec<Identify, SLOTS>,
        /// `idle` → `motion`, then `motion` → `control`: the drive of the identified motor
        /// (at most one each).
        rebuilt: Vec<Rebuilt, SLOTS>,
        rebuilt_isr: Vec<Rebuilt, SLOTS>,
    }

    #[local]
    struct Local {
        control: Control,
        motion: Motion,
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

        // The drive build.rs designed on the host (its design is not in this image).
        let (m, inv) = (motor::motor(), motor::inverter());
        let config = match DriveConfig::from_image(&super::image::DRIVE_IMAGE) {
            Ok(c) => c,
            Err(e) => {
                defmt::error!("drive image: {}", e);
                halt("the drive image of build.rs");
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
        let commission = if COMMISSIONING {
            commission_config(&inv)
        } else {
            None
        };
        let pwm = Tim1Pwm::new(dp.TIM1, timing, dead, board::BREAK, false);
        board::pwm_pins(&dp.GPIOA, &dp.GPIOB, &dp.GPIOC);
        board::button_pin(&dp.GPIOC);
        let _ = adc.read_regular();

        // SAFETY: `motion` touches only ADC1's regular conversion (start bit, EOC flag, data
        // register) and `control` only its injected flags and data (InjectedAdc::read_raw).
        let adc1 = unsafe { pac::ADC1::steal() };
        let max_speed = base.speed_pu(0.8 * base.omega_e_rad_s);
        let control = Control {
            isr: DriveIsr::new(&config),
            pwm,
            adc,
            // 1024 samples (51 ms) with the outputs off; offsets within 1.65 V ± 15 %.
            calibration: Some(OffsetCalibration::new(1024, (1741, 2355))),
            budget: hw::SYSCLK_HZ / motor::PWM_HZ,
            max_cycles: 0,
            tick: 0,
            last_state: DriveState::Idle,
            drive_scaling: scaling,
            commission,
            commissioning: false,
            last_stage: None,
        };
        let motion = Motion {
            task: DriveTask::new(&config),
            polls: 0,
            adc1,
            gpioc: dp.GPIOC,
            knob: SpeedKnob::new(150, 300, 4000, max_speed),
            knob_running: false,
            pressed_polls: 0,
            latched: false,
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
                reports: Queue::new(),
                flags: Flags::default(),
                identify: Vec::new(),
                rebuilt: Vec::new(),
                rebuilt_isr: Vec::new(),
            },
            Local {
                control,
                motion,
                logger,
            },
        )
    }

    /// The identification of the motor connected: its pole pairs and the inverter from
    /// `motor.rs`, the current limit from `board.rs`, the default design. `None` (logged) if
    /// the configuration or its ADC scaling fails: the drive runs, commissioning is refused.
    fn commission_config(inv: &pmsm_core::InverterParams) -> Option<(IdentifyConfig, Scaling)> {
        let config = match IdentifyConfig::new(
            motor::POLE_PAIRS,
            inv,
            board::COMMISSION_CURRENT_A,
            IdentifyDesign::default(),
        ) {
            Ok(c) => c,
            Err(e) => {
                defmt::warn!("commissioning unavailable: {}", e);
                return None;
            }
        };
        let (Ok(current), Ok(voltage)) = (
            board::CURRENT.scale(config.current_base_a),
            board::VBUS.scale(config.voltage_base_v),
        ) else {
            defmt::warn!("commissioning unavailable: ADC scaling out of range");
            return None;
        };
        let scaling = Scaling {
            current,
            voltage,
            offsets: [2048; 3],
        };
        Some((config, scaling))
    }

    /// The control interrupt: ADC1's end of injected sequence, once per PWM period.

    /// The control interrupt: ADC1's end of injected sequence, once per PWM period.
    #[task(
        binds = ADC1_2,
        priority = 3,
        local = [control],
        shared = [recorder, reports, flags, identify, rebuilt_isr]
    )]
    fn control(mut cx: control::Context) {
        let start = DWT::cycle_count();
        let c = cx.local.control;
        c.tick = c.tick.wrapping_add(1);
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
            cx.shared.reports.lock(|q| report(q, c, Pu::ZERO, event));
            return;
        }
        let mut event = Event::None;
        let mut flags = cx.shared.flags.lock(|f| *f);
        if c.pwm.take_break() {
            flags.latched = true;
            if COMMISSIONING && c.commissioning {
                end_commissioning(c);
                cx.shared.identify.lock(|id| id.clear());
            }
            event = Event::Break;
        }
        if COMMISSIONING {
            event = commission_requests(c, &mut flags, &mut cx.shared.identify, event);
        }
        // The drive of an identified motor, taken in `Idle`, before this sample is scaled (its
        // bases may differ).
        if COMMISSIONING
            && !c.commissioning
            && matches!(c.isr.state(), DriveState::Idle)
            && let Some(r) = cx.shared.rebuilt_isr.lock(|r| r.pop())
        {
            c.isr = DriveIsr::new(&r.config);
            c.drive_scaling = Scaling {
                offsets: c.adc.scaling.offsets,
                ..r.scaling
            };
            c.adc.scaling = c.drive_scaling;
            event = Event::DriveRebuilt;
        }
        cx.shared.flags.lock(|f| {
            f.latched = flags.latched;
            f.commission = flags.commission;
            f.abort = flags.abort;
            f.commissioning = c.commissioning;
        });
        // One sample for either path (one inlined copy of the scaling).
        let input = c.adc.sample();
        if COMMISSIONING && c.commissioning {
            let shared = &mut cx.shared;
            commission_step(
                c,
                &input,
                &mut shared.identify,
                &mut shared.reports,
                start,
                event,
            );
            return;
        }
        let out = c.isr.step(&HANDOFF, &input);
        apply(&mut c.pwm, &out);
        if c.isr.task_due() {
            // SPI1 is unused on the board: its vector runs `motion`, pended from here.
            rtic::pend(pac::Interrupt::SPI1);
        }
        cx.shared.recorder.lock(|r| r.record(&c.isr, &input));
        let cycles = DWT::cycle_count().wrapping_sub(start);
        c.max_cycles = c.max_cycles.max(cycles);
        if cycles > c.budget {
            c.isr.report_overrun();
            c.pwm.disable();
        }
        let state = c.isr.state();
        // A new state or fault (their codes: no comparison of the faults' values).
        let changed =
            (state.code(), state.fault_code()) != (c.last_state.code(), c.last_state.fault_code());
        if changed || event != Event::None || c.tick.is_multiple_of(REPORT_PERIOD) {
            c.last_state = state;
            cx.shared
                .reports
                .lock(|q| report(q, c, flags.speed_ref, event));
        }
    }

    /// `motion`'s requests for commissioning: start it (in `Idle`, with the offsets measured
    /// and no break latched) or abort it; the event to report.
    fn commission_requests(
        c: &mut Control,
        flags: &mut Flags,
        identify: &mut impl Mutex<T = Vec<Identify, SLOTS>>,
        event: Event,
    ) -> Event {
        if flags.abort {
            flags.abort = false;
            if c.commissioning {
                end_commissioning(c);
                identify.lock(|id| id.clear());
                return Event::CommissionAborted;
            }
        }
        if !flags.commission {
            return event;
        }
        flags.commission = false;
        match c.commission {
            Some((config, scaling))
                if matches!(c.isr.state(), DriveState::Idle)
                    && !flags.latched
                    && !c.commissioning =>
            {
                c.adc.scaling = Scaling {
                    offsets: c.adc.scaling.offsets,
                    ..scaling
                };
                identify.lock(|id| {
                    id.clear();
                    // Capacity 1 here: always fits.
                    let _ = id.push(Identify::new(config));
                });
                c.commissioning = true;
                c.last_stage = None;
                Event::CommissionStarted
            }
            _ => Event::CommissionRefused,
        }
    }

    /// One sample of commissioning: the identification's step on the currents in its per
    /// unit, its duties to TIM1; the outputs go off and the drive's scaling comes back when
    /// its sequence ends (`idle` then polls the result). `start`: the interrupt's first cycle.
    fn commission_step(
        c: &mut Control,
        input: &DriveInput,
        identify: &mut impl Mutex<T = Vec<Identify, SLOTS>>,
        reports: &mut impl Mutex<T = Queue<Report, 16>>,
        start: u32,
        event: Event,
    ) {
        let i = clarke(input.i_abc);
        let out = identify.lock(|id| id.first_mut().map(|id| id.step(i, input.vdc)));
        let mut event = event;
        let mut stage = c.last_stage;
        match out {
            Some(o) => {
                apply_identify(&mut c.pwm, &o);
                stage = Some(o.stage);
                if o.finished {
                    end_commissioning(c);
                    event = Event::CommissionEnded;
                }
            }
            None => {
                end_commissioning(c);
                event = Event::CommissionAborted;
            }
        }
        let cycles = DWT::cycle_count().wrapping_sub(start);
        c.max_cycles = c.max_cycles.max(cycles);
        if cycles > c.budget && c.commissioning {
            // The identification has no overrun report of its own: stop it.
            end_commissioning(c);
            identify.lock(|id| id.clear());
            event = Event::CommissionAborted;
        }
        if event != Event::None || stage != c.last_stage {
            c.last_stage = stage;
            reports.lock(|q| report(q, c, Pu::ZERO, event));
        }
    }

    /// The identification's duties to TIM1 (as `apply` does the drive's).
    fn apply_identify(pwm: &mut Tim1Pwm, o: &IdentifyOutput) {
        if o.pwm_on {
            pwm.set_duties(&o.duties);
            if !pwm.is_enabled() {
                pwm.enable();
            }
        } else if pwm.is_enabled() {
            pwm.disable();
        }
    }

    /// Outputs off, the drive's ADC scaling back: the drive (still `Idle`) takes over.
    fn end_commissioning(c: &mut Control) {
        c.pwm.disable();
        c.commissioning = false;
        c.adc.scaling = Scaling {
            offsets: c.adc.scaling.offsets,
            ..c.drive_scaling
        };
    }

    /// Queues a report for the logger (dropped if the logger is behind: the next one tells).
    fn report(q: &mut Queue<Report, 16>, c: &Control, speed_ref: Pu, event: Event) {
        let _ = q.enqueue(Report {
            state: c.isr.state(),
            speed_est: c.isr.telemetry().estimate.omega,
            speed_ref,
            max_cycles: c.max_cycles,
            event,
            stage: if c.commissioning { c.last_stage } else { None },
        });
    }

    /// The drive's task side, once per task period (a hardware task on the unused SPI1
    /// vector, pended by `control`: no executor, no timer); every 10 ms the knob and the
    /// button.
    #[task(binds = SPI1, priority = 2, local = [motion], shared = [flags, recorder, rebuilt, rebuilt_isr])]
    fn motion(mut cx: motion::Context) {
        let m = cx.local.motion;
        let flags = cx.shared.flags.lock(|f| *f);
        // A new break latch stops the task side too.
        if flags.latched && !m.latched {
            m.task.stop();
        }
        m.latched = flags.latched;
        m.task.step(&HANDOFF);
        m.polls += 1;
        if m.polls < UI_PERIOD {
            return;
        }
        m.polls = 0;
        // The drive of an identified motor, taken in `Idle`; `control` takes it next.
        if COMMISSIONING
            && !flags.commissioning
            && matches!(m.task.state(), DriveState::Idle)
            && let Some(r) = cx.shared.rebuilt.lock(|r| r.pop())
        {
            let speed_ref = flags.speed_ref;
            m.task = DriveTask::new(&r.config);
            m.task.set_speed_ref(speed_ref);
            cx.shared.rebuilt_isr.lock(|slot| {
                slot.clear();
                let _ = slot.push(r);
            });
        }
        for cmd in poll_ui(m).into_iter().flatten() {
            run_command(
                m,
                cmd,
                &flags,
                &mut cx.shared.flags,
                &mut cx.shared.recorder,
            );
        }
    }

    /// One command of the knob or the button to the task side (or to commissioning).
    fn run_command(
        m: &mut Motion,
        cmd: Command,
        seen: &Flags,
        flags: &mut impl Mutex<T = Flags>,
        recorder: &mut impl Mutex<T = FaultRecorder<RECORD>>,
    ) {
        if COMMISSIONING && seen.commissioning {
            // Anything that would stop the drive stops the identification.
            match cmd {
                Command::Speed(w) => {
                    m.task.set_speed_ref(w);
                    flags.lock(|f| f.speed_ref = w);
                }
                Command::Stop | Command::Button => flags.lock(|f| f.abort = true),
                Command::Start | Command::Commission => {}
            }
            return;
        }
        match cmd {
            // Set on change only: the setter computes the closed loop's reference.
            Command::Speed(w) => {
                m.task.set_speed_ref(w);
                flags.lock(|f| f.speed_ref = w);
            }
            Command::Commission if !COMMISSIONING => {}
            Command::Commission if matches!(m.task.state(), DriveState::Idle) => {
                flags.lock(|f| f.commission = true);
            }
            Command::Commission => {}
            // `start` acts only from Idle: a fault needs the button first.
            Command::Start if !seen.latched => m.task.start(),
            Command::Start => {}
            Command::Stop => {
                flags.lock(|f| f.latched = false);
                m.task.stop();
            }
            Command::Button => match m.task.state() {
                DriveState::Fault(_) => {
                    flags.lock(|f| f.latched = false);
                    m.task.clear_fault();
                    recorder.lock(|r| r.rearm());
                }
                DriveState::Idle if !seen.latched => m.task.start(),
                _ => m.task.stop(),
            },
        }
    }

    /// The knob and the button: their commands (at most one of each kind), in order.
    fn poll_ui(m: &mut Motion) -> [Option<Command>; 3] {
        let mut out = [None; 3];
        let pot = read_pot(&m.adc1);
        let cmd = m.knob.update(pot);
        let running = matches!(cmd, KnobCommand::Run(_));
        // The knob starts and stops on its edges only, so the button can stop a drive that
        // the knob keeps at speed.
        match cmd {
            KnobCommand::Run(w) => {
                out[0] = Some(Command::Speed(w));
                if !m.knob_running {
                    out[1] = Some(Command::Start);
                }
            }
            KnobCommand::Stop if m.knob_running => out[1] = Some(Command::Stop),
            KnobCommand::Stop => {}
        }
        m.knob_running = running;
        // With the mode a short press acts when released (held 30 ms to 2 s), a long one
        // once held 2 s.
        // Without the mode the button acts once held 30 ms.
        if board::button_down(&m.gpioc) {
            m.pressed_polls = m.pressed_polls.saturating_add(1);
            if !COMMISSIONING && m.pressed_polls == 3 {
                out[2] = Some(Command::Button);
            }
            if COMMISSIONING && m.pressed_polls == board::LONG_PRESS_POLLS {
                out[2] = Some(Command::Commission);
            }
        } else {
            if COMMISSIONING && (3..board::LONG_PRESS_POLLS).contains(&m.pressed_polls) {
                out[2] = Some(Command::Button);
            }
            m.pressed_polls = 0;
        }
        out
    }

    /// A software-started conversion of the pot (ADC1 regular channel).
    fn read_pot(adc1: &pac::ADC1) -> u16 {
        adc1.isr().write(|w| w.eoc().clear());
        adc1.cr().modify(|_, w| w.adstart().start_conversion());
        while adc1.isr().read().eoc().bit_is_clear() {}
        adc1.dr().read().rdata().bits()
    }

    /// The logger: reports as they come, and the recorder's samples once a fault froze it.
    #[idle(local = [logger], shared = [recorder, reports, identify, rebuilt])]
    fn idle(mut cx: idle::Context) -> ! {
        let l = cx.local.logger;
        loop {
            while let Some(r) = cx.shared.reports.lock(|q| q.dequeue()) {
                log(l, &r);
            }
            // The identification's background work; its result once.
            if COMMISSIONING
                && let Some(result) = cx
                    .shared
                    .identify
                    .lock(|id| id.first_mut().and_then(Identify::poll))
            {
                match result {
                    Ok(found) => {
                        if let Some(r) = rebuild(l, &found) {
                            cx.shared.rebuilt.lock(|slot| {
                                slot.clear();
                                let _ = slot.push(r);
                            });
                        }
                    }
                    Err(e) => log_identify_error(e),
                }
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

    /// Logs the identified motor as a motor file (the keys `pmsm identify` writes, ratings
    /// from `motor.rs`) and builds the drive for it; `None` (logged) if the drive's
    /// configuration rejects it: the compiled-in motor stays.
    fn rebuild(l: &mut Logger, found: &Identified) -> Option<Rebuilt> {
        let mut m = found.motor;
        let rated = motor::motor();
        m.rated_current_a = rated.rated_current_a;
        m.rated_speed_rpm = rated.rated_speed_rpm;
        // One frame (one call: flash), a motor file line by line. The ratings are not
        // identified: `motor.rs`'s rated current, and no rated speed unless it gives one.
        defmt::println!(
            "# identified motor (a motor file; src/motor.rs takes the same values)\npole_pairs = {=u32}\nrs_ohm = {=f64}\nld_h = {=f64}\nlq_h = {=f64}\nflux_wb = {=f64}\nj_kg_m2 = {=f64}\nb_nm_s = {=f64}\nrated_current_a = {=f64}\n# rated_speed_rpm = {=f64} (0: not given in src/motor.rs)\n# distortion {=f64} V (resistance fit residual {=f64} V), load angle {=f64} rad",
            m.pole_pairs,
            m.rs_ohm,
            m.ld_h,
            m.lq_h,
            m.flux_wb,
            m.j_kg_m2,
            m.b_nm_s,
            m.rated_current_a.unwrap_or(0.0),
            m.rated_speed_rpm.unwrap_or(0.0),
            found.distortion_v,
            found.resistance_residual_v,
            found.load_angle_rad
        );
        let config = match DriveConfig::from_params(
            &m,
            &motor::inverter(),
            motor::PWM_HZ as f64,
            motor::options(),
        ) {
            Ok(c) => c,
            Err(e) => {
                defmt::warn!(
                    "the identified motor does not make a drive ({}): the compiled-in one stays",
                    e
                );
                return None;
            }
        };
        let base = config.base;
        let (Ok(current), Ok(voltage)) = (
            board::CURRENT.scale(base.current_a),
            board::VBUS.scale(base.voltage_v),
        ) else {
            defmt::warn!(
                "the identified motor's bases are out of the ADC's range: the compiled-in one stays"
            );
            return None;
        };
        l.rpm_per_pu = (base.omega_e_rad_s / m.p() * 60.0 / core::f64::consts::TAU) as f32;
        Some(Rebuilt {
            config,
            scaling: Scaling {
                current,
                voltage,
                offsets: [2048; 3],
            },
        })
    }

    fn log_identify_error(e: IdentifyError) {
        let why = match e {
            IdentifyError::NoCurrent(_) => "no current (open phase or no motor)",
            IdentifyError::RotorMoved(_) => "the rotor moved (or did not follow the field)",
            IdentifyError::Saturation(_) => "the voltage saturated",
            IdentifyError::Noise(_) => "inconsistent measurements (noise)",
            IdentifyError::OverCurrent(_) => "overcurrent",
            IdentifyError::BusLow(_) => "bus voltage too low",
        };
        defmt::warn!(
            "identification failed at the {=str} step: {=str}; the compiled-in motor stays",
            stage_name(e.stage()),
            why
        );
    }

    fn stage_name(s: Stage) -> &'static str {
        match s {
            Stage::Resistance => "resistance",
            Stage::InductanceD => "d-axis inductance",
            Stage::InductanceQ => "q-axis inductance",
            Stage::Flux => "flux",
            Stage::Inertia => "inertia",
        }
    }

    fn log(l: &mut Logger, r: &Report) {
        match r.event {
            Event::None => {}
            // Without the mode these never come (the guards drop their code).
            Event::CommissionStarted
            | Event::CommissionRefused
            | Event::CommissionAborted
            | Event::CommissionEnded
            | Event::DriveRebuilt
                if !COMMISSIONING => {}
            Event::CommissionStarted => defmt::info!(
                "commissioning: identifying the motor ({=u32} pole pairs, limit {=f32} A); the button stops it",
                motor::POLE_PAIRS,
                board::COMMISSION_CURRENT_A as f32
            ),
            Event::CommissionRefused => {
                defmt::warn!("commissioning: only from Idle, with the offsets measured")
            }
            Event::CommissionAborted => defmt::warn!("commissioning stopped: outputs off"),
            Event::CommissionEnded => defmt::info!("commissioning: sequence ended, fitting"),
            Event::DriveRebuilt => {
                defmt::info!("drive rebuilt for the identified motor (until reset)")
            }
            Event::Calibrated => defmt::info!("current offsets measured: ready"),
            Event::CalibrationFailed => {
                defmt::error!("current offsets out of range: check the OPAMPs and the motor wiring")
            }
            Event::Break => defmt::warn!(
                "break input: outputs off in hardware; stop (knob or button) to re-arm"
            ),
        }
        if COMMISSIONING && let Some(stage) = r.stage {
            defmt::info!("commissioning: {=str} step", stage_name(stage));
            return;
        }
        if l.last_state.map(|s| (s.code(), s.fault_code()))
            != Some((r.state.code(), r.state.fault_code()))
        {
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
