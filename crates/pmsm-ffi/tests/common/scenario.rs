//! The recorded scenario of the C replays: motor B (examples/motor-b.toml) on its 540 V,
//! 14 kHz inverter with 2 µs dead time (switching-level model, 12-bit ADC), the current-model
//! MRAS drive started by IPD from 137°, a speed ramp to 600 r/min, then an injected
//! overcurrent sample (a fault), its clearance and a second start.
//!
//! The drive is the Rust one, built with the Rust API (not through the C configuration), so a
//! replay through the C ABI checks the conversion of `pmsm_config_t` too.
//!
//! File format (little-endian `i32` words): `MAGIC, VERSION, steps, WORDS, period`, then
//! `WORDS` words per step, in the order of [`Word`].
#![allow(dead_code)]

use pmsm_core::{
    Abc, Drive, DriveConfig, DriveInput, DriveOptions, InverterParams, PerUnit, StartupMode,
};
use pmsm_ffi::{fault_code, pmsm_config_t, state_code};
use pmsm_plant::{AdcParams, InverterKind, InverterModel, Motor, MotorModel, Plant};
use std::f64::consts::TAU;

/// Control samples recorded.
pub const STEPS: usize = 6000;
/// PWM timer period for the compare values (84 MHz, centre-aligned, 14 kHz).
pub const PERIOD: u16 = 3000;
/// "CFFI".
pub const MAGIC: i32 = 0x4946_4643;
/// Format version.
pub const VERSION: i32 = 1;
/// Command bits applied before a step.
pub const CMD_START: i32 = 1;
/// See [`CMD_START`].
pub const CMD_STOP: i32 = 2;
/// See [`CMD_START`].
pub const CMD_CLEAR_FAULT: i32 = 4;
/// Step at which an overcurrent sample is injected (the plant does not see it).
pub const FAULT_STEP: usize = 5000;
/// Step at which the fault is cleared and the drive started again.
pub const RESTART_STEP: usize = 5040;

/// The words of one step.
#[derive(Clone, Copy)]
pub enum Word {
    /// Command bits applied before the step.
    Cmd,
    /// Speed reference, Q8.24 pu.
    SpeedRef,
    /// Inputs, Q8.24 pu.
    Ia,
    /// See `Ia`.
    Ib,
    /// See `Ia`.
    Ic,
    /// See `Ia`.
    Vdc,
    /// Duties, Q2.30.
    DutyA,
    /// See `DutyA`.
    DutyB,
    /// See `DutyA`.
    DutyC,
    /// Compare values for [`PERIOD`].
    CmpA,
    /// See `CmpA`.
    CmpB,
    /// See `CmpA`.
    CmpC,
    /// 0 or 1.
    PwmOn,
    /// `pmsm_state_t` after the step.
    State,
    /// `pmsm_fault_t` after the step.
    Fault,
    /// Estimated angle, turn.
    Theta,
    /// Estimated speed, Q8.24 pu.
    Omega,
}
/// Words per step.
pub const WORDS: usize = 17;

pub use pmsm_core::fixtures::motor_b;

/// Its inverter (the current full scale is set from the base, as `pmsm simulate` does).
pub fn inverter_b() -> InverterParams {
    InverterParams {
        vdc_v: 540.0,
        pwm_hz: 14_000.0,
        dead_time_s: 2e-6,
        current_full_scale_a: 1.0,
    }
}

/// The same drive as a C configuration (the values the C programs use).
pub fn config_c() -> pmsm_config_t {
    pmsm_config_t {
        pole_pairs: 3,
        estimator: 0,
        startup: 1,
        pwm_period_ticks: PERIOD as u32,
        rs_ohm: 7.2,
        ld_h: 0.025025,
        lq_h: 0.04017,
        flux_wb: 0.305,
        j_kg_m2: 0.0036,
        b_nm_s: 0.0011,
        rated_current_a: 2.53,
        rated_speed_rpm: 3000.0,
        vdc_v: 540.0,
        pwm_hz: 14_000.0,
        dead_time_s: 2e-6,
        ..Default::default()
    }
}

/// Runs the Rust drive against the plant; one row of [`WORDS`] per step.
pub fn record() -> Vec<[i32; WORDS]> {
    let m = motor_b();
    let mut inv = inverter_b();
    let sample_hz = inv.pwm_hz;
    let base = PerUnit::new(&m, &inv, sample_hz).expect("base");
    inv.current_full_scale_a = 4.0 * base.current_a;
    let options = DriveOptions {
        startup: Some(StartupMode::Ipd),
        ..DriveOptions::default()
    };
    let config = DriveConfig::from_params(&m, &inv, sample_hz, options).expect("config");
    let mut drive = Drive::new(config);

    let motor = Motor::new(MotorModel::new(m), 137f64.to_radians(), 0.0).expect("motor");
    let adc = AdcParams::from_inverter(&inv);
    let mut plant =
        Plant::new(motor, InverterModel::new(inv, InverterKind::Switching), adc).expect("plant");

    let rpm_to_pu = |rpm: f64| base.speed_pu(rpm * TAU / 60.0 * m.p()).to_bits();
    let (mut i_meas, mut vdc) = ([0.0; 3], inv.vdc_v);
    let mut rows = Vec::with_capacity(STEPS);
    for k in 0..STEPS {
        let t = k as f64 / sample_hz;
        let mut row = [0i32; WORDS];
        let cmd = match k {
            0 => CMD_START,
            RESTART_STEP => CMD_CLEAR_FAULT | CMD_START,
            _ => 0,
        };
        if cmd & CMD_STOP != 0 {
            drive.stop();
        }
        if cmd & CMD_CLEAR_FAULT != 0 {
            drive.clear_fault();
        }
        if cmd & CMD_START != 0 {
            drive.start();
        }
        let rpm = (600.0 * (t - 0.03) / 0.15).clamp(0.0, 600.0);
        let speed_ref = rpm_to_pu(rpm);
        drive.set_speed_ref(pmsm_core::Pu::from_bits(speed_ref));
        let mut input = DriveInput {
            i_abc: Abc {
                a: base.current_pu(i_meas[0]),
                b: base.current_pu(i_meas[1]),
                c: base.current_pu(i_meas[2]),
            },
            vdc: base.voltage_pu(vdc),
        };
        if k == FAULT_STEP {
            input.i_abc.a = base.current_pu(-4.0 * base.current_a);
        }
        let out = drive.step(&input);
        let cmp = out.duties.to_compare(PERIOD);
        let s = drive.state();
        let e = drive.telemetry().estimate;
        row[Word::Cmd as usize] = cmd;
        row[Word::SpeedRef as usize] = speed_ref;
        row[Word::Ia as usize] = input.i_abc.a.to_bits();
        row[Word::Ib as usize] = input.i_abc.b.to_bits();
        row[Word::Ic as usize] = input.i_abc.c.to_bits();
        row[Word::Vdc as usize] = input.vdc.to_bits();
        row[Word::DutyA as usize] = out.duties.a.to_bits();
        row[Word::DutyB as usize] = out.duties.b.to_bits();
        row[Word::DutyC as usize] = out.duties.c.to_bits();
        row[Word::CmpA as usize] = cmp[0] as i32;
        row[Word::CmpB as usize] = cmp[1] as i32;
        row[Word::CmpC as usize] = cmp[2] as i32;
        row[Word::PwmOn as usize] = out.pwm_on as i32;
        row[Word::State as usize] = state_code(&s) as i32;
        row[Word::Fault as usize] = fault_code(&s).0 as i32;
        row[Word::Theta as usize] = e.theta.0;
        row[Word::Omega as usize] = e.omega.to_bits();
        rows.push(row);
        let sample = if out.pwm_on {
            plant.step_pwm(out.duties.to_f64(), 0.0)
        } else {
            plant.step_off(0.0)
        }
        .expect("plant step");
        i_meas = sample.i_abc_a_measured;
        vdc = sample.vdc_v;
    }
    rows
}

/// The file contents.
pub fn encode(rows: &[[i32; WORDS]]) -> Vec<u8> {
    let head = [
        MAGIC,
        VERSION,
        rows.len() as i32,
        WORDS as i32,
        PERIOD as i32,
    ];
    head.iter()
        .chain(rows.iter().flatten())
        .flat_map(|w| w.to_le_bytes())
        .collect()
}
