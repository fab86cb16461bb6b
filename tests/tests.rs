//! Integration tests compile to one binary (one link on a 2-core machine). Each module drives
//! the library or the real binary the way a user would.

mod calib_hdr;
mod calib_sphere;
mod calib_synth;
mod calib_white;
mod util;
