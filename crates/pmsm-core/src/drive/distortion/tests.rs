//! The learner against its f64 reference on synthetic steady states of motor B: a current
//! and a voltage with the sixth-harmonic ripple the residual dead-time error leaves, shared
//! between the two as current loops would share it.

extern crate std;

use super::batch::END_STAGES as END;
use super::*;
use crate::angle::Angle;
use crate::fixtures::{inverter_b, motor_b};
use crate::frames::{AlphaBeta, Dq};
use crate::num::pu_from_f64;
use crate::units::PerUnit;
use std::println;
use std::vec::Vec;

/// One sample of a synthetic steady state, per unit: the frame's angle, the current and the
/// loops' voltage (αβ).
struct Sample {
    theta: f64,
    i: [f64; 2],
    v: [f64; 2],
}

/// Motor B, its bases at 14 kHz, and `R`, `L_d`, `L_q` per unit.
fn model() -> (MotorParams, PerUnit, [f64; 3]) {
    let m = motor_b();
    let base = PerUnit::new(&m, &inverter_b(), 14e3).unwrap();
    let z = [
        m.rs_ohm / base.impedance_ohm,
        m.ld_h / base.inductance_h,
        m.lq_h / base.inductance_h,
    ];
    (m, base, z)
}

/// The sign pattern in f64 (docs/distortion.md), `band` per unit.
fn pattern(ia: f64, ib: f64, band: f64) -> [f64; 2] {
    let h = 0.5 * 3f64.sqrt();
    let sg = |x: f64| (x / band).clamp(-1.0, 1.0);
    let (sa, sb, sc) = (sg(ia), sg(-0.5 * ia + h * ib), sg(-0.5 * ia - h * ib));
    [
        (2.0 / 3.0) * (sa - 0.5 * (sb + sc)),
        (sb - sc) / 3f64.sqrt(),
    ]
}

/// A motor at speed `w` (pu) with the current `i0` (dq, pu) plus a ripple of `ripple` (pu,
/// complex amplitude on d and q at 6θ), whose loops put out the voltage of the model plus
/// `e P` (`e` pu): `n` samples `every` control samples apart.
fn steady(w: f64, i0: [f64; 2], ripple: [(f64, f64); 2], e: f64, n: usize) -> Vec<Sample> {
    let (m, base, [r, ld, lq]) = model();
    let psi = m.flux_wb / base.flux_wb;
    let band = 0.19 / base.current_a;
    let turn = w * base.omega_e_rad_s * base.sample_s * 4.0;
    (0..n)
        .map(|k| {
            let th = 0.3 + turn * k as f64;
            let (s6, c6) = (6.0 * th).sin_cos();
            // x = Re(X e^{j6θ}), dx/dt = Re(j6w X e^{j6θ}) (per-unit time).
            let re = |x: (f64, f64)| x.0 * c6 - x.1 * s6;
            let dre = |x: (f64, f64)| 6.0 * w * (-x.1 * c6 - x.0 * s6);
            let id = i0[0] + re(ripple[0]);
            let iq = i0[1] + re(ripple[1]);
            let (s, c) = th.sin_cos();
            let (ia, ib) = (id * c - iq * s, id * s + iq * c);
            let p = pattern(ia, ib, band);
            let (pd, pq) = (p[0] * c + p[1] * s, p[1] * c - p[0] * s);
            let vd = r * id + ld * dre(ripple[0]) - w * lq * iq + e * pd;
            let vq = r * iq + lq * dre(ripple[1]) + w * ld * id + w * psi + e * pq;
            Sample {
                theta: th,
                i: [id, iq],
                v: [vd * c - vq * s, vd * s + vq * c],
            }
        })
        .collect()
}

fn input(s: &Sample) -> TrackerInput {
    let i = Dq {
        d: pu_from_f64(s.i[0]),
        q: pu_from_f64(s.i[1]),
    };
    TrackerInput {
        running: true,
        theta: Angle::from_rad(s.theta),
        omega: Pu::ZERO,
        i_dq: i,
        i_ref: i,
        v: AlphaBeta {
            alpha: pu_from_f64(s.v[0]),
            beta: pu_from_f64(s.v[1]),
        },
        saturated: false,
    }
}

/// The batch's `ê` in f64, written from docs/distortion.md: demodulation at 6θ with the means
/// removed, then least squares against the pattern after the impedance.
fn reference_error(samples: &[Sample], w: f64, band: f64) -> f64 {
    let (_, _, [r, ld, lq]) = model();
    let sig: Vec<([f64; 6], f64)> = samples
        .iter()
        .map(|s| {
            let (sn, c) = s.theta.sin_cos();
            let (ud, uq) = (s.v[0] * c + s.v[1] * sn, s.v[1] * c - s.v[0] * sn);
            let (ia, ib) = (s.i[0] * c - s.i[1] * sn, s.i[0] * sn + s.i[1] * c);
            let p = pattern(ia, ib, band);
            let (pd, pq) = (p[0] * c + p[1] * sn, p[1] * c - p[0] * sn);
            ([ud, uq, s.i[0], s.i[1], pd, pq], s.theta)
        })
        .collect();
    let n = sig.len() as f64;
    let ph: Vec<(f64, f64)> = (0..6)
        .map(|k| {
            let mean = sig.iter().map(|(x, _)| x[k]).sum::<f64>() / n;
            let (mut re, mut im) = (0.0, 0.0);
            for (x, th) in &sig {
                re += 2.0 * (x[k] - mean) * (6.0 * th).cos() / n;
                im -= 2.0 * (x[k] - mean) * (6.0 * th).sin() / n;
            }
            (re, im)
        })
        .collect();
    let cm = |a: (f64, f64), b: (f64, f64)| (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0);
    let zi_d = cm((r, 6.0 * w * ld), ph[2]);
    let zi_q = cm((r, 6.0 * w * lq), ph[3]);
    let res_d = (
        ph[0].0 - zi_d.0 + w * lq * ph[3].0,
        ph[0].1 - zi_d.1 + w * lq * ph[3].1,
    );
    let res_q = (
        ph[1].0 - zi_q.0 - w * ld * ph[2].0,
        ph[1].1 - zi_q.1 - w * ld * ph[2].1,
    );
    let num = ph[4].0 * res_d.0 + ph[4].1 * res_d.1 + ph[5].0 * res_q.0 + ph[5].1 * res_q.1;
    let den = ph[4].0.powi(2) + ph[4].1.powi(2) + ph[5].0.powi(2) + ph[5].1.powi(2);
    num / den
}

/// Motor B and its drive's default configuration at 14 kHz.
fn drive_config() -> (MotorParams, crate::drive::DriveConfig) {
    let m = motor_b();
    let config =
        crate::drive::DriveConfig::from_params(&m, &inverter_b(), 14e3, Default::default())
            .unwrap();
    (m, config)
}

/// The learner of motor B's drive with the design `d` makes of the default, its design and
/// the bases.
fn learner(
    d: impl FnOnce(&mut DistortionDesign),
) -> (DistortionLearner, DistortionDesign, PerUnit) {
    let (m, config) = drive_config();
    let mut design = DistortionDesign::for_drive(&config);
    design.settle_s = 0.0;
    d(&mut design);
    (
        DistortionLearner::new(&m, &config, design).unwrap(),
        design,
        config.base,
    )
}

/// Feeds `samples` at speed `w` (pu); the scales written.
fn feed(l: &mut DistortionLearner, samples: &[Sample], w: f64) -> Vec<f64> {
    let mut written = Vec::new();
    let mut scale = pu_from_f64(1.0);
    for s in samples {
        let mut i = input(s);
        i.omega = pu_from_f64(w);
        if let Some(x) = l.update(&i, scale) {
            scale = x;
            written.push(x.to_num::<f64>());
        }
    }
    written
}

/// Motor B's 800 r/min (3 pole pairs) in per unit of `base`'s electrical speed.
fn speed_800_rpm(base: &PerUnit) -> f64 {
    800.0 / 60.0 * core::f64::consts::TAU * 3.0 / base.omega_e_rad_s
}

/// A residual of 4 V (a quarter of motor B's told `V_dead`) at 800 r/min under load, the
/// ripple shared between the voltage and a current ripple of 0.02 pu: the learner's `ê`
/// within 2 % of the f64 reference's on the same samples and within 5 % of the truth; the
/// scale moves at the second batch, which confirms the first, by the gain's share of it.
#[test]
fn the_residual_is_measured_at_speed_and_matches_the_reference() {
    let (mut l, design, base) = learner(|_| {});
    let w = speed_800_rpm(&base);
    let e = 4.0 / base.voltage_v;
    let n = l.batch_updates as usize;
    // Each batch ends over the updates after its last sample.
    let samples = steady(
        w,
        [0.0, 0.8],
        [(0.01, -0.005), (0.02, 0.01)],
        e,
        2 * (n + END),
    );
    let band = 0.19 / base.current_a;
    let want = reference_error(&samples[n + END..2 * n + END], w, band);
    let written = feed(&mut l, &samples, w);
    let got = f64::from(l.status().error_v) / base.voltage_v;
    println!(
        "ê {:.4} V, reference {:.4} V, true 4 V; written {written:?}",
        got * base.voltage_v,
        want * base.voltage_v
    );
    assert_eq!(l.status().batches, 2);
    assert!((got - want).abs() <= 0.02 * want.abs(), "{got} vs {want}");
    assert!((want - e).abs() <= 0.05 * e, "{want} vs {e}");
    // The gain times the error, over the told V_dead (15.1 V), in one write.
    let v_dead = design.v_dead_v;
    let step = design.gain * got * base.voltage_v / v_dead;
    assert_eq!(written.len(), 1);
    assert!(
        (written[0] - 1.0 - step).abs() < 1e-3,
        "{written:?} vs {step}"
    );
}

/// With no residual the same ripple of the current alone (a disturbance of another origin
/// that the loops leave in the current, its voltage the motor's) gives no step: the
/// impedance accounts for it.
#[test]
fn a_current_ripple_the_impedance_explains_is_no_error() {
    let (mut l, _, base) = learner(|_| {});
    let w = speed_800_rpm(&base);
    let n = l.batch_updates as usize;
    let samples = steady(w, [0.0, 0.8], [(0.01, -0.005), (0.02, 0.01)], 0.0, n + END);
    let written = feed(&mut l, &samples, w);
    let got = l.status().error_v;
    println!("ê {got:.4} V");
    assert!(got.abs() < 0.1, "{got} V");
    assert!(written.is_empty(), "{written:?}");
}

/// Gates: a current within ten bands, a stopped drive, the modulator at its limit and a
/// speed too low for a batch's sector steps all leave the batch empty; a speed that moves by
/// more than a tenth in a batch, or a current reference that steps or swings, throws it away.
#[test]
fn gates_keep_what_is_not_a_steady_run_out() {
    let (mut l, _, base) = learner(|_| {});
    let w = speed_800_rpm(&base);
    let e = 3.0 / base.voltage_v;
    let n = l.batch_updates as usize;
    // 0.3 pu is below ten bands of 0.19 A (1.9 A, 0.53 pu on motor B).
    let light = steady(w, [0.0, 0.3], [(0.0, 0.0), (0.0, 0.0)], e, n + 1);
    feed(&mut l, &light, w);
    assert_eq!(l.status().frozen, DistortionFrozen::LowCurrent);
    assert_eq!(l.status().batches, 0);
    let loaded = steady(w, [0.0, 0.8], [(0.0, 0.0), (0.0, 0.0)], e, n + 1);
    for s in &loaded {
        let mut i = input(s);
        i.omega = pu_from_f64(w);
        i.saturated = true;
        assert_eq!(l.update(&i, pu_from_f64(1.0)), None);
    }
    assert_eq!(l.status().frozen, DistortionFrozen::Saturated);
    feed(&mut l, &loaded, 0.01);
    assert_eq!(l.status().frozen, DistortionFrozen::Speed);
    let mut i = input(&loaded[0]);
    i.running = false;
    assert_eq!(l.update(&i, pu_from_f64(1.0)), None);
    assert_eq!(l.status().frozen, DistortionFrozen::NotRunning);
    assert_eq!(l.status().batches, 0);
    // A ramp: the speed from w to 1.2 w over the batch.
    let mut scale = pu_from_f64(1.0);
    for (k, s) in loaded.iter().take(n + 1).enumerate() {
        let mut i = input(s);
        i.omega = pu_from_f64(w * (1.0 + 0.2 * k as f64 / n as f64));
        if let Some(x) = l.update(&i, scale) {
            scale = x;
        }
    }
    assert_eq!(l.status().discarded, 1);
    // A load step: the current reference from 0.8 to 0.95 pu mid-batch.
    for (k, s) in loaded.iter().take(n + 1).enumerate() {
        let mut i = input(s);
        i.omega = pu_from_f64(w);
        if 2 * k > n {
            i.i_ref.q = pu_from_f64(0.95);
        }
        if let Some(x) = l.update(&i, scale) {
            scale = x;
        }
    }
    assert_eq!(l.status().discarded, 2);
    // A speed loop that rings: the q reference swings between 0.2 and 1.4 pu, its halves'
    // means alike.
    for (k, s) in loaded.iter().take(n + 1).enumerate() {
        let mut i = input(s);
        i.omega = pu_from_f64(w);
        i.i_ref.q = pu_from_f64(0.8 + 0.6 * (k as f64 * 0.3).sin());
        if let Some(x) = l.update(&i, scale) {
            scale = x;
        }
    }
    assert_eq!(l.status().discarded, 3);
    assert_eq!(l.status().batches, 0);
    assert_eq!(scale, pu_from_f64(1.0));
}

/// The scale stays within its range and moves by at most its step per batch, and a scale the
/// drive took from elsewhere (a standstill calibration) is where the learner goes on from.
#[test]
fn the_scale_is_bounded_and_follows_the_drive() {
    let (mut l, _, base) = learner(|_| {});
    let w = speed_800_rpm(&base);
    let n = l.batch_updates as usize;
    // A residual of 100 V: the scale would be 7.6; a quarter per batch by default (two
    // batches: the first is confirmed by the second).
    let samples = steady(
        w,
        [0.0, 0.8],
        [(0.0, 0.0), (0.0, 0.0)],
        100.0 / base.voltage_v,
        2 * (n + END),
    );
    let written = feed(&mut l, &samples, w);
    assert_eq!(written.len(), 1);
    assert!((written[0] - 1.25).abs() < 1e-6, "{written:?}");
    let (mut l, design, _) = learner(|d| {
        d.gain = 1.0;
        d.max_step = 4.0;
    });
    let written = feed(&mut l, &samples, w);
    assert_eq!(written.len(), 1);
    assert!((written[0] - 4.0).abs() < 1e-6, "{written:?}");
    // The drive was calibrated to 0.5 meanwhile; a residual of −3 V takes a fifth off it
    // (gain 1).
    let samples = steady(
        w,
        [0.0, 0.8],
        [(0.0, 0.0), (0.0, 0.0)],
        -3.0 / base.voltage_v,
        2 * (n + END),
    );
    let mut last = None;
    for s in &samples {
        let mut i = input(s);
        i.omega = pu_from_f64(w);
        last = l.update(&i, pu_from_f64(0.5)).or(last);
    }
    let got = last.unwrap().to_num::<f64>();
    let want = 0.5 - 3.0 / design.v_dead_v;
    assert!((got - want).abs() < 0.01, "{got} vs {want}");
}

/// A batch of `n` samples and its end at speed `w` (pu) with the current (0, 0.8) pu and a
/// residual of `v` volts, no ripple.
fn one_batch(n: usize, base: &PerUnit, w: f64, v: f64) -> Vec<Sample> {
    steady(
        w,
        [0.0, 0.8],
        [(0.0, 0.0), (0.0, 0.0)],
        v / base.voltage_v,
        n + END,
    )
}

/// A reading within the dead band of the drive's own scale is not written: two batches of
/// 1 V (the scale read 1.05) leave the drive at 1; two of 4 V take the reading beyond 15 %
/// and write it.
#[test]
fn readings_within_the_dead_band_are_not_written() {
    let (mut l, design, base) = learner(|_| {});
    let w = speed_800_rpm(&base);
    let n = l.batch_updates as usize;
    let batch = |v: f64| one_batch(n, &base, w, v);
    for _ in 0..2 {
        assert!(feed(&mut l, &batch(1.0), w).is_empty());
    }
    let read = f64::from(l.status().scale);
    assert!(read > 1.03 && read < 1.07, "{read}");
    let mut written = feed(&mut l, &batch(4.0), w);
    written.extend(feed(&mut l, &batch(4.0), w));
    assert_eq!(written.len(), 1, "{written:?}");
    assert!(written[0] > 1.0 + design.dead_band, "{written:?}");
}

/// A batch moves the scale only when the one before it agrees in sign, by the smaller of the
/// two: a residual of +4 V then −4 V writes nothing, a second −4 V writes the gain's share.
#[test]
fn one_batch_alone_does_not_move_the_scale() {
    let (mut l, design, base) = learner(|_| {});
    let w = speed_800_rpm(&base);
    let n = l.batch_updates as usize;
    let batch = |v: f64| one_batch(n, &base, w, v);
    assert!(feed(&mut l, &batch(4.0), w).is_empty());
    assert!(feed(&mut l, &batch(-4.0), w).is_empty());
    assert_eq!(l.status().batches, 2);
    let written = feed(&mut l, &batch(-4.0), w);
    let step = design.gain * 4.0 / design.v_dead_v;
    assert_eq!(written.len(), 1, "{written:?}");
    assert!(
        (written[0] - (1.0 - step)).abs() < 0.01,
        "{written:?} vs {step}"
    );
}

/// A drive without compensation has no `V_dead` to scale: the constructor names the field.
#[test]
fn no_compensation_is_an_error_naming_the_field() {
    let (m, config) = drive_config();
    let mut design = DistortionDesign::for_drive(&config);
    design.v_dead_v = 0.0;
    let e = DistortionLearner::new(&m, &config, design).unwrap_err();
    assert!(std::format!("{e}").contains("distortion.v_dead_v"), "{e}");
    design.v_dead_v = 15.0;
    design.gain = 2.0;
    let e = DistortionLearner::new(&m, &config, design).unwrap_err();
    assert!(std::format!("{e}").contains("distortion.gain"), "{e}");
}
