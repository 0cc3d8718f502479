//! `relief-client`: the Relief client library and command line.
//!
//! - [`session`]: a streaming session: hello, poses, deltas applied to a mirror of the cut and
//!   its fan mesh, digests checked, acknowledgements, and reconnect-and-resume on its own.
//! - [`http`]: a small HTTP/1.1 client for the server's HTTP endpoints.
//! - [`flight`]: one session flown along camera poses, recording latency and bytes over time.
//! - [`fly`]: `relief-client fly`: one flight along a camera path, with its figures.
//!
//! The cut mirror and the fan builder themselves live in `relief-proto` (`mirror`, `mesh`),
//! where the server's benchmarks replay deltas with them too. The wgpu renderer and the load
//! generator arrive with their own issues.
pub mod flight;
pub mod fly;
pub mod http;
pub mod session;

pub use session::{Session, SessionConfig};
