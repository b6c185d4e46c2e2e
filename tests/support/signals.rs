//! Voltage sequences for plant tests that are not stored in the repository: generated from a
//! seed, so each run of a test sees the same data and different seeds see different data.

/// A small deterministic generator (splitmix64), enough for test signals.
#[derive(Clone, Debug)]
pub struct SplitMix(pub u64);

impl SplitMix {
    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * ((self.next_u64() >> 11) as f64 / (1u64 << 53) as f64)
    }
}

/// One row of a voltage sequence: time, αβ voltage, load torque.
#[derive(Clone, Copy, Debug)]
pub struct VoltageRow {
    /// Time, s.
    pub t_s: f64,
    /// α voltage, V.
    pub v_alpha_v: f64,
    /// β voltage, V.
    pub v_beta_v: f64,
    /// Load torque, N·m.
    pub load_nm: f64,
}

/// A rotating voltage vector whose frequency ramps (an open-loop V/f start), with a few random
/// amplitude and load steps and an irregular time grid: `rows` rows over `duration_s`.
pub fn vf_ramp_with_steps(
    seed: u64,
    rows: usize,
    duration_s: f64,
    v_per_rad_s: f64,
    top_omega_e_rad_s: f64,
    max_load_nm: f64,
) -> Vec<VoltageRow> {
    let mut rng = SplitMix(seed);
    let mut out = Vec::with_capacity(rows);
    let mut t = 0.0;
    let mut phase = 0.0;
    let mut load = 0.0;
    let mut boost = 1.0;
    let mean_dt = duration_s / rows as f64;
    for _ in 0..rows {
        let w = top_omega_e_rad_s * (t / (0.6 * duration_s)).min(1.0);
        if rng.uniform(0.0, 1.0) < 0.002 {
            load = rng.uniform(-max_load_nm, max_load_nm);
        }
        if rng.uniform(0.0, 1.0) < 0.002 {
            boost = rng.uniform(0.8, 1.3);
        }
        let v = boost * (v_per_rad_s * w + 0.05 * v_per_rad_s * top_omega_e_rad_s);
        out.push(VoltageRow {
            t_s: t,
            v_alpha_v: v * (phase + 1.2f64).cos(),
            v_beta_v: v * (phase + 1.2f64).sin(),
            load_nm: load,
        });
        let dt = mean_dt * rng.uniform(0.5, 1.5);
        phase += w * dt;
        t += dt;
    }
    out
}

/// Random voltage steps (a bang-bang sequence), for a locked or free rotor.
pub fn random_steps(seed: u64, rows: usize, dt_s: f64, amplitude_v: f64) -> Vec<VoltageRow> {
    let mut rng = SplitMix(seed);
    let mut v = [0.0, 0.0];
    (0..rows)
        .map(|k| {
            if k % 17 == 0 {
                v = [
                    rng.uniform(-amplitude_v, amplitude_v),
                    rng.uniform(-amplitude_v, amplitude_v),
                ];
            }
            VoltageRow {
                t_s: k as f64 * dt_s,
                v_alpha_v: v[0],
                v_beta_v: v[1],
                load_nm: 0.0,
            }
        })
        .collect()
}
