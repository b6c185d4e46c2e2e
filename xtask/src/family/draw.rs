//! The family's motors: drawn from bus-voltage classes and a few dimensionless proportions
//! ([`PROPORTIONS`], printed into docs/PERFORMANCE.md).

use pmsm_tests::signals::SplitMix;
use std::f64::consts::TAU;

/// The proportions the family is drawn with (printed with the table).
pub const PROPORTIONS: &str = "\
- Bus classes (equally likely): 12 V (rated 3000–10000 r/min, 20–150 W, PWM 20–40 kHz, dead time 0.2–0.4 µs), \
24 V (2000–8000 r/min, 50–400 W, 20–40 kHz, 0.3–0.5 µs), 48 V (1500–6000 r/min, 0.2–2 kW, 16–32 kHz, 0.3–1 µs), \
320 V (1000–6000 r/min, 0.4–4 kW, 10–20 kHz, 1–2 µs), 540 V (1000–4000 r/min, 0.75–7.5 kW, 8–16 kHz, 1.5–3 µs); \
power log-uniform, the rest uniform; pole pairs 2–7.
- EMF at rated speed `ω_e ψ` = 55–90 % of the phase voltage limit `V_DC/√3` (gives ψ).
- Rated torque = power / rated speed; rated peak current `I = T/(1.5 p ψ)` (the file's `rated_current_a` is `I/√2`).
- Copper loss at rated current `1.5 R I²` = 4–15 % of the rated power (gives R).
- Armature reaction `L_d I/ψ` = 0.15–0.5 (gives L_d); half the motors surface (`L_q = L_d`), half interior with `L_q/L_d` = 1.1–2.5. \
The electrical time constant `L_d/R` follows; its range over the family is given below.
- Mechanical time constant (rest to rated speed at rated torque) `J ω_m/T` = 30–300 ms, log-uniform (gives J); \
friction `B ω_m` = 0.5–3 % of the rated torque.
- PWM drawn in the class's range, raised to at least 30 samples per electrical period at rated speed and to a \
full-voltage current step `V_DC T/(√3 L_d)` of at most half the rated peak current per period (the ripple a designer \
accepts); a motor that would need more than the class's highest PWM frequency is drawn again.
- Plant: linear magnetics but for the default d-axis saturation the scenario files give every motor, the \
switching-level inverter with the dead time, 12-bit current ADC; initial rotor angle uniform.";

/// A bus-voltage class: bus V, rated r/min, power W, PWM Hz, dead time s (each a range).
struct Class {
    vdc_v: f64,
    rpm: (f64, f64),
    power_w: (f64, f64),
    pwm_hz: (f64, f64),
    dead_time_s: (f64, f64),
}

const CLASSES: [Class; 5] = [
    Class {
        vdc_v: 12.0,
        rpm: (3000.0, 10000.0),
        power_w: (20.0, 150.0),
        pwm_hz: (20e3, 40e3),
        dead_time_s: (0.2e-6, 0.4e-6),
    },
    Class {
        vdc_v: 24.0,
        rpm: (2000.0, 8000.0),
        power_w: (50.0, 400.0),
        pwm_hz: (20e3, 40e3),
        dead_time_s: (0.3e-6, 0.5e-6),
    },
    Class {
        vdc_v: 48.0,
        rpm: (1500.0, 6000.0),
        power_w: (200.0, 2000.0),
        pwm_hz: (16e3, 32e3),
        dead_time_s: (0.3e-6, 1e-6),
    },
    Class {
        vdc_v: 320.0,
        rpm: (1000.0, 6000.0),
        power_w: (400.0, 4000.0),
        pwm_hz: (10e3, 20e3),
        dead_time_s: (1e-6, 2e-6),
    },
    Class {
        vdc_v: 540.0,
        rpm: (1000.0, 4000.0),
        power_w: (750.0, 7500.0),
        pwm_hz: (8e3, 16e3),
        dead_time_s: (1.5e-6, 3e-6),
    },
];

/// One motor of the family with its inverter.
#[derive(Clone, Debug)]
pub struct Motor {
    /// Index in the family.
    pub index: usize,
    pub vdc_v: f64,
    pub pole_pairs: u32,
    pub rated_rpm: f64,
    pub power_w: f64,
    pub rs_ohm: f64,
    pub ld_h: f64,
    pub lq_h: f64,
    pub flux_wb: f64,
    pub j_kg_m2: f64,
    pub b_nm_s: f64,
    /// Rated peak current, A.
    pub rated_peak_a: f64,
    pub rated_nm: f64,
    pub pwm_hz: f64,
    pub dead_time_s: f64,
    /// Initial electrical angle, degrees.
    pub theta0_deg: f64,
    /// Surface magnets (`L_q = L_d`).
    pub surface: bool,
}

impl Motor {
    pub fn surface(&self) -> bool {
        self.surface
    }

    /// Electrical time constant `L_d/R`, s.
    pub fn tau_e_s(&self) -> f64 {
        self.ld_h / self.rs_ohm
    }

    /// Rest to rated speed at rated torque, s.
    pub fn tau_m_s(&self) -> f64 {
        self.j_kg_m2 * self.rated_rpm * TAU / 60.0 / self.rated_nm
    }

    /// The scenario file's `motor` (inline) and `[inverter]` (switching) lines for this motor.
    pub fn hardware_toml(&self) -> String {
        format!(
            "motor = {{ name = \"family {}\", pole_pairs = {}, rs_ohm = {}, ld_h = {}, lq_h = {}, flux_wb = {}, \
             j_kg_m2 = {}, b_nm_s = {}, rated_current_a = {}, rated_speed_rpm = {} }}\n\
             [inverter]\nvdc_v = {}\npwm_hz = {}\ndead_time_s = {}\nmodel = \"switching\"\n",
            self.index,
            self.pole_pairs,
            self.rs_ohm,
            self.ld_h,
            self.lq_h,
            self.flux_wb,
            self.j_kg_m2,
            self.b_nm_s,
            self.rated_peak_a / std::f64::consts::SQRT_2,
            self.rated_rpm,
            self.vdc_v,
            self.pwm_hz,
            self.dead_time_s,
        )
    }

    /// A short description for the lists.
    pub fn describe(&self) -> String {
        format!(
            "#{} {:.0} V {}, p={}, {:.0} r/min, {:.0} W, L_q/L_d {:.2}, τ_e {:.2} ms, τ_m {:.0} ms, {:.0} kHz",
            self.index,
            self.vdc_v,
            if self.surface() {
                "surface"
            } else {
                "interior"
            },
            self.pole_pairs,
            self.rated_rpm,
            self.power_w,
            self.lq_h / self.ld_h,
            1e3 * self.tau_e_s(),
            1e3 * self.tau_m_s(),
            self.pwm_hz / 1e3
        )
    }
}

/// Draws motor `index` (with redraws, counted in `redrawn`) from `rng`.
fn draw(rng: &mut SplitMix, index: usize, redrawn: &mut usize) -> Motor {
    loop {
        let class = &CLASSES[(rng.uniform(0.0, CLASSES.len() as f64) as usize).min(4)];
        let p = (rng.uniform(2.0, 8.0) as u32).min(7);
        let rated_rpm = rng.uniform(class.rpm.0, class.rpm.1).round();
        let power_w = log_uniform(rng, class.power_w);
        let w_m = rated_rpm * TAU / 60.0;
        let w_e = w_m * p as f64;
        let v_ph = class.vdc_v / 3f64.sqrt();
        let flux_wb = rng.uniform(0.55, 0.9) * v_ph / w_e;
        let rated_nm = power_w / w_m;
        let i_pk = rated_nm / (1.5 * p as f64 * flux_wb);
        let rs_ohm = rng.uniform(0.04, 0.15) * power_w / (1.5 * i_pk * i_pk);
        let ld_h = rng.uniform(0.15, 0.5) * flux_wb / i_pk;
        let surface = rng.uniform(0.0, 1.0) < 0.5;
        let ratio = if surface { 1.0 } else { rng.uniform(1.1, 2.5) };
        let j_kg_m2 = log_uniform(rng, (0.03, 0.3)) * rated_nm / w_m;
        let b_nm_s = rng.uniform(0.005, 0.03) * rated_nm / w_m;
        let pwm_drawn = rng.uniform(class.pwm_hz.0, class.pwm_hz.1);
        let dead_time_s = rng.uniform(class.dead_time_s.0, class.dead_time_s.1);
        let theta0_deg = rng.uniform(0.0, 360.0);
        // At least 30 samples per electrical period, and a full-voltage step of at most half
        // the rated current per period.
        let pwm_needed = (30.0 * w_e / TAU).max(2.0 * v_ph / (ld_h * i_pk));
        let pwm_hz = (pwm_drawn.max(pwm_needed) / 1e3).ceil() * 1e3;
        if pwm_hz > class.pwm_hz.1 {
            *redrawn += 1;
            continue;
        }
        return Motor {
            index,
            vdc_v: class.vdc_v,
            pole_pairs: p,
            rated_rpm,
            power_w,
            rs_ohm,
            ld_h,
            lq_h: ratio * ld_h,
            flux_wb,
            j_kg_m2,
            b_nm_s,
            rated_peak_a: i_pk,
            rated_nm,
            pwm_hz,
            dead_time_s: (dead_time_s * 1e8).round() / 1e8,
            theta0_deg,
            surface,
        };
    }
}

fn log_uniform(rng: &mut SplitMix, (lo, hi): (f64, f64)) -> f64 {
    (rng.uniform(lo.ln(), hi.ln())).exp()
}

/// The family of `n` motors from `seed`, and how many draws were redrawn.
pub fn family(n: usize, seed: u64) -> (Vec<Motor>, usize) {
    let mut rng = SplitMix(seed);
    let mut redrawn = 0;
    let motors = (0..n).map(|k| draw(&mut rng, k, &mut redrawn)).collect();
    (motors, redrawn)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::family::DEFAULT_SEED;

    #[test]
    fn the_family_has_the_documented_proportions() {
        let (motors, _) = family(200, DEFAULT_SEED);
        for m in &motors {
            let w_m = m.rated_rpm * TAU / 60.0;
            let w_e = w_m * m.pole_pairs as f64;
            let emf = w_e * m.flux_wb / (m.vdc_v / 3f64.sqrt());
            let cu = 1.5 * m.rs_ohm * m.rated_peak_a.powi(2) / m.power_w;
            let x_d = m.ld_h * m.rated_peak_a / m.flux_wb;
            let tau_m = m.tau_m_s();
            let class = CLASSES
                .iter()
                .find(|c| (c.vdc_v - m.vdc_v).abs() < 1e-9)
                .unwrap();
            assert!((0.55..0.9).contains(&emf), "{}: EMF {emf}", m.describe());
            assert!((0.04..0.15).contains(&cu), "{}: copper {cu}", m.describe());
            assert!(
                (0.15..0.5).contains(&x_d),
                "{}: L_d I/ψ {x_d}",
                m.describe()
            );
            assert!((0.03..0.3).contains(&tau_m), "{}", m.describe());
            assert!((1.0..=2.5).contains(&(m.lq_h / m.ld_h)), "{}", m.describe());
            assert!((2..=7).contains(&m.pole_pairs));
            assert!(m.pwm_hz <= class.pwm_hz.1 && m.pwm_hz >= class.pwm_hz.0);
            assert!(m.pwm_hz >= 30.0 * w_e / TAU, "{}", m.describe());
            let step = m.vdc_v / 3f64.sqrt() / (m.ld_h * m.pwm_hz);
            assert!(step <= 0.5 * m.rated_peak_a * 1.0001, "{}", m.describe());
        }
        // Both kinds and every class are drawn.
        assert!(motors.iter().any(|m| m.surface) && motors.iter().any(|m| !m.surface));
        for c in &CLASSES {
            assert!(
                motors.iter().any(|m| (m.vdc_v - c.vdc_v).abs() < 1e-9),
                "{} V",
                c.vdc_v
            );
        }
    }
}
