//! The lock-free handoff between the drive's two rates (docs/drive.md, "two rates").
//!
//! Each direction is a [`Mailbox`]: one writer, one reader, the latest message wins. Messages
//! are numbered 1, 2, …; message `n` is stored as 32-bit words in slot `n mod 2`. A counter
//! says what the writer does: `2n` once message `n` is published, `2n + 1` while it writes
//! message `n + 1` into the other slot. The reader loads the counter, reads the message from
//! the slot of the last one published (which the writer is not writing), and loads the
//! counter again: the message is whole unless the writer has since begun message `n + 2`, in
//! the same slot (the counter then reads `2n + 3` or more), and the reader reads again. Only
//! 32-bit atomic loads and stores: no compare-and-swap, which ARMv6-M (Cortex-M0/M0+) does
//! not have, and no lock, so the interrupt never waits. A message's fields go straight
//! between the slot and the value ([`Packer`], [`Unpacker`]), with no array of words between.
//!
//! | direction | writer | reader | how often |
//! |---|---|---|---|
//! | window | interrupt, at the end of each task period | task | every [`TASK_PERIOD`] samples |
//! | command | task | interrupt, at its first step after the task published | once per task step |
//! | model | task | interrupt, when a command says it changed | when the tracker or the learner writes |
//!
//! The interrupt is never preempted by the task, so it reads the task's mailboxes in one pass
//! ([`Mailbox::read_now`]); the task, which the interrupt preempts, reads with the check
//! ([`Mailbox::read`]).
//!
//! [`TASK_PERIOD`]: super::TASK_PERIOD

use core::sync::atomic::{AtomicU32, Ordering, fence};

/// A value that travels as `W` 32-bit words.
pub(crate) trait Message<const W: usize>: Sized {
    /// Stores the message's words in `slot`, in order (through a [`Packer`] made here, so
    /// that each word's place is known when compiled).
    fn pack(&self, slot: &[AtomicU32; W]);
    /// The message of [`Message::pack`]'s words in `slot` (through an [`Unpacker`]).
    fn unpack(slot: &[AtomicU32; W]) -> Self;
}

/// Stores a message's fields in order straight into a mailbox's slot: no copy of the message
/// as an array of words first (the window is 33 words, and the interrupt publishes it).
pub(crate) struct Packer<'a, const N: usize> {
    words: &'a [AtomicU32; N],
    at: usize,
}

impl<'a, const N: usize> Packer<'a, N> {
    /// From the first word of `words`.
    #[inline(always)]
    pub fn new(words: &'a [AtomicU32; N]) -> Self {
        Self { words, at: 0 }
    }

    /// The next word (dropped past the end, which a message of `N` words never reaches).
    #[inline(always)]
    pub fn u32(&mut self, x: u32) {
        if let Some(w) = self.words.get(self.at) {
            w.store(x, Ordering::Relaxed);
        }
        self.at += 1;
    }

    /// A signed word.
    #[inline(always)]
    pub fn i32(&mut self, x: i32) {
        self.u32(x as u32);
    }

    /// A flag, as a word.
    #[inline(always)]
    pub fn bool(&mut self, x: bool) {
        self.u32(u32::from(x));
    }

    /// Words filled so far.
    #[cfg(test)]
    pub fn len(&self) -> usize {
        self.at
    }
}

/// Loads a message's words in order straight from a mailbox's slot.
pub(crate) struct Unpacker<'a, const N: usize> {
    words: &'a [AtomicU32; N],
    at: usize,
}

impl<'a, const N: usize> Unpacker<'a, N> {
    /// From the first word of `words`.
    #[inline(always)]
    pub fn new(words: &'a [AtomicU32; N]) -> Self {
        Self { words, at: 0 }
    }

    /// The next word (zero past the end).
    #[inline(always)]
    pub fn u32(&mut self) -> u32 {
        let x = self
            .words
            .get(self.at)
            .map_or(0, |w| w.load(Ordering::Relaxed));
        self.at += 1;
        x
    }

    /// A signed word.
    #[inline(always)]
    pub fn i32(&mut self) -> i32 {
        self.u32() as i32
    }

    /// A flag.
    #[inline(always)]
    pub fn bool(&mut self) -> bool {
        self.u32() != 0
    }
}

/// One writer's latest message of at most `W` words for one reader.
pub(crate) struct Mailbox<const W: usize> {
    /// `2n` once message `n` is published (0: none yet), `2n + 1` while message `n + 1` is
    /// written; message `n` is in slot `n & 1`.
    count: AtomicU32,
    slots: [[AtomicU32; W]; 2],
}

impl<const W: usize> Mailbox<W> {
    /// Empty: [`Mailbox::read`] gives the message of all-zero words, numbered 0.
    pub const fn new() -> Self {
        Self {
            count: AtomicU32::new(0),
            slots: [const { [const { AtomicU32::new(0) }; W] }; 2],
        }
    }

    fn slot(&self, n: u32) -> &[AtomicU32; W] {
        let [even, odd] = &self.slots;
        if n & 1 == 0 { even } else { odd }
    }

    /// Publishes `m` (the one writer); returns its number.
    #[inline(always)]
    pub fn publish<M: Message<W>>(&self, m: &M) -> u32 {
        self.publish_packed(|slot| m.pack(slot))
    }

    /// Opens the next slot, has `pack` fill it with a message's words, and publishes it: the
    /// words go straight from where `pack` reads them into the slot, with no message built
    /// first (the interrupt's window, [`super::isr`]).
    #[inline(always)]
    pub fn publish_packed(&self, pack: impl FnOnce(&[AtomicU32; W])) -> u32 {
        let count = self.count.load(Ordering::Relaxed) & !1;
        let n = (count >> 1).wrapping_add(1);
        // Writing: a reader that sees this and then the slot's words retries.
        self.count.store(count | 1, Ordering::Relaxed);
        fence(Ordering::Release);
        pack(self.slot(n));
        // The words before the number that names them.
        fence(Ordering::Release);
        self.count.store(n << 1, Ordering::Relaxed);
        n
    }

    /// The number of the latest message published (a message being written is not).
    #[inline(always)]
    pub fn published(&self) -> u32 {
        self.count.load(Ordering::Relaxed) >> 1
    }

    /// The latest message and its number, for a reader that the writer cannot preempt (the
    /// interrupt reading the task's mailboxes): one pass (the message being written, if the
    /// reader preempted its writer, is not the one read).
    #[inline(always)]
    pub fn read_now<M: Message<W>>(&self) -> (u32, M) {
        let n = self.count.load(Ordering::Relaxed) >> 1;
        fence(Ordering::Acquire);
        (n, M::unpack(self.slot(n)))
    }

    /// The latest message and its number, for a reader that the writer may preempt (the task
    /// reading the interrupt's window): read again if the writer began to overwrite it. A
    /// message read while overwritten is unpacked and dropped: unpacking takes any words (an
    /// unknown tag reads as `Off`), so it cannot fail.
    pub fn read<M: Message<W>>(&self) -> (u32, M) {
        loop {
            let (n, m) = self.read_now();
            fence(Ordering::Acquire);
            // Message n + 2, in the same slot, begins at 2n + 3.
            if self.count.load(Ordering::Relaxed).wrapping_sub(n << 1) < 3 {
                return (n, m);
            }
        }
    }

    /// A copy of the mailbox's words (a drive cloned with its handoff).
    fn snapshot(&self) -> Self {
        let copy = Self::new();
        copy.count
            .store(self.count.load(Ordering::Relaxed), Ordering::Relaxed);
        for (to, from) in copy.slots.iter().zip(&self.slots) {
            for (t, f) in to.iter().zip(from) {
                t.store(f.load(Ordering::Relaxed), Ordering::Relaxed);
            }
        }
        copy
    }
}

/// Words of the interrupt's window ([`super::messages::Window`]).
pub(crate) const WINDOW_WORDS: usize = super::messages::WINDOW_WORDS;
/// Words of the task's command ([`super::messages::Command`]).
pub(crate) const COMMAND_WORDS: usize = super::messages::COMMAND_WORDS;
/// Words of a model update ([`super::messages::ModelUpdate`]).
pub(crate) const MODEL_WORDS: usize = super::messages::MODEL_WORDS;

/// What the two halves of a drive share: three mailboxes, no lock. A firmware keeps one in a
/// `static` (`Handoff::new` is `const`) and gives a reference to both of its contexts; the
/// host's [`super::Drive`] owns one.
pub struct Handoff {
    pub(crate) window: Mailbox<WINDOW_WORDS>,
    pub(crate) command: Mailbox<COMMAND_WORDS>,
    pub(crate) model: Mailbox<MODEL_WORDS>,
}

impl Handoff {
    /// Empty mailboxes: the interrupt reads the command "off" until the task publishes.
    pub const fn new() -> Self {
        Self {
            window: Mailbox::new(),
            command: Mailbox::new(),
            model: Mailbox::new(),
        }
    }
}

impl Default for Handoff {
    fn default() -> Self {
        Self::new()
    }
}

impl Clone for Handoff {
    fn clone(&self) -> Self {
        Self {
            window: self.window.snapshot(),
            command: self.command.snapshot(),
            model: self.model.snapshot(),
        }
    }
}

impl core::fmt::Debug for Handoff {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Handoff")
            .field("window", &self.window.count.load(Ordering::Relaxed))
            .field("command", &self.command.count.load(Ordering::Relaxed))
            .field("model", &self.model.count.load(Ordering::Relaxed))
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    struct Pair(u32, i32);

    impl Message<2> for Pair {
        fn pack(&self, slot: &[AtomicU32; 2]) {
            let w = &mut Packer::new(slot);
            w.u32(self.0);
            w.i32(self.1);
        }
        fn unpack(slot: &[AtomicU32; 2]) -> Self {
            let r = &mut Unpacker::new(slot);
            Pair(r.u32(), r.i32())
        }
    }

    #[test]
    fn the_latest_message_wins_and_is_numbered() {
        let m = Mailbox::<2>::new();
        assert_eq!(m.read::<Pair>(), (0, Pair(0, 0)));
        for k in 1..10u32 {
            assert_eq!(m.publish(&Pair(k, -(k as i32))), k);
            assert_eq!(m.read_now::<Pair>(), (k, Pair(k, -(k as i32))));
            assert_eq!(m.read::<Pair>(), (k, Pair(k, -(k as i32))));
        }
    }

    /// A writer in another thread publishing at irregular, short intervals: every message read
    /// is one that was written whole (its two words agree), and the numbers never go back.
    #[test]
    fn a_preempted_reader_never_sees_a_torn_message() {
        extern crate std;
        let m = std::sync::Arc::new(Mailbox::<2>::new());
        let go = std::sync::Arc::new(std::sync::Barrier::new(2));
        let writer = {
            let (m, go) = (m.clone(), go.clone());
            std::thread::spawn(move || {
                go.wait();
                for k in 1..=200_000u32 {
                    m.publish(&Pair(k, k as i32 ^ 0x5a5a_5a5a));
                    // As an interrupt publishes: with time between the messages.
                    for _ in 0..k % 64 {
                        core::hint::spin_loop();
                    }
                }
            })
        };
        let mut last = 0;
        let mut seen = 0u32;
        go.wait();
        while last < 200_000 {
            let (seq, Pair(a, b)) = m.read::<Pair>();
            assert!(seq >= last, "{seq} after {last}");
            if seq > 0 {
                assert_eq!(b, a as i32 ^ 0x5a5a_5a5a, "torn: {a} {b}");
                assert_eq!(seq, a);
            }
            if seq != last {
                seen += 1;
            }
            last = seq;
        }
        writer.join().unwrap();
        assert!(seen > 1, "{seen}");
    }
}
