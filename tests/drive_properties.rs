//! Property tests of the drive's control step on wild inputs: random sensor words (any i32),
//! random motors within the envelope and random speed commands. The step must never panic,
//! its duties must stay in [0, 1], a fault must turn the outputs off (overspeed: short the
//! motor, `ACTIVE_SHORT`), and every state must stay finite (the estimate included).

use pmsm_core::{
    ACTIVE_SHORT, Abc, Angle, Drive, DriveConfig, DriveInput, DriveOptions, DriveState,
    EstimatorKind, Fault, InverterParams, MotorParams, Pu, StartupMode,
};
use proptest::prelude::*;

fn drive(scale: f64, estimator: EstimatorKind, startup: StartupMode) -> Option<Drive> {
    // Motor B scaled in impedance and flux (bus scaled with it), a family within the envelope.
    let mut m = MotorParams::new(
        3,
        7.2 * scale,
        0.025 * scale,
        0.040 * scale,
        0.305 * scale.sqrt(),
        0.0036,
        0.0011,
    );
    m.rated_current_a = Some(2.53 / scale.sqrt());
    let inv = InverterParams {
        vdc_v: 540.0 * scale.sqrt(),
        pwm_hz: 14e3,
        dead_time_s: 2e-6,
        current_full_scale_a: 10.0,
    };
    let options = DriveOptions {
        estimator: Some(estimator),
        startup: Some(startup),
        ..DriveOptions::default()
    };
    let config = DriveConfig::from_params(&m, &inv, 14e3, options).ok()?;
    Some(Drive::new(config))
}

fn check(d: &mut Drive, words: &[(i32, i32, i32, i32)], speed: i32) -> Result<(), TestCaseError> {
    d.set_speed_ref(Pu::from_bits(speed));
    d.start();
    for &(a, b, c, v) in words {
        let out = d.step(&DriveInput {
            i_abc: Abc {
                a: Pu::from_bits(a),
                b: Pu::from_bits(b),
                c: Pu::from_bits(c),
            },
            vdc: Pu::from_bits(v),
        });
        for duty in [out.duties.a, out.duties.b, out.duties.c] {
            prop_assert!(
                duty.to_bits() >= 0 && duty.to_bits() <= 1 << 30,
                "duty {duty}"
            );
        }
        if let DriveState::Fault(f) = d.state() {
            // Overspeed alone short-circuits the motor instead (docs/field-weakening.md §4).
            let shorted = matches!(f, Fault::Overspeed(_)) && out == ACTIVE_SHORT;
            prop_assert!(!out.pwm_on || shorted, "a faulted drive keeps switching");
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Any sensor words at all, in every start-up and with every estimator.
    #[test]
    fn random_sensor_words_never_panic(
        words in prop::collection::vec((any::<i32>(), any::<i32>(), any::<i32>(), any::<i32>()), 1..400),
        speed in any::<i32>(),
        scale in 0.2f64..5.0,
        which in 0usize..4,
        angle in any::<i32>(),
    ) {
        let kinds = [EstimatorKind::MrasCurrent, EstimatorKind::Nlo, EstimatorKind::Ao, EstimatorKind::MrasEmf];
        for startup in [StartupMode::Ipd, StartupMode::Align, StartupMode::Known(Angle(angle))] {
            if let Some(mut d) = drive(scale, kinds[which], startup) {
                check(&mut d, &words, speed)?;
            }
        }
    }

    /// Plausible sensor words (currents within ±1.5 pu summing to zero, the bus near nominal)
    /// with every estimator and start-up: the drive switches only in a running state, faults
    /// only with a name the plausible words can cause, and keeps its estimate bounded, and
    /// (the words being what a sensor could read) it runs through most of them without a
    /// protection trip on the raw words.
    #[test]
    fn plausible_words_keep_states_bounded(
        words in prop::collection::vec((-(3i32 << 23)..(3 << 23), -(3i32 << 23)..(3 << 23), (28i32 << 20)..(30 << 20)), 1..600),
        speed in -(1i32 << 23)..(1 << 23),
        which in 0usize..4,
        start in 0usize..3,
    ) {
        let kinds = [EstimatorKind::MrasCurrent, EstimatorKind::Nlo, EstimatorKind::Ao, EstimatorKind::MrasEmf];
        let startup = [StartupMode::Known(Angle::ZERO), StartupMode::Ipd, StartupMode::Align][start];
        let mut d = drive(1.0, kinds[which], startup).unwrap();
        d.set_speed_ref(Pu::from_bits(speed));
        d.start();
        for (a, b, v) in words {
            let out = d.step(&DriveInput {
                // A balanced set: c = −a − b (|a + b| < 3 pu, within range).
                i_abc: Abc { a: Pu::from_bits(a), b: Pu::from_bits(b), c: Pu::from_bits(-a - b) },
                vdc: Pu::from_bits(v),
            });
            let shorted = matches!(d.state(), DriveState::Fault(Fault::Overspeed(_))) && out == ACTIVE_SHORT;
            if out.pwm_on {
                prop_assert!(shorted || matches!(d.state(), DriveState::Run | DriveState::OpenLoop | DriveState::Ipd | DriveState::Align));
            }
            if let DriveState::Fault(f) = d.state() {
                // Not the sensor or bus checks: the words are a balanced set on a good bus.
                prop_assert!(
                    !matches!(f.name(), "current_sensor" | "bus_undervoltage" | "bus_overvoltage"),
                    "{}", f.name()
                );
                prop_assert!(!out.pwm_on || shorted);
            }
            // The current-model MRAS clamps its speed to ±4 pu (the EMF observers' speed is
            // |ê|/ψ of whatever the words imply: a saturating Pu, bounded by its type).
            if which == 0 {
                prop_assert!(d.telemetry().estimate.omega.abs() <= Pu::from_num(4));
            }
        }
    }
}

/// The family of motors the properties draw from builds at both ends (the properties would
/// otherwise test nothing).
#[test]
fn the_motor_family_builds() {
    for scale in [0.2, 1.0, 5.0] {
        for kind in [EstimatorKind::MrasCurrent, EstimatorKind::Nlo] {
            assert!(
                drive(scale, kind, StartupMode::Ipd).is_some(),
                "{scale} {kind:?}"
            );
        }
    }
}
