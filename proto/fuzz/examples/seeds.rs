//! Writes the seed corpora, `seeds/<target>/<name>` beside this crate's `Cargo.toml`, from
//! [`relief_proto_fuzz::seeds`]: real encoded messages, deltas, snapshots and tile deltas for
//! the fuzzer to start from. Run it after changing a seed (the crate's tests compare them):
//! `cargo run --manifest-path proto/fuzz/Cargo.toml --example seeds`.

use relief_proto_fuzz::{TARGETS, seeds};
use std::path::Path;

fn main() -> std::io::Result<()> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("seeds");
    for target in TARGETS {
        let dir = root.join(target);
        if dir.exists() {
            std::fs::remove_dir_all(&dir)?;
        }
        std::fs::create_dir_all(&dir)?;
        let seeds = seeds(target).unwrap_or_default();
        let bytes: usize = seeds.iter().map(|(_, b)| b.len()).sum();
        for (name, b) in &seeds {
            std::fs::write(dir.join(name), b)?;
        }
        println!("{target}: {} seeds, {bytes} bytes", seeds.len());
    }
    Ok(())
}
