//! Accuracy of the fixed-point numerics of `pmsm-core` against f64, over dense sweeps and
//! random inputs across each function's whole input range.

use pmsm_core::Pu;
use pmsm_core::polar;
use pmsm_core::to_f64;
use pmsm_core::{Abc, AlphaBeta, Dq, clarke, inverse_clarke, inverse_park, park};
use pmsm_core::{Angle, sin_cos};
use pmsm_tests::signals::SplitMix;

const PU_LSB: f64 = 1.0 / (1u64 << 24) as f64;
const UNIT_LSB: f64 = 1.0 / (1u64 << 30) as f64;
const RANDOM: usize = 2_000_000;

struct Row {
    name: &'static str,
    domain: &'static str,
    points: usize,
    max_lsb: f64,
    lsb_name: &'static str,
    physical: String,
}

/// Random `i32` whose magnitude is log-uniform, so small and large inputs are both covered.
fn log_uniform_bits(rng: &mut SplitMix, max_bits: u32) -> i32 {
    let bits = rng.uniform(0.0, max_bits as f64);
    let mag = 2f64.powf(bits).min(i32::MAX as f64);
    let v = mag as i32;
    if rng.next_u64() & 1 == 0 { v } else { -v }
}

fn clamp_pu(x: f64) -> f64 {
    x.clamp(to_f64(Pu::MIN), to_f64(Pu::MAX))
}

fn sin_cos_row() -> Row {
    let mut worst: f64 = 0.0;
    let mut points = 0;
    let mut check = |t: i32| {
        let sc = sin_cos(Angle(t));
        let x = Angle(t).to_rad();
        let e = ((sc.sin.to_bits() as f64 * UNIT_LSB - x.sin()).abs())
            .max((sc.cos.to_bits() as f64 * UNIT_LSB - x.cos()).abs());
        worst = worst.max(e / UNIT_LSB);
        points += 1;
    };
    for k in 0..(1u32 << 24) {
        check((k << 8) as i32);
    }
    let mut rng = SplitMix(1);
    for _ in 0..RANDOM {
        check(rng.next_u64() as i32);
    }
    Row {
        name: "sin, cos",
        domain: "every 2⁸-th angle of the 2³² and 2·10⁶ random angles",
        points,
        max_lsb: worst,
        lsb_name: "Q2.30",
        physical: format!("{:.2e} absolute", worst * UNIT_LSB),
    }
}

fn polar_rows() -> [Row; 2] {
    let mut rng = SplitMix(2);
    let (mut ang, mut mag, mut rel) = (0.0f64, 0.0f64, 0.0f64);
    for _ in 0..RANDOM {
        let (x, y) = (
            log_uniform_bits(&mut rng, 31),
            log_uniform_bits(&mut rng, 31),
        );
        let (xf, yf) = (to_f64(Pu::from_bits(x)), to_f64(Pu::from_bits(y)));
        let p = polar(Pu::from_bits(x), Pu::from_bits(y));
        let exact = Angle::from_rad(yf.atan2(xf));
        ang = ang.max((p.angle - exact).0.unsigned_abs() as f64);
        let m = clamp_pu(xf.hypot(yf));
        let e = (to_f64(p.magnitude) - m).abs();
        mag = mag.max(e / PU_LSB);
        if m >= 0.1 {
            rel = rel.max(e / m);
        }
    }
    [
        Row {
            name: "atan2 (`polar`)",
            domain: "2·10⁶ random vectors, components log-uniform over the Q8.24 range",
            points: RANDOM,
            max_lsb: ang,
            lsb_name: "angle (2π/2³²)",
            physical: format!("{:.2e}°", ang * Angle::RAD_PER_LSB.to_degrees()),
        },
        Row {
            name: "magnitude (`polar`)",
            domain: "same vectors",
            points: RANDOM,
            max_lsb: mag,
            lsb_name: "Q8.24",
            physical: format!(
                "{:.2e} % of |v| (|v| ≥ 0.1 pu; below, ½ LSB of rounding dominates)",
                rel * 100.0
            ),
        },
    ]
}

/// Max error in LSB of the transforms for inputs up to `max_bits` bits (31 = whole range).
fn transform_rows(max_bits: u32, domain: &'static str) -> [Row; 4] {
    let mut rng = SplitMix(3 + max_bits as u64);
    let mut worst = [0.0f64; 4];
    let err = |got: Pu, exact: f64| (to_f64(got) - clamp_pu(exact)).abs() / PU_LSB;
    for _ in 0..RANDOM {
        let [a, b, c] = [(); 3].map(|_| log_uniform_bits(&mut rng, max_bits));
        let (af, bf, cf) = (
            to_f64(Pu::from_bits(a)),
            to_f64(Pu::from_bits(b)),
            to_f64(Pu::from_bits(c)),
        );
        let v = clarke(Abc {
            a: Pu::from_bits(a),
            b: Pu::from_bits(b),
            c: Pu::from_bits(c),
        });
        worst[0] = worst[0]
            .max(err(v.alpha, (2.0 * af - bf - cf) / 3.0))
            .max(err(v.beta, (bf - cf) / 3f64.sqrt()));
        let w = inverse_clarke(AlphaBeta {
            alpha: Pu::from_bits(a),
            beta: Pu::from_bits(b),
        });
        let k = 3f64.sqrt() / 2.0;
        worst[1] = worst[1]
            .max(err(w.b, -af / 2.0 + k * bf))
            .max(err(w.c, -af / 2.0 - k * bf));
        let t = rng.next_u64() as i32;
        let (s, co) = Angle(t).to_rad().sin_cos();
        let sc = Angle(t).sin_cos();
        let dq = park(
            AlphaBeta {
                alpha: Pu::from_bits(a),
                beta: Pu::from_bits(b),
            },
            sc,
        );
        worst[2] = worst[2]
            .max(err(dq.d, af * co + bf * s))
            .max(err(dq.q, -af * s + bf * co));
        let ab = inverse_park(
            Dq {
                d: Pu::from_bits(a),
                q: Pu::from_bits(b),
            },
            sc,
        );
        worst[3] = worst[3]
            .max(err(ab.alpha, af * co - bf * s))
            .max(err(ab.beta, af * s + bf * co));
    }
    let names = ["Clarke", "inverse Clarke", "Park", "inverse Park"];
    let range = to_f64(Pu::from_bits(((1u64 << max_bits) - 1) as i32));
    let mut rows = names.map(|name| Row {
        name,
        domain,
        points: RANDOM,
        max_lsb: 0.0,
        lsb_name: "Q8.24",
        physical: String::new(),
    });
    for (row, w) in rows.iter_mut().zip(worst) {
        row.max_lsb = w;
        row.physical = format!("{:.1e} % of {range:.0} pu", w * PU_LSB / range * 100.0);
    }
    rows
}

/// The markdown section.
pub fn section() -> String {
    let mut rows = vec![sin_cos_row()];
    rows.extend(polar_rows());
    rows.extend(transform_rows(
        27,
        "2·10⁶ random inputs, log-uniform up to ±8 pu (operating range)",
    ));
    rows.extend(transform_rows(
        31,
        "2·10⁶ random inputs, log-uniform over the whole Q8.24 range",
    ));
    let mut s = String::from(
        "## Accuracy of the fixed-point numerics\n\n\
         Each function of `pmsm-core` against f64 evaluated on the same (exactly representable) \
         inputs. The unit tests bound the same errors with proptest.\n\n\
         | function | inputs | points | max error (LSB) | LSB of | max error |\n\
         |---|---|---:|---:|---|---|\n",
    );
    for r in rows {
        s.push_str(&format!(
            "| {} | {} | {} | {:.2} | {} | {} |\n",
            r.name, r.domain, r.points, r.max_lsb, r.lsb_name, r.physical
        ));
    }
    s.push('\n');
    s
}
