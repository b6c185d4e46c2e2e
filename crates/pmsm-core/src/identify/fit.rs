//! The `f64` side of the identification: least-squares fits (nalgebra) and the closed forms
//! that turn the per-sample sums into parameters. Runs in [`super::Identify::poll`], never on
//! the per-sample path.

use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};

/// Least squares `y ≈ a x + b` over the points; `None` with fewer than two distinct `x`.
/// Returns `(a, b, rms residual)`.
pub fn line(points: &[(f64, f64)]) -> Option<(f64, f64, f64)> {
    let n = points.len();
    if n < 2 {
        return None;
    }
    // Normal equations of the two-column problem [x 1]: well conditioned for the few,
    // spread points used here, and fixed-size (no allocation).
    let (mut sxx, mut sx, mut sxy, mut sy) = (0.0, 0.0, 0.0, 0.0);
    for &(x, y) in points {
        sxx += x * x;
        sx += x;
        sxy += x * y;
        sy += y;
    }
    let ata = Matrix2::new(sxx, sx, sx, n as f64);
    let sol = ata.try_inverse()? * Vector2::new(sxy, sy);
    let (k, b) = (sol.x, sol.y);
    let ss: f64 = points
        .iter()
        .map(|p| {
            let e = p.1 - (k * p.0 + b);
            e * e
        })
        .sum();
    let rms = libm::sqrt(ss / n as f64);
    (k.is_finite() && b.is_finite()).then_some((k, b, rms))
}

/// Least squares `a·x ≈ y` for three unknowns over the rows `(a, y)`, columns scaled to unit
/// norm first (the unknowns differ by orders of magnitude). `None` if singular.
pub fn least_squares_3(rows: &[([f64; 3], f64)]) -> Option<[f64; 3]> {
    let mut norm = [0.0f64; 3];
    for (a, _) in rows {
        for (n, x) in norm.iter_mut().zip(a) {
            *n += x * x;
        }
    }
    let norm = norm.map(|n| if n > 0.0 { libm::sqrt(n) } else { 1.0 });
    let mut ata = Matrix3::<f64>::zeros();
    let mut aty = Vector3::<f64>::zeros();
    for (a, y) in rows {
        let v = Vector3::new(a[0] / norm[0], a[1] / norm[1], a[2] / norm[2]);
        ata += v * v.transpose();
        aty += v * *y;
    }
    let x = ata.try_inverse()? * aty;
    let out = [x.x / norm[0], x.y / norm[1], x.z / norm[2]];
    out.iter().all(|v| v.is_finite()).then_some(out)
}

/// Inductance from the peak-to-peak `d_a` (A) of the current under a square wave of
/// `±v_h_v` (V) and half period `n · t_s` on a winding of resistance `r_ohm`:
/// `D = (2 V_h/R) tanh(N R T/(2L))` (the exact zero-order-hold response), so
/// `L = N R T / (2 atanh(R D / (2 V_h)))`. `None` when the ratio is outside (0, 1).
pub fn inductance_from_ripple(d_a: f64, v_h_v: f64, n: u32, t_s: f64, r_ohm: f64) -> Option<f64> {
    let x = r_ohm * d_a / (2.0 * v_h_v);
    if !(x > 0.0 && x < 0.999) {
        return None;
    }
    let atanh = 0.5 * libm::log((1.0 + x) / (1.0 - x));
    let l = n as f64 * r_ohm * t_s / (2.0 * atanh);
    (l.is_finite() && l > 0.0).then_some(l)
}

/// Magnet flux from the stator flux `ψ_c = (x, y)` seen in the frame of a current vector
/// `(i_a, 0)` (the rotor lags it by `δ`): `ψ_dq = R(δ) ψ_c = (ψ_m + L_d i cos δ, L_q i sin δ)`
/// gives `tan δ = −y / (x − L_q i)` and `ψ_m = x cos δ − y sin δ − L_d i cos δ`.
/// Returns `(ψ_m, δ)`.
pub fn magnet_flux(psi_c: (f64, f64), i_a: f64, ld_h: f64, lq_h: f64) -> (f64, f64) {
    let (x, y) = psi_c;
    let delta = libm::atan2(-y, x - lq_h * i_a);
    let (s, c) = libm::sincos(delta);
    (x * c - y * s - ld_h * i_a * c, delta)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_recovers_slope_and_intercept() {
        let pts: [(f64, f64); 4] = [(1.0, 3.1), (2.0, 5.1), (3.0, 7.1), (4.0, 9.1)];
        let (a, b, rms) = line(&pts).unwrap();
        assert!((a - 2.0).abs() < 1e-12 && (b - 1.1).abs() < 1e-12 && rms < 1e-12);
        assert!(line(&pts[..1]).is_none());
        assert!(line(&[(1.0, 1.0), (1.0, 2.0)]).is_none());
    }

    #[test]
    fn least_squares_3_recovers_scaled_unknowns() {
        let x = [3e-3, 5e-4, 20.0];
        let rows: [[f64; 3]; 5] = [
            [9000.0, 700.0, 0.9],
            [-9000.0, 1400.0, 0.9],
            [0.0, 19000.0, 1.0],
            [0.0, 4800.0, 1.0],
            [0.0, 19500.0, 1.0],
        ];
        let rows = rows.map(|a| (a, a[0] * x[0] + a[1] * x[1] + a[2] * x[2]));
        let got = least_squares_3(&rows).unwrap();
        for (g, w) in got.iter().zip(x) {
            assert!((g / w - 1.0).abs() < 1e-9, "{got:?}");
        }
        assert!(least_squares_3(&rows[2..3]).is_none());
    }

    #[test]
    fn ripple_inverts_the_exact_response() {
        let (r, l, t, v) = (0.8, 3e-3, 62.5e-6, 20.0);
        for n in [1u32, 3, 17] {
            let d = 2.0 * v / r * libm::tanh(n as f64 * r * t / (2.0 * l));
            let got = inductance_from_ripple(d, v, n, t, r).unwrap();
            assert!((got / l - 1.0).abs() < 1e-9, "{n}: {got}");
        }
        assert!(inductance_from_ripple(0.0, 1.0, 1, t, r).is_none());
    }

    #[test]
    fn magnet_flux_inverts_the_rotation() {
        let (psi, ld, lq, i) = (0.1, 2e-3, 3.5e-3, 4.0);
        for delta in [-0.6f64, -0.1, 0.0, 0.3, 0.9] {
            let (s, c) = libm::sincos(delta);
            let (pd, pq) = (psi + ld * i * c, lq * i * s);
            // ψ_c = R(−δ) ψ_dq.
            let psi_c = (pd * c + pq * s, -pd * s + pq * c);
            let (m, d) = magnet_flux(psi_c, i, ld, lq);
            assert!(
                (m - psi).abs() < 1e-12 && (d - delta).abs() < 1e-12,
                "{delta}"
            );
        }
    }
}
