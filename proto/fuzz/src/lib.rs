//! The checks behind relief-proto's fuzz targets (one module per target, each with a `check`
//! that the target calls on every input and the `seeds` it starts from), kept in a library so
//! that the seed writer (`examples/seeds.rs`) and the tests share them.
//!
//! Every check decodes the input, returns `false` when the decoder refuses it (refusing is the
//! decoder's job: only a panic, a hang or a huge allocation is a failure), and otherwise
//! re-encodes what it decoded, decodes that again, asserts that nothing changed and returns
//! `true`.
//!
//! Inputs of the targets that decode against a terrain start with a [`Header`]: the grid size and
//! one parameter byte, so that the fuzzer explores shapes as well as bodies.

pub mod delta;
pub mod message;
pub mod snapshot;
pub mod tile_body;

/// The largest frame the message decoders accept: the server's default `max_message_bytes`.
pub const LIMIT: usize = 1 << 20;

/// The terrain an input is decoded against, from its first [`Header::LEN`] bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Header {
    /// Grid width in samples, 2 to 32768.
    pub width: u32,
    /// Grid height in samples, 2 to 32768.
    pub height: u32,
    /// One byte for the target's own use (the z quantum, the tile size).
    pub param: u8,
}

impl Header {
    /// Bytes a header takes: width and height as `u16` little endian, then the parameter.
    pub const LEN: usize = 5;

    /// The header at the start of `data` and the bytes after it, if `data` is long enough.
    pub fn split(data: &[u8]) -> Option<(Header, &[u8])> {
        let (head, rest) = data.split_first_chunk::<{ Header::LEN }>()?;
        let side = |lo: u8, hi: u8| 2 + u32::from(u16::from_le_bytes([lo, hi])) % 32767;
        let header = Header {
            width: side(head[0], head[1]),
            height: side(head[2], head[3]),
            param: head[4],
        };
        Some((header, rest))
    }

    /// The header's bytes (`width` and `height` must be in range), followed by `body`.
    pub fn with(self, body: &[u8]) -> Vec<u8> {
        let mut out = Vec::with_capacity(Header::LEN + body.len());
        out.extend_from_slice(&((self.width - 2) as u16).to_le_bytes());
        out.extend_from_slice(&((self.height - 2) as u16).to_le_bytes());
        out.push(self.param);
        out.extend_from_slice(body);
        out
    }
}

/// Asserts what re-encoding a decoded value must give: never more bytes than the input (every
/// encoder here writes the shortest form the decoder reads), and the input itself when just as
/// long (a longer form is the only freedom the decoders allow).
pub fn assert_canonical(input: &[u8], reencoded: &[u8]) {
    assert!(
        reencoded.len() <= input.len(),
        "re-encoding grew {} bytes to {}",
        input.len(),
        reencoded.len()
    );
    if reencoded.len() == input.len() {
        assert_eq!(reencoded, input, "same length, other bytes");
    }
}

/// The seeds of target `target` as (file name, bytes), or `None` for an unknown target.
pub fn seeds(target: &str) -> Option<Vec<(String, Vec<u8>)>> {
    match target {
        "message" => Some(message::seeds()),
        "delta" => Some(delta::seeds()),
        "snapshot" => Some(snapshot::seeds()),
        "tile_body" => Some(tile_body::seeds()),
        _ => None,
    }
}

/// The fuzz targets, as named in `Cargo.toml`.
pub const TARGETS: [&str; 4] = ["message", "delta", "snapshot", "tile_body"];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn headers_round_trip() {
        for (w, h) in [(2, 2), (5, 3), (32768, 2), (300, 32768)] {
            let header = Header {
                width: w,
                height: h,
                param: 7,
            };
            let bytes = header.with(&[1, 2]);
            assert_eq!(Header::split(&bytes), Some((header, &[1u8, 2][..])));
        }
        assert_eq!(Header::split(&[0; 4]), None);
    }

    /// Every seed passes its check, and the committed seed files are what the seed writer
    /// writes (run `cargo run --example seeds` after changing a seed).
    #[test]
    fn seeds_pass_and_are_committed() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("seeds");
        for target in TARGETS {
            let seeds = seeds(target).expect("a target");
            assert!(!seeds.is_empty());
            let check = match target {
                "message" => message::check,
                "delta" => delta::check,
                "snapshot" => snapshot::check,
                _ => tile_body::check,
            };
            for (name, bytes) in seeds {
                assert!(check(&bytes), "{target}/{name} does not decode");
                let path = dir.join(target).join(&name);
                let committed = std::fs::read(&path).unwrap_or_default();
                assert_eq!(committed, bytes, "{} is stale", path.display());
            }
        }
    }
}
