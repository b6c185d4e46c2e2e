//! One batch of the distortion learner: its sums while it listens, in integers, and its end
//! in `f32`, spread over five updates (docs/distortion.md, "Measurement" and "Cost").
//!
//! A Cortex-M0 does `f32` in software, about a hundred instructions an operation: the sums
//! are integer products and additions, and the end's 90 or so operations run one stage per
//! update (the updates of the end do not listen: five samples of a batch's hundreds).
//!
//! Formats: the six signals in Q12 per unit (`i32`, within ±2¹⁹: ±128 pu), `cos 6θ`,
//! `sin 6θ` in Q11 (within ±2¹¹): each product within ±2³⁰, an `i32`. Their sums are `i32`
//! that saturate; a batch in which one did is thrown away (a harmonic's sums stay near
//! zero over whole turns: a 1 pu signal's reach 2²⁹ only in a batch of 2¹⁷ samples). The
//! end keeps its `f32` results in the slots of the sums it has used (`f32` bits in `i32`):
//! the state stays small, which the Cortex-M0's stack notices.

/// Updates a batch's end takes when it is not thrown away.
#[cfg(test)]
pub(super) const END_STAGES: usize = 5;

/// Fractional bits of the signals and of `cos 6θ`, `sin 6θ`.
pub(super) const SIGNAL_FRAC: u32 = 12;
pub(super) const HARMONIC_FRAC: u32 = 11;

/// A complex number, `(re, im)`.
pub(super) type C = (f32, f32);

fn mul(a: C, b: C) -> C {
    (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0)
}

/// The motor's model per unit: `R`, `L_d`, `L_q`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Model {
    pub r: f32,
    pub ld: f32,
    pub lq: f32,
}

/// Signals of a batch, in the order of [`Batch::add`]'s `x`.
const U_D: usize = 0;
const U_Q: usize = 1;
const I_D: usize = 2;
const I_Q: usize = 3;
const P_D: usize = 4;
const P_Q: usize = 5;

/// The sums of one batch: for each of `u_d, u_q, i_d, i_q, p_d, p_q`, its sum and its sums
/// against `cos 6θ`, `sin 6θ`; the speed's and the current reference's; and the end's
/// scratch.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Batch {
    pub n: u32,
    sum: [i32; 6],
    cos: [i32; 6],
    sin: [i32; 6],
    sum_c: i32,
    sum_s: i32,
    /// The speed (Q8.24 bits): its sum, least and largest.
    sum_w: i64,
    w_min: i32,
    w_max: i32,
    /// The current reference's length (Q12) summed over the batch's first and second halves
    /// (its ripple averages out, a step does not), and the sum of its squares (an
    /// oscillation of the speed loop moves that, not the halves).
    sum_i: [i64; 2],
    sum_i2: i64,
    /// Stages of the end done.
    stage: u8,
}

/// What a stage of a batch's end gives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum End {
    /// More stages to come.
    Pending,
    /// The speed or the current reference moved in the batch, or a sum saturated: thrown
    /// away.
    Moved,
    /// No pattern to solve against.
    NoSolution,
    /// The batch's `ê`, per unit.
    Error(f32),
}

/// `x` within `[lo, hi]` by comparisons (`f32::clamp` may panic, `min`/`max` call into libm on
/// a Cortex-M).
pub(super) fn within(x: f32, lo: f32, hi: f32) -> f32 {
    if x < lo {
        lo
    } else if x > hi {
        hi
    } else {
        x
    }
}

impl Batch {
    /// Adds one sample: the six signals `x` (Q12), `cos 6θ`, `sin 6θ` (Q11), the speed `w`
    /// (Q8.24 bits), the current reference's length `i_ref` (Q12), in the batch's second half
    /// or not. Every product is within ±2³⁰ (module docs); the sums saturate.
    pub fn add(&mut self, x: &[i32; 6], c6: i32, s6: i32, w: i32, i_ref: i32, second: bool) {
        if self.n == 0 {
            (self.w_min, self.w_max) = (w, w);
        }
        let k = usize::from(second);
        if let Some(sum) = self.sum_i.get_mut(k) {
            *sum = sum.saturating_add(i64::from(i_ref));
        }
        self.sum_i2 = self.sum_i2.saturating_add(crate::num::wmul(i_ref, i_ref));
        self.n += 1;
        let sums = self.sum.iter_mut().zip(&mut self.cos).zip(&mut self.sin);
        for (((sum, cos), sin), &x) in sums.zip(x) {
            *sum = sum.saturating_add(x);
            *cos = cos.saturating_add(x.wrapping_mul(c6));
            *sin = sin.saturating_add(x.wrapping_mul(s6));
        }
        self.sum_c = self.sum_c.saturating_add(c6);
        self.sum_s = self.sum_s.saturating_add(s6);
        self.sum_w = self.sum_w.saturating_add(i64::from(w));
        self.w_min = self.w_min.min(w);
        self.w_max = self.w_max.max(w);
    }

    /// The next stage of the batch's end: the gates; the phasors of `i_d`, `i_q`; each axis's
    /// residual after the motor's impedance; the solution. `change` is the gates' fraction.
    /// Each stage's `f32` results go to the slots of sums no later stage reads.
    pub fn end_stage(&mut self, change: f32, m: &Model) -> End {
        let stage = self.stage;
        self.stage = stage.saturating_add(1);
        match stage {
            0 => self.gates(change),
            1 => {
                let (id, iq) = (self.phasor(I_D), self.phasor(I_Q));
                self.keep(I_D, id);
                self.keep(I_Q, iq);
                End::Pending
            }
            2 => {
                // U_d − (R + j6ωL_d) I_d + ω L_q I_q
                let (w, id, iq) = (self.w(), self.kept(I_D), self.kept(I_Q));
                let zi = mul((m.r, 6.0 * w * m.ld), id);
                let (u, k) = (self.phasor(U_D), w * m.lq);
                self.keep(U_D, (u.0 - zi.0 + k * iq.0, u.1 - zi.1 + k * iq.1));
                End::Pending
            }
            3 => {
                // U_q − (R + j6ωL_q) I_q − ω L_d I_d
                let (w, id, iq) = (self.w(), self.kept(I_D), self.kept(I_Q));
                let zi = mul((m.r, 6.0 * w * m.lq), iq);
                let (u, k) = (self.phasor(U_Q), w * m.ld);
                self.keep(U_Q, (u.0 - zi.0 - k * id.0, u.1 - zi.1 - k * id.1));
                End::Pending
            }
            _ => self.solve(),
        }
    }

    /// Throws the batch away when a sum saturated, or the speed or the current reference's
    /// length moved by more than `change` of its mean in it; keeps `1/n` and the mean speed
    /// (per unit) in the slots of the speed's least and largest.
    fn gates(&mut self, change: f32) -> End {
        let rail = |x: &i32| *x == i32::MAX || *x == i32::MIN;
        if self.sum.iter().chain(&self.cos).chain(&self.sin).any(rail) {
            return End::Moved;
        }
        let inv_n = 1.0 / self.n as f32;
        let w = self.sum_w as f32 * inv_n;
        let [a, c] = self.sum_i;
        // Each half's count taken as n/2 (within one sample).
        let (ia, ic) = (2.0 * a as f32 * inv_n, 2.0 * c as f32 * inv_n);
        let mean_i = 0.5 * (ia + ic);
        let var_i = self.sum_i2 as f32 * inv_n - mean_i * mean_i;
        let spread_w = (i64::from(self.w_max) - i64::from(self.w_min)) as f32;
        if spread_w > change * libm::fabsf(w)
            || libm::fabsf(ic - ia) > change * mean_i
            || var_i > change * change * mean_i * mean_i
        {
            return End::Moved;
        }
        let pu = 1.0 / (1u32 << crate::num::PU_FRAC) as f32;
        self.w_min = inv_n.to_bits() as i32;
        self.w_max = (w * pu).to_bits() as i32;
        End::Pending
    }

    /// `1/n` and the mean speed per unit, as [`Batch::gates`] kept them.
    fn inv_n(&self) -> f32 {
        f32::from_bits(self.w_min as u32)
    }

    fn w(&self) -> f32 {
        f32::from_bits(self.w_max as u32)
    }

    /// Keeps `x` in signal `j`'s sums against `cos`, `sin` (used: its phasor is taken).
    fn keep(&mut self, j: usize, x: C) {
        if let (Some(re), Some(im)) = (self.cos.get_mut(j), self.sin.get_mut(j)) {
            (*re, *im) = (x.0.to_bits() as i32, x.1.to_bits() as i32);
        }
    }

    /// What [`Batch::keep`] kept for signal `j`.
    fn kept(&self, j: usize) -> C {
        match (self.cos.get(j), self.sin.get(j)) {
            (Some(&re), Some(&im)) => (f32::from_bits(re as u32), f32::from_bits(im as u32)),
            _ => (0.0, 0.0),
        }
    }

    /// The phasor at `6θ` of signal `j` per unit (`x ≈ mean + Re(X e^{j6θ})`), its mean
    /// removed, from its sums.
    fn phasor(&self, j: usize) -> C {
        let (Some(&sum), Some(&cos), Some(&sin)) =
            (self.sum.get(j), self.cos.get(j), self.sin.get(j))
        else {
            return (0.0, 0.0);
        };
        let inv_n = self.inv_n();
        // The products' sums in the harmonic's units, 2⁻¹¹ of the signal's.
        let h = 1.0 / (1u32 << HARMONIC_FRAC) as f32;
        let k = 2.0 * inv_n * h / (1u32 << SIGNAL_FRAC) as f32;
        let mean = sum as f32 * inv_n;
        (
            k * (cos as f32 - mean * self.sum_c as f32),
            -k * (sin as f32 - mean * self.sum_s as f32),
        )
    }

    /// The least-squares `ê` of the pattern's phasors against the two residuals.
    fn solve(&self) -> End {
        let (pd, pq) = (self.phasor(P_D), self.phasor(P_Q));
        let (rd, rq) = (self.kept(U_D), self.kept(U_Q));
        let num = pd.0 * rd.0 + pd.1 * rd.1 + pq.0 * rq.0 + pq.1 * rq.1;
        let den = pd.0 * pd.0 + pd.1 * pd.1 + pq.0 * pq.0 + pq.1 * pq.1;
        let e = num / den;
        if den > 0.0 && e.is_finite() {
            End::Error(e)
        } else {
            End::NoSolution
        }
    }
}
