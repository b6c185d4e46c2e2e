//! The resistance stage's excitation: the current ramped onto α, then held at four levels
//! while the voltage that holds each is averaged (integer, per sample).

use super::machine::{Identify, Phase};
use super::{IdentifyError, Stage};
use crate::frames::AlphaBeta;
use crate::num::Pu;

/// Sums over one level's window, `Pu` bits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct LevelSums {
    pub(super) v: i64,
    pub(super) i: i64,
    pub(super) beta: i64,
    pub(super) first: i64,
    pub(super) second: i64,
    pub(super) n: u32,
}

/// Windows repeated in all while the rotor still moves at the resistance levels.
const MAX_RETRIES: u32 = 16;

impl Identify {
    /// The ramp of the α current up to the first level (the rotor turns onto α).
    pub(super) fn align_step(&mut self, ia: i32, ib: i32) -> AlphaBeta {
        self.i_ref = (self.i_ref + self.ramp_step_bits).min(self.level_bits[0]);
        self.k += 1;
        if self.k >= self.config.n_ramp {
            self.k = 0;
            self.phase = Phase::Level(0);
        }
        let v = self.pi([self.i_ref - ia, -ib]);
        AlphaBeta {
            alpha: v.d,
            beta: v.q,
        }
    }

    pub(super) fn level_step(
        &mut self,
        l: u8,
        ia: i32,
        ib: i32,
    ) -> Result<AlphaBeta, IdentifyError> {
        let c = self.config;
        let li = l as usize;
        let r = self.level_bits.get(li).copied().unwrap_or(0);
        let k = self.k;
        self.k += 1;
        if k < c.n_settle {
            // β is regulated to zero too: the rotor may still be turning onto α.
            let v = self.pi([r - ia, -ib]);
            let v = AlphaBeta {
                alpha: v.d,
                beta: v.q,
            };
            self.v_hold = v;
            return Ok(v);
        }
        if k == c.n_settle {
            if 2 * ia < r {
                return Err(IdentifyError::NoCurrent(Stage::Resistance));
            }
            if self.saturated {
                return Err(IdentifyError::Saturation(Stage::Resistance));
            }
            // At standstill the β voltage that keeps β current at zero is zero (the phase
            // currents' signs are symmetric about α); what the loop holds there now only
            // answers the rotor's motion, and holding it would pull the rotor off α.
            self.v_hold.beta = Pu::ZERO;
        }
        let w0 = c.n_settle + c.n_hold;
        if k >= w0 {
            let j = k - w0;
            self.level_sample(li, j, ia, ib);
            if j + 1 >= c.n_window {
                self.level_end(l, r)?;
            }
        }
        Ok(self.v_hold)
    }

    /// Adds sample `j` of level `li`'s window to its sums.
    fn level_sample(&mut self, li: usize, j: u32, ia: i32, ib: i32) {
        let c = self.config;
        if let Some(s) = self.levels.get_mut(li) {
            s.v += self.v_hold.alpha.to_bits() as i64;
            s.i += ia as i64;
            s.beta += ib as i64;
            if j < c.n_window / 2 {
                s.first += ia as i64;
            } else if j < 2 * (c.n_window / 2) {
                s.second += ia as i64;
            }
            s.n += 1;
        }
    }

    /// The end of level `l`'s window (reference `r`, `Pu` bits): checks it, then measures
    /// it again, moves to the next level or starts the first burst.
    fn level_end(&mut self, l: u8, r: i32) -> Result<(), IdentifyError> {
        let c = self.config;
        let li = l as usize;
        let w0 = c.n_settle + c.n_hold;
        let s = self.levels.get(li).copied().unwrap_or_default();
        let (n, r) = (s.n as i64, r as i64);
        if 2 * s.i < r * n {
            return Err(IdentifyError::NoCurrent(Stage::Resistance));
        }
        if 100 * (s.first - s.second).abs() > 2 * r * (c.n_window / 2) as i64
            || 50 * s.beta.abs() > r * n
        {
            // Still swinging (the held voltage brakes it through R): measure again,
            // a bounded number of times.
            if self.retries >= MAX_RETRIES {
                return Err(IdentifyError::RotorMoved(Stage::Resistance));
            }
            self.retries += 1;
            if let Some(s) = self.levels.get_mut(li) {
                *s = LevelSums::default();
            }
            self.k = w0;
            return Ok(());
        }
        self.k = 0;
        self.hold_integrators(self.v_hold);
        self.phase = if l >= 3 {
            self.start_burst(0, 1);
            Phase::Burst(0)
        } else {
            Phase::Level(l + 1)
        };
        Ok(())
    }
}
