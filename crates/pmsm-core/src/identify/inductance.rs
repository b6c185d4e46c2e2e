//! The inductance stages' excitation: a square voltage on the held one along d (α), then
//! along q (β), a coarse burst and a fine one each; the current's swing at the end of each
//! half period is summed (integer, per sample).

use super::machine::{Identify, Phase};
use super::spin::Seg;
use crate::frames::AlphaBeta;
use crate::num::Pu;

/// Sums over one burst.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct BurstSums {
    /// Σ over the ends of halves of `sign · i_axis`, `Pu` bits.
    pub(super) d: i64,
    pub(super) halves: u32,
    pub(super) n_half: u32,
}

impl Identify {
    pub(super) fn start_burst(&mut self, b: u8, n_half: u32) {
        if let Some(s) = self.bursts.get_mut(b as usize) {
            *s = BurstSums {
                n_half: n_half.max(1),
                ..Default::default()
            };
        }
        self.k = 0;
        self.sign = 1;
        self.in_half = 0;
        self.half_ended = false;
    }

    pub(super) fn burst_step(&mut self, b: u8, ia: i32, ib: i32) -> AlphaBeta {
        let c = self.config;
        let bi = b as usize;
        let along = if b < 2 { ia } else { ib };
        let fine = b % 2 == 1;
        let len = if fine { c.n_window } else { c.n_burst };
        let warm = c.n_hold;
        let Some(s) = self.bursts.get_mut(bi) else {
            return self.v_hold;
        };
        // The current now ends the period commanded last step.
        if self.half_ended {
            if self.k >= warm {
                s.d += -(self.sign as i64) * along as i64;
                s.halves += 1;
            }
            if self.k >= warm + len && s.halves % 2 == 0 && s.halves > 0 {
                self.burst_end(b);
                return self.v_hold;
            }
        }
        let n_half = s.n_half;
        let sign = self.sign;
        self.in_half += 1;
        self.half_ended = self.in_half >= n_half;
        if self.half_ended {
            self.in_half = 0;
            self.sign = -sign;
        }
        self.k += 1;
        let sq = Pu::from_bits(sign * self.sq_bits);
        let mut v = self.v_hold;
        if b < 2 {
            v.alpha = v.alpha.saturating_add(sq);
        } else {
            v.beta = v.beta.saturating_add(sq);
        }
        v
    }

    /// After burst `b`: a coarse one waits for [`Identify::poll`] to size the fine one, the
    /// fine d burst starts the coarse q one, the fine q burst starts the spin.
    fn burst_end(&mut self, b: u8) {
        self.k = 0;
        self.phase = match b {
            0 | 2 => Phase::AwaitPoll(b),
            1 => {
                self.start_burst(2, 1);
                Phase::Burst(2)
            }
            _ => {
                self.start_spin();
                Phase::Spin(Seg::First)
            }
        };
    }
}
