//! d-axis magnetic saturation (docs/khlaief2012.md §1).
//!
//! The initial-position detector of Khlaief, Boussak, Gossa (2012) (§4) tells north from south because current along
//! +d adds to the magnet flux and saturates the iron (lower incremental inductance, larger
//! current peak), while current along −d relieves it. The model here keeps the nominal
//! parameters exact at `i_d = 0` (`ψ_d(0) = ψ`, `dψ_d/di_d(0) = L_d`), so the linear model and
//! the saturated one agree for small signals.
//!
//! # Tanh model
//!
//! With the flux-domain variable `u = (ψ_0 + L_d0 i_d)/ψ_s`:
//!
//! ```text
//! ψ_d(i_d) = ψ_s tanh(u) + L_σ i_d    u ≥ 0   (d flux along the magnet: the iron saturates)
//! ψ_d(i_d) = ψ_s u + L_σ i_d          u < 0   (d flux reversed: unsaturated, slope L_d0 + L_σ)
//! ψ_0 = ψ_s atanh(ψ/ψ_s),  L_d0 = (L_d − L_σ) / (1 − (ψ/ψ_s)²),  ψ_s > ψ,  L_σ = 0.1 L_d
//! ```
//!
//! so that the incremental inductance `L_inc = dψ_d/di_d = L_d0 sech²(u) + L_σ` falls as `i_d`
//! grows, and rises toward `L_d0 + L_σ` as current along −d cancels the magnet flux. The
//! leakage (air-path) inductance `L_σ` ([`LEAKAGE_FRACTION`] of `L_d`) is what a saturated iron
//! leaves: without it `L_inc` would fall to zero and the current derivative grow without bound
//! under a strong +d pulse (a motor file with `ψ_s` close to `ψ` made the plant diverge).
//!
//! Beyond the point where the iron's d flux reverses (`i_d = −ψ_0/L_d0`, far below any drive
//! current, about −12.7 A ≈ 5× rated on motor B) a symmetric tanh would saturate again in the
//! reverse direction; the model instead stays at `L_d0 + L_σ` there (the two branches join with equal value, slope and curvature),
//! so `L_inc` never increases with `i_d`, and deep −d current cannot make the equations stiff.
//!
//! The stored field energy `∫₀^{i_d} i dψ_d(i)` is analytic (integration by parts:
//! `i ψ_d(i) − (ψ_s²/L_d0)(G(u) − G(u_0))` with `G = ln cosh` on the tanh branch and `u²/2` on
//! the linear one), plus `L_σ i_d²/2`; the magnet flux contributes nothing at `i_d = 0`.

use pmsm_core::validate::in_range;
use pmsm_core::{MotorParams, ParamError, ParamReason};

/// Strength `k` of the default saturation: `ψ_s = ψ + k L_d I_ref`.
///
/// `I_ref` is twice the rated peak current (`2√2 · rated_current_a`), the peak of Khlaief, Boussak, Gossa's (2012)
/// 700 µs polarity pulse. On motor B (540 V, `L_d` = 25.025 mH, rated 2.53 A) `k = 4` gives
/// `ψ_s` = 1.021 Wb and, for a 700 µs pulse whose linear peak is `I_ref` = 7.16 A (282 V,
/// rotor locked), peaks of 7.66 A along +d (north) and 6.86 A along −d (south): 11.6 % apart,
/// inside the 5–15 % wanted for a clear but not exaggerated polarity signal. Smaller `k`
/// saturates harder (k = 3: 19 %, k = 2: 38 %), larger is milder (k = 5: 8 %, k = 8: 3.6 %).
pub const DEFAULT_STRENGTH: f64 = 4.0;

/// Leakage inductance `L_σ` of the tanh model as a fraction of `L_d`: the floor of the
/// incremental inductance when the iron is saturated (the flux paths through air: slot and
/// end-winding leakage, typically 5–20 % of `L_d` in small PMSMs).
pub const LEAKAGE_FRACTION: f64 = 0.1;

/// Model of the d-axis flux linkage `ψ_d(i_d)`; the q axis stays linear (`ψ_q = L_q i_q`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Saturation {
    /// Linear magnetics: `ψ_d = L_d i_d + ψ`.
    Linear,
    /// Tanh saturation toward `psi_s_wb` (see the module documentation).
    Tanh {
        /// Saturation flux linkage `ψ_s`, V·s/rad electrical; must exceed the magnet flux `ψ`.
        psi_s_wb: f64,
    },
}

impl Saturation {
    /// Default for a motor: [`Saturation::Linear`] for a surface motor (`L_d = L_q`), and
    /// [`Saturation::Tanh`] with `ψ_s = ψ + k L_d I_ref` ([`DEFAULT_STRENGTH`]) for an interior
    /// one; `I_ref` is [`Saturation::reference_current_a`].
    pub fn default_for(params: &MotorParams) -> Self {
        if params.is_surface() {
            Saturation::Linear
        } else {
            let i_ref = Self::reference_current_a(params);
            Saturation::Tanh {
                psi_s_wb: params.flux_wb + DEFAULT_STRENGTH * params.ld_h * i_ref,
            }
        }
    }

    /// Current that scales the default saturation, A peak: twice the rated peak current
    /// (`2√2 · rated_current_a`), or `ψ/L_d` (the current that would cancel the magnet flux)
    /// when the motor has no rating.
    pub fn reference_current_a(params: &MotorParams) -> f64 {
        match params.rated_current_a {
            Some(i_rms) => 2.0 * core::f64::consts::SQRT_2 * i_rms,
            None => params.flux_wb / params.ld_h,
        }
    }

    /// Checks the model against validated motor parameters; the error names the key
    /// `saturation.psi_s_wb`. `ψ_s` must lie in `[1.001 ψ, 1000 ψ]`: closer to `ψ` the
    /// unsaturated inductance `L_d0` explodes, far above it the model is linear anyway.
    pub fn validate(&self, params: &MotorParams) -> Result<(), ParamError> {
        match *self {
            Saturation::Linear => Ok(()),
            Saturation::Tanh { psi_s_wb } => {
                let psi = params.flux_wb;
                in_range("saturation.psi_s_wb", psi_s_wb, 1.001 * psi, 1000.0 * psi).map_err(
                    |e| match e.reason {
                        ParamReason::OutOfRange { .. } if psi_s_wb > 0.0 && psi_s_wb <= psi => {
                            ParamError {
                                key: e.key,
                                reason: ParamReason::Inconsistent("flux_wb (ψ_s must exceed ψ)"),
                            }
                        }
                        _ => e,
                    },
                )?;
                Ok(())
            }
        }
    }

    /// True for [`Saturation::Linear`].
    pub fn is_linear(&self) -> bool {
        matches!(self, Saturation::Linear)
    }

    /// d-axis flux linkage `ψ_d(i_d)`, V·s/rad, at d current `i_d_a` (A). Expects a validated
    /// model (NaN otherwise).
    pub fn flux_d_wb(&self, params: &MotorParams, i_d_a: f64) -> f64 {
        DAxis::new(self, params).flux_wb(i_d_a)
    }

    /// Incremental d inductance `dψ_d/di_d`, H, at `i_d_a` (A). Expects a validated model.
    pub fn inductance_d_h(&self, params: &MotorParams, i_d_a: f64) -> f64 {
        DAxis::new(self, params).flux_and_inductance(i_d_a).1
    }

    /// Field energy integral `∫₀^{i_d} i dψ_d(i)`, J, per unit of the three-phase factor: the
    /// stored d-axis energy of the motor is `1.5 ×` this. Expects a validated model.
    pub fn energy_d_j(&self, params: &MotorParams, i_d_a: f64) -> f64 {
        DAxis::new(self, params).energy_j(i_d_a)
    }

    /// d current at which the iron's d flux reverses (`u = 0`), A; below it the tanh model is
    /// linear with slope `L_d0 + L_σ`. `None` for the linear model.
    pub fn zero_flux_current_a(&self, params: &MotorParams) -> Option<f64> {
        match DAxis::new(self, params) {
            DAxis::Linear { .. } => None,
            DAxis::Tanh { psi0_wb, ld0_h, .. } => Some(-psi0_wb / ld0_h),
        }
    }
}

/// Pre-computed coefficients of the d-axis flux model (saves an `atanh` per RK stage).
#[derive(Clone, Copy, Debug)]
pub(crate) enum DAxis {
    Linear {
        ld_h: f64,
        psi_wb: f64,
    },
    Tanh {
        psi_s_wb: f64,
        psi0_wb: f64,
        ld0_h: f64,
        leak_h: f64,
    },
}

impl DAxis {
    pub(crate) fn new(sat: &Saturation, params: &MotorParams) -> Self {
        match *sat {
            Saturation::Linear => DAxis::Linear {
                ld_h: params.ld_h,
                psi_wb: params.flux_wb,
            },
            Saturation::Tanh { psi_s_wb } => {
                let r = params.flux_wb / psi_s_wb;
                let leak_h = LEAKAGE_FRACTION * params.ld_h;
                DAxis::Tanh {
                    psi_s_wb,
                    psi0_wb: psi_s_wb * libm::atanh(r),
                    ld0_h: (params.ld_h - leak_h) / (1.0 - r * r),
                    leak_h,
                }
            }
        }
    }

    pub(crate) fn flux_wb(&self, i_d_a: f64) -> f64 {
        self.flux_and_inductance(i_d_a).0
    }

    /// `(ψ_d, dψ_d/di_d)` at `i_d_a`.
    pub(crate) fn flux_and_inductance(&self, i_d_a: f64) -> (f64, f64) {
        match *self {
            DAxis::Linear { ld_h, psi_wb } => (ld_h * i_d_a + psi_wb, ld_h),
            DAxis::Tanh {
                psi_s_wb,
                psi0_wb,
                ld0_h,
                leak_h,
            } => {
                let u = (psi0_wb + ld0_h * i_d_a) / psi_s_wb;
                let leak = leak_h * i_d_a;
                if u >= 0.0 {
                    // tanh and sech² through e^{−2u} ≤ 1: no overflow for large u.
                    let e = libm::exp(-2.0 * u);
                    let tanh = (1.0 - e) / (1.0 + e);
                    let sech2 = 4.0 * e / ((1.0 + e) * (1.0 + e));
                    (psi_s_wb * tanh + leak, ld0_h * sech2 + leak_h)
                } else {
                    (psi_s_wb * u + leak, ld0_h + leak_h)
                }
            }
        }
    }

    /// `∫₀^{i_d} i dψ_d(i)`, J (before the three-phase factor 1.5).
    pub(crate) fn energy_j(&self, i_d_a: f64) -> f64 {
        match *self {
            DAxis::Linear { ld_h, .. } => 0.5 * ld_h * i_d_a * i_d_a,
            DAxis::Tanh {
                psi_s_wb,
                psi0_wb,
                ld0_h,
                leak_h,
            } => {
                // Integration by parts on the iron's part: i ψ_iron(i) − ∫₀^i ψ_iron, with
                // ∫ψ_iron di = (ψ_s²/L_d0) ∫ g(u) du; the leakage's is L_σ i²/2.
                let u0 = psi0_wb / psi_s_wb;
                let u = (psi0_wb + ld0_h * i_d_a) / psi_s_wb;
                let g_int = |u: f64| if u >= 0.0 { ln_cosh(u) } else { 0.5 * u * u };
                let iron = self.flux_wb(i_d_a) - leak_h * i_d_a;
                i_d_a * iron - psi_s_wb * psi_s_wb / ld0_h * (g_int(u) - g_int(u0))
                    + 0.5 * leak_h * i_d_a * i_d_a
            }
        }
    }
}

/// `ln cosh u` without overflow for large `|u|` and without cancellation for small `|u|`.
fn ln_cosh(u: f64) -> f64 {
    let a = libm::fabs(u);
    if a < 1.0 {
        let s = libm::sinh(a);
        0.5 * libm::log1p(s * s)
    } else {
        a + libm::log1p(libm::exp(-2.0 * a)) - core::f64::consts::LN_2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use pmsm_core::fixtures::motor_b;

    #[test]
    fn nominal_values_exact_at_zero() {
        let m = motor_b();
        let sat = Saturation::default_for(&m);
        assert!(matches!(sat, Saturation::Tanh { .. }));
        assert_eq!(sat.validate(&m), Ok(()));
        assert!((sat.flux_d_wb(&m, 0.0) - m.flux_wb).abs() < 1e-9 * m.flux_wb);
        assert!((sat.inductance_d_h(&m, 0.0) - m.ld_h).abs() < 1e-9 * m.ld_h);
        assert!(sat.energy_d_j(&m, 0.0).abs() < 1e-15);
    }

    #[test]
    fn incremental_inductance_decreasing() {
        let m = motor_b();
        let sat = Saturation::default_for(&m);
        let i_ref = Saturation::reference_current_a(&m);
        let i_zero = sat.zero_flux_current_a(&m).unwrap();
        // The reversed-flux branch starts well beyond twice the rated peak.
        assert!(i_zero < -1.5 * i_ref, "zero-flux current {i_zero}");
        let n = 2000;
        let mut prev = f64::INFINITY;
        for k in 0..=n {
            let i = -3.0 * i_ref + 6.0 * i_ref * k as f64 / n as f64;
            let l = sat.inductance_d_h(&m, i);
            if i > i_zero {
                // Strictly decreasing wherever the d flux is along the magnet.
                assert!(l < prev, "L_inc not decreasing at {i} A: {l} ≥ {prev}");
            } else {
                // Non-increasing (constant L_d0) where it is reversed.
                assert!(l <= prev, "L_inc increasing at {i} A");
            }
            assert!(l > 0.0 && l.is_finite());
            prev = l;
        }
        // Saturation is real but not absurd at 3 I_ref: L_inc(3 I_ref)/L_d in (0.2, 0.9).
        let ratio = sat.inductance_d_h(&m, 3.0 * i_ref) / m.ld_h;
        assert!(ratio > 0.2 && ratio < 0.9, "ratio {ratio}");
    }

    #[test]
    fn saturated_inductance_keeps_the_leakage_floor() {
        // ψ_s barely above ψ (an iron already near saturation at no current): deep in
        // saturation the incremental inductance falls to the leakage, never below it.
        let mut m = motor_b();
        m.flux_wb = 0.288;
        let sat = Saturation::Tanh { psi_s_wb: 0.35 };
        assert_eq!(sat.validate(&m), Ok(()));
        let leak = LEAKAGE_FRACTION * m.ld_h;
        let i_ref = Saturation::reference_current_a(&m);
        for k in 0..=100 {
            let i = 20.0 * i_ref * k as f64 / 100.0;
            let l = sat.inductance_d_h(&m, i);
            assert!(l >= leak * (1.0 - 1e-12) && l.is_finite(), "{i} A: {l} H");
        }
        let deep = sat.inductance_d_h(&m, 20.0 * i_ref);
        assert!(deep < 1.01 * leak, "at 20 I_ref: {deep} H vs L_σ {leak} H");
        assert!((sat.inductance_d_h(&m, 0.0) - m.ld_h).abs() < 1e-9 * m.ld_h);
    }

    #[test]
    fn inductance_is_flux_derivative_and_energy_its_integral() {
        let m = motor_b();
        for sat in [Saturation::default_for(&m), Saturation::Linear] {
            let i_ref = Saturation::reference_current_a(&m);
            for k in -30..=30 {
                let i = i_ref * k as f64 / 10.0;
                let h = 1e-5;
                let dpsi = (sat.flux_d_wb(&m, i + h) - sat.flux_d_wb(&m, i - h)) / (2.0 * h);
                let l = sat.inductance_d_h(&m, i);
                assert!((dpsi - l).abs() < 1e-7 * m.ld_h, "at {i}: {dpsi} vs {l}");
                // dW/di = i dψ/di.
                let dw = (sat.energy_d_j(&m, i + h) - sat.energy_d_j(&m, i - h)) / (2.0 * h);
                assert!(
                    (dw - i * l).abs() < 1e-7 * (1.0 + i.abs()) * m.ld_h,
                    "at {i}"
                );
            }
        }
    }

    #[test]
    fn default_is_linear_for_surface_and_validates() {
        let mut a = MotorParams::new(3, 1.6, 0.0134, 0.0134, 0.288, 0.04256, 0.004256);
        assert_eq!(Saturation::default_for(&a), Saturation::Linear);
        a.rated_current_a = None;
        let bad = Saturation::Tanh { psi_s_wb: 0.2 };
        assert_eq!(
            bad.validate(&a).map_err(|e| e.key),
            Err("saturation.psi_s_wb")
        );
        let nan = Saturation::Tanh { psi_s_wb: f64::NAN };
        assert_eq!(
            nan.validate(&a).map_err(|e| e.reason),
            Err(ParamReason::NotFinite)
        );
    }

    #[test]
    fn ln_cosh_branches_agree() {
        for u in [1e-8, 0.3, 0.999_999, 1.000_001, 5.0, 400.0] {
            let direct = if u < 1e-3 {
                0.5 * u * u - u * u * u * u / 12.0
            } else if u < 20.0 {
                libm::log(libm::cosh(u))
            } else {
                u - core::f64::consts::LN_2
            };
            assert!(
                (ln_cosh(u) - direct).abs() <= 1e-12 * direct.abs().max(1e-16),
                "{u}"
            );
        }
    }
}
