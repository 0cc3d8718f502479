//! A batch of wire queries ([`relief_proto::query`]) answered against a [`Terrain`], item by
//! item in order: the one function `POST /v1/query` and query sessions both call.

use super::{Interp, QueryError, Ray, Sight, Terrain};
use glam::DVec3;
use relief_proto::query::{Answer, Fault, Query, RayHit};

/// The wire fault and message of a query error.
pub fn fault(e: &QueryError) -> Answer {
    let fault = match e {
        QueryError::NotFinite => Fault::NotFinite,
        QueryError::Outside { .. } | QueryError::OutOfReach(_) => Fault::Outside,
        QueryError::ZeroDirection => Fault::ZeroDirection,
        QueryError::Negative(_) => Fault::Negative,
        // A grid that cannot be queried never becomes a served terrain.
        QueryError::BadGrid(_) => Fault::Malformed,
    };
    Answer::Error {
        fault,
        message: clip(e.to_string()),
    }
}

/// Longest error message in an answer, bytes: a message can quote what the client sent, and an
/// answer must stay about the size of its query, not of the client's text.
pub const MAX_ANSWER_MESSAGE: usize = 96;

/// `s` cut to [`MAX_ANSWER_MESSAGE`] bytes (at a character boundary, with an ellipsis).
pub fn clip(mut s: String) -> String {
    if s.len() > MAX_ANSWER_MESSAGE {
        let mut end = MAX_ANSWER_MESSAGE - '…'.len_utf8();
        while !s.is_char_boundary(end) {
            end -= 1;
        }
        s.truncate(end);
        s.push('…');
    }
    s
}

/// The unit normal as the wire carries it.
fn normal32(n: DVec3) -> [f32; 3] {
    n.as_vec3().to_array()
}

impl Terrain {
    /// The answer to one wire query.
    pub fn answer(&self, q: &Query) -> Answer {
        let r = match *q {
            Query::Height {
                at: [x, y],
                bicubic,
            } => {
                let interp = if bicubic {
                    Interp::Bicubic
                } else {
                    Interp::Bilinear
                };
                // The surface's own height unless bicubic is asked: not located twice.
                self.surface(x, y).and_then(|s| {
                    let height = match interp {
                        Interp::Bilinear => s.height,
                        Interp::Bicubic => self.height_with(x, y, interp)?,
                    };
                    Ok(Answer::Height {
                        height,
                        normal: normal32(s.normal),
                    })
                })
            }
            Query::Hat { at } => self.hat_hot(DVec3::from_array(at)).map(|h| Answer::Hat {
                hot: h.hot,
                hat: h.hat,
                normal: normal32(h.normal),
            }),
            Query::Ray {
                origin,
                dir,
                max_dist,
            } => self
                .cast(&Ray {
                    origin: DVec3::from_array(origin),
                    dir: DVec3::from_array(dir),
                    max_dist: max_dist.unwrap_or(f64::INFINITY),
                })
                .map(|h| {
                    Answer::Ray(h.map(|h| RayHit {
                        point: h.point.to_array(),
                        distance: h.distance,
                        normal: normal32(h.normal),
                        cell: h.cell,
                    }))
                }),
            Query::Sight {
                from,
                to,
                clearance,
            } => self
                .line_of_sight(DVec3::from_array(from), DVec3::from_array(to), clearance)
                .map(|s| match s {
                    Sight::Visible => Answer::Sight {
                        visible: true,
                        blocked_at: None,
                        distance: None,
                    },
                    Sight::Blocked { point, distance } => Answer::Sight {
                        visible: false,
                        blocked_at: Some(point.to_array()),
                        distance: Some(distance),
                    },
                }),
        };
        r.unwrap_or_else(|e| fault(&e))
    }

    /// The answers to `queries`, one each in order, into `out` (cleared first).
    pub fn answer_all(&self, queries: &[Query], out: &mut Vec<Answer>) {
        out.clear();
        out.extend(queries.iter().map(|q| self.answer(q)));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_batch_of_the_longest_answers_fits_in_one_message() {
        // Every answer kind at its largest: an error with the longest message, a ray hit with
        // the widest cell, a blocked line of sight. A batch of the most queries of the longest
        // answer stays under the codec's limit, so answers need never be split.
        let longest = [
            Answer::Error {
                fault: Fault::Malformed,
                message: clip("é".repeat(200)),
            },
            Answer::Ray(Some(RayHit {
                point: [f64::MAX; 3],
                distance: f64::MAX,
                normal: [1.0; 3],
                cell: [u32::MAX; 2],
            })),
        ];
        for a in longest {
            let batch = relief_proto::query::AnswerBatch {
                id: u64::MAX,
                answers: vec![a.clone(); relief_proto::query::MAX_BATCH],
            };
            let n = relief_proto::codec::encode(&batch).len();
            assert!(n <= relief_proto::codec::HARD_LIMIT, "{n} bytes of {a:?}");
        }
        // A message of numbers the client chose stays short too.
        let e = QueryError::Outside {
            x: -1.797e308,
            y: f64::MIN_POSITIVE,
        };
        assert!(e.to_string().len() < 80, "{e}");
    }

    fn ramp() -> Terrain {
        // 5 x 5 samples 10 m apart, rising 1 m per metre east: z = x.
        let z: Vec<f32> = (0..25).map(|i| (i % 5) as f32 * 10.0).collect();
        Terrain::new(5, 5, 10.0, 10.0, &z).unwrap()
    }

    #[test]
    fn each_kind_is_answered_in_its_own_kind() {
        let t = ramp();
        let qs = [
            Query::Height {
                at: [15.0, 20.0],
                bicubic: false,
            },
            Query::Hat {
                at: [15.0, 20.0, 40.0],
            },
            Query::Ray {
                origin: [0.0, 20.0, 30.0],
                dir: [1.0, 0.0, 0.0],
                max_dist: None,
            },
            Query::Sight {
                from: [0.0, 20.0, 30.0],
                to: [40.0, 20.0, 30.0],
                clearance: 1.0,
            },
        ];
        let mut out = Vec::new();
        t.answer_all(&qs, &mut out);
        assert!(matches!(out[0], Answer::Height { height, .. } if (height - 15.0).abs() < 1e-9));
        assert!(matches!(out[1], Answer::Hat { hot, hat, .. }
            if (hot - 15.0).abs() < 1e-9 && (hat - 25.0).abs() < 1e-9));
        match &out[2] {
            Answer::Ray(Some(h)) => assert!((h.distance - 30.0).abs() < 1e-9, "{h:?}"),
            a => panic!("{a:?}"),
        }
        match &out[3] {
            Answer::Sight {
                visible: false,
                distance: Some(d),
                ..
            } => assert!((d - 29.0).abs() < 1e-9, "{d}"),
            a => panic!("{a:?}"),
        }
    }

    #[test]
    fn bad_items_get_their_own_faults() {
        let t = ramp();
        let cases = [
            (
                Query::Height {
                    at: [f64::NAN, 0.0],
                    bicubic: false,
                },
                Fault::NotFinite,
            ),
            (
                Query::Hat {
                    at: [-100.0, 0.0, 0.0],
                },
                Fault::Outside,
            ),
            (
                Query::Ray {
                    origin: [0.0; 3],
                    dir: [0.0; 3],
                    max_dist: None,
                },
                Fault::ZeroDirection,
            ),
            (
                Query::Sight {
                    from: [0.0; 3],
                    to: [1.0; 3],
                    clearance: -1.0,
                },
                Fault::Negative,
            ),
        ];
        for (q, want) in cases {
            match t.answer(&q) {
                Answer::Error { fault, message } => {
                    assert_eq!(fault, want, "{q:?}: {message}");
                    assert!(!message.is_empty());
                }
                a => panic!("{q:?}: {a:?}"),
            }
        }
    }
}
