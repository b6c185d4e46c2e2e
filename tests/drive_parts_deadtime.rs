//! Dead-time compensation (Khlaief, Boussak, Gossa (2012) eq. 7–9; docs/khlaief2012.md §4) against its f64
//! reference and against the plant's inverter model.

use pmsm_core::AlphaBeta;
use pmsm_core::SvpwmConfig;
use pmsm_core::pu_from_f64;
use pmsm_core::{DeadTimeConfig, DeadTimeDesign, DeadTimeMode, DeviceParams};
use pmsm_core::{PerUnit, to_f64};
use pmsm_plant::{InverterKind, InverterModel};
use pmsm_tests::drive_ref::{SQRT3, dead_time_vector_ref, inverter_b, motor_b, v_dead_ref};
use pmsm_tests::signals::SplitMix;

const LSB: f64 = 1.0 / (1u64 << 24) as f64;

/// Devices with delays and drops, so that every term of eq. 8 counts (V_sat = V_f keeps the
/// plant's averaged leg exactly `d V_DC − V_dead sgn i`).
fn devices() -> DeviceParams {
    DeviceParams {
        t_on_s: 0.3e-6,
        t_off_s: 0.5e-6,
        v_sat_v: 1.4,
        v_f_v: 1.4,
    }
}

fn design(band_a: f64) -> DeadTimeDesign {
    let mut d = DeadTimeDesign::default_for(&motor_b(), &inverter_b());
    d.device = devices();
    d.band_a = band_a;
    d
}

fn setup(band_a: f64) -> (DeadTimeConfig, PerUnit) {
    let inv = inverter_b();
    let base = PerUnit::new(&motor_b(), &inv, 14e3).unwrap();
    (
        DeadTimeConfig::new(&inv, &base, design(band_a)).unwrap(),
        base,
    )
}

/// Fixed vs f64 over random currents (inside and outside the band) and buses from 0.3 to 1.5×
/// nominal: within 2 LSB of `V_b` per component (measured 1.7 LSB).
#[test]
fn error_vector_matches_f64() {
    let band = 0.2;
    let (c, base) = setup(band);
    let d = devices();
    let inv = inverter_b();
    let mut rng = SplitMix(3);
    let mut worst: f64 = 0.0;
    for _ in 0..100_000 {
        let vdc_v = inv.vdc_v * rng.uniform(0.3, 1.5);
        let vdc = base.voltage_pu(vdc_v);
        let scale = if rng.uniform(0.0, 1.0) < 0.5 {
            0.3
        } else {
            5.0
        };
        let i_ab = [rng.uniform(-scale, scale), rng.uniform(-scale, scale)];
        let i = AlphaBeta {
            alpha: base.current_pu(i_ab[0]),
            beta: base.current_pu(i_ab[1]),
        };
        let got = c.error_vector(i, vdc);
        // The reference sees exactly the currents and bus the fixed code saw.
        let i_abc = pmsm_plant::inverse_clarke([base.current_a(i.alpha), base.current_a(i.beta)]);
        let vd = v_dead_ref(
            inv.dead_time_s,
            d.t_on_s,
            d.t_off_s,
            inv.pwm_hz,
            base.voltage_v(vdc),
            d.v_sat_v,
            d.v_f_v,
        );
        let want = dead_time_vector_ref(vd, i_abc, band);
        for k in 0..2 {
            let g = [got.alpha, got.beta][k];
            worst = worst.max((to_f64(g) - want[k] / base.voltage_v).abs() / LSB);
        }
    }
    println!("V_dt fixed vs f64: {worst:.2} LSB");
    assert!(worst <= 2.0, "{worst} LSB");
}

/// The plant's averaged inverter (delays and drops as above, its own smooth-sign band of
/// 0.1 A): outside both bands the compensation vector equals the plant's error vector within
/// 1 mV (measured 0.026 mV, under 2 LSB of `V_b`), and commanding `v_ref + V_dt` through the
/// fixed-point SVPWM makes the plant apply `v_ref` within 2 mV (measured 0.033 mV), where the
/// uncompensated command is off by `(4/3) V_dead` (at least 16.4 V here).
#[test]
fn compensation_cancels_the_plant_error_outside_the_band() {
    let band = 0.2;
    let (c, base) = setup(band);
    let inv = inverter_b();
    let mut model = InverterModel::new(inv, InverterKind::Averaged);
    let d = devices();
    model.t_on_s = d.t_on_s;
    model.t_off_s = d.t_off_s;
    model.v_sat_v = d.v_sat_v;
    model.v_f_v = d.v_f_v;
    let svpwm = SvpwmConfig::default();
    let mut rng = SplitMix(5);
    let (mut worst_vec, mut worst_cancel, mut uncomp) = (0.0f64, 0.0f64, f64::INFINITY);
    let mut n = 0;
    while n < 20_000 {
        let i_ab = [rng.uniform(-5.0, 5.0), rng.uniform(-5.0, 5.0)];
        let i = AlphaBeta {
            alpha: base.current_pu(i_ab[0]),
            beta: base.current_pu(i_ab[1]),
        };
        let i_abc = pmsm_plant::inverse_clarke([base.current_a(i.alpha), base.current_a(i.beta)]);
        if i_abc.iter().any(|x| x.abs() <= band.max(model.sign_band_a)) {
            continue;
        }
        n += 1;
        let vdc_v = inv.vdc_v * rng.uniform(0.8, 1.1);
        let vdc = base.voltage_pu(vdc_v);
        let v_dt = c.error_vector(i, vdc);
        let plant = model.dead_time_error_alpha_beta_v(base.voltage_v(vdc), i_abc);
        worst_vec = worst_vec.max(
            (base.voltage_v(v_dt.alpha) - plant[0]).hypot(base.voltage_v(v_dt.beta) - plant[1]),
        );
        // A reference well inside the linear range, so no leg is pinned at 0 or 1.
        let mag = rng.uniform(0.0, 0.8) * to_f64(vdc) / SQRT3;
        let phi = rng.uniform(-3.2, 3.2);
        let v_ref = AlphaBeta {
            alpha: pu_from_f64(mag * phi.cos()),
            beta: pu_from_f64(mag * phi.sin()),
        };
        let cmd = c.command(v_ref, v_dt);
        let out = svpwm.modulate(cmd, vdc);
        assert!(!out.saturated);
        let applied = model.averaged_alpha_beta_v(out.duties.to_f64(), base.voltage_v(vdc), i_abc);
        let want = [base.voltage_v(v_ref.alpha), base.voltage_v(v_ref.beta)];
        worst_cancel = worst_cancel.max((applied[0] - want[0]).hypot(applied[1] - want[1]));
        let raw = svpwm.modulate(v_ref, vdc);
        let applied_raw =
            model.averaged_alpha_beta_v(raw.duties.to_f64(), base.voltage_v(vdc), i_abc);
        uncomp = uncomp.min((applied_raw[0] - want[0]).hypot(applied_raw[1] - want[1]));
    }
    println!(
        "vector vs plant {:.3} mV, compensated error {:.3} mV, uncompensated at least {uncomp:.2} V",
        worst_vec * 1e3,
        worst_cancel * 1e3
    );
    assert!(worst_vec < 1e-3, "{worst_vec} V");
    assert!(worst_cancel < 2e-3, "{worst_cancel} V");
    assert!(
        uncomp > 0.9 * 4.0 / 3.0 * design(band).v_dead_v(&inverter_b()) * 0.8,
        "{uncomp} V"
    );
}

/// Inside the band the vector shrinks linearly to zero instead of flipping: for a current
/// along phase a with all three phases inside the band, `s = (f, −f/2, −f/2)` and
/// `V_dt = (V_dead f, 0)` (within 2 LSB); and each mode compensates the command and corrects
/// the estimator as its table says.
#[test]
fn linear_band_and_modes() {
    let band = 0.2;
    let (c, base) = setup(band);
    let vdc = base.voltage_pu(540.0);
    let vd = base.voltage_v(c.v_dead(vdc));
    for frac in [0.0, 0.1, 0.5, 0.9] {
        // i_a = frac·band, i_b = i_c = −frac·band/2: all three inside the band.
        let i = AlphaBeta {
            alpha: base.current_pu(frac * band),
            beta: pu_from_f64(0.0),
        };
        let v = c.error_vector(i, vdc);
        // s = (f, −f/2, −f/2): clarke gives (f, 0) → V_dt = (V_dead f, 0).
        let want = vd * frac;
        assert!(
            (base.voltage_v(v.alpha) - want).abs() < 2.0 * LSB * base.voltage_v,
            "{frac}"
        );
        assert!(v.beta.abs().to_bits() <= 2);
    }
    let mut d = design(band);
    for mode in [
        DeadTimeMode::Off,
        DeadTimeMode::Command,
        DeadTimeMode::Estimator,
        DeadTimeMode::Both,
    ] {
        d.mode = mode;
        let c = DeadTimeConfig::new(&inverter_b(), &base, d).unwrap();
        let v_ref = AlphaBeta {
            alpha: pu_from_f64(0.3),
            beta: pu_from_f64(-0.2),
        };
        let v_dt = c.error_vector(
            AlphaBeta {
                alpha: base.current_pu(2.0),
                beta: base.current_pu(1.0),
            },
            vdc,
        );
        let cmd = c.command(v_ref, v_dt);
        let est = c.estimator_voltage(cmd, v_dt);
        // What the inverter applies is cmd − V_dt; the estimator is exact iff it corrects.
        let applied_alpha = cmd.alpha - v_dt.alpha;
        assert_eq!(cmd == v_ref, !mode.compensates_command(), "{mode:?}");
        assert_eq!(
            est.alpha == applied_alpha,
            mode.corrects_estimator(),
            "{mode:?}"
        );
    }
}
