//! What `cargo xtask isr-profile` reads of the image and of QEMU's execution log: the
//! addresses it needs from the ELF's symbols, the functions inlined at an address
//! (`addr2line`), the address of a log line, and the call sites a trace is inside.

use anyhow::{Context, Result, bail};
use std::path::Path;
use std::process::Command;

/// The addresses the trace needs, from the ELF's symbols.
pub(super) struct Symbols {
    /// The core's code, from its first function to the end of its last.
    pub(super) core: (u32, u32),
    pub(super) meter: (u32, u32),
    pub(super) begin: u32,
    pub(super) end: u32,
    pub(super) step: u32,
    /// The addresses of the end of a task period (`DriveIsr::end_period`, its function or,
    /// where it is inlined (ARMv6-M), the step's addresses inlined from it): a step that runs
    /// one publishes the window.
    pub(super) end_period: std::collections::HashSet<u32>,
    /// The addresses of a mode change (`DriveIsr::enter`, inlined into the command's take):
    /// a step that runs one enters a mode, which the benchmark's counted steps never do.
    pub(super) enter: std::collections::HashSet<u32>,
    /// The estimators' updates: a call that runs one is in the closed loop.
    pub(super) updates: Vec<(u32, u32)>,
    /// Every function's first address: a jump there is a call.
    pub(super) entries: std::collections::HashSet<u32>,
}

pub(super) fn symbols(elf: &Path) -> Result<Symbols> {
    let out = Command::new("arm-none-eabi-nm")
        .arg("-S")
        .arg(elf)
        .output()
        .context("arm-none-eabi-nm (apt-get install binutils-arm-none-eabi)")?;
    let text = String::from_utf8_lossy(&out.stdout);
    let mut core = (u32::MAX, 0);
    let (mut meter, mut begin, mut end, mut step) = (None, None, None, None);
    let mut end_period = None;
    let mut take = None;
    let mut updates = Vec::new();
    let mut entries = std::collections::HashSet::new();
    for line in text.lines() {
        let f: Vec<&str> = line.split_whitespace().collect();
        let [addr, size, kind, name] = f[..] else {
            continue;
        };
        if !kind.eq_ignore_ascii_case("t") {
            continue;
        }
        let (a, n) = (
            u32::from_str_radix(addr, 16)?,
            u32::from_str_radix(size, 16)?,
        );
        entries.insert(a);
        if name.contains("pmsm_core") {
            core = (core.0.min(a), core.1.max(a + n));
        }
        if name.contains("5meter5ticks") {
            meter = Some((a, a + n));
        }
        if name.contains("13profile_begin") {
            begin = Some(a);
        }
        if name.contains("11profile_end") {
            end = Some(a);
        }
        if name.contains("8DriveIsr4step") {
            step = Some((a, a + n));
        }
        if name.contains("DriveIsr$GT$4take") {
            take = Some((a, a + n));
        }
        if name.contains("10end_period") {
            end_period = Some((a, a + n));
        }
        if name.contains("Estimator$GT$6update") {
            updates.push((a, a + n));
        }
    }
    let need = |x: Option<u32>, what: &str| x.with_context(|| format!("no symbol for {what}"));
    let step = step.context("no symbol for DriveIsr::step")?;
    // Out of line, its function's addresses; inlined, the step's that addr2line names it at.
    let end_period: std::collections::HashSet<u32> = match end_period {
        Some((a, b)) => (a..b).collect(),
        None => chains(elf, (step.0..step.1).step_by(2))?
            .into_iter()
            .filter(|(_, chain)| chain.iter().any(|f| f.name.contains("end_period")))
            .map(|(pc, _)| pc)
            .collect(),
    };
    if end_period.is_empty() {
        bail!("no code of DriveIsr::end_period in {}", elf.display());
    }
    let take = take.context("no symbol for DriveIsr::take")?;
    let enter: std::collections::HashSet<u32> = chains(elf, (take.0..take.1).step_by(2))?
        .into_iter()
        .filter(|(_, chain)| chain.iter().any(|f| f.name.contains("DriveIsr>::enter")))
        .map(|(pc, _)| pc)
        .collect();
    Ok(Symbols {
        core,
        meter: meter.context("no symbol for the meter's ticks")?,
        begin: need(begin, "profile_begin")?,
        end: need(end, "profile_end")?,
        step: step.0,
        end_period,
        enter,
        updates,
        entries,
    })
}

/// The call sites not yet returned from, innermost last.
#[derive(Default)]
pub(super) struct Sites(Vec<u32>);

impl Sites {
    /// Follows the executed address `pc` after `last`; `entry`: `pc` is a function's first
    /// address. A return lands after its call site (`bl`, 4 bytes, or `blx`, 2) and returns
    /// from every call made since (a tail call's `b` never sees its own return); a jump to a
    /// function's first address is a call from `last`.
    pub(super) fn follow(&mut self, pc: u32, last: u32, entry: bool) {
        if let Some(k) = self
            .0
            .iter()
            .rposition(|&s| pc == s.wrapping_add(4) || pc == s.wrapping_add(2))
        {
            self.0.truncate(k);
        } else if entry && self.0.len() < 64 {
            self.0.push(last);
        }
    }

    pub(super) fn innermost(&self) -> Option<u32> {
        self.0.last().copied()
    }
}

/// The address of a line of QEMU's execution log, `Trace 0: 0x… [flags/pc/…] name`.
pub(super) fn trace_pc(line: &[u8]) -> Option<u32> {
    if !line.starts_with(b"Trace") {
        return None;
    }
    let open = line.iter().position(|&c| c == b'[')?;
    let mut fields = line[open + 1..].split(|&c| c == b'/');
    fields.next()?;
    u32::from_str_radix(std::str::from_utf8(fields.next()?).ok()?, 16).ok()
}

/// The functions inlined at each address, innermost first (`addr2line -a -f -i -C`).
pub(super) fn chains(elf: &Path, pcs: impl Iterator<Item = u32>) -> Result<Vec<(u32, Vec<Frame>)>> {
    let pcs: Vec<String> = pcs.map(|p| format!("{p:#x}")).collect();
    let out = Command::new("arm-none-eabi-addr2line")
        .args(["-a", "-f", "-i", "-C", "-e"])
        .arg(elf)
        .args(&pcs)
        .output()
        .context("arm-none-eabi-addr2line")?;
    let text = String::from_utf8_lossy(&out.stdout);
    let mut chains: Vec<(u32, Vec<Frame>)> = Vec::new();
    let mut lines = text.lines();
    while let Some(line) = lines.next() {
        if let Some(hex) = line.strip_prefix("0x") {
            chains.push((u32::from_str_radix(hex, 16)?, Vec::new()));
        } else if let Some((_, chain)) = chains.last_mut() {
            // A function's name, then its file and line.
            let at = lines.next().unwrap_or("");
            let at = at.rsplit('/').next().unwrap_or(at);
            chain.push(Frame {
                name: line.to_owned(),
                at: at.split(' ').next().unwrap_or(at).to_owned(),
            });
        }
    }
    Ok(chains)
}

/// A function inlined at an address, and the file and line in it.
pub(super) struct Frame {
    pub(super) name: String,
    pub(super) at: String,
}
