//! Current-model MRAS speed and position estimator of Khlaief, Boussak, Gossa (2012) (eq. 14–23, docs/khlaief2012.md §2).
//!
//! The measured currents are taken to the **estimated** rotor frame (`θ̂`) and compared with
//! an adjustable model of the motor run in that frame at the estimated speed:
//!
//! ```text
//! dî_d/dt = −(R/L_d) î_d + (L_q/L_d) ω̂ î_q + v_d/L_d                      (eq. 15)
//! dî_q/dt = −(R/L_q) î_q − (L_d/L_q) ω̂ î_d − (ψ/L_q) ω̂ + v_q/L_q
//! ε_d = i_d − î_d,   ε_q = i_q − î_q                                          (eq. 16)
//! ξ = (L_q/L_d) i_q ε_d − (L_d/L_q) i_d ε_q − (ψ/L_q) ε_q                     (eq. 21–22)
//! ω̂ = K_i ∫ξ dt + K_p ξ,   θ̂ = ∫ω̂ dt + θ_0                                   (eq. 22–23)
//! ```
//!
//! The estimator works with `ξ̃ = (L_q/L_d) ξ = w (L_q/L_d)² i_q ε_d − (i_d + ψ/L_d) ε_q` (one
//! weight fewer), with `K_p`, `K_i` and the load gain rescaled to match: the same eq. 22, but
//! for `w`, the d-axis error's weight (below; `w = 1` is eq. 21's).
//!
//! # Sign of ξ
//!
//! With `ε = i − î`, a rotor ahead of the estimate (`δ = θ − θ̂ > 0`) or faster than it
//! (`ω > ω̂`) gives `ξ > 0` at any speed away from zero: the back-EMF error they cause,
//! `ψ ω (−sin δ, cos δ) − ψ ω̂ (0, 1)`, drives `ε_q < 0` through the q inductance, and
//! `−(ψ/L_q) ε_q` dominates ξ. So `ω̂` grows and `θ̂` catches up: the stated sign is the
//! stable one. Checked against the plant (`tests/drive_parts_mras.rs`: the estimate converges
//! from ±20° at ±800 r/min, motoring and generating).
//!
//! # The d-axis error's weight
//!
//! Eq. 21 weighs `ε_d` by `(L_q/L_d) i_q`, which Popov's criterion asks of an exact model. With
//! the model off, `ε_d` carries the model's error more than the position: at speed and `δ = 0`
//! the model's flux error `Δψ = ψ̂ − ψ` leaves `ε_d ≈ Δψ/L_d`, its resistance error
//! `ΔR = R̂ − R` leaves `ε_d ≈ ΔR i_q/(ω L_d)` (the steady state of eq. 15 against eq. 14),
//! while a position error reaches `ε_d` only through the saliency (`(ρ − 1) i_q δ`). Under
//! load the `i_q ε_d` term turns those errors into an angle offset that moves with `i_q`, so
//! the speed loop's current steps move the estimate. [`MrasCurrentGains::d_weight`] scales the
//! term; the default, `w = 1/2` ([`DEFAULT_D_WEIGHT`]), was measured against `w = 1`
//! (docs/khlaief2012.md §2, "The d-axis error's weight"): the random family holds 9 more of
//! 800 runs, and (measured with the current loops at `0.05/T_s`) motor B at 1500 r/min under
//! rated load settles 3–4 times closer with the plant's R at ×1.5 or ×0.7 of its model's. At
//! `w = 1/ρ²` (the surface motor's cross product `i_d î_q − i_q î_d`) motor B's no-load speed
//! on the averaged inverter with a hard sign left its bar; at `w = 0` a resistance error cost
//! more than at `w = 1`. The price: a slower pull-in at low speed under load, where the
//! saliency's share of the loop's gain is halved.
//!
//! # Discretisation
//!
//! In flux coordinates, `λ = (L_d î_d + ψ, L_q î_q)`, the model is a decay through `R`, a drive
//! by `v`, and a pure rotation by `−ω̂ t` (the frame turning under a fixed flux):
//! `dλ/dt = −R î + v + ω̂ (λ_q, −λ_d)`. One sample is a Strang splitting of the two parts, each
//! solved exactly:
//!
//! 1. half an R–L step in the frame at `θ̂_{k−1}`: `î ← a î + g v_dq(θ̂_{k−1})`,
//!    `a = e^{−R T_s/(2L)}`, `g = (1 − a)/R` (zero-order hold: matched pole, exact for a held
//!    voltage);
//! 2. the exact rotation of `λ` by `−Δ`, `Δ = ω̂ T_s`, written in currents:
//!    `î_d ← c î_d + s (L_q/L_d) î_q − (1 − c) ψ/L_d`, `î_q ← c î_q − s (L_d/L_q) î_d − s ψ/L_q`
//!    (`s, c = sin Δ, cos Δ`);
//! 3. half an R–L step in the frame at `θ̂_k = θ̂_{k−1} + Δ`.
//!
//! The three maps are affine, and the voltage of step 3 is that of step 1 turned by the same
//! `Δ` (`v_dq(θ̂_k) = (c v_d + s v_q, c v_q − s v_d)` with `v = v_dq(θ̂_{k−1})`), so one sample
//! is computed as their composition, exactly (with `ρ = L_q/L_d`, `Ψ_d = a_d ψ/L_d`,
//! `Ψ_q = a_q ψ/L_q`):
//!
//! ```text
//! X_d = a_d² î_d + (1 + a_d) g_d v_d + Ψ_d      X_q = a_d a_q ρ î_q + (a_d ρ g_q + g_d) v_q
//! Y_q = a_q² î_q + (1 + a_q) g_q v_q            Y_d = (a_q a_d/ρ) î_d + (a_q g_d/ρ + g_q) v_d + Ψ_q
//! î_d ← c X_d + s X_q − Ψ_d                     î_q ← c Y_q − s Y_d
//! ```
//!
//! (expand `a (rotation of (a î + g v)) + g v_dq(θ̂_k)` and collect `c` and `s`): one Park
//! transform of `v` instead of two, and eight weights, each applied once with one rounding
//! per pair, instead of the twenty-odd products of the three steps done one after the other.
//!
//! The splitting error is third order per step; forward Euler on eq. 15 would instead inflate
//! the model's EMF by `√(1 + Δ²)` and mis-damp it by `R T_s/L`, both of which the adaptation
//! reads as a speed and position error. The f64 reference of this scheme (in
//! `tests/support/drive_ref.rs`) settles within 0.004° at 800 r/min on motor B.
//!
//! The voltage of the input was applied over `[t_{k−1}, t_k)` (see [`super`]'s timing
//! convention) and is constant in the stationary frame: its rotor-frame value is taken at the
//! frame angle of each half step. `θ̂` advances with the `ω̂` held over the same interval, so
//! the model frame and the estimate are the same frame.
//!
//! # Gains
//!
//! Near `δ = 0` and away from zero speed, `ξ ≈ k_δ δ + k_ω (ω − ω̂)`; at high speed
//! `k_δ → k_∞ = (ψ/L_q)²` (A²/rad). The PI on ξ closes a phase-locked loop on `θ`; at high
//! speed its characteristic polynomial is `s² + K_p k_∞ s + K_i k_∞`, so for a natural
//! frequency `ω_n` and damping 1:
//!
//! ```text
//! K_p = 2 ω_n / k_∞,   K_i = ω_n² / k_∞,   k_∞ = (ψ/L_q)²
//! ```
//!
//! Default ([`MrasCurrentGains::default_for`]): `ω_n = 0.02/T_s` (280 rad/s at 14 kHz), raised
//! on a light rotor towards `√(a I_b/0.15 rad)`, at most `0.06/T_s` and as far as the
//! per-unit gains keep room in their formats: the loop's angle error after a step `α` of the
//! acceleration is of the order of `α/ω_n²`, and a rated load step on a rotor with a 30 ms
//! mechanical time constant at half rated speed outruns the design at `0.02/T_s`. At low
//! speed `k_δ` falls (at zero current as `ω²/(ω² + ω_c²)`, `ω_c = R/√(L_d L_q)`) and the loop
//! slows, which is the MRAS's known weakness near standstill ("Low-speed schedule" makes up
//! for it down to `ω_c/√3`); the position error at steady state is still zero with exact
//! parameters. Accepted range:
//! `K_p ∈ [0, 1/(k_∞ T_s)]`, `K_i ∈ [0, 0.25/(k_∞ T_s²)]`, and within the formats of their
//! per-unit values ("Formats").
//!
//! # Low-speed schedule
//!
//! At zero current the sensitivity is `k = k_∞ ω²/(ω² + ω_c²)`, `ω_c = R/√(L_d L_q)`: the
//! loop's gain falls by `1 + (ω_c/ω)²` below the corner. The three gains (`K_p`, `K_i`, `K_L`)
//! are raised by about that loss, in five levels `b = (1, 3/2, 2, 3, 4)` (shifts and adds):
//! level `j` from `|ω̂| ≥ c_j ω_c` up, `c_j = 1/√(√(b_j b_{j+1}) − 1)` (the geometric midpoint
//! to the next factor), the last down to zero. All three scale together, so the roots of the
//! linearised loop stay near where they were designed down to `ω̂ ≈ ω_c/√3`, and `k_t` is
//! unchanged. Levels whose gains would leave their formats are not used. The update reads the
//! gains in use from the configuration; [`MrasCurrent::schedule`] picks the level and writes
//! them there (the drive, every eighth sample); [`MrasCurrentGains::low_speed_schedule`] turns
//! it on. Off by default: it saves reversals under load on the random family, and costs starts
//! on a motor whose model or inverter is off, where the raised gains pass the voltage error
//! (read as a speed `ΔV/ψ` near standstill) faster (docs/khlaief2012.md §2 gives both).
//!
//! The PI is the estimator's own: `ω̂ = clamp(K_p ξ + I, ±ω_max)`, the feed-forward of the
//! mechanical model and `K_i T_s ξ` added to `I` every sample, `I` clamped to `±ω_max`. While
//! `K_p ξ + I` (before the integration) is on or beyond a limit, the integrator is
//! back-calculated, `I ← I + K_i T_s ξ + k_t (clamp − (K_p ξ + I))`, `k_t = min(1, K_i T_s/K_p)`
//! (with `K_p = 0`: no integration that pushes further out).
//!
//! # Through zero speed
//!
//! Near standstill ξ carries almost no information on the position (the EMF error vanishes
//! with ω), and a speed that changes sign under load drags the estimate away. The mechanical
//! model knows how the speed changes: the measured torque current accelerates the rotor by
//! `a (i_q − i_L) − (B/J) ω̂`, `a = p K_T/J` (docs/algorithms.md (conventions)), where `i_L` is the load seen as
//! a current. Every sample that acceleration is added to the speed integrator, and the load
//! estimate follows `dî_L/dt = −K_L ξ` (a rotor ahead of the estimate means less load than
//! assumed). Linearised, `ξ ≈ k δ`, the position error obeys
//! `δ‴ + K_p k δ″ + K_i k δ′ + a K_L k δ = 0`; [`MrasCurrentGains::design`] places its poles.
//! Through zero speed `k → 0`: the loop opens, and the model carries the estimate with the load
//! learned before, so a reversal under a load that does not reverse with it keeps its lock.
//! `K_L = 0` gives the plain MRAS of Khlaief, Boussak, Gossa (2012).
//!
//! # Held
//!
//! [`MrasCurrent::hold`] suspends the adaptation for a number of updates: each takes the model
//! to the measured current (`î = i`, so `ε = 0` and `ξ = 0`) and moves the speed by the
//! mechanical model alone, and the update after them seeds the model afresh as the first
//! after a reset does. The drive holds it through a phase current's zero crossing at low speed
//! and light load, where the inverter's distortion, which no compensation follows there, is as
//! large as the EMF the adaptation reads (docs/drive.md, "zero crossings at low speed").
//!
//! # Formats
//!
//! Every per-sample product has a compile-time binary point ([`Coef`]): one multiply, a
//! constant shift and a high-word fit test. The coefficient groups and their ranges (checked
//! by [`MrasCurrentConfig::new`], which names the motor parameter or gain of a coefficient
//! that does not fit; the motor family of [`crate::units`] spans the "family" column):
//!
//! | signal or coefficient | format | range accepted | family |
//! |---|---|---|---|
//! | `î`, `i`, `v`, `ε`, `X`, `Y` | [`Pu`] Q8.24 | ±128 | per unit of `I_b`, `V_b` |
//! | sin/cos of `θ̂` and of `Δ` | [`Unit`] Q2.30 | ±1 | |
//! | model weights `a_d²`, `(1 + a_d) g_d`, `a_d a_q ρ`, `a_d ρ g_q + g_d`, `a_q²`, `(1 + a_q) g_q`, `a_q a_d/ρ`, `a_q g_d/ρ + g_q` | `Coef<28>` (LSB 3.7e−9) | [0, 4] (so `L_q/L_d` within about [¼, 4]) | [0.016, 1.66] |
//! | offsets `a_d ψ/L_d`, `a_q ψ/L_q`; `ψ/L_d` of ξ̃ | [`Pu`] Q8.24 | [0, 32] | [0.047, 7.1] |
//! | `w ρ² = w (L_q/L_d)²` | `Coef<26>` | [0, 16] | [0.5, 1.4] (`w = 1/2`) |
//! | `ξ̃ = (L_q/L_d) ξ` | [`Pu`] Q8.24 | ±128 | per unit of `I_b²` |
//! | `K_p` on ξ̃ | `Coef<24>` | [0, 128) | default [0.033, 58] |
//! | `K_i T_s`, `T_s a`, `T_s B/J` on ξ̃, `i_q − i_L`, `ω̂` | `Coef<31>`, exact products | `K_i T_s` [0, 1), the other two [0, 1/16] | [4.4e−4, 0.78], [5.6e−5, 0.014], [1e−6, 4.6e−5] |
//! | speed integrator `I` | `i64` Q9.55 (LSB = the exact product's) | clamped to `±ω_max` (≤ 4 pu) | |
//! | `T_s K_L I_b/ρ` (load estimate) | `Coef<27>` | [0, 16) | default [0.001, 0.58] |
//! | `i_L` | [`Pu`] Q8.24 | ±128 | |
//! | `ω̂` | [`Pu`] Q8.24 | `±ω_max` | per unit of `ω_b` |
//! | `θ̂` | `u64` turn, 2⁶⁴ per turn | wraps | the top 32 bits are the [`Angle`] |
//! | `ω_b T_s 2³³/(2π)` (angle step per unit of speed, ×2⁷) | `i32` | `ω_b T_s ≤ 1` rad | |
//!
//! Overflow: every weight above is at most 2³⁰ in bits, so a sum of two products and an
//! offset stays below 2⁶² (the rounding kernel's contract is 2⁶³ − 2³²); the bounds of the
//! integrator are given beside the code.

mod config;
mod gains;
mod model;
#[cfg(test)]
mod tests;
mod update;

pub use config::MrasCurrentConfig;
pub use gains::MrasCurrentGains;
pub use model::MrasModel;
pub(crate) use model::{MRAS_MODEL_WORDS, MrasDecay, MrasModelScaling};
pub use update::MrasCurrent;

use crate::num::PU_FRAC;

/// Default `ω_n T_s` of the adaptation loop.
pub const DEFAULT_BANDWIDTH_TS: f64 = 0.02;
/// Largest `ω_n T_s` of the default design (raised for a light rotor).
pub const MAX_DEFAULT_BANDWIDTH_TS: f64 = 0.06;
/// The angle lag, rad, the default design allows a rated load step (`α/ω_n²`).
pub(super) const LOAD_STEP_LAG_RAD: f64 = 0.15;
/// Largest per-unit `K_i T_s` and load gain a raised default bandwidth may reach (of 1 and
/// 16 in their formats).
pub(super) const KI_TS_ROOM: f64 = 0.75;
pub(super) const LOAD_GAIN_ROOM: f64 = 8.0;

/// Levels of the low-speed schedule (module docs, "Low-speed schedule").
pub(super) const BOOST_LEVELS: usize = 5;
/// Level `j < 4` holds from `|ω̂| ≥ c_j ω_c` up, `c_j = 1/√(√(b_j b_{j+1}) − 1)` with the
/// factors `b = (1, 3/2, 2, 3, 4)`; the last down to zero.
pub(super) const BOOST_ABOVE: [f64; BOOST_LEVELS - 1] = [
    2.109_381_364_946_41,
    1.168_770_894_480_367_9,
    0.830_600_956_269_998_3,
    0.637_045_853_575_688_5,
];

/// Default [`MrasCurrentGains::d_weight`]: half of eq. 21's weight on `ε_d` (module docs,
/// "The d-axis error's weight").
pub const DEFAULT_D_WEIGHT: f32 = 0.5;

/// Largest estimated speed, per unit of `ω_b` (also at most 1 rad per sample).
pub const MAX_SPEED_PU: f64 = 4.0;

/// Binary point of the model weights (module docs, "Formats").
pub(super) const MODEL_FRAC: u32 = 28;
/// Largest model weight.
pub(super) const MODEL_MAX: f64 = 4.0;
/// Largest offset `ψ/L` (per unit): with the signals below 4 pu, `X_d`, `Y_d` and
/// `i_d + ψ/L_d` stay far inside Q8.24.
pub(super) const OFFSET_MAX: f64 = 32.0;
/// Fractional bits of the speed integrator (Q9.55): the LSB of a `Coef<31>` times a [`Pu`].
pub(super) const INTEG_FRAC: u32 = 55;
/// Extra fractional bits of the integrator over [`Pu`].
pub(super) const INTEG_EXTRA: u32 = INTEG_FRAC - PU_FRAC;
/// Largest `T_s a` and `T_s B/J`: keeps the feed-forward below 2⁵⁸ (see `update`).
pub(super) const MECH_MAX: f64 = 1.0 / 16.0;
/// The angle step is `ω · turn_per_speed · 2^TURN_SHIFT` (2⁻⁶⁴ turn).
pub(super) const TURN_SHIFT: u32 = 7;
