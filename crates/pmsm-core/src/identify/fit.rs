//! The floating-point side of the identification: least-squares fits and the closed forms
//! that turn the per-sample sums into parameters. Runs in [`super::Identify::poll`], never on
//! the per-sample path.
//!
//! `f32`: a board's FPU computes it in hardware, where `f64` is emulated (about three times
//! the code per operation; on the B-G431B-ESC1's 64 KiB the difference decides whether the
//! commissioning mode fits). The sums are integers (exact); the fits below are centred or
//! column-scaled so that single precision loses nothing against the measurements' own
//! resolution (the tests bound every fit against its exact `f64` answer).

use crate::num::pu_from_f64;

/// Least squares `y ≈ a x + b` over the points; `None` with fewer than two distinct `x`.
/// Returns `(a, b, rms residual)`.
pub fn line(points: &[(f32, f32)]) -> Option<(f32, f32, f32)> {
    let n = points.len() as f32;
    if points.len() < 2 {
        return None;
    }
    // Centred: no cancellation between the sums of a closed form.
    let (mut mx, mut my) = (0.0f32, 0.0f32);
    for &(x, y) in points {
        mx += x;
        my += y;
    }
    let (mx, my) = (mx / n, my / n);
    let (mut sxx, mut sxy) = (0.0f32, 0.0f32);
    for &(x, y) in points {
        sxx += (x - mx) * (x - mx);
        sxy += (x - mx) * (y - my);
    }
    if sxx.is_nan() || sxx <= 0.0 {
        return None;
    }
    let k = sxy / sxx;
    let b = my - k * mx;
    let mut ss = 0.0f32;
    for &(x, y) in points {
        let e = y - (k * x + b);
        ss += e * e;
    }
    let rms = sqrt(ss / n);
    (k.is_finite() && b.is_finite()).then_some((k, b, rms))
}

/// Square root (the FPU's instruction on a board with one).
fn sqrt(x: f32) -> f32 {
    libm::sqrtf(x)
}

/// Least squares `a·x ≈ y` for three unknowns over the rows `(a, y)`, columns scaled to unit
/// norm first (the unknowns differ by orders of magnitude), solved by Givens rotations (the
/// normal equations would square the condition number, too much for `f32`). `None` if the
/// scaled columns are (nearly) dependent.
pub fn least_squares_3(rows: &[([f32; 3], f32)]) -> Option<[f32; 3]> {
    let mut norm = [0.0f32; 3];
    for (a, _) in rows {
        for (n, x) in norm.iter_mut().zip(a) {
            *n += x * x;
        }
    }
    let norm = norm.map(|n| if n > 0.0 { sqrt(n) } else { 1.0 });
    // R (upper triangular, row-major: r00 r01 r02 r11 r12 r22) and Qᵀy.
    let [mut r00, mut r01, mut r02, mut r11, mut r12, mut r22] = [0.0f32; 6];
    let mut z = [0.0f32; 3];
    for (a, y) in rows {
        let [a0, mut a1, mut a2] = [a[0] / norm[0], a[1] / norm[1], a[2] / norm[2]];
        let mut y = *y;
        // Each rotation zeroes one entry of the new row against R's diagonal.
        let (c, s) = givens(r00, a0);
        r00 = c * r00 + s * a0;
        (r01, a1) = (c * r01 + s * a1, c * a1 - s * r01);
        (r02, a2) = (c * r02 + s * a2, c * a2 - s * r02);
        (z[0], y) = (c * z[0] + s * y, c * y - s * z[0]);
        let (c, s) = givens(r11, a1);
        r11 = c * r11 + s * a1;
        (r12, a2) = (c * r12 + s * a2, c * a2 - s * r12);
        (z[1], y) = (c * z[1] + s * y, c * y - s * z[1]);
        let (c, s) = givens(r22, a2);
        r22 = c * r22 + s * a2;
        z[2] = c * z[2] + s * y;
    }
    // Unit columns: |R_ii| is the distance of column i from the span of the ones before it.
    let tiny = 1e-4;
    if !(r00.abs() > tiny && r11.abs() > tiny && r22.abs() > tiny) {
        return None;
    }
    let x2 = z[2] / r22;
    let x1 = (z[1] - r12 * x2) / r11;
    let x0 = (z[0] - r01 * x1 - r02 * x2) / r00;
    let out = [x0 / norm[0], x1 / norm[1], x2 / norm[2]];
    out.iter().all(|v| v.is_finite()).then_some(out)
}

/// The rotation `(c, s)` that turns `(p, q)` into `(√(p² + q²), 0)`.
fn givens(p: f32, q: f32) -> (f32, f32) {
    let h = sqrt(p * p + q * q);
    if h > 0.0 { (p / h, q / h) } else { (1.0, 0.0) }
}

/// Inductance from the peak-to-peak `d_a` (A) of the current under a square wave of
/// `±v_h_v` (V) and half period `n · t_s` on a winding of resistance `r_ohm`:
/// `D = (2 V_h/R) tanh(N R T/(2L))` (the exact zero-order-hold response), so
/// `L = N R T / (2 atanh(R D / (2 V_h)))`. `None` when the ratio is outside (0, 1).
pub fn inductance_from_ripple(d_a: f32, v_h_v: f32, n: u32, t_s: f32, r_ohm: f32) -> Option<f32> {
    let x = r_ohm * d_a / (2.0 * v_h_v);
    if !(x > 0.0 && x < 0.999) {
        return None;
    }
    // ln through the f64 log2 that the drive's configuration links already (flash); a
    // small x keeps its precision there.
    let z = (1.0 + x as f64) / (1.0 - x as f64);
    let atanh = (0.5 * core::f64::consts::LN_2 * libm::log2(z)) as f32;
    let l = n as f32 * r_ohm * t_s / (2.0 * atanh);
    (l.is_finite() && l > 0.0).then_some(l)
}

/// Magnet flux from the stator flux `ψ_c = (x, y)` seen in the frame of a current vector
/// `(i_a, 0)` (the rotor lags it by `δ`): `ψ_dq = R(δ) ψ_c = (ψ_m + L_d i cos δ, L_q i sin δ)`
/// gives `tan δ = −y / (x − L_q i)` and `ψ_m = x cos δ − y sin δ − L_d i cos δ`.
/// Returns `(ψ_m, δ)`.
pub fn magnet_flux(psi_c: (f32, f32), i_a: f32, ld_h: f32, lq_h: f32) -> (f32, f32) {
    let (x, y) = psi_c;
    let (a, b) = (x - lq_h * i_a, -y);
    // cos δ and sin δ straight from the vector; δ itself (reported only) from the core's
    // CORDIC, which the drive links already.
    let h = sqrt(a * a + b * b);
    let (s, c) = if h > 0.0 { (b / h, a / h) } else { (0.0, 1.0) };
    let delta = crate::cordic::polar(pu_from_f64(c as f64), pu_from_f64(s as f64))
        .angle
        .to_rad() as f32;
    (x * c - y * s - ld_h * i_a * c, delta)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_recovers_slope_and_intercept() {
        let pts: [(f32, f32); 4] = [(1.0, 3.1), (2.0, 5.1), (3.0, 7.1), (4.0, 9.1)];
        let (a, b, rms) = line(&pts).unwrap();
        assert!((a - 2.0).abs() < 1e-6 && (b - 1.1).abs() < 1e-6 && rms < 1e-6);
        assert!(line(&pts[..1]).is_none());
        assert!(line(&[(1.0, 1.0), (1.0, 2.0)]).is_none());
    }

    /// The f64 reference: the normal equations solved by Cramer's rule in double precision.
    fn least_squares_3_f64(rows: &[([f64; 3], f64)]) -> [f64; 3] {
        let mut m = [[0.0f64; 3]; 3];
        let mut v = [0.0f64; 3];
        for (a, y) in rows {
            for i in 0..3 {
                for j in 0..3 {
                    m[i][j] += a[i] * a[j];
                }
                v[i] += a[i] * y;
            }
        }
        let det = |m: &[[f64; 3]; 3]| {
            m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
        };
        let d = det(&m);
        core::array::from_fn(|k| {
            let mut mk = m;
            for i in 0..3 {
                mk[i][k] = v[i];
            }
            det(&mk) / d
        })
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
        let rows32 = rows.map(|a| {
            (
                a.map(|v| v as f32),
                (a[0] * x[0] + a[1] * x[1] + a[2] * x[2]) as f32,
            )
        });
        let got = least_squares_3(&rows32).unwrap();
        for (g, w) in got.iter().zip(x) {
            assert!((*g as f64 / w - 1.0).abs() < 1e-4, "{got:?}");
        }
        assert!(least_squares_3(&rows32[2..3]).is_none());
        // Inconsistent rows (residuals): the f64 least-squares answer, within f32's reach.
        let noisy: [([f64; 3], f64); 5] = core::array::from_fn(|k| {
            let a = rows[k];
            let e = [0.3, -0.2, 0.5, -0.4, 0.1][k];
            (a, a[0] * x[0] + a[1] * x[1] + a[2] * x[2] + e)
        });
        let want = least_squares_3_f64(&noisy);
        let got = least_squares_3(&noisy.map(|(a, y)| (a.map(|v| v as f32), y as f32))).unwrap();
        for (g, w) in got.iter().zip(want) {
            assert!((*g as f64 / w - 1.0).abs() < 1e-4, "{got:?} vs {want:?}");
        }
    }

    #[test]
    fn ripple_inverts_the_exact_response() {
        let (r, l, t, v) = (0.8f64, 3e-3f64, 62.5e-6f64, 20.0f64);
        for n in [1u32, 3, 17] {
            let d = 2.0 * v / r * libm::tanh(n as f64 * r * t / (2.0 * l));
            let got = inductance_from_ripple(d as f32, v as f32, n, t as f32, r as f32).unwrap();
            assert!((got as f64 / l - 1.0).abs() < 1e-5, "{n}: {got}");
        }
        assert!(inductance_from_ripple(0.0, 1.0, 1, t as f32, r as f32).is_none());
    }

    #[test]
    fn magnet_flux_inverts_the_rotation() {
        let (psi, ld, lq, i) = (0.1f64, 2e-3f64, 3.5e-3f64, 4.0f64);
        for delta in [-0.6f64, -0.1, 0.0, 0.3, 0.9] {
            let (s, c) = libm::sincos(delta);
            let (pd, pq) = (psi + ld * i * c, lq * i * s);
            // ψ_c = R(−δ) ψ_dq.
            let psi_c = (pd * c + pq * s, -pd * s + pq * c);
            let (m, d) = magnet_flux(
                (psi_c.0 as f32, psi_c.1 as f32),
                i as f32,
                ld as f32,
                lq as f32,
            );
            assert!(
                (m as f64 - psi).abs() < 1e-6 && (d as f64 - delta).abs() < 1e-5,
                "{delta}: {m} {d}"
            );
        }
    }
}
