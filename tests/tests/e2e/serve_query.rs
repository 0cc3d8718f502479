//! End to end over 127.0.0.1: terrain queries. `POST /v1/query` in JSON and in the
//! binary form, and query sessions on `/v1/stream`: answers in order, each equal to the query
//! library's own answer on the same store, bad items answered item by item, batches over the
//! limits refused without ending the session, and messages of the wrong kind closed.

use futures_util::{SinkExt, StreamExt};
use relief_client::http::{HttpError, post_json, request};
use relief_client::query::{QueryClient, Reply};
use relief_proto::close::CloseReason;
use relief_proto::codec;
use relief_proto::msg::{ClientMsg, WireCamera};
use relief_proto::query::{Answer, AnswerBatch, Fault, MAX_BATCH_RAYS, Query, QueryBatch};
use relief_server::query::Terrain;
use relief_server::serve::config::Limits;
use relief_server::store::Store;
use relief_tests::{TestServer, hello, test_store};
use tokio_tungstenite::tungstenite::Message;

/// A mixed batch over the test terrain (19.4 x 17.8 km): good queries of every kind, and one
/// bad item of each kind of fault the binary form can carry.
fn mixed(id: u64) -> QueryBatch {
    let mut queries = Vec::new();
    for k in 0..40 {
        let (x, y) = (500.0 + 450.0 * k as f64, 300.0 + 400.0 * k as f64);
        queries.push(Query::Height {
            at: [x, y],
            bicubic: k % 2 == 0,
        });
        queries.push(Query::Hat { at: [x, y, 2500.0] });
        queries.push(Query::Ray {
            origin: [x, y, 3900.0],
            dir: [1.0, 0.5 - 0.02 * k as f64, -0.05 - 0.03 * k as f64],
            max_dist: if k % 3 == 0 { Some(8000.0) } else { None },
        });
        queries.push(Query::Sight {
            from: [x, y, 2000.0],
            to: [19000.0 - x, y, 2000.0 + 30.0 * k as f64],
            clearance: 2.0,
        });
    }
    queries.extend([
        Query::Hat {
            at: [f64::NAN, 1.0, 1.0],
        },
        Query::Height {
            at: [-5000.0, 100.0],
            bicubic: false,
        },
        Query::Ray {
            origin: [100.0, 100.0, 4000.0],
            dir: [0.0; 3],
            max_dist: None,
        },
        Query::Sight {
            from: [100.0, 100.0, 4000.0],
            to: [200.0, 200.0, 4000.0],
            clearance: -1.0,
        },
    ]);
    QueryBatch { id, queries }
}

/// The query library's answers on the test store: what every edge must return.
fn reference(batch: &QueryBatch) -> Vec<Answer> {
    let t = Terrain::from_store(&Store::open(test_store()).unwrap()).unwrap();
    let mut out = Vec::new();
    t.answer_all(&batch.queries, &mut out);
    out
}

fn faults(answers: &[Answer]) -> Vec<Fault> {
    answers
        .iter()
        .filter_map(|a| match a {
            Answer::Error { fault, .. } => Some(*fault),
            _ => None,
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn http_answers_json_and_binary_batches_item_by_item() {
    let server = TestServer::start(Limits::default()).await;
    let url = format!("{}/v1/query", server.http());
    let batch = mixed(11);
    let want = reference(&batch);
    assert_eq!(
        faults(&want),
        [
            Fault::NotFinite,
            Fault::Outside,
            Fault::ZeroDirection,
            Fault::Negative
        ]
    );
    let hits = want
        .iter()
        .filter(|a| matches!(a, Answer::Ray(Some(_))))
        .count();
    let blocked = want
        .iter()
        .filter(|a| matches!(a, Answer::Sight { visible: false, .. }))
        .count();
    assert!(
        hits > 10 && blocked > 5 && blocked < 40,
        "{hits} hits, {blocked} blocked"
    );

    // Binary: every answer, NaN item included, exactly the library's.
    let body = request(
        "POST",
        &url,
        "application/octet-stream",
        codec::encode(&batch),
    )
    .await
    .unwrap();
    let got: AnswerBatch = codec::decode(&body, codec::HARD_LIMIT).unwrap();
    assert_eq!(got.id, 11);
    assert_eq!(got.answers, want);

    // JSON: the same batch without its NaN item (JSON has no NaN), plus items that are not
    // queries, each answered with its own error at its place.
    let mut json = serde_json::to_value(QueryBatch {
        id: 12,
        queries: batch.queries[..batch.queries.len() - 4].to_vec(),
    })
    .unwrap();
    let items = json["queries"].as_array_mut().unwrap();
    items.push(serde_json::json!({"hat": {"at": [1.0, null, 2.0]}}));
    items.push(serde_json::json!({"teleport": {"to": [0, 0, 0]}}));
    items.push(serde_json::json!({"ray": {"origin": [100.0, 100.0, 4000.0], "dir": [0, 0, 0]}}));
    let reply = post_json(&url, &json).await.unwrap();
    assert_eq!(reply["id"], 12);
    let answers: Vec<Answer> = serde_json::from_value(reply["answers"].clone()).unwrap();
    let n = batch.queries.len() - 4;
    assert_eq!(answers.len(), n + 3);
    // The library's answers as they read back from JSON text: f64s exactly (serde_json with
    // float_roundtrip), f32 normals through an f64.
    let text = serde_json::to_string(&want[..n]).unwrap();
    let want_json: Vec<Answer> = serde_json::from_str(&text).unwrap();
    assert_eq!(answers[..n], want_json[..]);
    assert_eq!(
        faults(&answers[n..]),
        [Fault::Malformed, Fault::Malformed, Fault::ZeroDirection]
    );
    match &answers[n + 1] {
        Answer::Error { message, .. } => assert!(message.contains("item 161"), "{message}"),
        a => panic!("{a:?}"),
    }

    // Whole-request errors: not a batch, and over the limits.
    for (body, needle) in [
        ("[1, 2, 3]".to_string(), "not a query batch"),
        (
            serde_json::json!({"queries": vec![serde_json::json!({"ray": {"origin": [0, 0, 0], "dir": [1, 0, 0]}}); MAX_BATCH_RAYS + 1]}).to_string(),
            "rays and lines of sight",
        ),
    ] {
        match request("POST", &url, "application/json", body.into_bytes()).await {
            Err(HttpError::Status { status: 400, body, .. }) => {
                assert!(body.contains(needle), "{body}")
            }
            other => panic!("expected 400 ({needle}), got {other:?}"),
        }
    }
    let metrics = relief_client::http::request(
        "GET",
        &format!("{}/metrics", server.http()),
        "text/plain",
        Vec::new(),
    )
    .await
    .unwrap();
    let text = String::from_utf8_lossy(&metrics);
    let line = text
        .lines()
        .find(|l| l.starts_with("relief_queries_total "))
        .unwrap();
    assert_eq!(line, format!("relief_queries_total {}", 2 * n + 4 + 3));
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_query_session_answers_pipelined_batches_in_order_and_survives_a_refusal() {
    let server = TestServer::start(Limits::default()).await;
    let client = QueryClient::connect(&server.url()).await.unwrap();
    assert_eq!(client.welcome.digest, 0);
    assert!(client.welcome.tiles.is_none());
    let (mut tx, mut rx) = client.split();
    let batches: Vec<QueryBatch> = (1..=6).map(mixed).collect();
    let want = reference(&batches[0]);
    // Six batches sent before any answer is read, then one over the limits, then one more.
    for b in &batches {
        tx.send(b).await.unwrap();
    }
    // Within the message size limit (50 bytes a ray), over the batch's ray limit.
    let too_many = QueryBatch {
        id: 99,
        queries: vec![
            Query::Ray {
                origin: [1.0; 3],
                dir: [1.0, 0.0, -1.0],
                max_dist: None,
            };
            MAX_BATCH_RAYS + 1
        ],
    };
    tx.send(&too_many).await.unwrap();
    tx.send(&mixed(7)).await.unwrap();
    for id in 1..=6 {
        match rx.next().await.unwrap().0 {
            Reply::Answers(a) => {
                assert_eq!(a.id, id);
                assert_eq!(a.answers, want, "batch {id}");
            }
            r => panic!("{r:?}"),
        }
    }
    match rx.next().await.unwrap().0 {
        Reply::Refused(r) => {
            assert_eq!(r.id, 99);
            assert!(r.reason.contains("at most 20000"), "{}", r.reason);
        }
        r => panic!("{r:?}"),
    }
    assert_eq!(rx.next().await.unwrap().0.id(), 7);
    tx.close().await;
    server.stop().await;
}

/// Reads until the server's close frame; returns its code and text.
async fn close_of<S>(ws: &mut S) -> (u16, String)
where
    S: futures_util::Stream<Item = Result<Message, tokio_tungstenite::tungstenite::Error>> + Unpin,
{
    loop {
        match tokio::time::timeout(std::time::Duration::from_secs(10), ws.next()).await {
            Ok(Some(Ok(Message::Close(Some(f))))) => {
                return (u16::from(f.code), f.reason.to_string());
            }
            Ok(Some(Ok(_))) => continue,
            other => panic!("no close frame: {other:?}"),
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn messages_of_the_other_kind_of_session_are_protocol_errors() {
    let server = TestServer::start(Limits::default()).await;
    let protocol = CloseReason::Protocol.code();
    // A pose on a query session.
    let (mut ws, _) = tokio_tungstenite::connect_async(server.url())
        .await
        .unwrap();
    let query_hello = relief_proto::msg::ClientMsg::Hello(relief_proto::msg::Hello {
        version: relief_proto::msg::PROTOCOL_VERSION,
        kind: relief_proto::msg::StreamKind::Query,
        lens: relief_proto::view::Lens::STANDARD.into(),
        tau: 1.0,
        budget: None,
        resume: None,
    });
    ws.send(Message::Binary(codec::encode(&query_hello).into()))
        .await
        .unwrap();
    let pose = ClientMsg::Pose {
        seq: 1,
        camera: WireCamera {
            eye: [100.0, 100.0, 4000.0],
            yaw: 0.0,
            pitch: -0.3,
        },
    };
    ws.send(Message::Binary(codec::encode(&pose).into()))
        .await
        .unwrap();
    let (code, text) = close_of(&mut ws).await;
    assert_eq!(code, protocol, "{text}");
    assert!(text.contains("query session"), "{text}");
    // A query batch on a vertex session.
    let (mut ws, _) = tokio_tungstenite::connect_async(server.url())
        .await
        .unwrap();
    ws.send(Message::Binary(hello().into())).await.unwrap();
    ws.send(Message::Binary(
        codec::encode(&ClientMsg::Query(mixed(1))).into(),
    ))
    .await
    .unwrap();
    let (code, text) = close_of(&mut ws).await;
    assert_eq!(code, protocol, "{text}");
    assert!(text.contains("query sessions"), "{text}");
    server.stop().await;
}
