//! Self-commissioning: the motor's `R`, `L_d`, `L_q`, `ψ`, `J` and `B` measured by the drive
//! itself, from nothing but the pole pairs, the inverter and a current limit.
//!
//! [`Identify`] is a state machine stepped once per control sample, like the
//! [IPD](crate::ipd): it sees the sampled phase currents (αβ) and the bus voltage, and returns
//! duties and `pwm_on`. Its per-sample path is integer only (a PI current loop, an angle
//! generator and sums in `i64`); the few divisions, logarithms and least-squares fits run in
//! [`Identify::poll`], which a caller runs in the background (on the host, after each step).
//! The method is described with its equations in `docs/identification.md`; in short:
//!
//! # Bases
//!
//! Nothing about the motor is known, so the per-unit bases are the inverter's: current
//! `I_b` = the current limit, voltage `V_b = V_DC/√3`. Every step is designed from those, the
//! sample period `T` and the pole pairs `p`. The current loop's proportional gain is
//! `0.2 V_b/I_b`: with the smallest inductance the inverter can control at all,
//! `L_min = V_b T/I_b` (a full-voltage sample changes the current by the whole limit), the
//! loop gain per sample is 0.2, and any larger inductance only makes the loop slower. The
//! integral gain is 2 % of it per sample (its zero well below the proportional bandwidth).
//!
//! # 1. Alignment and resistance
//!
//! Current along α at four levels (30, 40, 50, 60 % of the limit), the first reached by a
//! ramp so that the rotor turns quasi-statically onto the α axis (its d axis then lies along
//! α: `θ = 0` is known from here on). At each level the loop settles, then its voltage is
//! **held** (integrator frozen, no proportional action): a rotor still swinging now induces
//! currents that brake it through `R`, the current settles to `(v − v_0)/R`, and the mean
//! voltage and current over a window give one point of `v = R i + v_0`. The least-squares
//! line through the four points gives `R` (the slope) and the inverter's distortion voltage
//! `v_0` (the intercept: dead time and device drops, constant while no phase current changes
//! sign; `(4/3) V_dead` for an ideal dead-time model). The held β voltage is zero (at
//! standstill that keeps `i_β = 0` by symmetry; what the loop held there only answered the
//! rotor's motion). A current that drifts between the two halves of the window, or a mean
//! `i_β`, means the rotor is still moving: the window is measured again, at most 16 times,
//! then [`IdentifyError::RotorMoved`].
//!
//! # 2. Inductances
//!
//! With the rotor held by the last level's d-axis current (its voltage `v_h` held), a square
//! wave `±V_sq` of half period `N` samples is added along α (the d axis) and then along β
//! (the q axis). The current's peak-to-peak over a period, `D`, is exactly (zero-order hold,
//! linear motor) `D = (2 V_sq/R) tanh(N R T/(2L))`, so `L = N R T/(2 atanh(R D/(2 V_sq)))`:
//! the identified `R` corrects the resistive part, the distortion voltage is the same at both
//! ends of the period and cancels, and the bias keeps every phase current away from zero so
//! that it stays constant. A first burst with `N = 1` gives a coarse `L`; the second uses the
//! `N` that makes `D` about 30 % of the limit (resolution against the ADC's quantisation).
//! Across the d axis the injection makes a torque of zero mean at `1/(2NT)`: the rotor does
//! not follow.
//!
//! # 3. Flux: open-loop spin (I–f)
//!
//! A current vector of amplitude `I_f` (60 % of the limit) is turned at a commanded speed
//! `ω_c`, regulated in its own frame (x along the vector). The rotor follows, lagging by the
//! load angle `δ`. In that frame, at constant speed and averaged over the rotor's hunting,
//! `v − R i = jω ψ_c + v_off` with `ψ_c` the stator flux and `v_off` the distortion voltage
//! (along the current, the same at every speed). The speed is ramped up (acceleration
//! `p · 200` rad/s² electrical by default) until the voltage reaches 45 % of `V_b` (or a
//! mechanical speed limit), giving `ω_1`; windows at `ω_1`, `ω_1/2` and `ω_1` again give
//! three points of that line, whose slope is `jψ_c` and intercept `v_off` (two speeds cancel
//! the offset, and `R`'s error with it). Then `ψ_dq = R(δ) ψ_c` and
//! `ψ_dq = (ψ + L_d I_f cos δ, L_q I_f sin δ)` give `δ` and `ψ` in closed form. Open-loop
//! I–f barely damps the rotor's hunting; the field is slowed when the x voltage
//! (`ω ψ sin δ`) rises above its slow mean, which adds damping `c cos δ · δ'` to
//! `δ'' + (K/J) sin δ = 0`; each window's speed is the mean of the field's actual steps.
//!
//! # 4. Inertia and friction: the energy of the speed steps
//!
//! The electrical power `P = 1.5 v·i` (commanded voltage, measured current) is summed into an
//! energy `C(t)`, and the squared field speed into `F(t) = Σ ω_m² T`. With `C̄`, `F̄`, `t̄`
//! their means over each window (which average the hunting out), `K = ½ ω_m²` and `P̄` a
//! window's mean power, `C̄_b − C̄_a = J ΔK + B ΔF̄ + P_loss Δt̄` for the two speed steps and
//! `P̄ = B ω_m² + P_loss` for the three windows: five equations in `(J, B, P_loss)`, solved
//! by least squares. The up- and the down-step change the kinetic energy by opposite amounts
//! at nearly equal friction and losses (copper, inverter: the same current amplitude
//! throughout), which is what makes `J` well conditioned; no load angle is needed, since the
//! air-gap power `1.5 (v − R i)·i = T ω_m` holds for any motor. `B` rests on differences of
//! mean powers and is a coarse figure.
//!
//! # Faults
//!
//! [`IdentifyError`] names the kind and the [`Stage`]: no current (an open phase), the rotor
//! moving when it should not (or losing the rotating field), the voltage saturating, an
//! inconsistent measurement (noise), an overcurrent or a bus too low.
//!
//! # Formats
//!
//! Currents per unit of the current limit and voltages per unit of `V_DC/√3`, [`Pu`](crate::num::Pu) Q8.24;
//! sums `i64` of `Pu` bits (at most 2²⁴ · 2 per sample, 2¹⁸ samples a window: 2⁴³); the
//! energy `C` sums `v·i` products in `Pu` bits (below 2⁴⁰ for ten minutes at 20 kHz), the
//! squared field speed `F` and its window sums are `i128`; every sum saturates. The angle
//! generator is a `u64` phase in 2⁻¹⁶ angle counts.

mod finish;
mod fit;
mod inductance;
mod machine;
mod poll;
mod resistance;
mod spin;
#[cfg(test)]
mod tests;

pub use machine::{Identify, IdentifyOutput};

use crate::error::ConfigError;
use crate::params::{InverterParams, MotorParams, ParamError, ParamReason, in_range};
use core::fmt;

/// How the identification excites the motor; [`IdentifyDesign::default`] gives the defaults.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdentifyDesign {
    /// The four current levels of the resistance step, fractions of the limit, increasing.
    pub levels: [f64; 4],
    /// Square-wave amplitude of the inductance step, fraction of `V_b`.
    pub square_v_pu: f64,
    /// Wanted peak-to-peak current of the fine inductance burst, fraction of the limit.
    pub ripple_pu: f64,
    /// Current amplitude of the open-loop spin, fraction of the limit.
    pub spin_current_pu: f64,
    /// Mechanical acceleration of the spin's ramps, rad/s².
    pub accel_m_rad_s2: f64,
    /// Highest mechanical speed of the spin, rad/s.
    pub max_speed_m_rad_s: f64,
    /// Voltage that ends the first ramp, fraction of `V_b`.
    pub spin_voltage_pu: f64,
    /// Damping rate of the spin's hunting damper at the first spin speed, 1/s.
    pub damping_per_s: f64,
    /// Proportional gain of the current loop, `V_b/I_b`.
    pub kp_pu: f64,
    /// Integral gain per sample, relative to the proportional gain.
    pub ki_per_sample: f64,
    /// Phase current that aborts, fraction of the limit.
    pub trip_pu: f64,
    /// Settling of each resistance level (loop, then held voltage), s.
    pub settle_s: f64,
    /// Each measuring window, s.
    pub window_s: f64,
}

impl Default for IdentifyDesign {
    fn default() -> Self {
        Self {
            levels: [0.3, 0.4, 0.5, 0.6],
            square_v_pu: 0.25,
            ripple_pu: 0.3,
            spin_current_pu: 0.6,
            accel_m_rad_s2: 200.0,
            max_speed_m_rad_s: 200.0,
            spin_voltage_pu: 0.45,
            damping_per_s: 150.0,
            kp_pu: 0.2,
            ki_per_sample: 0.02,
            trip_pu: 1.5,
            settle_s: 0.12,
            window_s: 0.12,
        }
    }
}

/// The configuration: design turned into sample counts and fixed-point coefficients.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdentifyConfig {
    /// Pole pairs (given).
    pub pole_pairs: u32,
    /// Current base `I_b` = the current limit, A.
    pub current_base_a: f64,
    /// Voltage base `V_b = V_DC/√3`, V.
    pub voltage_base_v: f64,
    /// Control sample period, s.
    pub sample_s: f64,
    /// The design.
    pub design: IdentifyDesign,
    pub(crate) n_ramp: u32,
    pub(crate) n_settle: u32,
    pub(crate) n_hold: u32,
    pub(crate) n_window: u32,
    pub(crate) n_burst: u32,
    /// Per-sample gains, `Pu` bits × 2⁻²⁴.
    pub(crate) kp_q24: i64,
    pub(crate) ki_q24: i64,
    /// Speed increment per sample, angle counts × 2⁻¹⁶ per sample.
    pub(crate) accel_q16: u64,
    pub(crate) max_speed_q16: u64,
    /// Speed correction per `Pu` bit of x voltage, angle counts × 2⁻¹⁶ per sample, × 2⁻²⁴.
    pub(crate) damp_q24: i64,
}

fn samples(key: &'static str, t_s: f64, ts: f64) -> Result<u32, ConfigError> {
    let n = libm::round(t_s / ts);
    if n.is_finite() && (4.0..=(1u32 << 22) as f64).contains(&n) {
        Ok(n as u32)
    } else {
        Err(ConfigError::OutOfEnvelope {
            quantity: key,
            value: n,
            min: 4.0,
            max: (1u32 << 22) as f64,
            fit: crate::error::Fit::Other,
        })
    }
}

/// Angle counts (2³² a turn) × 2¹⁶ per radian.
pub(crate) const Q16_COUNTS_PER_RAD: f64 = 4_294_967_296.0 * 65_536.0 / core::f64::consts::TAU;

impl IdentifyConfig {
    /// Identification of a motor with `pole_pairs` on `inverter` (control at its PWM rate),
    /// limited to `current_limit_a` (A peak). Errors name the offending key.
    pub fn new(
        pole_pairs: u32,
        inverter: &InverterParams,
        current_limit_a: f64,
        design: IdentifyDesign,
    ) -> Result<Self, ConfigError> {
        inverter.validate()?;
        if pole_pairs == 0 || pole_pairs > 100 {
            return Err(ParamError {
                key: "pole_pairs",
                reason: ParamReason::OutOfRange {
                    min: 1.0,
                    max: 100.0,
                },
            }
            .into());
        }
        in_range(
            "current_limit_a",
            current_limit_a,
            1e-3,
            inverter.current_full_scale_a,
        )?;
        let mut last = 0.0;
        for l in design.levels {
            in_range("identify.levels", l, 0.05, 0.9)?;
            if l <= last + 0.02 {
                return Err(ParamError {
                    key: "identify.levels",
                    reason: ParamReason::Inconsistent("increasing by at least 0.02"),
                }
                .into());
            }
            last = l;
        }
        in_range("identify.square_v_pu", design.square_v_pu, 0.02, 0.6)?;
        in_range("identify.ripple_pu", design.ripple_pu, 0.02, 0.5)?;
        in_range("identify.spin_current_pu", design.spin_current_pu, 0.1, 0.9)?;
        in_range("identify.accel_m_rad_s2", design.accel_m_rad_s2, 1.0, 1e5)?;
        in_range(
            "identify.max_speed_m_rad_s",
            design.max_speed_m_rad_s,
            1.0,
            1e4,
        )?;
        in_range(
            "identify.spin_voltage_pu",
            design.spin_voltage_pu,
            0.05,
            0.8,
        )?;
        in_range("identify.damping_per_s", design.damping_per_s, 0.0, 1e4)?;
        in_range("identify.kp_pu", design.kp_pu, 0.01, 0.8)?;
        in_range("identify.ki_per_sample", design.ki_per_sample, 1e-4, 0.2)?;
        in_range("identify.trip_pu", design.trip_pu, 1.0, 3.0)?;
        in_range("identify.settle_s", design.settle_s, 1e-3, 10.0)?;
        in_range("identify.window_s", design.window_s, 1e-3, 10.0)?;
        let ts = 1.0 / inverter.pwm_hz;
        let p = pole_pairs as f64;
        let q24 = |x: f64| libm::round(x * 16_777_216.0) as i64;
        let max_w_e = design.max_speed_m_rad_s * p;
        // The angle step must stay far below half a turn per sample.
        in_range("identify.max_speed_m_rad_s", max_w_e * ts, 0.0, 0.5)?;
        Ok(Self {
            pole_pairs,
            current_base_a: current_limit_a,
            voltage_base_v: inverter.vdc_v / libm::sqrt(3.0),
            sample_s: ts,
            design,
            n_ramp: samples("identify align ramp samples", 2.0 * design.settle_s, ts)?,
            n_settle: samples("identify.settle_s", design.settle_s, ts)?,
            n_hold: samples("identify.settle_s", 0.5 * design.settle_s, ts)?,
            n_window: samples("identify.window_s", design.window_s, ts)?,
            n_burst: samples("identify.window_s", 0.5 * design.window_s, ts)?,
            kp_q24: q24(design.kp_pu),
            ki_q24: q24(design.kp_pu * design.ki_per_sample),
            accel_q16: libm::round(design.accel_m_rad_s2 * p * ts * ts * Q16_COUNTS_PER_RAD)
                .max(1.0) as u64,
            max_speed_q16: libm::round(max_w_e * ts * Q16_COUNTS_PER_RAD) as u64,
            // Δω = (c / v_spin) Δv_x: at the first speed v_x ≈ v_spin sin δ.
            damp_q24: libm::round(
                design.damping_per_s / design.spin_voltage_pu * ts * Q16_COUNTS_PER_RAD,
            ) as i64,
        })
    }

    /// Electrical speed of a generator step, rad/s.
    pub(crate) fn omega_e(&self, speed_q16: u64) -> f64 {
        speed_q16 as f64 / Q16_COUNTS_PER_RAD / self.sample_s
    }
}

/// The steps of the identification, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Alignment and the resistance levels.
    Resistance,
    /// The square wave along d.
    InductanceD,
    /// The square wave along q.
    InductanceQ,
    /// The open-loop spin's constant-speed windows.
    Flux,
    /// The spin's speed steps.
    Inertia,
}

impl fmt::Display for Stage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Stage::Resistance => "resistance",
            Stage::InductanceD => "d-axis inductance",
            Stage::InductanceQ => "q-axis inductance",
            Stage::Flux => "flux",
            Stage::Inertia => "inertia",
        })
    }
}

/// Why the identification stopped, and at which stage.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IdentifyError {
    /// The current stayed below half its reference (open phase, no motor).
    NoCurrent(Stage),
    /// The rotor moved when it should have stood still, or lost the rotating field.
    RotorMoved(Stage),
    /// The voltage needed is beyond the inverter's (resistance too high for the limit).
    Saturation(Stage),
    /// The measurements do not fit the model (noise, or a result out of physical range).
    Noise(Stage),
    /// A phase current exceeded the trip level.
    OverCurrent(Stage),
    /// The bus is too low to modulate.
    BusLow(Stage),
}

impl IdentifyError {
    /// The stage that failed.
    pub fn stage(&self) -> Stage {
        match *self {
            IdentifyError::NoCurrent(s)
            | IdentifyError::RotorMoved(s)
            | IdentifyError::Saturation(s)
            | IdentifyError::Noise(s)
            | IdentifyError::OverCurrent(s)
            | IdentifyError::BusLow(s) => s,
        }
    }
}

impl fmt::Display for IdentifyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let what = match self {
            IdentifyError::NoCurrent(_) => "no current (open phase or no motor)",
            IdentifyError::RotorMoved(_) => "the rotor moved (or did not follow the field)",
            IdentifyError::Saturation(_) => "the voltage saturated",
            IdentifyError::Noise(_) => "inconsistent measurements (noise)",
            IdentifyError::OverCurrent(_) => "overcurrent",
            IdentifyError::BusLow(_) => "bus voltage too low",
        };
        write!(f, "{} step: {what}", self.stage())
    }
}

/// What the identification found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Identified {
    /// The motor (no ratings: the caller adds them).
    pub motor: MotorParams,
    /// Distortion voltage along α at the resistance levels (the intercept), V.
    pub distortion_v: f64,
    /// RMS residual of the resistance line, V.
    pub resistance_residual_v: f64,
    /// Load angle at the constant-speed windows, rad.
    pub load_angle_rad: f64,
    /// The two spin speeds `ω_1`, `ω_2`, electrical rad/s.
    pub spin_speeds_rad_s: [f64; 2],
}
