//! Where the bench studies' notes go: stderr, each step with the time since the study started.
//! Its own file so that the bench commands and `bench.rs`, which lists them, do not import
//! each other.

/// Prints a study's notes on stderr: steps with the time since the study started.
pub fn printer() -> impl FnMut(brdf_rig::eval::bench::Note<'_>) {
    let start = std::time::Instant::now();
    move |note| match note {
        brdf_rig::eval::bench::Note::Step(line) => {
            errln!("[{:7.1} s] {line}", start.elapsed().as_secs_f64())
        }
        brdf_rig::eval::bench::Note::Detail(text) => errln!("{text}"),
    }
}
