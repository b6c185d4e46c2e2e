//! Library side of the host tool `pmsm`: file formats, plotting and the subcommands, so that
//! tests and other tools can call them without a process.

pub mod commands;
pub mod csv_io;
pub mod motor_file;
pub mod out;
pub mod plot;
pub mod scenario_extras;
pub mod scenario_file;
