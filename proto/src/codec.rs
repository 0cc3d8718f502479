//! The wire codec: bincode 2.0.1, standard configuration (little endian, varint integers), with a
//! hard byte limit on every decode. This is the only module that names bincode, so that a change
//! of format touches one file.
//!
//! bincode allocates from length prefixes it reads; the configured limit bounds every such
//! allocation, and a frame longer than the caller's limit is refused before decoding starts.

use bincode::config::{self, Configuration, Limit, LittleEndian, Varint};

/// The largest frame any decode accepts, whatever the caller's own limit.
pub const HARD_LIMIT: usize = 16 << 20;

type Config = Configuration<LittleEndian, Varint, Limit<HARD_LIMIT>>;

fn config() -> Config {
    config::standard().with_limit::<HARD_LIMIT>()
}

/// Re-exported derive traits so that message types need no direct bincode dependency.
pub use bincode::{Decode, Encode};

/// A frame that does not decode.
#[derive(Debug, thiserror::Error)]
pub enum CodecError {
    /// The frame is longer than the limit.
    #[error("message of {0} bytes exceeds the limit of {1} bytes")]
    TooLarge(usize, usize),
    /// The bytes are not a valid message.
    #[error("malformed message: {0}")]
    Malformed(String),
    /// A valid message followed by extra bytes.
    #[error("malformed message: {0} trailing bytes")]
    Trailing(usize),
}

/// Encodes `msg`.
pub fn encode<T: Encode>(msg: &T) -> Vec<u8> {
    // Encoding into a Vec cannot fail for the plain data types of this crate.
    bincode::encode_to_vec(msg, config()).unwrap_or_default()
}

/// Decodes one message that must fill `bytes` exactly, refusing frames over `limit` bytes.
pub fn decode<T: Decode<()>>(bytes: &[u8], limit: usize) -> Result<T, CodecError> {
    let limit = limit.min(HARD_LIMIT);
    if bytes.len() > limit {
        return Err(CodecError::TooLarge(bytes.len(), limit));
    }
    let (msg, used) = bincode::decode_from_slice(bytes, config())
        .map_err(|e| CodecError::Malformed(e.to_string()))?;
    if used != bytes.len() {
        return Err(CodecError::Trailing(bytes.len() - used));
    }
    Ok(msg)
}
