//! Self-commissioning against the plant on motors the routine was not tuned for: surface and
//! interior, 12 V to 540 V, 2 to 7 pole pairs, linear magnetics. The routine sees only the
//! ADC's phase currents and the bus voltage; the bars are R within 3 %, L_d and L_q within
//! 5 %, ψ within 3 % and J within 15 %. Run with `--nocapture` for the table.

use pmsm_cli::commands::identify::{BARS, errors, identify, identify_with};
use pmsm_core::{InverterParams, MotorParams};
use pmsm_plant::{AdcParams, InverterKind, MotorModel, Saturation};

struct Case {
    name: &'static str,
    vdc_v: f64,
    dead_time_s: f64,
    /// p, R, L_d, L_q, ψ, J, B, rated A RMS.
    m: (u32, f64, f64, f64, f64, f64, f64, f64),
}

/// The bars: R 3 %, L_d and L_q 5 %, ψ 3 %, J 15 % ([`BARS`]).
fn assert_within_bars(what: &str, e: &[f64; 6]) {
    for (k, (x, bar)) in e.iter().zip(BARS).enumerate() {
        assert!(
            x.abs() < bar,
            "{what}: {} off by {:+.2} %",
            ["R", "L_d", "L_q", "psi", "J"][k],
            100.0 * x
        );
    }
}

const CASES: [Case; 10] = [
    Case {
        name: "12 V gimbal, surface, p=7",
        vdc_v: 12.0,
        dead_time_s: 0.3e-6,
        m: (7, 0.10, 60e-6, 60e-6, 0.0025, 2e-5, 4e-6, 10.0),
    },
    Case {
        name: "24 V servo, surface, p=4",
        vdc_v: 24.0,
        dead_time_s: 0.3e-6,
        m: (4, 0.35, 0.5e-3, 0.5e-3, 0.008, 5e-5, 1e-5, 5.0),
    },
    Case {
        name: "24 V wheel, interior, p=7",
        vdc_v: 24.0,
        dead_time_s: 0.3e-6,
        m: (7, 0.12, 80e-6, 130e-6, 0.004, 3e-5, 5e-6, 12.0),
    },
    Case {
        name: "48 V traction, interior, p=5",
        vdc_v: 48.0,
        dead_time_s: 0.5e-6,
        m: (5, 0.08, 0.15e-3, 0.25e-3, 0.012, 2e-4, 4e-5, 20.0),
    },
    Case {
        name: "48 V pump, surface, p=2",
        vdc_v: 48.0,
        dead_time_s: 0.5e-6,
        m: (2, 0.5, 1.2e-3, 1.2e-3, 0.03, 1e-4, 2e-5, 4.0),
    },
    Case {
        name: "310 V compressor, interior, p=4",
        vdc_v: 310.0,
        dead_time_s: 1.5e-6,
        m: (4, 1.2, 6e-3, 11e-3, 0.12, 1.2e-3, 2e-4, 4.0),
    },
    Case {
        name: "400 V servo, surface, p=3",
        vdc_v: 400.0,
        dead_time_s: 1.5e-6,
        m: (3, 2.5, 15e-3, 15e-3, 0.25, 3e-3, 5e-4, 3.0),
    },
    Case {
        name: "540 V spindle, interior, p=3",
        vdc_v: 540.0,
        dead_time_s: 2e-6,
        m: (3, 4.0, 20e-3, 35e-3, 0.4, 6e-3, 1e-3, 3.5),
    },
    Case {
        name: "540 V traction, interior, p=6",
        vdc_v: 540.0,
        dead_time_s: 2e-6,
        m: (6, 0.6, 5e-3, 12e-3, 0.15, 4e-3, 8e-4, 10.0),
    },
    // A mechanical time constant J/B of 0.6 s: friction is a large part of the spin's power.
    Case {
        name: "400 V fan, surface, p=3, friction",
        vdc_v: 400.0,
        dead_time_s: 1.5e-6,
        m: (3, 2.5, 15e-3, 15e-3, 0.25, 3e-3, 5e-3, 3.0),
    },
];

#[test]
fn identifies_motors_it_was_not_tuned_for() {
    println!(
        "{:<34} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>6}",
        "motor", "R %", "Ld %", "Lq %", "psi %", "J %", "B %", "t s"
    );
    let mut worst = [0.0f64; 6];
    for c in &CASES {
        let (p, r, ld, lq, psi, j, b, irated) = c.m;
        let mut params = MotorParams::new(p, r, ld, lq, psi, j, b);
        params.rated_current_a = Some(irated);
        let mut model = MotorModel::new(params);
        model.saturation = Saturation::Linear;
        let limit = std::f64::consts::SQRT_2 * irated;
        let inverter = InverterParams {
            vdc_v: c.vdc_v,
            pwm_hz: 16e3,
            dead_time_s: c.dead_time_s,
            current_full_scale_a: 2.5 * limit,
        };
        let run = identify(&model, &inverter, InverterKind::Switching, limit, 40.0)
            .unwrap_or_else(|e| panic!("{}: {e:#}", c.name));
        let e = errors(&run.identified.motor, &model.params);
        println!(
            "{:<34} {:>+7.2} {:>+7.2} {:>+7.2} {:>+7.2} {:>+7.2} {:>+7.1} {:>6.2}",
            c.name,
            100.0 * e[0],
            100.0 * e[1],
            100.0 * e[2],
            100.0 * e[3],
            100.0 * e[4],
            100.0 * e[5],
            run.duration_s
        );
        for (w, x) in worst.iter_mut().zip(e) {
            *w = w.max(x.abs());
        }
    }
    println!(
        "worst: R {:.2} %, Ld {:.2} %, Lq {:.2} %, psi {:.2} %, J {:.2} %",
        100.0 * worst[0],
        100.0 * worst[1],
        100.0 * worst[2],
        100.0 * worst[3],
        100.0 * worst[4]
    );
    assert_within_bars("worst", &worst);
}

/// A board's current sensing is not ideal: offsets of 0.2 % and 0.1 % of full scale on two
/// phases and white noise of 0.5 % of full scale RMS on each reading. The same bars hold.
#[test]
fn adc_offsets_and_noise() {
    let c = &CASES[5];
    let (p, r, ld, lq, psi, j, b, irated) = c.m;
    let mut params = MotorParams::new(p, r, ld, lq, psi, j, b);
    params.rated_current_a = Some(irated);
    let mut model = MotorModel::new(params);
    model.saturation = Saturation::Linear;
    let limit = std::f64::consts::SQRT_2 * irated;
    let inverter = InverterParams {
        vdc_v: c.vdc_v,
        pwm_hz: 16e3,
        dead_time_s: c.dead_time_s,
        current_full_scale_a: 2.5 * limit,
    };
    let fs = inverter.current_full_scale_a;
    let mut adc = AdcParams::from_inverter(&inverter);
    adc.noise_rms_a = 0.005 * fs;
    adc.offset_a = [0.002 * fs, -0.001 * fs, 0.0];
    adc.seed = 7;
    let run = identify_with(
        &model,
        &inverter,
        InverterKind::Switching,
        adc,
        limit,
        -120.0,
        Default::default(),
    )
    .unwrap();
    let e = errors(&run.identified.motor, &model.params);
    println!(
        "{} with ADC offsets and noise: R {:+.2} %, Ld {:+.2} %, Lq {:+.2} %, psi {:+.2} %, J {:+.2} %",
        c.name,
        100.0 * e[0],
        100.0 * e[1],
        100.0 * e[2],
        100.0 * e[3],
        100.0 * e[4]
    );
    assert_within_bars(c.name, &e);
}

/// A heavy 540 V rotor (J = 0.027 kg m², 0.66 Wb, 11 kHz) starting near the unstable side of
/// α: it swings about α for longer than a level's settling, and still follows the spin's
/// damper after a window's settling. The routine waits for it (a fixed-time routine stopped at
/// the resistance step with no current, and with that fixed, read ψ and J 67 % high).
#[test]
fn a_heavy_rotor_is_waited_for() {
    let (p, r, l, psi, j, b) = (3, 8.4689, 48.05e-3, 0.6643, 0.02746, 7.07e-4);
    let mut params = MotorParams::new(p, r, l, l, psi, j, b);
    let limit = 4.025;
    params.rated_current_a = Some(limit / std::f64::consts::SQRT_2);
    let mut model = MotorModel::new(params);
    model.saturation = Saturation::Linear;
    let inverter = InverterParams {
        vdc_v: 540.0,
        pwm_hz: 11e3,
        dead_time_s: 2.06e-6,
        current_full_scale_a: 2.5 * limit,
    };
    let run = identify(&model, &inverter, InverterKind::Switching, limit, 153.7).unwrap();
    let e = errors(&run.identified.motor, &model.params);
    println!(
        "heavy rotor: R {:+.2} %, Ld {:+.2} %, Lq {:+.2} %, psi {:+.2} %, J {:+.2} % in {:.2} s",
        100.0 * e[0],
        100.0 * e[1],
        100.0 * e[2],
        100.0 * e[3],
        100.0 * e[4],
        run.duration_s
    );
    assert_within_bars("heavy rotor", &e);
}
