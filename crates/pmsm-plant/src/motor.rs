//! Electrical and mechanical model of the motor, integrated by classical RK4.
//!
//! Two state representations, chosen once from the model:
//!
//! - **αβ** (surface motor, `L_d = L_q`, linear magnetics): state `(i_α, i_β, θ, ω_m)`,
//!   Solsona, Valla, Muravchik (2000) eq. 1–6 as restated in docs/solsona2000.md §1, with the 5th and 7th EMF harmonics.
//!   `L = (L_d + L_q)/2` ([`MotorParams::is_surface`] tolerates 0.1 % of difference).
//! - **dq** (interior motor, or any motor with non-linear [`Saturation`]): state
//!   `(i_d, i_q, θ, ω_m)`, Khlaief, Boussak, Gossa (2012) eq. 1–4 as restated in docs/khlaief2012.md §1, with `i_d` as the
//!   state of the saturable d axis, `di_d/dt = (v_d − R i_d + ω ψ_q − e_h,d) / L_inc,d(i_d)`.
//!
//! In both, the stator voltage is given in the stationary frame and held constant over a step
//! (zero-order hold); in dq it is rotated to the rotor frame at every RK stage.
//!
//! # Torque and energy
//!
//! The electromagnetic torque is the one that makes the model energy-consistent, scaled by
//! `K_T/(1.5 p ψ)` so that the motor's stated torque constant is honoured:
//!
//! - αβ: `T = K_T (k(θ)·i)`, where the back-EMF is `e = ψ ω k(θ)` (without harmonics
//!   `k·i = i_q`);
//! - dq: `T = K_T/(1.5 p ψ) · 1.5 p (ψ_d(i_d) i_q − L_q i_q i_d + ψ (k_h·i_dq))` (Khlaief, Boussak, Gossa (2012) eq. 5
//!   with the 1.5 of the amplitude-invariant transform, docs/algorithms.md (conventions)).
//!
//! With the default `K_T = 1.5 p ψ` the electrical power `1.5 v·i` splits exactly into copper
//! loss `1.5 R |i|²`, the rate of change of [`Motor::magnetic_energy_j`] and the air-gap power
//! `T ω_m`. A different `K_T` (motor A states 1.108 N·m/A where `1.5 p ψ` = 1.296) makes the
//! mechanical side see a torque that the electrical side does not pay for; that is the model
//! Solsona, Valla, Muravchik (2000) simulates, and it is kept on purpose.
//!
//! # EMF harmonics (docs/solsona2000.md §1)
//!
//! `k(θ) = (−sin θ + h5 sin 5θ − h7 sin 7θ,  cos θ + h5 cos 5θ + h7 cos 7θ)`: a 5th harmonic
//! turning backwards and a 7th turning forwards. In the rotor frame they are both at 6θ:
//! `k_dq = ((h5 − h7) sin 6θ, 1 + (h5 + h7) cos 6θ)`; the dq model adds the harmonic part
//! `e_h = ψ ω k_h` to the speed voltages, so harmonics also work with saturation.
//!
//! # Mechanics (docs/algorithms.md (conventions))
//!
//! `J dω_m/dt = T − B ω_m − T_L`, `dθ/dt = p ω_m`, or the rotor held ([`Mechanics`]).

use pmsm_core::validate::in_range;
use pmsm_core::{MotorParams, ParamError};

use crate::saturation::{DAxis, Saturation};
use crate::{PlantError, inverse_clarke, inverse_park, park};

/// Upper bound on the RK4 sub-step, s.
pub const MAX_SUBSTEP_S: f64 = 5e-6;
/// The sub-step is also at most `τ_e / SUBSTEPS_PER_TAU`, `τ_e = L_min / R`.
pub const SUBSTEPS_PER_TAU: f64 = 50.0;
/// The sub-step is also at most this electrical angle (of the highest EMF harmonic), rad.
pub const MAX_ANGLE_PER_SUBSTEP_RAD: f64 = 0.02;
/// Largest number of sub-steps one call may take (about 21 s of motor time at 5 µs).
pub const MAX_SUBSTEPS: u32 = 1 << 22;

/// How the rotor moves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Mechanics {
    /// Free rotor: `J dω_m/dt = T − B ω_m − T_L`, `dθ/dt = p ω_m`.
    Free,
    /// Rotor held at its present angle: `ω_m = 0`, `θ` fixed (initial-position tests).
    Locked,
    /// Rotor driven at this mechanical speed, rad/s, whatever the torque (a dynamometer).
    ConstantSpeed(f64),
}

/// Everything that defines a motor: parameters, d-axis saturation and EMF harmonics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorModel {
    /// Electrical and mechanical parameters (SI).
    pub params: MotorParams,
    /// d-axis flux model; non-linear forces the dq state representation.
    pub saturation: Saturation,
    /// Relative amplitude of the 5th EMF harmonic (turning backwards), e.g. 0.042 in Solsona, Valla, Muravchik (2000).
    pub emf_h5: f64,
    /// Relative amplitude of the 7th EMF harmonic (turning forwards), e.g. 0.025 in Solsona, Valla, Muravchik (2000).
    pub emf_h7: f64,
}

impl MotorModel {
    /// Model with the default saturation for these parameters
    /// ([`Saturation::default_for`]) and no EMF harmonics.
    pub fn new(params: MotorParams) -> Self {
        Self {
            saturation: Saturation::default_for(&params),
            params,
            emf_h5: 0.0,
            emf_h7: 0.0,
        }
    }

    /// Checks every parameter; the error names the first offending key (`emf_h5`, `emf_h7`
    /// in `[−0.5, 0.5]`, `saturation.psi_s_wb`, or a key of [`MotorParams::validate`]).
    pub fn validate(&self) -> Result<(), ParamError> {
        self.params.validate()?;
        in_range("emf_h5", self.emf_h5, -0.5, 0.5)?;
        in_range("emf_h7", self.emf_h7, -0.5, 0.5)?;
        self.saturation.validate(&self.params)
    }

    /// True if the model is integrated in the rotor (dq) frame: interior motor or non-linear
    /// saturation. A surface motor with linear magnetics uses the αβ frame.
    pub fn uses_dq_frame(&self) -> bool {
        !self.params.is_surface() || !self.saturation.is_linear()
    }
}

/// The state of the motor, in the stationary frame whatever the internal representation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorState {
    /// α stator current, A.
    pub i_alpha_a: f64,
    /// β stator current, A.
    pub i_beta_a: f64,
    /// Electrical rotor angle, rad; continuous (not wrapped), so it counts turns.
    pub theta_e_rad: f64,
    /// Mechanical rotor speed, rad/s.
    pub omega_m_rad_s: f64,
}

/// Coefficients of the state equations, computed once from a validated model.
#[derive(Clone, Copy, Debug)]
struct Coeffs {
    dq: bool,
    r_ohm: f64,
    /// Inductance of the αβ model (mean of `L_d` and `L_q`), H.
    l_h: f64,
    lq_h: f64,
    daxis: DAxis,
    psi_wb: f64,
    p: f64,
    /// `K_T / (1.5 p ψ)`: 1 for an energy-consistent motor.
    kt_scale: f64,
    j_kg_m2: f64,
    b_nm_s: f64,
    h5: f64,
    h7: f64,
    harmonics: bool,
}

impl Coeffs {
    fn new(m: &MotorModel) -> Self {
        let p = &m.params;
        Self {
            dq: m.uses_dq_frame(),
            r_ohm: p.rs_ohm,
            l_h: 0.5 * (p.ld_h + p.lq_h),
            lq_h: p.lq_h,
            daxis: DAxis::new(&m.saturation, p),
            psi_wb: p.flux_wb,
            p: p.p(),
            kt_scale: p.kt_nm_per_a / (1.5 * p.p() * p.flux_wb),
            j_kg_m2: p.j_kg_m2,
            b_nm_s: p.b_nm_s,
            h5: m.emf_h5,
            h7: m.emf_h7,
            harmonics: m.emf_h5 != 0.0 || m.emf_h7 != 0.0,
        }
    }

    /// Stationary-frame EMF shape `k(θ)`, `e = ψ ω k` (docs/solsona2000.md §1).
    fn emf_shape(&self, theta: f64) -> [f64; 2] {
        let (s1, c1) = libm::sincos(theta);
        if !self.harmonics {
            return [-s1, c1];
        }
        let (s5, c5) = libm::sincos(5.0 * theta);
        let (s7, c7) = libm::sincos(7.0 * theta);
        [
            -s1 + self.h5 * s5 - self.h7 * s7,
            c1 + self.h5 * c5 + self.h7 * c7,
        ]
    }

    /// Harmonic part of the EMF shape in the rotor frame, `k_h,dq` (both at 6θ).
    fn emf_harmonic_dq(&self, theta: f64) -> [f64; 2] {
        if !self.harmonics {
            return [0.0; 2];
        }
        let (s6, c6) = libm::sincos(6.0 * theta);
        [(self.h5 - self.h7) * s6, (self.h5 + self.h7) * c6]
    }

    /// Stationary-frame currents of a state vector.
    fn i_ab(&self, x: &[f64; 4]) -> [f64; 2] {
        if self.dq {
            inverse_park([x[0], x[1]], x[2])
        } else {
            [x[0], x[1]]
        }
    }

    /// Electromagnetic torque, N·m.
    fn torque(&self, x: &[f64; 4]) -> f64 {
        if self.dq {
            let (i_d, i_q) = (x[0], x[1]);
            let psi_d = self.daxis.flux_wb(i_d);
            let kh = self.emf_harmonic_dq(x[2]);
            self.kt_scale
                * 1.5
                * self.p
                * (psi_d * i_q - self.lq_h * i_q * i_d + self.psi_wb * (kh[0] * i_d + kh[1] * i_q))
        } else {
            let k = self.emf_shape(x[2]);
            self.kt_scale * 1.5 * self.p * self.psi_wb * (k[0] * x[0] + k[1] * x[1])
        }
    }

    /// Time derivative of the state for stationary voltage `v_ab` and load torque `load_nm`.
    fn deriv(&self, mech: Mechanics, x: &[f64; 4], v_ab: [f64; 2], load_nm: f64) -> [f64; 4] {
        let theta = x[2];
        let w_m = x[3];
        let w = self.p * w_m;
        let (di0, di1, torque) = if self.dq {
            // Khlaief, Boussak, Gossa (2012) eq. 1–4, docs/khlaief2012.md §1: v_d = R i_d + dψ_d/dt − ω ψ_q (+ e_h,d),
            // v_q = R i_q + L_q di_q/dt + ω ψ_d (+ e_h,q); v rotated at this stage's angle.
            let (i_d, i_q) = (x[0], x[1]);
            let v = park(v_ab, theta);
            let (psi_d, l_inc) = self.daxis.flux_and_inductance(i_d);
            let kh = self.emf_harmonic_dq(theta);
            let e_hd = self.psi_wb * w * kh[0];
            let e_hq = self.psi_wb * w * kh[1];
            let did = (v[0] - self.r_ohm * i_d + w * self.lq_h * i_q - e_hd) / l_inc;
            let diq = (v[1] - self.r_ohm * i_q - w * psi_d - e_hq) / self.lq_h;
            let t = self.kt_scale
                * 1.5
                * self.p
                * (psi_d * i_q - self.lq_h * i_q * i_d + self.psi_wb * (kh[0] * i_d + kh[1] * i_q));
            (did, diq, t)
        } else {
            // Solsona, Valla, Muravchik (2000) eq. 3–6, docs/solsona2000.md §1: L di/dt = −R i − e + v, e = ψ ω k(θ).
            let k = self.emf_shape(theta);
            let e = [self.psi_wb * w * k[0], self.psi_wb * w * k[1]];
            let dia = (v_ab[0] - self.r_ohm * x[0] - e[0]) / self.l_h;
            let dib = (v_ab[1] - self.r_ohm * x[1] - e[1]) / self.l_h;
            let t = self.kt_scale * 1.5 * self.p * self.psi_wb * (k[0] * x[0] + k[1] * x[1]);
            (dia, dib, t)
        };
        // Solsona, Valla, Muravchik (2000) eq. 1–2, docs/algorithms.md (conventions): J dω_m/dt = T − B ω_m − T_L, dθ/dt = p ω_m.
        let (dtheta, dw_m) = match mech {
            Mechanics::Free => (w, (torque - self.b_nm_s * w_m - load_nm) / self.j_kg_m2),
            Mechanics::Locked => (0.0, 0.0),
            Mechanics::ConstantSpeed(_) => (w, 0.0),
        };
        [di0, di1, dtheta, dw_m]
    }
}

/// A motor: a validated [`MotorModel`], its mechanics and its state.
#[derive(Clone, Debug)]
pub struct Motor {
    model: MotorModel,
    c: Coeffs,
    mech: Mechanics,
    /// `(i_α, i_β, θ, ω_m)` or `(i_d, i_q, θ, ω_m)`.
    x: [f64; 4],
    substep_scale: f64,
}

fn finite(key: &'static str, v: f64) -> Result<f64, PlantError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(PlantError::NonFinite(key))
    }
}

impl Motor {
    /// Motor at rest electrically (zero current) at electrical angle `theta_e0_rad` and
    /// mechanical speed `omega_m0_rad_s`, with [`Mechanics::Free`]. Validates the model.
    pub fn new(
        model: MotorModel,
        theta_e0_rad: f64,
        omega_m0_rad_s: f64,
    ) -> Result<Self, ParamError> {
        model.validate()?;
        in_range("theta_e0_rad", theta_e0_rad, -f64::MAX, f64::MAX)?;
        in_range("omega_m0_rad_s", omega_m0_rad_s, -f64::MAX, f64::MAX)?;
        Ok(Self {
            c: Coeffs::new(&model),
            model,
            mech: Mechanics::Free,
            x: [0.0, 0.0, theta_e0_rad, omega_m0_rad_s],
            substep_scale: 1.0,
        })
    }

    /// The model this motor was built from.
    pub fn model(&self) -> &MotorModel {
        &self.model
    }

    /// True if the state is kept in the rotor (dq) frame ([`MotorModel::uses_dq_frame`]).
    pub fn uses_dq_frame(&self) -> bool {
        self.c.dq
    }

    /// Scales the model's resistance by `rs_factor` and its magnet flux (and torque constant)
    /// by `flux_factor`, both in `[0.2, 5]`, from the next step on; the state is kept.
    pub fn set_factors(&mut self, rs_factor: f64, flux_factor: f64) -> Result<(), PlantError> {
        let mut m = self.model;
        m.params.rs_ohm *= in_range("rs_factor", rs_factor, 0.2, 5.0)?;
        m.params.flux_wb *= in_range("flux_factor", flux_factor, 0.2, 5.0)?;
        m.params.kt_nm_per_a *= flux_factor;
        m.validate()?;
        let dq = self.c.dq;
        self.c = Coeffs::new(&m);
        // The state's frame was chosen at construction.
        self.c.dq = dq;
        Ok(())
    }

    /// Present mechanics.
    pub fn mechanics(&self) -> Mechanics {
        self.mech
    }

    /// Changes the mechanics: [`Mechanics::Locked`] sets `ω_m = 0` and holds `θ`;
    /// [`Mechanics::ConstantSpeed`] sets `ω_m` to its speed; [`Mechanics::Free`] continues from
    /// the present speed.
    pub fn set_mechanics(&mut self, mechanics: Mechanics) -> Result<(), PlantError> {
        match mechanics {
            Mechanics::Free => {}
            Mechanics::Locked => self.x[3] = 0.0,
            Mechanics::ConstantSpeed(w_m) => self.x[3] = finite("omega_m_rad_s", w_m)?,
        }
        self.mech = mechanics;
        Ok(())
    }

    /// Present state (stationary-frame currents, continuous angle, mechanical speed).
    pub fn state(&self) -> MotorState {
        let i = self.c.i_ab(&self.x);
        MotorState {
            i_alpha_a: i[0],
            i_beta_a: i[1],
            theta_e_rad: self.x[2],
            omega_m_rad_s: self.x[3],
        }
    }

    /// Overwrites the state. Under [`Mechanics::Locked`] or [`Mechanics::ConstantSpeed`] the
    /// speed of `state` is ignored and the imposed one kept.
    pub fn set_state(&mut self, state: MotorState) -> Result<(), PlantError> {
        let ia = finite("i_alpha_a", state.i_alpha_a)?;
        let ib = finite("i_beta_a", state.i_beta_a)?;
        let th = finite("theta_e_rad", state.theta_e_rad)?;
        let w = finite("omega_m_rad_s", state.omega_m_rad_s)?;
        let i = if self.c.dq {
            park([ia, ib], th)
        } else {
            [ia, ib]
        };
        let w = match self.mech {
            Mechanics::Free => w,
            Mechanics::Locked => 0.0,
            Mechanics::ConstantSpeed(w_m) => w_m,
        };
        self.x = [i[0], i[1], th, w];
        Ok(())
    }

    /// Electrical speed `ω = p ω_m`, rad/s.
    pub fn omega_e_rad_s(&self) -> f64 {
        self.c.p * self.x[3]
    }

    /// Stator current `[α, β]`, A.
    pub fn i_alpha_beta(&self) -> [f64; 2] {
        self.c.i_ab(&self.x)
    }

    /// Stator current in the rotor frame `[d, q]`, A (Park at the true angle).
    pub fn i_dq(&self) -> [f64; 2] {
        if self.c.dq {
            [self.x[0], self.x[1]]
        } else {
            park([self.x[0], self.x[1]], self.x[2])
        }
    }

    /// Phase currents `[a, b, c]`, A (zero sum: isolated neutral).
    pub fn i_abc(&self) -> [f64; 3] {
        inverse_clarke(self.c.i_ab(&self.x))
    }

    /// Rate of change of the stationary-frame currents `d[i_α, i_β]/dt`, A/s, at the present
    /// state under stationary voltage `v_ab` (V). Affine in `v_ab`; the switching inverter
    /// solves it for the voltage of a phase whose diodes both block (a floating phase).
    pub fn current_rate_ab(&self, v_ab: [f64; 2]) -> [f64; 2] {
        let d = self.c.deriv(self.mech, &self.x, v_ab, 0.0);
        if self.c.dq {
            // i_αβ = R(θ) i_dq: d/dt = R(θ) di_dq/dt + dθ/dt · R(θ + π/2) i_dq.
            let r = inverse_park([d[0], d[1]], self.x[2]);
            let i = inverse_park([self.x[0], self.x[1]], self.x[2]);
            [r[0] - d[2] * i[1], r[1] + d[2] * i[0]]
        } else {
            [d[0], d[1]]
        }
    }

    /// Electromagnetic torque, N·m (see the module documentation for its scaling).
    pub fn torque_nm(&self) -> f64 {
        self.c.torque(&self.x)
    }

    /// Back-EMF of the magnet `e = ψ ω k(θ)` in the stationary frame, V, harmonics included.
    /// For an interior or saturated motor this is the magnet's part only: the current-dependent
    /// speed voltages (`−ω L_q i_q`, `ω (ψ_d(i_d) − ψ)`) are not included.
    pub fn emf_alpha_beta_v(&self) -> [f64; 2] {
        let k = self.c.emf_shape(self.x[2]);
        let e = self.c.psi_wb * self.omega_e_rad_s();
        [e * k[0], e * k[1]]
    }

    /// Magnetic energy stored by the stator currents, J:
    /// `1.5 (∫₀^{i_d} i dψ_d + ½ L_q i_q²)` (`0.75 L |i|²` for the αβ model). The magnet flux
    /// contributes nothing at zero current.
    pub fn magnetic_energy_j(&self) -> f64 {
        if self.c.dq {
            1.5 * (self.c.daxis.energy_j(self.x[0]) + 0.5 * self.c.lq_h * self.x[1] * self.x[1])
        } else {
            0.75 * self.c.l_h * (self.x[0] * self.x[0] + self.x[1] * self.x[1])
        }
    }

    /// Kinetic energy of the rotor `½ J ω_m²`, J.
    pub fn kinetic_energy_j(&self) -> f64 {
        0.5 * self.c.j_kg_m2 * self.x[3] * self.x[3]
    }

    /// Smallest incremental inductance at the present current, H (`L_q` or `L_inc,d(i_d)`).
    pub fn min_inductance_h(&self) -> f64 {
        if self.c.dq {
            let l_d = self.c.daxis.flux_and_inductance(self.x[0]).1;
            l_d.min(self.c.lq_h)
        } else {
            self.c.l_h
        }
    }

    /// Longest RK4 sub-step at the present state, s: `min(5 µs, τ_e/50, 0.02/(n |ω|))`
    /// times the sub-step scale, with `τ_e = L_min/R` and `n` the highest EMF harmonic (1, or 7
    /// with harmonics). RK4's local error goes as `(h/τ)^5`: about 1e-12 per sub-step here.
    pub fn max_substep_s(&self) -> f64 {
        let tau_s = self.min_inductance_h() / self.c.r_ohm;
        let mut h = MAX_SUBSTEP_S.min(tau_s / SUBSTEPS_PER_TAU);
        let order = if self.c.harmonics { 7.0 } else { 1.0 };
        let w = libm::fabs(self.omega_e_rad_s()) * order;
        if w > 0.0 {
            h = h.min(MAX_ANGLE_PER_SUBSTEP_RAD / w);
        }
        h * self.substep_scale
    }

    /// Scales [`Motor::max_substep_s`] (convergence tests); `scale` in `[1e-3, 100]`.
    pub fn set_substep_scale(&mut self, scale: f64) -> Result<(), PlantError> {
        self.substep_scale = in_range("substep_scale", scale, 1e-3, 100.0)?;
        Ok(())
    }

    /// Advances by `dt_s` with stationary voltage `(v_alpha_v, v_beta_v)` held constant and load
    /// torque `load_nm` (N·m, opposing positive speed), in equal RK4 sub-steps no longer than
    /// [`Motor::max_substep_s`].
    ///
    /// Errors, with the state left unchanged: a non-finite input
    /// ([`PlantError::NonFinite`] naming it) or negative `dt_s` ([`PlantError::Param`]), a
    /// non-finite result (`NonFinite("state")`), or too many sub-steps. `dt_s = 0` does nothing.
    pub fn step(
        &mut self,
        v_alpha_v: f64,
        v_beta_v: f64,
        load_nm: f64,
        dt_s: f64,
    ) -> Result<(), PlantError> {
        let v = [
            finite("v_alpha_v", v_alpha_v)?,
            finite("v_beta_v", v_beta_v)?,
        ];
        self.integrate(dt_s, load_nm, f64::INFINITY, |_| v)
    }

    /// Like [`Motor::step`], but the stationary voltage is `f(i_abc)`, recomputed from the
    /// phase currents (A) at every RK stage; `f` returns `[v_α, v_β]`, V. This is how the
    /// averaged inverter, whose error depends on the current signs, is integrated.
    pub fn step_with(
        &mut self,
        dt_s: f64,
        load_nm: f64,
        f: impl FnMut([f64; 3]) -> [f64; 2],
    ) -> Result<(), PlantError> {
        self.step_with_limit(dt_s, load_nm, f64::INFINITY, f)
    }

    /// [`Motor::step_with`] with the sub-step also limited to `h_max_s` (s): a voltage that
    /// depends steeply on the current (a narrow sign band) adds stiffness the motor cannot
    /// see.
    pub fn step_with_limit(
        &mut self,
        dt_s: f64,
        load_nm: f64,
        h_max_s: f64,
        mut f: impl FnMut([f64; 3]) -> [f64; 2],
    ) -> Result<(), PlantError> {
        if h_max_s.is_nan() || h_max_s <= 0.0 {
            return Err(PlantError::NonFinite("h_max_s"));
        }
        let c = self.c;
        self.integrate(dt_s, load_nm, h_max_s, |x| f(inverse_clarke(c.i_ab(x))))
    }

    fn integrate(
        &mut self,
        dt_s: f64,
        load_nm: f64,
        h_limit_s: f64,
        mut volt: impl FnMut(&[f64; 4]) -> [f64; 2],
    ) -> Result<(), PlantError> {
        let dt_s = finite("dt_s", dt_s)?;
        let load_nm = finite("load_nm", load_nm)?;
        if dt_s < 0.0 {
            in_range("dt_s", dt_s, 0.0, f64::MAX)?;
        }
        if dt_s == 0.0 {
            return Ok(());
        }
        let h_max = self.max_substep_s().min(h_limit_s);
        let n = libm::ceil(dt_s / h_max);
        // Also catches h_max = 0 (n = ∞) and NaN.
        if n.is_nan() || n > MAX_SUBSTEPS as f64 {
            return Err(PlantError::TooManySubsteps);
        }
        let n = (n as u32).max(1);
        let h = dt_s / n as f64;
        let (c, mech) = (self.c, self.mech);
        let axpy = |x: &[f64; 4], a: f64, k: &[f64; 4]| {
            [
                x[0] + a * k[0],
                x[1] + a * k[1],
                x[2] + a * k[2],
                x[3] + a * k[3],
            ]
        };
        let mut x = self.x;
        for _ in 0..n {
            // Classical RK4.
            let k1 = c.deriv(mech, &x, volt(&x), load_nm);
            let x2 = axpy(&x, 0.5 * h, &k1);
            let k2 = c.deriv(mech, &x2, volt(&x2), load_nm);
            let x3 = axpy(&x, 0.5 * h, &k2);
            let k3 = c.deriv(mech, &x3, volt(&x3), load_nm);
            let x4 = axpy(&x, h, &k3);
            let k4 = c.deriv(mech, &x4, volt(&x4), load_nm);
            for k in 0..4 {
                x[k] += h / 6.0 * (k1[k] + 2.0 * (k2[k] + k3[k]) + k4[k]);
            }
        }
        if x.iter().all(|v| v.is_finite()) {
            self.x = x;
            Ok(())
        } else {
            Err(PlantError::NonFinite("state"))
        }
    }
}
