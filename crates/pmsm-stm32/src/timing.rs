//! TIM1 timing: prescaler and auto-reload of a centre-aligned PWM at a frequency, and the
//! dead-time generator's register encoding (RM0440 §28.6.20, TIMx_BDTR.DTG and CR1.CKD).

/// Why a timing cannot be made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimingError {
    /// The PWM frequency is zero or too high for a useful resolution (fewer than
    /// [`MIN_PERIOD`] counts per half period).
    FrequencyTooHigh,
    /// The dead time exceeds what the generator encodes (1008 × 4 timer clocks).
    DeadTimeTooLong,
}

/// The smallest auto-reload accepted (the duty resolution is one count in `ARR`).
pub const MIN_PERIOD: u32 = 100;

/// Prescaler and auto-reload of a centre-aligned (up-down) timer:
/// `f_pwm = f_tim / ((PSC + 1) · 2 · ARR)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PwmTiming {
    /// TIMx_PSC.
    pub psc: u16,
    /// TIMx_ARR: the counter peak; compare values run from 0 to `arr`.
    pub arr: u16,
}

impl PwmTiming {
    /// The smallest prescaler that fits `ARR` in 16 bits, and the `ARR` nearest to the
    /// requested frequency.
    pub fn centre_aligned(tim_hz: u32, pwm_hz: u32) -> Result<Self, TimingError> {
        if pwm_hz == 0 {
            return Err(TimingError::FrequencyTooHigh);
        }
        // Any u32 timer clock reaches 1 Hz: 2^32 / (2 · 65 536) < 65 536, so PSC fits.
        let denom = 2 * pwm_hz as u64;
        let mut psc = tim_hz as u64 / denom / (u16::MAX as u64 + 1);
        loop {
            let div = denom * (psc + 1);
            let arr = (tim_hz as u64 + div / 2) / div;
            if arr <= u16::MAX as u64 {
                if arr < MIN_PERIOD as u64 {
                    return Err(TimingError::FrequencyTooHigh);
                }
                return Ok(Self {
                    psc: psc as u16,
                    arr: arr as u16,
                });
            }
            psc += 1;
        }
    }

    /// The frequency this timing makes, Hz.
    pub fn frequency_hz(&self, tim_hz: u32) -> f64 {
        tim_hz as f64 / ((self.psc as f64 + 1.0) * 2.0 * self.arr as f64)
    }
}

/// The dead-time generator's setting: `CR1.CKD` (t_DTS = 2^ckd timer clocks) and `BDTR.DTG`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeadTime {
    /// TIMx_CR1.CKD (0, 1 or 2).
    pub ckd: u8,
    /// TIMx_BDTR.DTG.
    pub dtg: u8,
}

impl DeadTime {
    /// The shortest encodable dead time not shorter than `dead_time_ns` (never rounds down: a
    /// short dead time shoots through a leg), with the smallest `CKD` that reaches it.
    pub fn at_least(tim_hz: u32, dead_time_ns: u32) -> Result<Self, TimingError> {
        for ckd in 0..=2u8 {
            let clocks_per_dts = 1u64 << ckd;
            let num = dead_time_ns as u64 * tim_hz as u64;
            let den = 1_000_000_000u64 * clocks_per_dts;
            let ticks = num.div_ceil(den);
            if let Some(dtg) = encode_dtg(ticks) {
                return Ok(Self { ckd, dtg });
            }
        }
        Err(TimingError::DeadTimeTooLong)
    }

    /// The dead time, in timer clocks.
    pub fn timer_clocks(&self) -> u32 {
        decode_dtg(self.dtg) << self.ckd
    }

    /// The dead time, ns (rounded down).
    pub fn nanoseconds(&self, tim_hz: u32) -> u32 {
        (self.timer_clocks() as u64 * 1_000_000_000 / tim_hz as u64) as u32
    }
}

/// DTG for at least `ticks` t_DTS (RM0440 TIMx_BDTR.DTG):
///
/// | DTG\[7:5\] | dead time            | range, t_DTS |
/// |---|---|---|
/// | 0xx      | DTG\[7:0\]             | 0–127     |
/// | 10x      | (64 + DTG\[5:0\]) · 2  | 128–254   |
/// | 110      | (32 + DTG\[4:0\]) · 8  | 256–504   |
/// | 111      | (32 + DTG\[4:0\]) · 16 | 512–1008  |
pub fn encode_dtg(ticks: u64) -> Option<u8> {
    if ticks <= 127 {
        Some(ticks as u8)
    } else if ticks <= 254 {
        Some(0x80 | (ticks.div_ceil(2) - 64) as u8)
    } else if ticks <= 504 {
        Some(0xC0 | (ticks.div_ceil(8) - 32) as u8)
    } else if ticks <= 1008 {
        Some(0xE0 | (ticks.div_ceil(16) - 32) as u8)
    } else {
        None
    }
}

/// The dead time a DTG value encodes, t_DTS.
pub fn decode_dtg(dtg: u8) -> u32 {
    let d = dtg as u32;
    if d & 0x80 == 0 {
        d
    } else if d & 0xC0 == 0x80 {
        (64 + (d & 0x3F)) * 2
    } else if d & 0xE0 == 0xC0 {
        (32 + (d & 0x1F)) * 8
    } else {
        (32 + (d & 0x1F)) * 16
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn board_pwm_20khz_at_170mhz() {
        let t = PwmTiming::centre_aligned(170_000_000, 20_000).unwrap();
        assert_eq!(t, PwmTiming { psc: 0, arr: 4250 });
        assert!((t.frequency_hz(170_000_000) - 20_000.0).abs() < 1e-9);
    }

    #[test]
    fn low_frequency_uses_the_prescaler() {
        // 170 MHz / (2 · 1 kHz) = 85 000 > 65 535: PSC = 1, ARR = 42 500.
        let t = PwmTiming::centre_aligned(170_000_000, 1_000).unwrap();
        assert_eq!(
            t,
            PwmTiming {
                psc: 1,
                arr: 42_500
            }
        );
        let t = PwmTiming::centre_aligned(170_000_000, 16_000).unwrap();
        assert!((t.frequency_hz(170_000_000) / 16_000.0 - 1.0).abs() < 1e-4);
        assert_eq!(
            PwmTiming::centre_aligned(170_000_000, 1_000_000),
            Err(TimingError::FrequencyTooHigh)
        );
        assert_eq!(
            PwmTiming::centre_aligned(170_000_000, 0),
            Err(TimingError::FrequencyTooHigh)
        );
        let t = PwmTiming::centre_aligned(u32::MAX, 1).unwrap();
        assert!((t.frequency_hz(u32::MAX) - 1.0).abs() < 1e-4);
    }

    #[test]
    fn frequencies_within_half_a_count() {
        for f in (5_000..=100_000).step_by(1_000) {
            let t = PwmTiming::centre_aligned(170_000_000, f).unwrap();
            let err = (t.frequency_hz(170_000_000) - f as f64).abs() / f as f64;
            assert!(err <= 0.5 / t.arr as f64 + 1e-12, "{f} Hz: {t:?}");
        }
    }

    #[test]
    fn board_dead_time() {
        // 0.5 µs at 170 MHz = 85 clocks, DTG = 85 (linear range), exact.
        let d = DeadTime::at_least(170_000_000, 500).unwrap();
        assert_eq!(d, DeadTime { ckd: 0, dtg: 85 });
        assert_eq!(d.nanoseconds(170_000_000), 500);
        // 1 µs = 170 clocks: (64 + 21) · 2.
        let d = DeadTime::at_least(170_000_000, 1_000).unwrap();
        assert_eq!(
            d,
            DeadTime {
                ckd: 0,
                dtg: 0x80 | 21
            }
        );
        assert_eq!(d.timer_clocks(), 170);
        // 2 µs = 340: (32 + 11) · 8 = 344 (rounded up).
        let d = DeadTime::at_least(170_000_000, 2_000).unwrap();
        assert_eq!(
            d,
            DeadTime {
                ckd: 0,
                dtg: 0xC0 | 11
            }
        );
        assert_eq!(d.timer_clocks(), 344);
        // 10 µs = 1700 clocks: beyond 1008, CKD = 1 (850 t_DTS → (32 + 22) · 16 = 864).
        let d = DeadTime::at_least(170_000_000, 10_000).unwrap();
        assert_eq!(d.ckd, 1);
        assert_eq!(d.timer_clocks(), 1728);
        assert_eq!(
            DeadTime::at_least(170_000_000, 30_000),
            Err(TimingError::DeadTimeTooLong)
        );
        assert_eq!(DeadTime::at_least(170_000_000, 0).unwrap().dtg, 0);
    }

    #[test]
    fn dtg_encoding_is_the_smallest_not_below() {
        // Every representable value, sorted, for a minimality check.
        let mut values: [u32; 256] = core::array::from_fn(|d| decode_dtg(d as u8));
        values.sort_unstable();
        for ticks in 0..=1008u64 {
            let dtg = encode_dtg(ticks).unwrap();
            let got = decode_dtg(dtg) as u64;
            assert!(got >= ticks, "{ticks}: {got}");
            let best = values
                .iter()
                .find(|&&v| v as u64 >= ticks)
                .copied()
                .unwrap();
            assert_eq!(got, best as u64, "{ticks}");
        }
        assert_eq!(encode_dtg(1009), None);
        assert_eq!(decode_dtg(0xFF), 1008);
    }
}
