//! Integration tests compile to one binary (one link on a 2-core machine). Each module drives
//! the library or the real binary the way a user would.

mod firmware;
mod firmware_flash;
mod firmware_qemu;
mod util;
