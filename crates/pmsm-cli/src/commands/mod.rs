//! One module per subcommand of `pmsm`.

pub mod plant;
