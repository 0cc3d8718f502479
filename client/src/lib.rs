//! `relief-client`: the Relief client.
//!
//! Today the client's cut mirror and fan builder live in `relief-proto` (`mirror`, `fan`), where
//! the server's benchmarks replay deltas with them too. The network session, the wgpu renderer
//! and the load generator arrive with the streaming-server, client and load-testing issues.
