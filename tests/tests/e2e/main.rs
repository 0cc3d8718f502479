//! The end-to-end tests of Relief, one module a subject, in one test binary so that the
//! workspace links it once (each file of `tests/tests/` would be a binary of its own, linked
//! against the server, the client, wgpu, axum and tokio). Run one subject with a filter:
//! `cargo test --release -p relief-tests --test e2e -- serve_http::`.

mod bench_lod;
mod browser_formats;
mod browser_page;
mod cog_input;
mod deploy;
mod hostile_frames;
mod hostile_http;
mod hostile_load;
mod hostile_messages;
mod hostile_requests;
mod hostile_resume;
mod hostile_store;
mod load_run;
mod raycast_shot;
mod render_gpu;
mod render_tiles;
mod scale_out;
mod serve_formats;
mod serve_http;
mod serve_process;
mod serve_query;
mod serve_sessions;
mod serve_tiles;
mod soak;
