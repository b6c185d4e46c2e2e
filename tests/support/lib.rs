//! Support code of the integration tests: independent float64 references of the models and
//! algorithms that the crates implement, and generators of test signals.

pub mod drive_ref;
pub mod observers;
pub mod reference;
pub mod signals;
pub mod trajectory;
