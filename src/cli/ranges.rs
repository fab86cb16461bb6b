//! The range-checked number parsers every command uses, from the library (`brdf_rig::ranges`),
//! where the lab page's request checks (`brdf-rig serve`) use the same ranges.

pub use brdf_rig::ranges::*;
