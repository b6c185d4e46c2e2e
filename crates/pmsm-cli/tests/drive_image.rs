//! A drive loaded from its image (`DriveConfig::write_image` / `from_image`, docs/image.md)
//! runs exactly as the drive designed in place: motor B and the 24 V interior motor C with
//! their defaults (the detection, the current-model MRAS, the tracker of R and ψ and the
//! learner of the inverter's distortion) and motor A's surface drive, in a closed loop with
//! the switching plant from rest to speed under load, every output compared bit for bit.

use core::f64::consts::TAU;
use pmsm_core::fixtures::{inverter_b, motor_b};
use pmsm_core::{
    Abc, Drive, DriveConfig, DriveInput, DriveOptions, DriveState, InverterParams, MotorParams,
    PerUnit,
};
use pmsm_plant::{AdcParams, InverterKind, InverterModel, Motor, MotorModel, Plant};

mod common;

/// Per step: the duties' bits, the state and the estimate; at the end the rotor's speed.
struct Run {
    log: Vec<(u64, DriveState, u64, i32)>,
    rotor_rpm: f64,
    ran: bool,
}

fn run(m: MotorParams, inv: InverterParams, config: DriveConfig, rpm: f64, load_nm: f64) -> Run {
    let fs = inv.pwm_hz;
    let base = PerUnit::new(&m, &inv, fs).unwrap();
    let mut drive = Drive::new(config);
    let motor = Motor::new(MotorModel::new(m), 1.0, 0.0).unwrap();
    let mut plant = Plant::new(
        motor,
        InverterModel::new(inv, InverterKind::Switching),
        AdcParams::from_inverter(&inv),
    )
    .unwrap();
    drive.start();
    let (mut i, mut vdc) = ([0.0; 3], inv.vdc_v);
    let mut log = Vec::new();
    let mut ran = false;
    for k in 0..(1.2 * fs) as usize {
        let t = k as f64 / fs;
        drive.set_speed_ref(base.speed_pu(rpm * (t / 0.5).min(1.0) * TAU / 60.0 * m.p()));
        let out = drive.step(&DriveInput {
            i_abc: Abc {
                a: base.current_pu(i[0]),
                b: base.current_pu(i[1]),
                c: base.current_pu(i[2]),
            },
            vdc: base.voltage_pu(vdc),
        });
        let e = drive.telemetry().estimate;
        let d = out.duties;
        let bits = u64::from(d.a.to_bits() as u32)
            ^ (u64::from(d.b.to_bits() as u32) << 20)
            ^ (u64::from(d.c.to_bits() as u32) << 40)
            ^ u64::from(out.pwm_on);
        log.push((
            bits,
            drive.state(),
            e.theta.to_rad().to_bits(),
            e.omega.to_bits(),
        ));
        ran |= drive.state() == DriveState::Run;
        let load = if t > 0.7 { load_nm } else { 0.0 };
        let s = if out.pwm_on {
            plant.step_pwm(out.duties.to_f64(), load)
        } else {
            plant.step_off(load)
        }
        .unwrap();
        i = s.i_abc_a_measured;
        vdc = s.vdc_v;
    }
    let rotor_rpm = plant.motor().state().omega_m_rad_s * 60.0 / TAU;
    Run {
        log,
        rotor_rpm,
        ran,
    }
}

fn image_of(config: &DriveConfig) -> Vec<u32> {
    let mut words = [0u32; DriveConfig::IMAGE_WORDS];
    config.write_image(&mut words);
    words.to_vec()
}

fn check(name: &str, m: MotorParams, inv: InverterParams, rpm: f64, load_nm: f64) {
    let config = DriveConfig::from_params(&m, &inv, inv.pwm_hz, DriveOptions::default()).unwrap();
    let loaded = DriveConfig::from_image(&image_of(&config)).unwrap();
    let a = run(m, inv, config, rpm, load_nm);
    let b = run(m, inv, loaded, rpm, load_nm);
    // The comparison means something: the drive ran and holds the speed under load.
    assert!(a.ran, "{name}: never ran");
    assert!(
        (a.rotor_rpm - rpm).abs() < 0.05 * rpm,
        "{name}: rotor at {:.0} r/min, asked {rpm}",
        a.rotor_rpm
    );
    let differ = a.log.iter().zip(&b.log).filter(|(x, y)| x != y).count();
    assert_eq!(a.log.len(), b.log.len());
    assert_eq!(
        differ,
        0,
        "{name}: {differ} of {} steps differ",
        a.log.len()
    );
    assert_eq!(a.rotor_rpm.to_bits(), b.rotor_rpm.to_bits(), "{name}");
}

#[test]
fn motor_b_runs_the_same_bits_from_its_image() {
    check("motor B", motor_b(), inverter_b(), 1500.0, 3.0);
}

/// The motor of `examples/<name>` (the ideal plant of its parameters).
fn example_motor(name: &str) -> MotorParams {
    pmsm_cli::motor_file::read(&common::example(name))
        .unwrap()
        .model
        .params
}

/// An inverter of `vdc_v` switching at `pwm_hz` with the current sensing's full scale.
fn inverter(
    vdc_v: f64,
    pwm_hz: f64,
    dead_time_s: f64,
    current_full_scale_a: f64,
) -> InverterParams {
    InverterParams {
        vdc_v,
        pwm_hz,
        dead_time_s,
        current_full_scale_a,
    }
}

#[test]
fn interior_motor_c_runs_the_same_bits_from_its_image() {
    let inv = inverter(24.0, 20e3, 0.5e-6, 60.0);
    check(
        "motor C",
        example_motor("motor-c-24v.toml"),
        inv,
        1000.0,
        1.0,
    );
}

#[test]
fn surface_motor_a_runs_the_same_bits_from_its_image() {
    let inv = inverter(300.0, 10e3, 1e-6, 40.0);
    check("motor A", example_motor("motor-a.toml"), inv, 600.0, 3.0);
}
