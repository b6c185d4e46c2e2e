//! One module per subcommand of `pmsm`.

pub mod fault_dump;
pub mod identify;
pub mod ipd;
pub mod observe;
pub mod plant;
pub mod simulate;
