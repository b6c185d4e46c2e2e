//! One module per subcommand of `pmsm`.

pub mod observe;
pub mod plant;
pub mod simulate;
