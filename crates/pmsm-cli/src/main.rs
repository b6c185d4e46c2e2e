//! `pmsm`: the host tool of the sensorless PMSM drive library.

use clap::error::ErrorKind;
use clap::{Parser, Subcommand};
use pmsm_cli::commands;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "pmsm",
    version,
    about = "Sensorless PMSM drive: plant model, observers, simulation"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Integrate the motor model under a voltage sequence (CSV in, state CSV out).
    Plant(commands::plant::Args),
    /// Run a fixed-point estimator (NLO, AO, MRAS) on sampled voltages and currents.
    Observe(commands::observe::Args),
    /// Run the fixed-point sensorless drive against the plant on a scenario file.
    Simulate(commands::simulate::Args),
    /// Detect the initial rotor position against the plant, at one angle or a sweep.
    Ipd(commands::ipd::Args),
    /// Identify R, L_d, L_q, ψ, J and B against the plant of a true motor file.
    Identify(commands::identify::Args),
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) => {
            e.exit()
        }
        Err(e) => {
            // One line, like every other error of `pmsm`; `--help` has the rest.
            let text = e.render().to_string();
            let message: Vec<&str> = text
                .lines()
                .map(str::trim)
                .take_while(|l| !l.is_empty() && !l.starts_with("Usage:"))
                .collect();
            eprintln!("{} (see `pmsm --help`)", message.join(" "));
            return ExitCode::from(2);
        }
    };
    let result = match cli.command {
        Command::Plant(args) => commands::plant::run(&args),
        Command::Observe(args) => commands::observe::run(&args),
        Command::Simulate(args) => commands::simulate::run(&args),
        Command::Ipd(args) => commands::ipd::run(&args),
        Command::Identify(args) => commands::identify::run(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // One line: the context chain joined by ": ".
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
