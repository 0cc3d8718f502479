//! Hostile input: WebSocket frames that break RFC 6455. Each closes its
//! session with 1002 (protocol error) or 1007 (invalid text) and a reason, not a bare
//! `88 00`, is counted under `relief_errors_total`, and leaves a bystander's latency alone.

use relief_proto::close::CloseReason;
use relief_server::serve::config::Limits;
use relief_tests::bystander::{Bystander, assert_kept};
use relief_tests::raw::{Closed, binary, frame, lo, read_close, ws_open};
use relief_tests::{TestServer, hello};
use std::sync::atomic::Ordering;
use std::time::Duration;
use tokio::io::AsyncWriteExt;

/// Opens a session from 127.0.0.2 (hello sent), sends `bytes`, and returns how it closed,
/// while a bystander from 127.0.0.1 flies; checks the bystander and the error count.
async fn violation(bytes: Vec<u8>, want: CloseReason, needle: &str) {
    let server = TestServer::start(Limits::default()).await;
    let by = Bystander::start(&server.url(), 0).await;
    let calm = by.measure(Duration::from_millis(400)).await;
    let (closed, attacked) = by
        .during(async {
            let mut tcp = ws_open(lo(2), server.addr).await;
            tcp.write_all(&binary(&hello())).await.unwrap();
            tcp.write_all(&bytes).await.unwrap();
            let c = read_close(&mut tcp).await;
            tokio::time::sleep(Duration::from_millis(200)).await;
            c
        })
        .await;
    match &closed {
        Closed::Code(code, text) => {
            assert_eq!(*code, want.code(), "{closed:?}");
            assert!(text.starts_with(want.name()), "{closed:?}");
            assert!(
                text.to_lowercase().contains(needle),
                "{closed:?} lacks {needle:?}"
            );
        }
        other => panic!("closed without a code: {other:?}"),
    }
    let m = server.state.metrics.render();
    let line = format!("relief_errors_total{{kind=\"{}\"}} 1", want.name());
    assert!(m.contains(&line), "{line} missing:\n{m}");
    assert_kept(want.name(), calm, attacked);
    assert_eq!(by.stop().await.desyncs, 0);
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn invalid_utf8_in_a_text_frame_closes_with_1007() {
    violation(
        frame(0x81, true, &[0xc3, 0x28, 0xff]),
        CloseReason::Malformed,
        "utf-8",
    )
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_reserved_data_opcode_closes_with_1002() {
    violation(
        frame(0x83, true, b"x"),
        CloseReason::Protocol,
        "invalid opcode: 3",
    )
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_reserved_control_opcode_closes_with_1002() {
    violation(
        frame(0x8b, true, b""),
        CloseReason::Protocol,
        "invalid opcode: 11",
    )
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rsv_bits_close_with_1002() {
    violation(
        frame(0xc2, true, b"x"),
        CloseReason::Protocol,
        "reserved bits",
    )
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_unmasked_client_frame_closes_with_1002() {
    violation(frame(0x82, false, b"x"), CloseReason::Protocol, "mask").await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_oversized_control_frame_closes_with_1002() {
    violation(
        frame(0x89, true, &[7u8; 126]),
        CloseReason::Protocol,
        "control frame too big",
    )
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_fragmented_control_frame_closes_with_1002() {
    violation(
        frame(0x09, true, b"ping"),
        CloseReason::Protocol,
        "fragmented control",
    )
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stray_continuation_frame_closes_with_1002() {
    violation(
        frame(0x80, true, b"tail"),
        CloseReason::Protocol,
        "nothing to continue",
    )
    .await;
}

/// A client that leaves without a close frame has dropped off the network (`docs/protocol.md`,
/// section 10: reconnect and resume), which is no protocol error: connection churn once counted
/// 1,759 such leavers under `relief_errors_total{kind="protocol"}`.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_that_leaves_without_a_close_frame_is_no_protocol_error() {
    let server = TestServer::start(Limits::default()).await;
    let leavers = 5;
    for _ in 0..leavers {
        let mut tcp = ws_open(lo(2), server.addr).await;
        tcp.write_all(&binary(&hello())).await.unwrap();
        tokio::time::sleep(Duration::from_millis(100)).await;
        // A FIN where the close frame should have been.
        tcp.shutdown().await.unwrap();
    }
    let state = server.state.clone();
    let gone = async {
        while state.metrics.sessions_active.load(Ordering::Relaxed) != 0 {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    };
    tokio::time::timeout(Duration::from_secs(10), gone)
        .await
        .expect("the leavers' sessions end");
    let text = server.state.metrics.render();
    let opened = format!("relief_sessions_total {leavers}");
    assert!(text.contains(&opened), "{opened} missing:\n{text}");
    let protocol_errors = text
        .lines()
        .find_map(|l| l.strip_prefix("relief_errors_total{kind=\"protocol\"} "))
        .map_or(0, |v| v.trim().parse::<u64>().unwrap());
    assert_eq!(
        protocol_errors, 0,
        "leavers counted as protocol errors:\n{text}"
    );
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_slow_reader_reads_its_4007_after_what_it_was_sent() {
    let limits = Limits {
        idle_timeout: Duration::from_secs(1),
        ..Limits::default()
    };
    let server = TestServer::start(limits).await;
    let mut ws = ws_open(lo(1), server.addr).await;
    let hello = relief_tests::query_hello();
    ws.write_all(&binary(&hello)).await.unwrap();
    // Batches whose answers (about 1.2 MB each) fill the socket's buffers, and no reading.
    let batch = |id| binary(&relief_tests::hat_batch(id));
    let (mut rd, mut wr) = ws.into_split();
    let writer = tokio::spawn(async move {
        for id in 0..12 {
            if wr.write_all(&batch(id)).await.is_err() {
                break;
            }
        }
        wr
    });
    // Past the idle timeout, a send waits in vain and the server gives up on this reader,
    // which then reads everything.
    tokio::time::sleep(Duration::from_secs(3)).await;
    let closed = read_close(&mut rd).await;
    drop(writer);
    match closed {
        Closed::Code(code, text) => {
            assert_eq!(code, 4007, "{text}");
            assert!(text.starts_with("slow_reader: "), "{text}");
        }
        other => panic!("the slow reader saw no close frame: {other:?}"),
    }
    server.stop().await;
}
