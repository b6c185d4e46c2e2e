//! The bus terms the modulator, the current loops' circle and the dead-time compensation
//! share, kept while the bus reading stays near the one they were computed from.

use crate::num::{Pu, Reciprocal};

/// What the modulator and the current loops need of the bus: the reading's [`Reciprocal`],
/// for the reading it was computed from, kept while later readings stay within
/// [`BUS_TOLERANCE_SHIFT`]'s share of it (a converter's reading moves by a few codes at every
/// sample: taken afresh each time, the reciprocal costs a 32-bit division and two Newton
/// steps, and the dead-time compensation's terms, keyed on the reading, four products). The
/// modulator, the current loops' circle and the dead-time compensation all take the kept
/// reading ([`BusReciprocal::reading`]): the voltage they make is off by at most that share of
/// the bus, 0.2 %, which the current loops take up; the trips take the raw reading.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct BusReciprocal {
    /// The bus reading (bits of [`Pu`]) the rest belongs to; 0 when empty (never a valid bus).
    vdc: i32,
    /// The readings that keep these terms, `lo ..= lo + span`: the reading `± vdc >> 9`
    /// (only itself when empty or not positive).
    lo: i32,
    span: u32,
    /// `1/v_dc`: `x/v_dc` in Q2.30 for `x` in the bits of [`Pu`].
    recip: Reciprocal,
}

/// The bus terms are kept while the reading stays within `2^−9` (0.2 %) of the one they were
/// computed from ([`BusReciprocal`]).
pub(crate) const BUS_TOLERANCE_SHIFT: u32 = 9;

impl BusReciprocal {
    /// The bus terms for the reading `vdc`: the kept ones while `vdc` is within the tolerance
    /// of their reading, else computed for `vdc` and kept (a reading `≤ 0`, which the
    /// modulator never passes, gives a zero reciprocal and keeps only itself).
    #[inline(always)]
    pub(crate) fn get(&mut self, vdc: Pu) -> &Self {
        // The empty cache keeps the reading 0 only, below any bus the modulator passes here.
        if vdc.to_bits().wrapping_sub(self.lo) as u32 > self.span {
            self.take(vdc);
        }
        self
    }

    /// The terms of the reading `vdc` and the readings that keep them, kept from now on. Out
    /// of line: the rare path.
    #[inline(never)]
    fn take(&mut self, vdc: Pu) {
        let bits = vdc.to_bits();
        // 0 ≤ tol ≤ bits for a positive reading: lo and 2 tol cannot wrap.
        let tol = bits.max(0) >> BUS_TOLERANCE_SHIFT;
        *self = Self {
            vdc: bits,
            lo: bits - tol,
            span: 2 * tol as u32,
            recip: Reciprocal::of(bits),
        };
    }

    /// The reading the terms were computed from, which the control path takes for the bus.
    #[inline(always)]
    pub(crate) fn reading(&self) -> Pu {
        Pu::from_bits(self.vdc)
    }

    /// The reading's [`Reciprocal`] (zero for a reading `≤ 0`).
    #[inline(always)]
    pub(crate) fn recip(&self) -> Reciprocal {
        self.recip
    }
}
