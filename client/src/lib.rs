//! `relief-client`: the Relief client library and command line.
//!
//! - [`session`]: a streaming session: hello, poses, deltas applied to a mirror of the cut and
//!   its fan mesh, digests checked, acknowledgements, and reconnect-and-resume on its own.
//! - [`http`]: a small HTTP/1.1 client for the server's HTTP endpoints.
//! - [`server_url`]: `--server` parsed once: the stream URL and the HTTP base, and errors in
//!   words.
//! - [`chaos`]: `relief-client chaos`: the replica drill (sessions and queries through a load
//!   balancer while replicas are killed or restarted).
//! - [`flight`]: one session flown along camera poses, recording latency and bytes over time.
//! - [`fly`]: `relief-client fly`: one flight along a camera path, with its figures.
//! - [`load`]: `relief-client load`: many sessions at once, with reports, plots and sweeps.
//! - [`query`]: a query session: batches of terrain queries, pipelined, answered in order.
//! - [`plot`]: PNG charts for load reports, drawn with plotters (embedded font, log axes, markers,
//!   notes).
//! - [`render`]: the wgpu renderer: GPU buffers that follow the mirror, the geomorph and terrain
//!   passes, offscreen shots and the renderer's benchmark.
//! - [`viewer`]: `relief-client view`: a window with a fly camera over the streamed terrain.
//!
//! The cut mirror, the fan builder and the geomorph rule themselves live in `relief-proto`
//! (`mirror`, `mesh`), where the server's benchmarks replay deltas with them too.
pub mod chaos;
pub mod flight;
pub mod fly;
pub mod http;
pub mod load;
pub mod plot;
pub mod query;
pub mod render;
pub mod server_url;
pub mod session;
pub mod viewer;

pub use session::{Session, SessionConfig};
