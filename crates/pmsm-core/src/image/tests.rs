extern crate std;

use super::*;
use crate::drive::{Drive, DriveConfig, DriveInput, DriveOptions};
use crate::fixtures::{inverter_b, motor_b};
use crate::frames::{Abc, AlphaBeta, inverse_clarke};
use crate::num::Pu;
use crate::observer::EstimatorKind;
use crate::params::{InverterParams, MotorParams};
use crate::units::to_f64;
use std::format;
use std::vec::Vec;

/// Motor A of Solsona, Valla, Muravchik (2000) on a 300 V inverter at 10 kHz.
fn motor_a() -> (MotorParams, InverterParams) {
    let mut m = MotorParams::new(3, 1.6, 0.0134, 0.0134, 0.288, 0.04256, 0.004256);
    m.kt_nm_per_a = 1.108;
    let inv = InverterParams {
        vdc_v: 300.0,
        pwm_hz: 10e3,
        dead_time_s: 1e-6,
        current_full_scale_a: 40.0,
    };
    (m, inv)
}

/// The drives of the tests: motor A with its defaults and with the AO; motor B with its
/// defaults (the current-model MRAS, the detection, the tracker and the learner), with the
/// MRAS on the EMF and with a PWM update delay.
fn drives() -> Vec<(&'static str, DriveConfig)> {
    let (a, inv_a) = motor_a();
    let (b, inv_b) = (motor_b(), inverter_b());
    let with = |estimator, pwm_delay_samples| DriveOptions {
        estimator,
        pwm_delay_samples,
        ..DriveOptions::default()
    };
    let mut out = Vec::new();
    for (name, m, inv, options) in [
        ("motor A", a, inv_a, with(None, None)),
        ("motor A, AO", a, inv_a, with(Some(EstimatorKind::Ao), None)),
        ("motor B", b, inv_b, with(None, None)),
        (
            "motor B, MRAS-EMF",
            b,
            inv_b,
            with(Some(EstimatorKind::MrasEmf), None),
        ),
        ("motor B, PWM delay", b, inv_b, with(None, Some(1))),
    ] {
        let config = DriveConfig::from_params(&m, &inv, inv.pwm_hz, options)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        out.push((name, config));
    }
    out
}

fn image_of(config: &DriveConfig) -> Vec<u32> {
    let mut words = [0u32; DriveConfig::IMAGE_WORDS];
    config.write_image(&mut words);
    words.to_vec()
}

/// A drive run: started, the speed reference at `speed`, fed the currents of a rotor turning
/// at the drive's estimated speed with a lag, for `steps` samples. Every output and telemetry.
fn run(config: DriveConfig, steps: usize) -> Vec<std::string::String> {
    let mut drive = Drive::new(config);
    drive.start();
    drive.set_speed_ref(Pu::from_num(0.3));
    let mut theta = 0.0f64;
    let mut log = Vec::with_capacity(steps);
    for k in 0..steps {
        let omega = to_f64(drive.telemetry().estimate.omega);
        theta += omega * 0.05 + 1e-3;
        let amp = 0.2 + 0.1 * libm::sin(k as f64 * 1e-3);
        let i: Abc = inverse_clarke(AlphaBeta {
            alpha: Pu::from_num(amp * libm::cos(theta + 0.3)),
            beta: Pu::from_num(amp * libm::sin(theta + 0.3)),
        });
        let out = drive.step(&DriveInput {
            i_abc: i,
            vdc: Pu::from_num(1.732),
        });
        log.push(format!(
            "{out:?} {:?} {:?}",
            drive.state(),
            drive.telemetry()
        ));
    }
    log
}

/// The configuration printed, but for why the injection was declined (a diagnostic the image
/// does not hold: `None` once read back).
fn printed(config: &DriveConfig) -> std::string::String {
    let s = format!("{config:?}");
    #[cfg(feature = "injection")]
    if let (Some(a), Some(b)) = (
        s.find("injection_declined: "),
        s.find("injection_figures: "),
    ) {
        return format!("{}{}", &s[..a], &s[b..]);
    }
    s
}

#[test]
fn every_drive_reads_back_from_its_image_bit_for_bit() {
    for (name, config) in drives() {
        let words = image_of(&config);
        assert_eq!(words.len(), DriveConfig::IMAGE_WORDS, "{name}");
        assert_eq!(words[0], IMAGE_MAGIC, "{name}");
        assert_eq!(words[1], DriveConfig::IMAGE_SCHEMA, "{name}");
        let read = DriveConfig::from_image(&words).unwrap_or_else(|e| panic!("{name}: {e}"));
        #[cfg(feature = "injection")]
        assert_eq!(read.injection_declined(), None, "{name}");
        // Every field (the design's f64 figures by their bits) is in the words: the same
        // words again, the same value printed.
        assert_eq!(image_of(&read), words, "{name}");
        assert_eq!(printed(&read), printed(&config), "{name}");
        // And the drives built from both compute the same bits.
        let (a, b) = (run(config, 3000), run(read, 3000));
        let differ = a.iter().zip(&b).filter(|(x, y)| x != y).count();
        assert_eq!(differ, 0, "{name}: {differ} of 3000 steps differ");
    }
}

#[test]
fn drives_of_other_motors_have_other_images_of_the_same_length() {
    let configs = drives();
    let images: Vec<_> = configs.iter().map(|(_, c)| image_of(c)).collect();
    for (i, a) in images.iter().enumerate() {
        for b in &images[i + 1..] {
            assert_eq!(a.len(), b.len());
            let differ = a.iter().zip(b).filter(|(x, y)| x != y).count();
            // Motor A and B differ in most coefficients; the drives of one motor in a few.
            assert!(differ >= 3, "{differ} words differ");
        }
    }
}

#[test]
fn images_of_another_build_or_corrupted_are_refused_by_name() {
    let (_, config) = drives().remove(2);
    let words = image_of(&config);
    let mut bad = words.clone();
    bad[0] ^= 1;
    assert_eq!(DriveConfig::from_image(&bad).err(), Some(ImageError::Magic));
    let mut bad = words.clone();
    bad[1] = bad[1].wrapping_add(1);
    assert_eq!(
        DriveConfig::from_image(&bad).err(),
        Some(ImageError::Schema {
            expected: DriveConfig::IMAGE_SCHEMA,
            found: DriveConfig::IMAGE_SCHEMA.wrapping_add(1)
        })
    );
    let n = words.len() as u32;
    assert_eq!(
        DriveConfig::from_image(&words[..words.len() - 1]).err(),
        Some(ImageError::Length {
            expected: n,
            found: n - 1
        })
    );
    let mut long = words.clone();
    long.push(0);
    assert!(matches!(
        DriveConfig::from_image(&long),
        Err(ImageError::Length { .. })
    ));
    // Every word set: tags, flags and narrow integers out of their range.
    let mut bad = words.clone();
    bad[2..].fill(u32::MAX);
    assert_eq!(
        DriveConfig::from_image(&bad).err(),
        Some(ImageError::Invalid)
    );
    assert_eq!(DriveConfig::from_image(&[]).err(), Some(ImageError::Magic));
}

#[test]
fn a_flipped_tag_is_refused_not_misread() {
    // Each word after the header raised by 7 in turn: a word that is a tag, a flag, a narrow
    // integer or padding makes the image invalid; any other reads back as that value.
    let (_, config) = drives().remove(2);
    let words = image_of(&config);
    let mut refused = 0;
    for k in 2..words.len() {
        let mut w = words.clone();
        w[k] = w[k].wrapping_add(7);
        match DriveConfig::from_image(&w) {
            Err(ImageError::Invalid) => refused += 1,
            Err(e) => panic!("word {k}: {e}"),
            Ok(c) => assert_eq!(image_of(&c), w, "word {k}"),
        }
    }
    // Motor B's drive has dozens of enum tags, options and flags.
    assert!(refused >= 30, "{refused} words refused");
}

#[test]
fn narrow_integers_and_flags_read_only_their_values() {
    let mut out = [0u32; 4];
    let mut w = WordWriter::new(&mut out);
    (-3i8).put(&mut w);
    200u8.put(&mut w);
    true.put(&mut w);
    (-30_000i16).put(&mut w);
    assert_eq!(out, [0xFFFF_FFFD, 200, 1, (-30_000i32) as u32]);
    let mut r = WordReader::new(&out);
    assert_eq!(
        (
            i8::get(&mut r),
            u8::get(&mut r),
            bool::get(&mut r),
            i16::get(&mut r)
        ),
        (-3, 200, true, -30_000)
    );
    assert!(r.done());
    for (w, ok) in [(0x80u32, false), (0xFFFF_FF80, true), (0x7F, true)] {
        let mut r = WordReader::new(core::slice::from_ref(&w));
        let _ = i8::get(&mut r);
        assert_eq!(r.done(), ok, "{w:#x} as i8");
    }
    let mut r = WordReader::new(&[2]);
    let _ = bool::get(&mut r);
    assert!(!r.done());
}

/// `FLOATS` counts the floating-point values where they are (what the interrupt side keeps is
/// checked at compile time to have none): the dead-time design's five figures, an array's,
/// an option's, an enum's over its variants, and the many of a drive's whole configuration.
#[test]
fn floats_are_counted_where_they_are() {
    assert_eq!(<crate::deadtime::DeadTimeDesign as Words>::FLOATS, 5);
    assert_eq!(<[f64; 3] as Words>::FLOATS, 3);
    assert_eq!(<Option<(f32, u32)> as Words>::FLOATS, 1);
    assert_eq!(<crate::drive::StartupMode as Words>::FLOATS, 0);
    // The MRAS on the EMF's constants, in its variant of the estimator's configuration.
    if cfg!(any(
        not(feature = "select-estimators"),
        feature = "mras-emf"
    )) {
        assert_eq!(<crate::observer::EstimatorConfig as Words>::FLOATS, 3);
    }
    assert_eq!(<Pu as Words>::FLOATS, 0);
    // A struct's count is its fields': the drive's whole configuration, whose interrupt-side
    // parts (the current loops', the detection's, the interrupt's own) count none.
    fn floats<T: Words>(_: &T) -> usize {
        T::FLOATS
    }
    let inv = inverter_b();
    let c =
        DriveConfig::from_params(&motor_b(), &inv, inv.pwm_hz, DriveOptions::default()).unwrap();
    #[allow(unused_mut)]
    let mut parts = <crate::units::PerUnit as Words>::FLOATS
        + <crate::drive::DriveDesign as Words>::FLOATS
        + <MotorParams as Words>::FLOATS
        + <f64 as Words>::FLOATS // the dead-time voltage at the nominal bus
        + <crate::observer::EstimatorConfig as Words>::FLOATS
        + <crate::control::speed::SpeedConfig as Words>::FLOATS
        + floats(&c.task);
    #[cfg(feature = "injection")]
    {
        parts += <Option<crate::observer::InjectionFigures> as Words>::FLOATS;
    }
    assert_eq!(<DriveConfig as Words>::FLOATS, parts);
}
