//! How the project runs its HTML pages (the report, the lab page) in a headless Chromium: where
//! Debian installs it and the flags that keep it offline and quiet. Shared by the report's test
//! and `bench capture --page`. Pure: it names things, it runs nothing.

use std::path::PathBuf;

/// Where Debian's `chromium` package puts the browser (scripts/setup.sh installs it).
pub const CHROMIUM_PATHS: [&str; 2] = ["/usr/bin/chromium", "/usr/bin/chromium-browser"];

/// Headless, no sandbox (CI containers), no GPU, and no network of its own: no QUIC, no
/// background fetches, no component updates, no sync.
pub const HEADLESS_FLAGS: [&str; 8] = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
];

/// The first of [`CHROMIUM_PATHS`] that is a file.
pub fn chromium() -> Option<PathBuf> {
    CHROMIUM_PATHS
        .iter()
        .map(PathBuf::from)
        .find(|p| p.is_file())
}
