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
/// What a hand-written [`Decode`] names (see [`decode_seq`]).
pub use bincode::{de::Decoder, error::DecodeError, impl_borrow_decode};

/// Items a sequence decoded by [`decode_seq`] makes room for before any has arrived.
const PREALLOC: usize = 16;

/// Decodes a `Vec<T>` as bincode encodes one (a length, then the items), making room as the
/// items arrive rather than for the length the frame claims. bincode's own `Vec` decoding
/// reserves the claimed length at once (up to [`HARD_LIMIT`] bytes), so a three-byte frame
/// claiming a few thousand 64-byte items allocated more than its message limit; here a batch
/// holds at most twice the room of the items it really decoded.
pub fn decode_seq<T, D>(d: &mut D) -> Result<Vec<T>, DecodeError>
where
    D: Decoder,
    T: Decode<D::Context>,
{
    let len = u64::decode(d)?;
    let len = usize::try_from(len).map_err(|_| DecodeError::OutsideUsizeRange(len))?;
    d.claim_container_read::<T>(len)?;
    let mut v = Vec::with_capacity(len.min(PREALLOC));
    for _ in 0..len {
        // As bincode's own Vec decoding does: the claim above counted the items' size already.
        d.unclaim_bytes_read(core::mem::size_of::<T>());
        v.push(T::decode(d)?);
    }
    Ok(v)
}

/// Decodes a `String` as bincode encodes one (a length, then UTF-8 bytes), making room as the
/// bytes arrive, in steps of at most 256, rather than for the length the frame claims (which
/// bincode's own `String` decoding reserves at once).
pub fn decode_text<D: Decoder>(d: &mut D) -> Result<String, DecodeError> {
    let len = u64::decode(d)?;
    let len = usize::try_from(len).map_err(|_| DecodeError::OutsideUsizeRange(len))?;
    d.claim_container_read::<u8>(len)?;
    let mut bytes = Vec::with_capacity(len.min(256));
    let mut chunk = [0u8; 256];
    let mut left = len;
    while left > 0 {
        let n = left.min(chunk.len());
        bincode::de::read::Reader::read(d.reader(), &mut chunk[..n])?;
        bytes.extend_from_slice(&chunk[..n]);
        left -= n;
    }
    String::from_utf8(bytes).map_err(|e| DecodeError::Utf8 {
        inner: e.utf8_error(),
    })
}

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
