//! `relief-server`: serve terrains, preprocess DEMs into stores, benchmark the LOD engine.
//! Thin: everything is in [`relief_server::cli`].

fn main() -> std::process::ExitCode {
    relief_server::cli::main()
}
