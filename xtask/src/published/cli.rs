//! The arguments of `cargo xtask family --published` and `cargo xtask family --widened`.

use anyhow::{Result, bail};

/// Motors of the widened family per seed of `cargo xtask family --widened` without `N`.
pub const WIDENED_MOTORS: usize = 20;
/// Its seeds: the documented table's, and the CI's sample.
pub const WIDENED_SEEDS: (u64, u64) = (1, 10);

/// `cargo xtask family [N] --widened [--seeds A-B] [--check] [--write]`: the widened family
/// (`published/classes.rs`), `N` motors a seed.
pub fn widened_main(args: &[String]) -> Result<()> {
    let (mut n, mut seeds) = (WIDENED_MOTORS, WIDENED_SEEDS);
    let (mut check_bars, mut write) = (false, false);
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--widened" => {}
            "--seeds" => match it.next().and_then(|s| crate::family_seeds::parse_seeds(s)) {
                Some(s) => seeds = (*s.start(), *s.end()),
                None => bail!("--seeds needs A-B, two seeds with A ≤ B"),
            },
            "--seed" => match it.next().and_then(|s| s.parse().ok()) {
                Some(s) => seeds = (s, s),
                None => bail!("--seed needs a number"),
            },
            "--check" => check_bars = true,
            "--write" => write = true,
            x => match x.parse() {
                Ok(k) => n = k,
                Err(_) => bail!(
                    "usage: cargo xtask family [N] --widened [--seeds A-B] [--check] [--write]"
                ),
            },
        }
    }
    let (table, missed) = super::widened_section(n, seeds)?;
    let section = format!("{}\n\n{table}\n", super::WIDENED_TITLE);
    print!("{section}");
    if write {
        crate::family::write_performance(|doc| {
            crate::family::put_section(doc, super::WIDENED_TITLE, &section)
        })?;
    }
    if check_bars && !missed.is_empty() {
        bail!("the widened family misses its bars:\n{}", missed.join("\n"));
    }
    Ok(())
}

/// `cargo xtask family --published [--held-out | --file PATH] [--check] [--write]`: the
/// published motors, or those of a file in their format (`published.rs`); `--write` records the development set's table in docs/PERFORMANCE.md.
pub fn published_main(args: &[String]) -> Result<()> {
    let (mut file, mut check_bars, mut write) = (super::MOTORS, false, false);
    let mut control = Vec::new();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--published" => {}
            "--control" => match it.next().and_then(|s| s.split_once('=')) {
                Some((k, v)) if !k.trim().is_empty() && !v.trim().is_empty() => {
                    control.push(format!("{} = {}", k.trim(), v.trim()));
                }
                _ => bail!("--control needs KEY=VALUE (a [control] key of the scenario file)"),
            },
            "--held-out" => file = super::HELD_OUT,
            "--file" => match it.next() {
                Some(f) => file = f,
                None => bail!("--file needs the path of a motors file"),
            },
            "--check" => check_bars = true,
            "--write" => write = true,
            _ => bail!(
                "usage: cargo xtask family --published [--held-out | --file PATH] [--control KEY=VALUE]... [--check] [--write]"
            ),
        }
    }
    if write && (file != super::MOTORS || !control.is_empty()) {
        bail!(
            "--write records the development set with the defaults: leave out --held-out, --file and --control"
        );
    }
    let (table, missed) = super::section(file, &control)?;
    let section = format!("{}\n\n{table}\n", super::SECTION_TITLE);
    print!("{section}");
    if write {
        crate::family::write_performance(|doc| {
            crate::family::put_section(doc, super::SECTION_TITLE, &section)
        })?;
    }
    if check_bars && !missed.is_empty() {
        bail!(
            "the published motors miss their bars:\n{}",
            missed.join("\n")
        );
    }
    Ok(())
}
