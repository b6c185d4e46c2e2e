//! The flux and inertia stages' excitation: an I–f spin (current on the rotating field's x
//! axis) up to the first speed, a window there, down to half of it, a window, up again, a
//! window, then the stop; the windows sum the voltages, currents, energy and field speed
//! (integer, per sample).

use super::machine::{Identify, Phase};
use super::{IdentifyError, Stage};
use crate::angle::Angle;
use crate::frames::{AlphaBeta, park};

/// Windows measured again in all while the spin's speed still moves.
const MAX_SPIN_RETRIES: u32 = 24;

/// Sums over one of the spin's windows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct WindowSums {
    pub(super) v: [i64; 2],
    pub(super) i: [i64; 2],
    /// Σ of the energy `C` over the window.
    pub(super) c_sum: i64,
    /// Σ of `C` over the first and the second half of the window (their difference over
    /// the half length squared is the mean power, with the hunting averaged out at both ends).
    pub(super) c_first: i64,
    pub(super) c_second: i64,
    pub(super) n: u32,
    /// Σ of the field's actual step (commanded speed with the damper's correction).
    pub(super) speed_sum: u64,
    pub(super) speed_n: u32,
    /// Σ of the field's step over the window's first and second half.
    pub(super) speed_half: [u64; 2],
    /// Σ over the window of `F`, the running Σ of the squared field step, and of the spin's
    /// sample index.
    pub(super) f_sum: i128,
    pub(super) t_sum: i64,
}

/// The spin's segments.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Seg {
    First,
    Hold(u8),
    Down,
    Up,
    Stop,
    Rest,
}

impl Identify {
    pub(super) fn start_spin(&mut self) {
        self.k = 0;
        self.phase_q16 = 0;
        self.speed_q16 = 0;
        self.energy = 0;
        self.retries = 0;
        self.vx_mean = (self.v_hold.alpha.to_bits() as i64) << 12;
        self.hold_integrators(self.v_hold);
    }

    /// One sample of the spin: the x, y voltage and the angle of the field to output it at.
    pub(super) fn spin_step(
        &mut self,
        seg: Seg,
        i: AlphaBeta,
    ) -> Result<(AlphaBeta, Angle), IdentifyError> {
        let angle = Angle((self.phase_q16 >> 16) as u32 as i32);
        let ic = park(i, angle.sin_cos());
        let v = self.pi([self.spin_bits - ic.d.to_bits(), -ic.q.to_bits()]);
        if self.saturated && !matches!(seg, Seg::Stop | Seg::Rest) {
            return Err(IdentifyError::Saturation(Stage::Flux));
        }
        let (vx, vy) = (v.d.to_bits() as i64, v.q.to_bits() as i64);
        let (ix, iy) = (ic.d.to_bits() as i64, ic.q.to_bits() as i64);
        // Saturating: a healthy spin is far from the limits (see the module's formats).
        let p = vx.saturating_mul(ix).saturating_add(vy.saturating_mul(iy)) >> 24;
        self.energy = self.energy.saturating_add(p);
        let w_open = self.segment(seg, [vx, vy], [ix, iy])?;
        let (step, out_angle) = self.advance_field(vx);
        let half = self.config.n_window / 2;
        if let Seg::Hold(h) = seg
            && let Some(j) = w_open
            && let Some(w) = self.windows.get_mut(h as usize)
        {
            w.speed_sum = w.speed_sum.saturating_add(step);
            w.speed_n += 1;
            if let Some(x) = w.speed_half.get_mut((j / half.max(1)) as usize) {
                *x = x.saturating_add(step);
            }
            w.f_sum = w.f_sum.saturating_add(self.f_energy);
            w.t_sum = w.t_sum.saturating_add(self.spin_n);
        }
        Ok((
            AlphaBeta {
                alpha: v.d,
                beta: v.q,
            },
            out_angle,
        ))
    }

    /// The segment's speed profile and transitions; `v`, `i` the x, y voltage and current
    /// (`Pu` bits). Returns the window's sample index while one is open (summing).
    fn segment(
        &mut self,
        seg: Seg,
        v: [i64; 2],
        i: [i64; 2],
    ) -> Result<Option<u32>, IdentifyError> {
        let c = self.config;
        let accel = c.accel_q16;
        match seg {
            Seg::First => {
                self.speed_q16 += accel;
                let [vx, vy] = v;
                let v2 = vx.saturating_mul(vx).saturating_add(vy.saturating_mul(vy));
                if v2 >= self.spin_v2_bits || self.speed_q16 >= c.max_speed_q16 {
                    self.omega1_q16 = self.speed_q16 & !1;
                    self.omega2_q16 = self.omega1_q16 / 2;
                    self.speed_q16 = self.omega1_q16;
                    self.next_seg(Seg::Hold(0));
                }
            }
            Seg::Hold(h) => return self.hold_sample(h, v, i),
            Seg::Down => {
                self.speed_q16 = self.speed_q16.saturating_sub(accel);
                if self.speed_q16 <= self.omega2_q16 {
                    self.speed_q16 = self.omega2_q16;
                    self.next_seg(Seg::Hold(1));
                }
            }
            Seg::Up => {
                self.speed_q16 += accel;
                if self.speed_q16 >= self.omega1_q16 {
                    self.speed_q16 = self.omega1_q16;
                    self.next_seg(Seg::Hold(2));
                }
            }
            Seg::Stop => {
                self.speed_q16 = self.speed_q16.saturating_sub(accel);
                if self.speed_q16 == 0 {
                    self.next_seg(Seg::Rest);
                }
            }
            Seg::Rest => {
                self.k += 1;
                if self.k >= c.n_settle {
                    self.phase = Phase::Finished;
                }
            }
        }
        Ok(None)
    }

    /// One sample of hold `h` at constant speed: settling, then window `h`'s sums; the
    /// window's end starts the next segment, or the window again while the rotor's speed
    /// still moves. Returns the window's sample index while it is open.
    fn hold_sample(
        &mut self,
        h: u8,
        v: [i64; 2],
        i: [i64; 2],
    ) -> Result<Option<u32>, IdentifyError> {
        let c = self.config;
        let k = self.k;
        self.k += 1;
        if k < c.n_settle {
            return Ok(None);
        }
        let j = k - c.n_settle;
        let e = self.energy;
        if let Some(w) = self.windows.get_mut(h as usize) {
            w.v[0] += v[0];
            w.v[1] += v[1];
            w.i[0] += i[0];
            w.i[1] += i[1];
            w.c_sum = w.c_sum.saturating_add(e);
            let half = c.n_window / 2;
            if j < half {
                w.c_first = w.c_first.saturating_add(e);
            } else if j < 2 * half {
                w.c_second = w.c_second.saturating_add(e);
            }
            w.n += 1;
        }
        if k + 1 >= c.n_settle + c.n_window {
            let [a, b] = self
                .windows
                .get(h as usize)
                .map_or([0, 0], |w| w.speed_half);
            // A heavy rotor may still follow the damper's correction after the settling:
            // its field speed then differs between the window's halves by more than the
            // hunting does. Measure again, a bounded number of times.
            if 200 * a.abs_diff(b) > a {
                if self.retries >= MAX_SPIN_RETRIES {
                    return Err(IdentifyError::RotorMoved(Stage::Flux));
                }
                self.retries += 1;
                if let Some(w) = self.windows.get_mut(h as usize) {
                    *w = WindowSums::default();
                }
                self.k = c.n_settle;
                // This sample belongs to neither window.
                return Ok(None);
            }
            let next = match h {
                0 => Seg::Down,
                1 => Seg::Up,
                _ => Seg::Stop,
            };
            self.next_seg(next);
        }
        Ok(Some(j))
    }

    /// Turns the field by this sample's step, the commanded speed less the hunting damper's
    /// correction from the x voltage `vx` (`Pu` bits). Returns the step and the angle to
    /// output at.
    fn advance_field(&mut self, vx: i64) -> (u64, Angle) {
        let c = self.config;
        // Hunting damper: the x voltage carries `ω ψ sin δ`; slowing the field when it rises
        // above its slow mean (the rotor falling behind) damps the load angle's oscillation
        // (`δ'' + c cos δ δ' + (K/J) sin δ = 0`), which open-loop I–f otherwise lacks.
        self.vx_mean += vx - (self.vx_mean >> 12);
        let dv = vx - (self.vx_mean >> 12);
        let corr = c.damp_q24.saturating_mul(dv) >> 24;
        let step = (self.speed_q16 as i64).saturating_sub(corr).max(0) as u64;
        // Output at the middle of the coming period's angle (the vector turns during it).
        let out_angle = Angle((self.phase_q16.wrapping_add(step / 2) >> 16) as u32 as i32);
        self.phase_q16 = self.phase_q16.wrapping_add(step);
        let counts = (step >> 16) as i128;
        self.f_energy = self.f_energy.saturating_add(counts * counts);
        self.spin_n += 1;
        (step, out_angle)
    }

    fn next_seg(&mut self, s: Seg) {
        self.k = 0;
        self.phase = Phase::Spin(s);
    }
}
