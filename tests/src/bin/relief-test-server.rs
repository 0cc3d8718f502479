//! The `relief-server` program under another name, so that end-to-end tests in this package can
//! run it as a child process (Cargo hands a package's tests only its own binaries' paths).

fn main() -> std::process::ExitCode {
    relief_server::cli::main()
}
