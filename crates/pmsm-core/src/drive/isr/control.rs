//! The interrupt side's closed loop on a setpoint: the current loops in its frame, the
//! dead-time compensation and the modulator (Khlaief, Boussak, Gossa (2012), Fig. 1).

use super::{DriveIsr, Setpoint, mid_frame};
use crate::angle::{Angle, SinCos, sin_cos_frame};
use crate::control::current::CurrentInput;
use crate::deadtime::CurrentSource;
use crate::drive::interface::{DriveInput, DriveOutput};
use crate::frames::{Abc, AlphaBeta, Dq, inverse_park_frame, park, park_frame};
use crate::num::{Pu, Reciprocal, Unit, follow};
use crate::svpwm::SvpwmOutput;

impl DriveIsr {
    /// Current loops in the setpoint's frame, dead-time compensation and modulation
    /// (Khlaief, Boussak, Gossa (2012), Fig. 1). `i` is the Clarke transform of `input.i_abc`.
    #[inline(always)]
    pub(super) fn control(
        &mut self,
        input: &DriveInput,
        i: AlphaBeta,
        setpoint: Setpoint,
    ) -> DriveOutput {
        let Setpoint {
            theta,
            omega,
            i_ref,
            frame,
        } = setpoint;
        // Current loops, in the setpoint's frame.
        let i_dq = match frame {
            Some(f) => f.i_dq,
            // Standing still (the alignment, the calibration), exact: the calibration measures
            // the inverter's voltage error from the loops closed in this frame, and the grid's
            // 10⁻⁴ moved it enough to change a start (docs/drive.md, "every estimator's frames").
            None if omega == Pu::ZERO => park(i, theta.sin_cos()),
            None => park_frame(i, self.estimator.sin_cos_of(theta)),
        };
        // The bus terms first: the current loops share their reciprocal with the modulator.
        // From here on the bus is the reading they were computed from, within 0.2 % of this
        // sample's (`BusReciprocal`): the loops' circle, the dead-time compensation and the
        // modulator take the same bus.
        let bus = self.inv_vdc.get(input.vdc);
        let (vdc, inv_vdc) = (bus.reading(), bus.recip());
        let out = self.current.step_on(
            &CurrentInput {
                i_ref,
                i: i_dq,
                omega,
                vdc,
                hold: self.telemetry.saturated,
            },
            inv_vdc,
        );
        // The voltage acts over the coming period: rotate it to the frame's mid-period angle.
        // With the estimator's two frames, their mean points there exactly, at a length
        // cos(ω T_s/2) (0.9993 at 1 pu on motor B): a gain the current loops take up, while the
        // estimator sees the voltage actually modulated.
        // With a PWM update delay of d samples it acts d periods later, around
        // θ + (d + ½) ω T_s: `mid_turns` = 2d + 1 half steps (`mid_frame_k` = 2d − 1 on from
        // the next frame).
        let sc_mid = match frame {
            Some(f) => mid_frame(f.sc, f.sc_next, self.config.mid_frame_k),
            None => {
                let turn = self.config.open_loop.turn_per_speed;
                let step = turn.apply_bits(omega.to_bits());
                sin_cos_frame(theta + Angle(step.wrapping_mul(self.config.mid_turns) >> 1))
            }
        };
        #[cfg(feature = "injection")]
        let v_dq = self.with_injection(out.v);
        #[cfg(not(feature = "injection"))]
        let v_dq = out.v;
        // In the frames as the transforms take them, to 2⁻¹⁴ (`park_frame`).
        let v_ref = inverse_park_frame(v_dq, sc_mid);
        // Dead-time compensation, then the modulator.
        let v_dt = self.deadtime_vector(vdc, i_dq, i_ref, sc_mid);
        #[cfg(feature = "overmodulation")]
        let m = if self.config.svpwm.overmodulation() {
            self.overmodulate(input, vdc, inv_vdc, v_ref, v_dt)
        } else {
            self.modulate(v_ref, vdc, inv_vdc, v_dt)
        };
        #[cfg(not(feature = "overmodulation"))]
        let m = self.modulate(v_ref, vdc, inv_vdc, v_dt);
        self.frame_omega = omega;
        self.v_dt = v_dt;
        self.telemetry.theta = theta;
        self.telemetry.i_dq = i_dq;
        self.telemetry.i_ref = i_ref;
        self.telemetry.v = m.v;
        self.telemetry.saturated = m.saturated || out.saturated_d || out.saturated_q;
        DriveOutput {
            duties: m.duties,
            pwm_on: true,
        }
    }

    /// The voltage the estimator sees at the next sample, given the one modulated now: that
    /// of `pwm_delay` samples ago, the one that will have acted over the coming period (a
    /// delay line of `pwm_delay` vectors).
    #[inline(always)]
    pub(super) fn delayed(&mut self, v: AlphaBeta) -> AlphaBeta {
        match self.config.pwm_delay {
            0 => v,
            1 => core::mem::replace(&mut self.v_line[0], v),
            _ => {
                let out = self.v_line[1];
                self.v_line[1] = self.v_line[0];
                self.v_line[0] = v;
                out
            }
        }
    }

    /// [`DriveIsr::control`]'s linear modulation of `v_ref` with the dead-time compensation
    /// `v_dt`; the estimator is given the modulated vector less the dead-time error.
    #[inline(always)]
    fn modulate(
        &mut self,
        v_ref: AlphaBeta,
        vdc: Pu,
        inv_vdc: Reciprocal,
        v_dt: AlphaBeta,
    ) -> SvpwmOutput {
        let c = &self.config;
        let m = c
            .svpwm
            .modulate_on(c.deadtime.command(v_ref, v_dt), vdc, inv_vdc);
        let v_applied = c.deadtime.estimator_voltage(m.v, v_dt);
        self.v_est = self.delayed(v_applied);
        m
    }

    /// [`DriveIsr::control`]'s modulation when overmodulating (docs/overmodulation.md): a leg
    /// held at duty 0 or 1 does not switch and loses no dead time, and beyond the hexagon the
    /// currents carry the harmonics of the overmodulation, which the reference does not; so
    /// when a leg is held the estimator is given the duties' vector less the dead-time error
    /// of the legs that switch, with the signs of the measured currents. Inside the hexagon,
    /// as the linear drive.
    #[cfg(feature = "overmodulation")]
    #[cold]
    #[inline(never)]
    fn overmodulate(
        &mut self,
        input: &DriveInput,
        vdc: Pu,
        inv_vdc: Reciprocal,
        v_ref: AlphaBeta,
        v_dt: AlphaBeta,
    ) -> SvpwmOutput {
        let c = &self.config;
        let m = c
            .svpwm
            .overmodulate_on(c.deadtime.command(v_ref, v_dt), vdc, inv_vdc);
        let d = m.duties;
        let held = |x: Unit| x == Unit::ZERO || x == Unit::ONE;
        let v_dt = if held(d.a) || held(d.b) || held(d.c) {
            let mut i = input.i_abc;
            // A zero current is a zero sign: no dead-time error on a held leg.
            for (x, duty) in [(&mut i.a, d.a), (&mut i.b, d.b), (&mut i.c, d.c)] {
                if held(duty) {
                    *x = Pu::ZERO;
                }
            }
            c.deadtime
                .error_vector_abc_cached(i, vdc, &mut self.deadtime_bus)
        } else {
            v_dt
        };
        let v_applied = c.deadtime.estimator_voltage(m.v, v_dt);
        self.v_est = self.delayed(v_applied);
        m
    }

    /// The dead-time voltage error vector over the coming period (Khlaief, Boussak, Gossa
    /// (2012), eq. 6–9), from the measured current `i_dq` or from the reference `i_ref` (both
    /// in the setpoint's frame), turned to the mid-period angle `sc_mid` (docs/drive.md,
    /// "dead-time compensation: which current's sign").
    #[inline(always)]
    fn deadtime_vector(&mut self, vdc: Pu, i_dq: Dq, i_ref: Dq, sc_mid: SinCos) -> AlphaBeta {
        // The current the loop will carry, not the reference itself: the q reference
        // through the closed current loop's lag. The d reference moves slowly: taken as it is.
        self.i_q_expected = follow(self.i_q_expected, i_ref.q, self.config.deadtime_lag_shift);
        let deadtime = &self.config.deadtime;
        // The measured current as sampled is a period and a half old by the middle of the
        // period the command acts over: turned ahead with the frame, as the reference is.
        // Within the band its signs chatter with the ripple and the noise: there the
        // reference's. Under load with the current-model MRAS the task chooses.
        let measured = match deadtime.source() {
            CurrentSource::Measured => deadtime.beyond_band(i_dq),
            CurrentSource::MeasuredUnderLoad => self.measured_signs,
            CurrentSource::Reference => false,
        };
        let i = if measured {
            i_dq
        } else {
            Dq {
                d: i_ref.d,
                q: self.i_q_expected,
            }
        };
        self.config.deadtime.error_vector_abc_cached(
            phases_coarse(i, sc_mid),
            vdc,
            &mut self.deadtime_bus,
        )
    }
}

/// The phase currents of `i` turned from the frame at `sc`, to 2⁻¹² pu, in 32-bit products
/// (the Cortex-M0 has no 64-bit multiply): what the dead-time signs need, whose band is
/// hundredths of a pu. Each current is taken to 2⁻¹³ within ±16 pu (below 2¹⁷; the overcurrent
/// trip is far below), each of `sc` to 2⁻¹³ (below 2¹³·1.001): α and β are dot products of
/// (d, q) with (±sin, cos), of length about 2¹³ ([`mid_frame`]'s length is off by parts in
/// 10⁴), so below 2¹⁷·√2·2¹³·1.001 < 2³¹ in Q.26: no wrap. The legs b and c take `(√3/2) β`
/// from β's Q.13 (below 2¹⁷·⁵) times √3/2 in Q13 (below 2¹³): below 2³¹ again, and
/// `α/2 ± (√3/2) β` below 2³¹ as the phases of a vector below 2³¹ in Q.26.
#[inline(always)]
fn phases_coarse(i: Dq, sc: SinCos) -> Abc {
    let current = |x: Pu| (x.to_bits() >> 11).clamp(-(1 << 17), (1 << 17) - 1);
    let unit = |x: Unit| x.to_bits() >> 17;
    let (d, q) = (current(i.d), current(i.q));
    let (s, c) = (unit(sc.sin), unit(sc.cos));
    // Q.13 · Q.13 = Q.26, to Pu's Q.24.
    let alpha = d.wrapping_mul(c).wrapping_sub(q.wrapping_mul(s));
    let beta = d.wrapping_mul(s).wrapping_add(q.wrapping_mul(c));
    let half_alpha = alpha >> 1;
    let beta_term = (beta >> 13).wrapping_mul(SQRT3_2_Q13);
    Abc {
        a: Pu::from_bits(alpha >> 2),
        b: Pu::from_bits(beta_term.wrapping_sub(half_alpha) >> 2),
        c: Pu::from_bits(beta_term.wrapping_add(half_alpha).wrapping_neg() >> 2),
    }
}

/// √3/2 in Q13 (rounded).
const SQRT3_2_Q13: i32 = 7_094;

#[cfg(test)]
mod tests {
    use super::phases_coarse;
    use crate::angle::Angle;
    use crate::drive::{Drive, DriveConfig, DriveInput, DriveOptions, StartupMode};
    use crate::fixtures::{inverter_b, motor_b};
    use crate::frames::{AlphaBeta, Dq, inverse_clarke, inverse_park};
    use crate::num::Pu;
    use crate::svpwm::BUS_TOLERANCE_SHIFT;

    /// A bus reading that moves by up to 2⁻⁹ of the first at every sample, as a converter's
    /// does, leaves the drive's duties bit for bit those of the steady reading (the control
    /// path and the task take the kept reading); a step beyond takes the new reading.
    #[test]
    fn a_bus_reading_moving_within_its_tolerance_leaves_the_duties() {
        let (m, inv) = (motor_b(), inverter_b());
        let options = DriveOptions {
            startup: Some(StartupMode::Known(Angle::ZERO)),
            ..DriveOptions::default()
        };
        let config = DriveConfig::from_params(&m, &inv, inv.pwm_hz, options)
            .unwrap_or_else(|e| panic!("{e}"));
        let (mut steady, mut moving) = (Drive::new(config), Drive::new(config));
        let vdc = Pu::from_num(1.732);
        let tol = vdc.to_bits() >> BUS_TOLERANCE_SHIFT;
        let (mut driven, mut differ) = (0, 0);
        for drive in [&mut steady, &mut moving] {
            drive.start();
            drive.set_speed_ref(Pu::from_num(0.3));
        }
        for k in 0..1100 {
            let theta = 0.02 * k as f64;
            let i_abc = inverse_clarke(AlphaBeta {
                alpha: Pu::from_num(0.3 * libm::cos(theta)),
                beta: Pu::from_num(0.3 * libm::sin(theta)),
            });
            // Steady while the drive takes its first bus terms (at the first window), then
            // within their tolerance, then 1 % up from step 800.
            let jitter = if k < 16 {
                0
            } else {
                [0, tol, -tol, tol / 2, -1, 3][k % 6]
            };
            let step = if k >= 800 { vdc.to_bits() / 100 } else { 0 };
            let reading = Pu::from_bits(vdc.to_bits() + jitter + step);
            let a = steady.step(&DriveInput { i_abc, vdc });
            let b = moving.step(&DriveInput {
                i_abc,
                vdc: reading,
            });
            let kept = moving.isr().inv_vdc.reading();
            if k < 800 {
                assert_eq!(a, b, "step {k}");
            } else if b.pwm_on {
                // Beyond the tolerance: the bus of the reading 1 % up, kept within its own.
                driven += 1;
                let off = (kept.to_bits() - reading.to_bits()).abs();
                assert!(
                    off <= 2 * tol && kept > vdc,
                    "step {k}: {kept} for {reading}"
                );
                differ += usize::from(a.duties != b.duties);
            }
            if k >= 16 && steady.isr().active() {
                assert_eq!(steady.isr().inv_vdc.reading(), vdc, "step {k}");
            }
        }
        // The synthetic current holds the drive's loops past step 1100 (every build's).
        assert!(driven == 300 && differ > 290, "{differ} of {driven}");
    }

    /// Against the exact rotation and inverse Clarke transform: each phase within 2⁻¹² pu and
    /// 2⁻¹² of the current's magnitude, for currents within ±15 pu at every angle.
    #[test]
    fn the_coarse_phases_are_the_exact_ones_to_2_12() {
        let mut worst = 0.0f64;
        for k in 0..720 {
            let sc = Angle::from_rad(k as f64 * core::f64::consts::TAU / 720.0).sin_cos();
            for (d, q) in [
                (1.4, 0.0),
                (0.0, -2.0),
                (-15.0, 15.0),
                (0.013, -0.007),
                (3.3, 1.1),
            ] {
                let i = Dq {
                    d: Pu::from_num(d),
                    q: Pu::from_num(q),
                };
                let (x, y) = (phases_coarse(i, sc), inverse_clarke(inverse_park(i, sc)));
                let bound = (1.0 + libm::hypot(d, q)) / 4096.0;
                for (u, v) in [(x.a, y.a), (x.b, y.b), (x.c, y.c)] {
                    worst = worst.max((u - v).to_num::<f64>().abs() / bound);
                }
            }
        }
        assert!(worst < 1.0, "{worst} of the bound");
    }
}
