//! Wire messages. Each is one binary WebSocket frame, encoded by [`crate::codec`].
//!
//! The session messages (hello, welcome, poses, acknowledgements) arrive with the streaming
//! server; this module holds what the LOD engine produces today.

use crate::codec::{Decode, Encode};
use crate::delta::{BodyError, Delta};
use crate::tree::TreeShape;

/// A delta as it travels: the header in the clear, merges and splits in the compact body
/// ([`crate::delta`]).
#[derive(Clone, Debug, PartialEq, Eq, Encode, Decode)]
pub struct WireDelta {
    /// Sequence number within the session.
    pub seq: u64,
    /// Digest of the cut after the delta.
    pub digest: u64,
    /// Merges and splits, bit-packed.
    pub body: Vec<u8>,
}

impl WireDelta {
    /// Packs `delta` for a terrain of shape `shape` and z quantum `quantum`.
    pub fn pack(delta: &Delta, shape: &TreeShape, quantum: f32) -> WireDelta {
        WireDelta {
            seq: delta.seq,
            digest: delta.digest,
            body: delta.pack_body(shape, quantum),
        }
    }

    /// Unpacks the body against the terrain.
    pub fn unpack(&self, shape: &TreeShape, quantum: f32) -> Result<Delta, BodyError> {
        Delta::unpack_body(shape, quantum, self.seq, self.digest, &self.body)
    }
}

/// Messages from server to client.
#[derive(Clone, Debug, PartialEq, Eq, Encode, Decode)]
pub enum ServerMsg {
    /// An incremental update of the client's cut.
    Delta(WireDelta),
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::{CodecError, decode, encode};
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn messages_round_trip(seq in any::<u64>(), digest in any::<u64>(),
                               body in proptest::collection::vec(any::<u8>(), 0..300)) {
            let m = ServerMsg::Delta(WireDelta { seq, digest, body });
            let bytes = encode(&m);
            prop_assert_eq!(decode::<ServerMsg>(&bytes, 1 << 20).unwrap(), m);
        }

        #[test]
        fn random_frames_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
            let _ = decode::<ServerMsg>(&bytes, 1 << 20);
        }
    }

    #[test]
    fn oversized_and_lying_frames_are_refused() {
        let m = ServerMsg::Delta(WireDelta {
            seq: 1,
            digest: 2,
            body: vec![7; 100],
        });
        let bytes = encode(&m);
        assert!(matches!(
            decode::<ServerMsg>(&bytes, 50),
            Err(CodecError::TooLarge(..))
        ));
        // A length prefix claiming far more bytes than follow.
        let lie = [0u8, 1, 2, 0xFC, 0xFF, 0xFF, 0xFF, 0x7F];
        assert!(matches!(
            decode::<ServerMsg>(&lie, 1 << 20),
            Err(CodecError::Malformed(_))
        ));
        let mut trailing = bytes.clone();
        trailing.push(0);
        assert!(matches!(
            decode::<ServerMsg>(&trailing, 1 << 20),
            Err(CodecError::Trailing(1))
        ));
    }
}
