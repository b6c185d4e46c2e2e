//! Fuzzes `Drive::step` with arbitrary sensor words, speed commands and start/stop/clear
//! sequences on motor B: it must never panic, and a faulted drive must never switch.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pmsm_core::{
    Abc, Angle, Drive, DriveConfig, DriveInput, DriveOptions, DriveState, EstimatorKind,
    InverterParams, MotorParams, Pu, StartupMode,
};

fn word(b: &[u8]) -> i32 {
    let mut w = [0u8; 4];
    w[..b.len().min(4)].copy_from_slice(&b[..b.len().min(4)]);
    i32::from_le_bytes(w)
}

fuzz_target!(|data: &[u8]| {
    let Some((&head, rest)) = data.split_first() else { return };
    let mut m = MotorParams::new(3, 7.2, 0.025025, 0.04017, 0.305, 0.0036, 0.0011);
    m.rated_current_a = Some(2.53);
    let inv = InverterParams { vdc_v: 540.0, pwm_hz: 14e3, dead_time_s: 2e-6, current_full_scale_a: 10.0 };
    let kind = [EstimatorKind::MrasCurrent, EstimatorKind::Nlo, EstimatorKind::Ao, EstimatorKind::MrasEmf][(head & 3) as usize];
    let startup = match (head >> 2) & 3 {
        0 => StartupMode::Ipd,
        1 => StartupMode::Align,
        _ => StartupMode::Known(Angle(word(rest))),
    };
    let options = DriveOptions { estimator: kind, startup: Some(startup), ..DriveOptions::default() };
    let Ok(config) = DriveConfig::from_params(&m, &inv, 14e3, options) else { return };
    let mut d = Drive::new(config);
    d.start();
    for chunk in rest.chunks(17) {
        let op = chunk[0];
        let w = |k: usize| word(chunk.get(1 + 4 * k..).unwrap_or(&[]));
        match op % 16 {
            0 => d.stop(),
            1 => d.clear_fault(),
            2 => d.start(),
            3 => d.set_speed_ref(Pu::from_bits(w(0))),
            _ => {}
        }
        let out = d.step(&DriveInput {
            i_abc: Abc { a: Pu::from_bits(w(0)), b: Pu::from_bits(w(1)), c: Pu::from_bits(w(2)) },
            vdc: Pu::from_bits(w(3)),
        });
        for duty in [out.duties.a, out.duties.b, out.duties.c] {
            assert!((0..=1 << 30).contains(&duty.to_bits()));
        }
        if matches!(d.state(), DriveState::Fault(_) | DriveState::Idle) {
            assert!(!out.pwm_on);
        }
    }
});
