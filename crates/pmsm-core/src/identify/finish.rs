//! The result's assembly once the sequence has ended (`f32`, in the background): the
//! fine bursts' inductances, the magnet flux from the spin's windows and the inertia and
//! friction from their energies.

use super::fit::{least_squares_3, line, magnet_flux};
use super::machine::Identify;
use super::poll::Units;
use super::spin::WindowSums;
use super::{Identified, IdentifyError, Stage};
use crate::params::MotorParams;

/// `(ω, u)` of each of the spin's windows, `u = v − R i` along one axis.
type Points = [(f32, f32); 3];

/// One window's means in SI units, each computed once (one copy of the code for the three
/// windows: flash on a board).
#[derive(Clone, Copy, Debug, Default)]
struct Means {
    /// Field speed, electrical rad/s.
    omega_e: f32,
    /// Mechanical speed, rad/s.
    omega_m: f32,
    /// Voltage and current along x, y, V and A.
    v: [f32; 2],
    i: [f32; 2],
    /// Mean of the energy `C`, J.
    energy_j: f32,
    /// Mean power (the halves' difference), W.
    power_w: f32,
    /// Mean of `F = Σ ω_m² T`, rad²/s.
    f: f32,
    /// Mean time since the spin's start, s.
    t_s: f32,
}

// Not inlined: one copy for the three windows.
#[inline(never)]
fn means(u: &Units, s: &WindowSums, p: f32, half: f32) -> Means {
    let n = s.n.max(1) as f32;
    let ns = s.speed_n.max(1) as f32;
    let omega_e = s.speed_sum as f32 / ns * u.rad_s_per_q16;
    let rad = u.rad_s_per_count / p;
    Means {
        omega_e,
        omega_m: omega_e / p,
        v: s.v.map(|x| u.volts(x as f32 / n)),
        i: s.i.map(|x| u.amps(x as f32 / n)),
        energy_j: s.c_sum as f32 / n * u.joules_per_bit,
        power_w: (s.c_second - s.c_first) as f32 / (half * half) * u.joules_per_bit / u.sample_s,
        f: s.f_sum as f32 / ns * rad * rad * u.sample_s,
        t_s: s.t_sum as f32 / ns * u.sample_s,
    }
}

impl Identify {
    pub(super) fn finish(&mut self) -> Result<Identified, IdentifyError> {
        let c = self.config;
        let u = c.units();
        let ld = self.burst_inductance(1)?;
        self.inductance_h[0] = ld;
        let lq = self.burst_inductance(3)?;
        self.inductance_h[1] = lq;
        let p = c.pole_pairs as f32;
        let half = (c.n_window / 2).max(1) as f32;
        let mut w = [Means::default(); 3];
        for (m, s) in w.iter_mut().zip(self.windows.iter()) {
            *m = means(&u, s, p, half);
        }
        let (psi, delta) = self.flux(&u, &w, ld, lq)?;
        let (j, b) = inertia(&w)?;
        let motor = MotorParams::new(
            c.pole_pairs,
            self.r_ohm as f64,
            ld as f64,
            lq as f64,
            psi as f64,
            j as f64,
            b as f64,
        );
        motor
            .validate()
            .map_err(|_| IdentifyError::Noise(Stage::Inertia))?;
        let [h1a, h2, h1b] = w;
        let w1 = 0.5 * (h1a.omega_e + h1b.omega_e);
        Ok(Identified {
            motor,
            distortion_v: self.v0_v as f64,
            resistance_residual_v: self.r_rms_v as f64,
            load_angle_rad: delta as f64,
            spin_speeds_rad_s: [w1 as f64, h2.omega_e as f64],
        })
    }

    /// The magnet flux (Wb) and the load angle (rad) from the three windows' voltages.
    fn flux(
        &self,
        u: &Units,
        w: &[Means; 3],
        ld: f32,
        lq: f32,
    ) -> Result<(f32, f32), IdentifyError> {
        // u = v − R i in the current's frame, against ω.
        let mut ux = [(0.0, 0.0); 3];
        let mut uy = [(0.0, 0.0); 3];
        let mut i_f = 0.0;
        for ((m, x), y) in w.iter().zip(ux.iter_mut()).zip(uy.iter_mut()) {
            *x = (m.omega_e, m.v[0] - self.r_ohm * m.i[0]);
            *y = (m.omega_e, m.v[1] - self.r_ohm * m.i[1]);
            i_f += m.i[0] / 3.0;
        }
        let (ax, bx, _) = line(&ux).ok_or(IdentifyError::Noise(Stage::Flux))?;
        let (ay, by, _) = line(&uy).ok_or(IdentifyError::Noise(Stage::Flux))?;
        // u = jω ψ_c + v_off: u_x = −ω ψ_c,y, u_y = ω ψ_c,x.
        let psi_c = (ay, -ax);
        let (psi, delta) = magnet_flux(psi_c, i_f, ld, lq);
        if psi.is_nan() || psi <= 0.0 || !psi.is_finite() {
            return Err(IdentifyError::Noise(Stage::Flux));
        }
        // A rotor that did not turn leaves only the inductive voltage: no EMF worth the name
        // (below 5 % of the voltage the first ramp aimed at).
        let w_top = ux.iter().fold(0.0f32, |m, x| m.max(x.0));
        if psi * w_top < 0.05 * u.spin_voltage_v {
            return Err(IdentifyError::RotorMoved(Stage::Flux));
        }
        windows_agree(&ux, &uy, (bx, by), psi, i_f, ld, lq)?;
        Ok((psi, delta))
    }
}

/// The inertia (kg m²) and friction (N m s) from the windows' energies and powers: the
/// energy between the windows' centres and their mean powers,
/// `E = J ΔK + B ΔF + P_loss Δt` and `P = B ω_m² + P_loss` (least squares).
fn inertia(w: &[Means; 3]) -> Result<(f32, f32), IdentifyError> {
    let [h1a, h2, h1b] = *w;
    if h1a.omega_m.is_nan() || 0.5 * (h1a.omega_m + h1b.omega_m) <= h2.omega_m {
        return Err(IdentifyError::Noise(Stage::Inertia));
    }
    let kin = |m: &Means| 0.5 * m.omega_m * m.omega_m;
    let mut rows = [([0.0f32; 3], 0.0f32); 5];
    // The two speed steps, then the three windows' powers.
    for ((row, a), b) in rows.iter_mut().zip([h1a, h2]).zip([h2, h1b]) {
        *row = (
            [kin(&b) - kin(&a), b.f - a.f, b.t_s - a.t_s],
            b.energy_j - a.energy_j,
        );
    }
    for (row, m) in rows.iter_mut().skip(2).zip(w) {
        *row = ([0.0, m.omega_m * m.omega_m, 1.0], m.power_w);
    }
    let [j, b, _loss] = least_squares_3(&rows).ok_or(IdentifyError::Noise(Stage::Inertia))?;
    let b = b.max(0.0);
    if j.is_nan() || j <= 0.0 || !j.is_finite() {
        return Err(IdentifyError::Noise(Stage::Inertia));
    }
    Ok((j, b))
}

/// Each window on its own (less the fit's offsets `off`) must give the fitted flux `psi`:
/// a rotor that slipped out of the rotating field shows a much smaller flux at one speed.
fn windows_agree(
    ux: &Points,
    uy: &Points,
    off: (f32, f32),
    psi: f32,
    i_f: f32,
    ld: f32,
    lq: f32,
) -> Result<(), IdentifyError> {
    let (bx, by) = off;
    for (x, y) in ux.iter().zip(uy.iter()) {
        let om = x.0;
        let pc = ((y.1 - by) / om, -(x.1 - bx) / om);
        let (pk, _) = magnet_flux(pc, i_f, ld, lq);
        let dev = (pk / psi - 1.0).abs();
        if dev.is_nan() || dev >= 0.1 {
            return Err(IdentifyError::RotorMoved(Stage::Flux));
        }
    }
    Ok(())
}
