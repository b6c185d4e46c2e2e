//! The result's assembly once the sequence has ended (`f64`, in the background): the
//! fine bursts' inductances, the magnet flux from the spin's windows and the inertia and
//! friction from their energies.

use super::fit::{least_squares_3, line, magnet_flux};
use super::machine::{Identify, Q24};
use super::spin::WindowSums;
use super::{Identified, IdentifyConfig, IdentifyError, Stage};
use crate::params::MotorParams;

/// `(ω, u)` of each of the spin's windows, `u = v − R i` along one axis.
type Points = [(f64, f64); 3];

/// A window's mean field speed, electrical rad/s.
fn window_speed(c: &IdentifyConfig, s: &WindowSums) -> f64 {
    c.omega_e(s.speed_sum) / s.speed_n.max(1) as f64
}

impl Identify {
    pub(super) fn finish(&mut self) -> Result<Identified, IdentifyError> {
        let c = self.config;
        let ld = self.burst_inductance(1)?;
        self.inductance_h[0] = ld;
        let lq = self.burst_inductance(3)?;
        self.inductance_h[1] = lq;
        let p = c.pole_pairs as f64;
        let (psi, delta) = self.flux(ld, lq)?;
        let (j, b, w1, w2) = self.inertia()?;
        let motor = MotorParams::new(c.pole_pairs, self.r_ohm, ld, lq, psi, j, b);
        motor
            .validate()
            .map_err(|_| IdentifyError::Noise(Stage::Inertia))?;
        Ok(Identified {
            motor,
            distortion_v: self.v0_v,
            resistance_residual_v: self.r_rms_v,
            load_angle_rad: delta,
            spin_speeds_rad_s: [w1 * p, w2 * p],
        })
    }

    /// The magnet flux (Wb) and the load angle (rad) from the three windows' voltages.
    fn flux(&self, ld: f64, lq: f64) -> Result<(f64, f64), IdentifyError> {
        let c = self.config;
        let mean = |s: &WindowSums, k: usize| -> (f64, f64) {
            let n = s.n.max(1) as f64;
            (
                c.volts(s.v.get(k).copied().unwrap_or(0) as f64 / n),
                c.amps(s.i.get(k).copied().unwrap_or(0) as f64 / n),
            )
        };
        // u = v − R i in the current's frame, against ω.
        let mut ux = [(0.0, 0.0); 3];
        let mut uy = [(0.0, 0.0); 3];
        let mut i_f = 0.0;
        for ((s, x), y) in self.windows.iter().zip(ux.iter_mut()).zip(uy.iter_mut()) {
            let om = window_speed(&c, s);
            let (vx, ix) = mean(s, 0);
            let (vy, iy) = mean(s, 1);
            *x = (om, vx - self.r_ohm * ix);
            *y = (om, vy - self.r_ohm * iy);
            i_f += ix / 3.0;
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
        let w_top = ux.iter().fold(0.0f64, |m, x| m.max(x.0));
        if psi * w_top < 0.05 * c.design.spin_voltage_pu * c.voltage_base_v {
            return Err(IdentifyError::RotorMoved(Stage::Flux));
        }
        windows_agree(&ux, &uy, (bx, by), psi, i_f, ld, lq)?;
        Ok((psi, delta))
    }

    /// The inertia (kg m²), friction (N m s) and the two spin speeds (mechanical rad/s)
    /// from the windows' energies and powers.
    fn inertia(&self) -> Result<(f64, f64, f64, f64), IdentifyError> {
        let c = self.config;
        let p = c.pole_pairs as f64;
        // Energy: C in Pu bits of (v·i) per sample → joules.
        let joules = 1.5 * c.voltage_base_v * c.current_base_a * c.sample_s / Q24 as f64;
        let cbar = |s: &WindowSums| s.c_sum as f64 / s.n.max(1) as f64 * joules;
        let power = |s: &WindowSums| {
            let half = (c.n_window / 2).max(1) as f64;
            (s.c_second - s.c_first) as f64 / (half * half) * joules / c.sample_s
        };
        // J, B and the losses from the energy between the windows' centres and the windows'
        // mean powers: E = J ΔK + B ΔF + P_loss Δt, P = B ω_m² + P_loss (least squares).
        let rad = core::f64::consts::TAU / 4_294_967_296.0 / c.sample_s / p;
        let f_bar =
            |s: &WindowSums| s.f_sum as f64 / s.speed_n.max(1) as f64 * rad * rad * c.sample_s;
        let t_bar = |s: &WindowSums| s.t_sum as f64 / s.speed_n.max(1) as f64 * c.sample_s;
        let wm = |s: &WindowSums| window_speed(&c, s) / p;
        let kin = |s: &WindowSums| 0.5 * wm(s) * wm(s);
        let [h1a, h2, h1b] = self.windows;
        let w1 = 0.5 * (wm(&h1a) + wm(&h1b));
        let w2 = wm(&h2);
        if w1.is_nan() || w1 <= w2 {
            return Err(IdentifyError::Noise(Stage::Inertia));
        }
        let step_row = |a: &WindowSums, b: &WindowSums| {
            (
                [kin(b) - kin(a), f_bar(b) - f_bar(a), t_bar(b) - t_bar(a)],
                cbar(b) - cbar(a),
            )
        };
        let power_row = |s: &WindowSums| ([0.0, wm(s) * wm(s), 1.0], power(s));
        let rows = [
            step_row(&h1a, &h2),
            step_row(&h2, &h1b),
            power_row(&h1a),
            power_row(&h2),
            power_row(&h1b),
        ];
        let [j, b, _loss] = least_squares_3(&rows).ok_or(IdentifyError::Noise(Stage::Inertia))?;
        let b = b.max(0.0);
        if j.is_nan() || j <= 0.0 || !j.is_finite() {
            return Err(IdentifyError::Noise(Stage::Inertia));
        }
        Ok((j, b, w1, w2))
    }
}

/// Each window on its own (less the fit's offsets `off`) must give the fitted flux `psi`:
/// a rotor that slipped out of the rotating field shows a much smaller flux at one speed.
fn windows_agree(
    ux: &Points,
    uy: &Points,
    off: (f64, f64),
    psi: f64,
    i_f: f64,
    ld: f64,
    lq: f64,
) -> Result<(), IdentifyError> {
    let (bx, by) = off;
    for (x, y) in ux.iter().zip(uy.iter()) {
        let om = x.0;
        let pc = ((y.1 - by) / om, -(x.1 - bx) / om);
        let (pk, _) = magnet_flux(pc, i_f, ld, lq);
        let dev = libm::fabs(pk / psi - 1.0);
        if dev.is_nan() || dev >= 0.1 {
            return Err(IdentifyError::RotorMoved(Stage::Flux));
        }
    }
    Ok(())
}
