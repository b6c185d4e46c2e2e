//! The resistance stage's excitation: the current ramped onto α, then held at four levels
//! while the voltage that holds each is averaged (integer, per sample).

use super::machine::{Identify, Phase};
use super::{IdentifyError, Stage};
use crate::frames::AlphaBeta;
use crate::num::{Pu, sat_i32};

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
    /// The ramp of the α current up to the first level (the rotor turns onto α). No β
    /// voltage here or while a level settles: a rotor still turning drives β current
    /// through `R`, which brakes it; a β current loop would cancel that damping.
    pub(super) fn align_step(&mut self, ia: i32) -> AlphaBeta {
        self.i_ref = (self.i_ref + self.ramp_step_bits).min(self.level_bits[0]);
        self.k += 1;
        if self.k >= self.config.n_ramp {
            self.k = 0;
            self.phase = Phase::Level(0);
        }
        let v = self.pi([self.i_ref - ia, 0]);
        AlphaBeta {
            alpha: v.d,
            beta: Pu::ZERO,
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
            let v = self.pi([r - ia, 0]);
            let v = AlphaBeta {
                alpha: v.d,
                beta: Pu::ZERO,
            };
            // The loop's α output, summed over the settle's second half: a rotor still
            // swinging adds its EMF to any single sample of it, not to the mean.
            if k == c.n_settle / 2 {
                self.v_settle = 0;
            }
            self.v_settle += v.alpha.to_bits() as i64;
            return Ok(v);
        }
        if k == c.n_settle {
            if 2 * ia < r {
                return Err(IdentifyError::NoCurrent(Stage::Resistance));
            }
            if self.saturated {
                return Err(IdentifyError::Saturation(Stage::Resistance));
            }
            let n = (c.n_settle - c.n_settle / 2).max(1) as i64;
            self.v_hold = AlphaBeta {
                alpha: Pu::from_bits(sat_i32(self.v_settle / n)),
                beta: Pu::ZERO,
            };
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
        let swinging = 100 * (s.first - s.second).abs() > 2 * r * (c.n_window / 2) as i64
            || 50 * s.beta.abs() > r * n;
        // A held voltage taken while the rotor still swung drives another current than the
        // level's: regulate again and take it anew.
        let off = 5 * (s.i - r * n).abs() > r * n;
        if swinging || off {
            if self.retries >= MAX_RETRIES {
                return Err(if 2 * s.i < r * n {
                    IdentifyError::NoCurrent(Stage::Resistance)
                } else {
                    IdentifyError::RotorMoved(Stage::Resistance)
                });
            }
            self.retries += 1;
            if let Some(s) = self.levels.get_mut(li) {
                *s = LevelSums::default();
            }
            // Still swinging (the held voltage brakes it through R): measure again.
            // Off the level: back to the loop.
            self.k = if off { 0 } else { w0 };
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
