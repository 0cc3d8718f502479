//! `relief-client`: the Relief client library and command line.
//!
//! - [`session`]: a streaming session: hello, poses, deltas applied to a mirror of the cut and
//!   its fan mesh, digests checked, acknowledgements, and reconnect-and-resume on its own.
//! - [`http`]: a small HTTP/1.1 client for the server's HTTP endpoints.
//! - [`flight`]: one session flown along camera poses, recording latency and bytes over time.
//! - [`fly`]: `relief-client fly`: one flight along a camera path, with its figures.
//! - [`load`]: `relief-client load`: many sessions at once, with reports, plots and sweeps.
//! - [`plot`]: PNG line charts (embedded bitmap font, nice ticks, legend) for load reports.
//!
//! The cut mirror and the fan builder themselves live in `relief-proto` (`mirror`, `mesh`),
//! where the server's benchmarks replay deltas with them too. The wgpu renderer arrives with its
//! own issue.
pub mod flight;
pub mod fly;
pub mod http;
pub mod load;
pub mod plot;
pub mod session;

pub use session::{Session, SessionConfig};
