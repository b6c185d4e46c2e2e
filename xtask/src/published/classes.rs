//! The widened family: motors drawn from classes written from the published motors
//! (`examples/published/`), each with the inverter its class is run from ([`CLASS_RULES`],
//! printed into docs/PERFORMANCE.md).

use super::Published;
use pmsm_tests::signals::SplitMix;
use std::f64::consts::TAU;

/// The rules, as printed with the table.
pub const CLASS_RULES: &str = "\
Each motor is drawn from one of seven classes (equally likely); within a class, as the random family, from \
dimensionless proportions: the EMF at rated speed as a share of `V_DC/√3` (gives ψ), the copper loss at rated \
current as a share of the rated power (gives R), the armature reaction `L_d I/ψ` (gives L_d), the mechanical time \
constant from rest to rated speed at rated torque (gives J, log-uniform); friction 0.5–3 % of rated torque. \
The PWM frequency is drawn in the class's range and raised (within it) to the class's least samples per electrical \
period at rated speed and to a full-voltage current step `V_b T_s/(L I_b)` of at most 6; a motor that cannot be \
met is drawn again.

| class | bus V | pole pairs | rated r/min | power W | EMF share | copper share | `L_d I/ψ` | `τ_m` ms | L_q/L_d | PWM kHz | dead time µs | samples/period |
|---|---|---|---|---|---|---|---|---|---|---|---|---|
| drone outrunner | 11–25 | 7 | 8000–22000 | 80–800 | 0.70–0.85 | 0.05–0.15 | 0.1–0.4 | 5–30 | 1 | 24–48 | 0.1–0.3 | ≥ 10 |
| gimbal | 11–24 | 7–11 | 300–1500 | 2–15 | 0.40–0.70 | 0.30–0.60 | 0.02–0.1 | 5–30 | 1 | 20–32 | 0.2–0.5 | ≥ 30 |
| hub | 36–52 | 15–30 | 200–600 | 250–1000 | 0.70–0.85 | 0.05–0.12 | 0.1–0.3 | 100–1000 | 1 | 16–20 | 0.3–1 | ≥ 20 |
| legged-robot actuator | 24–48 | 14–21 | 1000–3000 | 100–600 | 0.70–0.85 | 0.10–0.25 | 0.1–0.3 | 3–20 | 1 | 20–40 | 0.1–0.5 | ≥ 15 |
| servo without its load | 24–48 | 4–5 | 3000–4000 | 50–400 | 0.55–0.85 | 0.05–0.15 | 0.15–0.4 | 3–15 | 1 | 16–25 | 0.3–0.5 | ≥ 20 |
| 600 V industrial servo | 560–600 | 3–5 | 2000–6000 | 400–7000 | 0.55–0.85 | 0.04–0.10 | 0.1–0.4 | 5–50 | 1 | 4–8 | 1.5–3 | ≥ 10 |
| compressor (interior) | 280–320 | 2–4 | 3000–7000 | 700–2000 | 0.60–0.85 | 0.03–0.08 | 0.3–0.8 | 30–200 | 1.3–2.5 | 6–10 | 1–2 | ≥ 10 |";

/// A class of motors and the inverter it is run from (each a range).
struct Class {
    name: &'static str,
    vdc_v: (f64, f64),
    pole_pairs: (u32, u32),
    rpm: (f64, f64),
    power_w: (f64, f64),
    emf: (f64, f64),
    copper: (f64, f64),
    reaction: (f64, f64),
    tau_m_s: (f64, f64),
    saliency: (f64, f64),
    pwm_hz: (f64, f64),
    dead_time_s: (f64, f64),
    min_samples: f64,
}

const CLASSES: [Class; 7] = [
    Class {
        name: "drone outrunner",
        vdc_v: (11.1, 25.2),
        pole_pairs: (7, 7),
        rpm: (8000.0, 22000.0),
        power_w: (80.0, 800.0),
        emf: (0.7, 0.85),
        copper: (0.05, 0.15),
        reaction: (0.1, 0.4),
        tau_m_s: (0.005, 0.03),
        saliency: (1.0, 1.0),
        pwm_hz: (24e3, 48e3),
        dead_time_s: (0.1e-6, 0.3e-6),
        min_samples: 10.0,
    },
    Class {
        name: "gimbal",
        vdc_v: (11.1, 24.0),
        pole_pairs: (7, 11),
        rpm: (300.0, 1500.0),
        power_w: (2.0, 15.0),
        emf: (0.4, 0.7),
        copper: (0.3, 0.6),
        reaction: (0.02, 0.1),
        tau_m_s: (0.005, 0.03),
        saliency: (1.0, 1.0),
        pwm_hz: (20e3, 32e3),
        dead_time_s: (0.2e-6, 0.5e-6),
        min_samples: 30.0,
    },
    Class {
        name: "hub",
        vdc_v: (36.0, 52.0),
        pole_pairs: (15, 30),
        rpm: (200.0, 600.0),
        power_w: (250.0, 1000.0),
        emf: (0.7, 0.85),
        copper: (0.05, 0.12),
        reaction: (0.1, 0.3),
        tau_m_s: (0.1, 1.0),
        saliency: (1.0, 1.0),
        pwm_hz: (16e3, 20e3),
        dead_time_s: (0.3e-6, 1e-6),
        min_samples: 20.0,
    },
    Class {
        name: "legged-robot actuator",
        vdc_v: (24.0, 48.0),
        pole_pairs: (14, 21),
        rpm: (1000.0, 3000.0),
        power_w: (100.0, 600.0),
        emf: (0.7, 0.85),
        copper: (0.1, 0.25),
        reaction: (0.1, 0.3),
        tau_m_s: (0.003, 0.02),
        saliency: (1.0, 1.0),
        pwm_hz: (20e3, 40e3),
        dead_time_s: (0.1e-6, 0.5e-6),
        min_samples: 15.0,
    },
    Class {
        name: "servo without its load",
        vdc_v: (24.0, 48.0),
        pole_pairs: (4, 5),
        rpm: (3000.0, 4000.0),
        power_w: (50.0, 400.0),
        emf: (0.55, 0.85),
        copper: (0.05, 0.15),
        reaction: (0.15, 0.4),
        tau_m_s: (0.003, 0.015),
        saliency: (1.0, 1.0),
        pwm_hz: (16e3, 25e3),
        dead_time_s: (0.3e-6, 0.5e-6),
        min_samples: 20.0,
    },
    Class {
        name: "600 V industrial servo",
        vdc_v: (560.0, 600.0),
        pole_pairs: (3, 5),
        rpm: (2000.0, 6000.0),
        power_w: (400.0, 7000.0),
        emf: (0.55, 0.85),
        copper: (0.04, 0.1),
        reaction: (0.1, 0.4),
        tau_m_s: (0.005, 0.05),
        saliency: (1.0, 1.0),
        pwm_hz: (4e3, 8e3),
        dead_time_s: (1.5e-6, 3e-6),
        min_samples: 10.0,
    },
    Class {
        name: "compressor (interior)",
        vdc_v: (280.0, 320.0),
        pole_pairs: (2, 4),
        rpm: (3000.0, 7000.0),
        power_w: (700.0, 2000.0),
        emf: (0.6, 0.85),
        copper: (0.03, 0.08),
        reaction: (0.3, 0.8),
        tau_m_s: (0.03, 0.2),
        saliency: (1.3, 2.5),
        pwm_hz: (6e3, 10e3),
        dead_time_s: (1e-6, 2e-6),
        min_samples: 10.0,
    },
];

/// The class names, in the order of the table.
pub fn class_names() -> impl Iterator<Item = &'static str> {
    CLASSES.iter().map(|c| c.name)
}

/// Largest full-voltage current step per sample the draw accepts, per unit.
const MAX_STEP_PU: f64 = 6.0;

fn log_uniform(rng: &mut SplitMix, (lo, hi): (f64, f64)) -> f64 {
    rng.uniform(lo.ln(), hi.ln()).exp()
}

/// Draws motor `index` of class `c` (redrawing until its PWM can be met; counted).
fn draw(rng: &mut SplitMix, c: &Class, index: usize, redrawn: &mut usize) -> Published {
    loop {
        let vdc_v = (rng.uniform(c.vdc_v.0, c.vdc_v.1) * 10.0).round() / 10.0;
        let p = (rng.uniform(c.pole_pairs.0 as f64, c.pole_pairs.1 as f64 + 1.0) as u32)
            .min(c.pole_pairs.1);
        let rpm = rng.uniform(c.rpm.0, c.rpm.1).round();
        let power_w = log_uniform(rng, c.power_w);
        let w_m = rpm * TAU / 60.0;
        let w_e = w_m * p as f64;
        let v_ph = vdc_v / 3f64.sqrt();
        let flux_wb = rng.uniform(c.emf.0, c.emf.1) * v_ph / w_e;
        let rated_nm = power_w / w_m;
        let i_pk = rated_nm / (1.5 * p as f64 * flux_wb);
        let rs_ohm = rng.uniform(c.copper.0, c.copper.1) * power_w / (1.5 * i_pk * i_pk);
        let ld_h = rng.uniform(c.reaction.0, c.reaction.1) * flux_wb / i_pk;
        let lq_h = rng.uniform(c.saliency.0, c.saliency.1) * ld_h;
        let j_kg_m2 = log_uniform(rng, c.tau_m_s) * rated_nm / w_m;
        let b_nm_s = rng.uniform(0.005, 0.03) * rated_nm / w_m;
        let dead_time_s = (rng.uniform(c.dead_time_s.0, c.dead_time_s.1) * 1e8).round() / 1e8;
        // The base current of the drive: the rated peak (the file's RMS times √2).
        let needed = (c.min_samples * w_e / TAU).max(v_ph / (ld_h * i_pk * MAX_STEP_PU));
        let pwm_hz = (rng.uniform(c.pwm_hz.0, c.pwm_hz.1).max(needed) / 1e3).ceil() * 1e3;
        if pwm_hz > c.pwm_hz.1 {
            *redrawn += 1;
            continue;
        }
        return Published {
            name: format!("{} #{index}", c.name),
            class: c.name.to_string(),
            source: "https://drawn.invalid/widened-family".into(),
            notes: "drawn by the class rules".into(),
            pole_pairs: p,
            rs_ohm,
            ld_h,
            lq_h,
            flux_wb,
            j_kg_m2,
            b_nm_s,
            rated_current_a: i_pk / 2f64.sqrt(),
            rated_speed_rpm: rpm,
            vdc_v,
            pwm_hz,
            dead_time_s,
        };
    }
}

/// `n` motors from `seed`, the class of each drawn uniformly; and how many were redrawn.
pub fn widened(n: usize, seed: u64) -> (Vec<Published>, usize) {
    // Another stream than the random family's for the same seed.
    let mut rng = SplitMix(seed ^ 0x5769_6465_6e65_6421);
    let mut redrawn = 0;
    let motors = (0..n)
        .map(|k| {
            let c = &CLASSES[(rng.uniform(0.0, CLASSES.len() as f64) as usize).min(6)];
            draw(&mut rng, c, k, &mut redrawn)
        })
        .collect();
    (motors, redrawn)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_widened_family_has_its_classes_proportions() {
        let (motors, _) = widened(300, 1);
        for m in &motors {
            let c = CLASSES.iter().find(|c| c.name == m.class).unwrap();
            let w_e = m.rated_speed_rpm * TAU / 60.0 * m.pole_pairs as f64;
            let emf = w_e * m.flux_wb / (m.vdc_v / 3f64.sqrt());
            assert!((c.emf.0..=c.emf.1).contains(&emf), "{}: EMF {emf}", m.name);
            assert!((c.pole_pairs.0..=c.pole_pairs.1).contains(&m.pole_pairs));
            assert!(
                m.samples_per_period() >= c.min_samples * 0.999,
                "{}",
                m.name
            );
            assert!(
                m.step_pu() <= MAX_STEP_PU * 1.0001,
                "{}: {}",
                m.name,
                m.step_pu()
            );
            assert!((c.pwm_hz.0..=c.pwm_hz.1).contains(&m.pwm_hz), "{}", m.name);
            let tau = m.motor(0).tau_m_s();
            assert!(
                (c.tau_m_s.0 * 0.999..=c.tau_m_s.1 * 1.001).contains(&tau),
                "{}: {tau}",
                m.name
            );
        }
        for name in class_names() {
            assert!(
                motors.iter().filter(|m| m.class == name).count() >= 20,
                "{name}"
            );
        }
    }
}
