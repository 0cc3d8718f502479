//! In-process benchmarks: figures printed by `relief-server bench`, never asserted by tests.
//!
//! - [`build`]: building a store: seconds by phase, samples a second, peak memory.
//! - [`flight`]: what they share: the store, the path, the measured pixel error.
//! - [`lod`]: the vertex stream over the standard or stress path.
//! - [`tiles`]: the tile stream over the same paths, with patches, skirts or nothing.
//! - [`compare`]: every stream at the same measured error.
//! - [`formats`]: the standard formats' tiles over a whole terrain: bytes and making time.
//! - [`query`]: the query library: max-mip rays against brute force, heights, HAT/HOT, sight.
//! - [`sessions`]: many vertex-stream sessions on one core, interleaved as on a loaded server
//!   and one at a time.
//! - [`stats`]: medians and quantiles.
pub mod build;
pub mod compare;
pub mod flight;
pub mod formats;
pub mod lod;
pub mod query;
pub mod sessions;
pub mod stats;
pub mod tiles;

/// A store build's progress bar on stderr when `show`, hidden otherwise: its length is the
/// grid's `samples`, its message the phase, and it shows the rate in samples a second and the
/// time left.
pub fn build_progress_bar(show: bool, samples: u64) -> indicatif::ProgressBar {
    if !show {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(samples);
    let rate = |s: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
        let _ = write!(w, "{:.1} M samples/s", s.per_sec() / 1e6);
    };
    let style = indicatif::ProgressStyle::with_template(
        "{msg:>12} [{bar:30}] {percent:>3}% of {human_len} samples, {rate} ({eta} left)",
    )
    .map(|s| s.with_key("rate", rate))
    .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
    .progress_chars("=> ");
    bar.set_style(style);
    bar
}

/// A progress bar on stderr when `show`, hidden otherwise.
pub fn progress_bar(show: bool, len: u64, what: &str) -> indicatif::ProgressBar {
    if !show {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(len);
    let style =
        indicatif::ProgressStyle::with_template("{msg:>10} [{bar:40}] {pos}/{len} ({eta} left)")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> ");
    bar.set_style(style);
    bar.set_message(what.to_string());
    bar
}
