//! Thermal factors: a plant whose resistance (or flux) is scaled by a factor runs exactly
//! like a plant built with the scaled value.

use pmsm_core::{InverterParams, MotorParams};
use pmsm_plant::{
    AdcParams, InverterKind, InverterModel, Motor, MotorModel, Plant, Saturation, Thermal,
};

fn plant(params: MotorParams) -> Plant {
    let inv = InverterParams {
        vdc_v: 540.0,
        pwm_hz: 14e3,
        dead_time_s: 2e-6,
        current_full_scale_a: 10.0,
    };
    // Linear magnetics: the default saturation is scaled to the motor's own flux.
    let mut model = MotorModel::new(params);
    model.saturation = Saturation::Linear;
    Plant::new(
        Motor::new(model, 0.3, 0.0).unwrap(),
        InverterModel::new(inv, InverterKind::Averaged),
        AdcParams::from_inverter(&inv),
    )
    .unwrap()
}

fn motor_b() -> MotorParams {
    MotorParams::new(3, 7.2, 0.025025, 0.04017, 0.305, 0.0036, 0.0011)
}

/// Largest difference of the true phase currents over 3000 periods of a turning voltage.
fn max_diff(a: &mut Plant, b: &mut Plant, thermal: Option<&Thermal>) -> (f64, f64) {
    let (mut worst, mut peak) = (0.0f64, 0.0f64);
    for k in 0..3000 {
        if let Some(th) = thermal {
            th.apply(a).unwrap();
        }
        let th = k as f64 * 0.01;
        let d = [0.0, 1.0, 2.0].map(|x: f64| 0.5 + 0.08 * (th - x * 2.094_395_1).cos());
        let sa = a.step_pwm(d, 0.0).unwrap();
        let sb = b.step_pwm(d, 0.0).unwrap();
        for (x, y) in sa.i_abc_a_true.iter().zip(sb.i_abc_a_true) {
            worst = worst.max((x - y).abs());
            peak = peak.max(y.abs());
        }
    }
    (worst, peak)
}

#[test]
fn rs_factor_matches_the_scaled_plant() {
    let mut hot = motor_b();
    hot.rs_ohm *= 1.4;
    let mut a = plant(motor_b());
    let mut b = plant(hot);
    let th = Thermal::new(&[0.0], &[1.4], &[1.0]).unwrap();
    let (worst, peak) = max_diff(&mut a, &mut b, Some(&th));
    assert!(peak > 0.5, "the test drives current: {peak}");
    assert!(worst < 1e-9 * peak, "{worst} A of {peak}");
    // And it does matter: the unscaled plant differs.
    let (cold, _) = max_diff(&mut plant(motor_b()), &mut plant(hot), None);
    assert!(cold > 1e-3 * peak, "{cold}");
}

#[test]
fn flux_factor_matches_the_scaled_plant() {
    let mut weak = motor_b();
    weak.flux_wb *= 0.9;
    weak.kt_nm_per_a *= 0.9;
    let mut a = plant(motor_b());
    let mut b = plant(weak);
    let th = Thermal::new(&[0.0, 1.0], &[1.0, 1.0], &[0.9, 0.9]).unwrap();
    let (worst, peak) = max_diff(&mut a, &mut b, Some(&th));
    assert!(worst < 1e-9 * peak, "{worst} A of {peak}");
}
