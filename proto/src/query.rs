//! Terrain queries on the wire (DESIGN.md section 5): the batches a simulator back end sends to
//! `POST /v1/query` or on a query session (`StreamKind::Query`), and the answers, item by item
//! in the same order. `docs/protocol.md` section 12 specifies every field and unit.
//!
//! The same types travel in the binary codec ([`crate::codec`]: an enum tag as one varint byte,
//! then the fields, each `f64` as 8 little-endian bytes) and, over HTTP, as JSON (serde's
//! externally tagged form: `{"hat": {"at": [x, y, z]}}`).
//!
//! Positions are world metres in the terrain's frame ([`crate::tree::WorldFrame`]): x east
//! from the westmost column, y north from the southmost row, z up.

use crate::codec::{
    Decode, DecodeError, Decoder, Encode, decode_seq, decode_text, impl_borrow_decode,
};
use serde::{Deserialize, Serialize};

/// Most queries in one batch.
pub const MAX_BATCH: usize = 100_000;

/// Most rays and lines of sight (together) in one batch: each follows its line across the
/// terrain, so they bound the batch's work where heights cannot.
pub const MAX_BATCH_RAYS: usize = 20_000;

/// One query.
#[derive(Clone, Copy, Debug, PartialEq, Encode, Decode, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Query {
    /// Height of terrain and its normal at a ground position.
    Height {
        /// `[x, y]`, metres.
        at: [f64; 2],
        /// Bicubic (Catmull-Rom over 4 x 4 samples) instead of the surface's own bilinear
        /// patch.
        #[serde(default)]
        bicubic: bool,
    },
    /// CIGI's height of terrain (HOT) under an entity and its height above terrain (HAT).
    Hat {
        /// The entity, `[x, y, z]`, metres.
        at: [f64; 3],
    },
    /// The first hit of a ray on the ground.
    Ray {
        /// Start, `[x, y, z]`, metres.
        origin: [f64; 3],
        /// Direction, any non-zero length.
        dir: [f64; 3],
        /// How far to look, metres; absent (`None`): to the terrain's end.
        #[serde(default)]
        max_dist: Option<f64>,
    },
    /// Whether `to` can be seen from `from`, with the line kept `clearance` metres above the
    /// ground.
    Sight {
        /// One end, `[x, y, z]`, metres.
        from: [f64; 3],
        /// The other end, `[x, y, z]`, metres.
        to: [f64; 3],
        /// Metres the line must stay above the ground (0: touching counts as blocked).
        #[serde(default)]
        clearance: f64,
    },
}

impl Query {
    /// Whether the query follows a line across the terrain (counted against
    /// [`MAX_BATCH_RAYS`]).
    pub fn is_line(&self) -> bool {
        matches!(self, Query::Ray { .. } | Query::Sight { .. })
    }
}

/// Where a ray first meets the ground.
#[derive(Clone, Copy, Debug, PartialEq, Encode, Decode, Serialize, Deserialize)]
pub struct RayHit {
    /// The hit point, `[x, y, z]`, metres.
    pub point: [f64; 3],
    /// Distance from the ray's origin, metres.
    pub distance: f64,
    /// The ground's unit upward normal there.
    pub normal: [f32; 3],
    /// The cell hit, `[col, row]` of its north-west sample (row 0 north).
    pub cell: [u32; 2],
}

/// Why a query has no answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Encode, Decode, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Fault {
    /// The item is not a query (JSON only: an unknown kind, a missing or mistyped field).
    Malformed,
    /// A coordinate, direction, distance or clearance is NaN or infinite.
    NotFinite,
    /// The ground position lies outside the terrain.
    Outside,
    /// A ray's direction, or a line of sight's length, is zero.
    ZeroDirection,
    /// A maximum distance or a clearance is negative.
    Negative,
}

/// The answer to one query, in the kind of the query (or an error). Decoded by hand, so that
/// an error's message reserves no memory before its bytes arrive ([`decode_text`]).
#[derive(Clone, Debug, PartialEq, Encode, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Answer {
    /// For [`Query::Height`].
    Height {
        /// Height of terrain, metres.
        height: f64,
        /// Unit upward normal.
        normal: [f32; 3],
    },
    /// For [`Query::Hat`].
    Hat {
        /// Height of terrain under the entity, metres.
        hot: f64,
        /// The entity's height above it, metres (negative: below the ground).
        hat: f64,
        /// The ground's unit upward normal under the entity.
        normal: [f32; 3],
    },
    /// For [`Query::Ray`]: the first hit, or `None` when the ray meets no ground.
    Ray(Option<RayHit>),
    /// For [`Query::Sight`].
    Sight {
        /// Whether the line is clear.
        visible: bool,
        /// Where it is first blocked, `[x, y, z]` on the line, metres, if it is.
        blocked_at: Option<[f64; 3]>,
        /// That point's distance from `from`, metres, if blocked.
        distance: Option<f64>,
    },
    /// The query has no answer.
    Error {
        /// Why, as a code.
        fault: Fault,
        /// Why, in words.
        message: String,
    },
}

/// A batch of queries: from the client on a query session, or the binary body of
/// `POST /v1/query`. Decoded by hand ([`decode_seq`]), so that a frame's claimed length
/// reserves no memory before its queries arrive.
#[derive(Clone, Debug, PartialEq, Encode, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct QueryBatch {
    /// Chosen by the client; its answers carry it back (batches may be pipelined).
    #[serde(default)]
    pub id: u64,
    /// The queries, at most [`MAX_BATCH`], of which at most [`MAX_BATCH_RAYS`] rays and lines
    /// of sight.
    pub queries: Vec<Query>,
}

/// The answers to a batch, one per query in the same order (decoded as [`QueryBatch`] is).
#[derive(Clone, Debug, PartialEq, Encode, Serialize, Deserialize)]
pub struct AnswerBatch {
    /// The batch's id.
    pub id: u64,
    /// One answer per query.
    pub answers: Vec<Answer>,
}

impl<C> Decode<C> for QueryBatch {
    fn decode<D: Decoder<Context = C>>(d: &mut D) -> Result<Self, DecodeError> {
        Ok(QueryBatch {
            id: u64::decode(d)?,
            queries: decode_seq(d)?,
        })
    }
}
impl_borrow_decode!(QueryBatch);

impl<C> Decode<C> for AnswerBatch {
    fn decode<D: Decoder<Context = C>>(d: &mut D) -> Result<Self, DecodeError> {
        Ok(AnswerBatch {
            id: u64::decode(d)?,
            answers: decode_seq(d)?,
        })
    }
}
impl_borrow_decode!(AnswerBatch);

impl<C> Decode<C> for Answer {
    fn decode<D: Decoder<Context = C>>(d: &mut D) -> Result<Self, DecodeError> {
        // The variant index, then the fields in order, as the derived encoding writes them.
        Ok(match u32::decode(d)? {
            0 => Answer::Height {
                height: Decode::decode(d)?,
                normal: Decode::decode(d)?,
            },
            1 => Answer::Hat {
                hot: Decode::decode(d)?,
                hat: Decode::decode(d)?,
                normal: Decode::decode(d)?,
            },
            2 => Answer::Ray(Decode::decode(d)?),
            3 => Answer::Sight {
                visible: Decode::decode(d)?,
                blocked_at: Decode::decode(d)?,
                distance: Decode::decode(d)?,
            },
            4 => Answer::Error {
                fault: Decode::decode(d)?,
                message: decode_text(d)?,
            },
            v => {
                return Err(DecodeError::OtherString(format!(
                    "answer kind {v} does not exist (0 to 4)"
                )));
            }
        })
    }
}
impl_borrow_decode!(Answer);

impl<C> Decode<C> for BatchRefused {
    fn decode<D: Decoder<Context = C>>(d: &mut D) -> Result<Self, DecodeError> {
        Ok(BatchRefused {
            id: u64::decode(d)?,
            reason: decode_text(d)?,
        })
    }
}
impl_borrow_decode!(BatchRefused);

/// Why a whole batch was refused (its items are not answered). Decoded by hand, as
/// [`Answer`] is.
#[derive(Clone, Debug, PartialEq, Eq, Encode, Serialize, Deserialize)]
pub struct BatchRefused {
    /// The batch's id.
    pub id: u64,
    /// Why, in words: too many queries, or too many rays.
    pub reason: String,
}

/// Whether a batch of `n` queries is within [`MAX_BATCH`]; the reason it is not, else.
pub fn check_len(n: usize) -> Result<(), String> {
    if n > MAX_BATCH {
        return Err(format!("{n} queries in one batch; at most {MAX_BATCH}"));
    }
    Ok(())
}

/// Whether a batch of `queries` is within the limits; the reason it is not, else.
pub fn check_batch(queries: &[Query]) -> Result<(), String> {
    check_len(queries.len())?;
    let lines = queries.iter().filter(|q| q.is_line()).count();
    if lines > MAX_BATCH_RAYS {
        return Err(format!(
            "{lines} rays and lines of sight in one batch; at most {MAX_BATCH_RAYS}"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::{decode, encode};

    #[test]
    fn binary_sizes_are_as_documented() {
        let q = Query::Hat {
            at: [1.0, 2.0, 3.0],
        };
        assert_eq!(encode(&q).len(), 25);
        let a = Answer::Hat {
            hot: 1.0,
            hat: 2.0,
            normal: [0.0, 0.0, 1.0],
        };
        assert_eq!(encode(&a).len(), 29);
        // The sizes docs/protocol.md section 16.1 gives for rays.
        let ray = |max_dist| Query::Ray {
            origin: [0.0; 3],
            dir: [1.0; 3],
            max_dist,
        };
        assert_eq!(encode(&ray(None)).len(), 50);
        assert_eq!(encode(&ray(Some(5.0))).len(), 58);
        let hit = |cell| {
            Answer::Ray(Some(RayHit {
                point: [0.0; 3],
                distance: 1.0,
                normal: [0.0, 0.0, 1.0],
                cell,
            }))
        };
        assert_eq!(encode(&hit([0, 250])).len(), 48);
        assert_eq!(encode(&hit([4096, 60000])).len(), 52);
        assert_eq!(encode(&Answer::Ray(None)).len(), 2);
    }

    #[test]
    fn batches_round_trip_in_both_forms() {
        let b = QueryBatch {
            id: 7,
            queries: vec![
                Query::Height {
                    at: [1.0, 2.0],
                    bicubic: true,
                },
                Query::Hat {
                    at: [1.0, 2.0, 3.0],
                },
                Query::Ray {
                    origin: [0.0; 3],
                    dir: [1.0, 0.0, -1.0],
                    max_dist: None,
                },
                Query::Sight {
                    from: [0.0; 3],
                    to: [1.0; 3],
                    clearance: 2.0,
                },
            ],
        };
        assert_eq!(decode::<QueryBatch>(&encode(&b), 1 << 20).unwrap(), b);
        let json = serde_json::to_string(&b).unwrap();
        assert_eq!(serde_json::from_str::<QueryBatch>(&json).unwrap(), b);
        let short: QueryBatch =
            serde_json::from_str(r#"{"queries": [{"hat": {"at": [1, 2, 3]}}]}"#).unwrap();
        assert_eq!(short.id, 0);
        assert_eq!(
            short.queries,
            vec![Query::Hat {
                at: [1.0, 2.0, 3.0]
            }]
        );
    }

    #[test]
    fn hand_decoded_answers_read_back_what_the_derived_encoding_writes() {
        let answers = vec![
            Answer::Height {
                height: 1.5,
                normal: [0.0, 0.6, 0.8],
            },
            Answer::Hat {
                hot: 2.0,
                hat: -3.0,
                normal: [0.0, 0.0, 1.0],
            },
            Answer::Ray(None),
            Answer::Ray(Some(RayHit {
                point: [1.0, 2.0, 3.0],
                distance: 4.0,
                normal: [0.0, 0.0, 1.0],
                cell: [5, 300],
            })),
            Answer::Sight {
                visible: false,
                blocked_at: Some([1.0; 3]),
                distance: Some(9.0),
            },
            Answer::Error {
                fault: Fault::Outside,
                message: "point (-5, 0) lies outside the terrain; ünïcode".repeat(20),
            },
        ];
        let b = AnswerBatch { id: 3, answers };
        assert_eq!(decode::<AnswerBatch>(&encode(&b), 1 << 20).unwrap(), b);
        let r = BatchRefused {
            id: 4,
            reason: "too many".into(),
        };
        assert_eq!(decode::<BatchRefused>(&encode(&r), 1 << 20).unwrap(), r);
        // A kind that does not exist, invalid UTF-8, and a message shorter than it claims.
        assert!(decode::<Answer>(&[5], 1 << 20).is_err());
        assert!(decode::<Answer>(&[4, 0, 2, 0xC3, 0x28], 1 << 20).is_err());
        assert!(decode::<Answer>(&[4, 0, 251, 0x00, 0x10, b'a'], 1 << 20).is_err());
    }

    #[test]
    fn batches_over_the_limits_are_refused() {
        let hat = Query::Hat { at: [0.0; 3] };
        let ray = Query::Ray {
            origin: [0.0; 3],
            dir: [1.0; 3],
            max_dist: None,
        };
        assert!(check_batch(&vec![hat; MAX_BATCH]).is_ok());
        assert!(check_batch(&vec![hat; MAX_BATCH + 1]).is_err());
        assert!(check_batch(&vec![ray; MAX_BATCH_RAYS]).is_ok());
        let e = check_batch(&vec![ray; MAX_BATCH_RAYS + 1]).unwrap_err();
        assert!(e.contains("rays"), "{e}");
    }
}
