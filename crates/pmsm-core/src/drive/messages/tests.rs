use super::*;
use crate::drive::handoff::Mailbox;

/// Written and read back through a mailbox of its size.
fn roundtrip<M: Message<W> + Copy + PartialEq + core::fmt::Debug, const W: usize>(m: M) {
    let b = Mailbox::<W>::new();
    b.publish(&m);
    assert_eq!(b.read::<M>().1, m);
}

/// Each message fills its words exactly: one more word would be dropped, one fewer left
/// unused.
#[test]
fn every_message_fills_its_words() {
    fn filled<const N: usize>(write: impl Fn(&mut Packer<N>)) -> usize {
        let words = [const { core::sync::atomic::AtomicU32::new(0) }; N];
        let mut w = Packer::new(&words);
        write(&mut w);
        w.len()
    }
    let status = Status::Tripped(Fault::Handover(Angle(1), Pu::ZERO));
    assert_eq!(filled::<16>(|w| status.write(w)), TAGGED_WORDS);
    assert_eq!(filled::<16>(|w| Status::Run.write(w)), TAGGED_WORDS);
    assert_eq!(
        filled::<16>(|w| Mode::Fault(Fault::Stall).write(w)),
        TAGGED_WORDS
    );
    assert_eq!(filled::<16>(|w| Mode::Align.write(w)), TAGGED_WORDS);
    let model = ModelUpdate {
        mras: None,
        psi: Pu::ONE,
        deadtime: (1, 2),
    };
    roundtrip(model);
}

#[test]
fn every_message_reads_back_what_was_written() {
    let faults = [
        Fault::OverCurrent(Pu::from_bits(-7)),
        Fault::BusUnderVoltage(Pu::from_bits(3)),
        Fault::BusOverVoltage(Pu::from_bits(1 << 30)),
        Fault::InitialPosition(IpdFault::OverCurrent(Pu::from_bits(5))),
        Fault::InitialPosition(IpdFault::NoCurrent(Pu::from_bits(6))),
        Fault::InitialPosition(IpdFault::LowSaliency {
            modulation: Pu::from_bits(1),
            sum: Pu::from_bits(2),
        }),
        Fault::InitialPosition(IpdFault::NoPolarity {
            along: Pu::from_bits(-1),
            opposite: Pu::from_bits(-2),
        }),
        Fault::InitialPosition(IpdFault::BusLow),
        Fault::Handover(Angle(-123), Pu::from_bits(45)),
        Fault::CurrentSensor(None),
        Fault::CurrentSensor(Some(2)),
        Fault::PhaseLoss(1),
        Fault::Stall,
        Fault::LossOfLock,
        Fault::Overrun,
        Fault::Overspeed(Pu::from_bits(99)),
        Fault::DrivenBackwards,
    ];
    let statuses = [
        Status::Off,
        Status::Ipd,
        Status::IpdDone(Angle(77)),
        Status::Align,
        Status::Aligned(Angle(-9)),
        Status::Calibrate,
        Status::OpenLoop { at_handover: true },
        Status::OpenLoop { at_handover: false },
        Status::Run,
        Status::IpdNoPolarity(IpdFault::NoPolarity {
            along: Pu::from_bits(11),
            opposite: Pu::from_bits(-12),
        }),
    ]
    .into_iter()
    .chain(faults.iter().map(|&f| Status::Tripped(f)));
    for (k, status) in statuses.enumerate() {
        let k = k as i32;
        roundtrip::<_, WINDOW_WORDS>(Window {
            epoch: 3,
            trips: 4,
            status,
            theta_est: Angle(k),
            omega: Pu::from_bits(-k),
            omega_mean: Pu::from_bits(2 * k),
            health: Pu::from_bits(3 * k),
            theta: Angle(4 * k),
            omega_frame: Pu::from_bits(5 * k),
            reverse: k % 2 == 0,
            reversal: k % 3 == 0,
            i_dq: Dq {
                d: Pu::from_bits(6),
                q: Pu::from_bits(7),
            },
            i_ref: Dq {
                d: Pu::from_bits(8),
                q: Pu::from_bits(9),
            },
            v: AlphaBeta {
                alpha: Pu::from_bits(10),
                beta: Pu::from_bits(11),
            },
            v_est: AlphaBeta {
                alpha: Pu::from_bits(12),
                beta: Pu::from_bits(13),
            },
            v_dt: AlphaBeta {
                alpha: Pu::from_bits(-12),
                beta: Pu::from_bits(-13),
            },
            saturated: true,
            injecting: true,
            i_abc: Abc {
                a: Pu::from_bits(14),
                b: Pu::from_bits(15),
                c: Pu::from_bits(16),
            },
            vdc: Pu::from_bits(17),
            power: [18, 19, u32::MAX],
        });
    }
    let modes = [
        Mode::Off,
        Mode::Ipd,
        Mode::Align,
        Mode::Calibrate {
            theta: Angle(5),
            reset: true,
        },
        Mode::OpenLoop {
            theta: Angle(-5),
            reverse: true,
        },
        Mode::Reverse {
            omega: Pu::from_bits(-3),
            iq: Pu::from_bits(4),
            reverse: false,
        },
        Mode::Run { from: None },
        Mode::Run {
            from: Some(Angle(0)),
        },
    ]
    .into_iter()
    .chain(faults.iter().map(|&f| Mode::Fault(f)));
    for (k, mode) in modes.enumerate() {
        roundtrip::<_, COMMAND_WORDS>(Command {
            window: k as u32,
            epoch: 2 * k as u32,
            mode,
            i_ref: Dq {
                d: Pu::from_bits(-1),
                q: Pu::from_bits(1),
            },
            measured_signs: k % 2 == 1,
            hold: k % 3 == 1,
            model: 7,
            health: Pu::from_bits(-8),
            frame_shift: Angle(-9),
        });
    }
}
