//! The floating-point side of the identification: least-squares fits and the closed forms
//! that turn the per-sample sums into parameters. Runs in [`super::Identify::poll`], never on
//! the per-sample path.
//!
//! The least-squares fits are nalgebra's: fixed-size matrices (no allocation), each row
//! folded into an upper-triangular factor by nalgebra's Givens rotations
//! ([`GivensRotation`]), the triangle solved by its `solve_upper_triangular`. Rotations, not
//! the normal equations, because those square the condition number, which single precision
//! cannot afford; the columns are scaled to unit norm (and the line's abscissae centred) for
//! the same reason.
//!
//! `f32`: a board's FPU computes it in hardware, where `f64` is emulated (about three times
//! the code per operation; in the B-G431B-ESC1's flash the difference decides whether the
//! commissioning mode fits). The sums are integers (exact); with the conditioning above,
//! single precision loses nothing against the measurements' own resolution (the tests bound
//! every fit against its exact `f64` answer).

use nalgebra::{RowSVector, SMatrix, Vector2, linalg::givens::GivensRotation};

use crate::num::pu_from_f64;

/// Least squares `y ≈ a x + b` over the points; `None` with fewer than two distinct `x`.
/// Returns `(a, b, rms residual)`.
pub fn line(points: &[(f32, f32)]) -> Option<(f32, f32, f32)> {
    if points.len() < 2 {
        return None;
    }
    let n = points.len() as f32;
    // Centred abscissae: the columns `x − x̄` and `1` are orthogonal, where `x` and `1`
    // would be nearly parallel for points far from the origin.
    let mx = points.iter().map(|p| p.0).sum::<f32>() / n;
    let ([k, c], residual) =
        least_squares::<2, 3, _>(points.iter().map(|&(x, y)| ([x - mx, 1.0], y)))?;
    let b = c - k * mx;
    let rms = sqrt(residual * residual / n);
    (k.is_finite() && b.is_finite()).then_some((k, b, rms))
}

/// Square root (the FPU's instruction on a board with one).
fn sqrt(x: f32) -> f32 {
    libm::sqrtf(x)
}

/// Least squares `a·x ≈ y` for three unknowns over the rows `(a, y)`, columns scaled to unit
/// norm first (the unknowns differ by orders of magnitude). `None` if the scaled columns are
/// (nearly) dependent.
pub fn least_squares_3(rows: &[([f32; 3], f32)]) -> Option<[f32; 3]> {
    least_squares::<3, 4, _>(rows.iter().copied()).map(|(x, _)| x)
}

/// Least squares for `N` unknowns (`M = N + 1`, the augmented width) over the rows
/// `(a, y)`: the columns of `a` scaled to unit norm, each row `[a | y]` rotated into the
/// augmented triangle `[R | Qᵀy]` (one Givens rotation per entry), then `R x = Qᵀy` solved.
/// The triangle's last diagonal entry collects what no combination of the columns explains:
/// its magnitude is the residual norm `‖y − a x‖`, returned with `x`. `None` if the scaled
/// columns are (nearly) dependent or the rows not finite.
fn least_squares<const N: usize, const M: usize, I>(rows: I) -> Option<([f32; N], f32)>
where
    I: Iterator<Item = ([f32; N], f32)> + Clone,
{
    const { assert!(M == N + 1) };
    let mut norm = [0.0f32; N];
    for (a, _) in rows.clone() {
        for (n, x) in norm.iter_mut().zip(a) {
            *n += x * x;
        }
    }
    let norm = norm.map(|n| if n > 0.0 { sqrt(n) } else { 1.0 });
    // The augmented triangle, row by row.
    let mut t = [RowSVector::<f32, M>::zeros(); M];
    for (a, y) in rows {
        let mut row = [y; M];
        for ((r, x), n) in row.iter_mut().zip(a).zip(norm) {
            *r = x / n;
        }
        let mut row = RowSVector::<f32, M>::from_row_slice(&row);
        for (k, tk) in t.iter_mut().enumerate() {
            // Zero the new row's entry k against the diagonal entry of row k (both rows are
            // zero left of k). Checked access: no bounds panic in the firmware.
            let (Some(&p), Some(&q)) = (tk.get(k), row.get(k)) else {
                break;
            };
            let Some((rot, d)) = GivensRotation::cancel_y(&Vector2::new(p, q)) else {
                continue;
            };
            let mut pair = SMatrix::<f32, 2, M>::from_rows(&[*tk, row]);
            rot.rotate(&mut pair);
            (*tk, row) = (pair.row(0).into_owned(), pair.row(1).into_owned());
            // The exact values, not the rotation's rounding: the diagonal entry is the norm
            // `cancel_y` computed, and the zeros left of the diagonal stay zeros.
            if let (Some(p), Some(q)) = (tk.get_mut(k), row.get_mut(k)) {
                (*p, *q) = (d, 0.0);
            }
        }
    }
    let t = SMatrix::<f32, M, M>::from_rows(&t);
    // Unit columns: |R_ii| is the distance of column i from the span of the ones before it.
    let diagonal = t.diagonal();
    if !diagonal.iter().take(N).all(|d| d.abs() > 1e-4) {
        return None;
    }
    let r = t.fixed_view::<N, N>(0, 0);
    let x = r.solve_upper_triangular(&t.fixed_view::<N, 1>(0, N))?;
    let mut out: [f32; N] = x.into();
    for (o, n) in out.iter_mut().zip(norm) {
        *o /= n;
    }
    let residual = diagonal.iter().next_back().map_or(0.0, |d| d.abs());
    (out.iter().all(|v| v.is_finite()) && residual.is_finite()).then_some((out, residual))
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
    // `polar`, which the drive links already.
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
        assert!(
            (a - 2.0).abs() < 1e-6 && (b - 1.1).abs() < 1e-6 && rms < 1e-6,
            "{a} {b} {rms}"
        );
        assert!(line(&pts[..1]).is_none());
        assert!(line(&[(1.0, 1.0), (1.0, 2.0)]).is_none());
    }

    /// Inconsistent points far from the origin (the resistance levels' shape: amperes
    /// against volts with an offset): slope, intercept and the rms residual, which comes from
    /// the triangle's last diagonal entry, against the f64 closed form.
    #[test]
    fn line_matches_f64_with_residuals() {
        let pts: [(f64, f64); 4] = [(12.5, 10.31), (14.0, 11.52), (15.5, 12.69), (17.0, 13.93)];
        let n = pts.len() as f64;
        let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
        let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
        let sxx: f64 = pts.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
        let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
        let (a, b) = (sxy / sxx, my - sxy / sxx * mx);
        let rms = libm::sqrt(
            pts.iter()
                .map(|p| (p.1 - a * p.0 - b) * (p.1 - a * p.0 - b))
                .sum::<f64>()
                / n,
        );
        let (ga, gb, grms) = line(&pts.map(|(x, y)| (x as f32, y as f32))).unwrap();
        assert!((ga as f64 / a - 1.0).abs() < 1e-5, "{ga} vs {a}");
        assert!((gb as f64 - b).abs() < 1e-5 * my, "{gb} vs {b}");
        assert!((grms as f64 / rms - 1.0).abs() < 1e-3, "{grms} vs {rms}");
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
