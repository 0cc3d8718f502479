//! The session driven through channels instead of a socket, on paused time.

use super::*;
use crate::serve::config::Limits;
use crate::serve::limits::SlotLimits;
use relief_proto::codec;
use std::pin::Pin;
use std::task::{Context, Poll};
use tokio::sync::mpsc;

/// One end of an in-memory WebSocket: messages in from the test, messages out to it.
struct Duplex {
    /// What the test sends.
    rx: mpsc::UnboundedReceiver<Result<Message, std::io::Error>>,
    /// What the session sends.
    tx: mpsc::UnboundedSender<Message>,
}

impl Stream for Duplex {
    type Item = Result<Message, std::io::Error>;
    fn poll_next(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Self::Item>> {
        self.rx.poll_recv(cx)
    }
}

impl Sink<Message> for Duplex {
    type Error = std::io::Error;
    fn poll_ready(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<Result<(), Self::Error>> {
        Poll::Ready(Ok(()))
    }
    fn start_send(self: Pin<&mut Self>, item: Message) -> Result<(), Self::Error> {
        self.tx
            .send(item)
            .map_err(|_| std::io::Error::other("the test hung up"))
    }
    fn poll_flush(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<Result<(), Self::Error>> {
        Poll::Ready(Ok(()))
    }
    fn poll_close(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<Result<(), Self::Error>> {
        Poll::Ready(Ok(()))
    }
}

fn state(
    dir: &std::path::Path,
    limits: Limits,
) -> (Arc<AppState>, tokio::sync::watch::Sender<bool>) {
    let store =
        crate::serve::source::open_terrain(&crate::serve::config::TerrainSource::Embedded, dir)
            .unwrap();
    let (tx, rx) = tokio::sync::watch::channel(false);
    let s = Arc::new(AppState::new(limits, rx));
    let _ = s.terrain.set(Arc::new(Terrain::new(store)));
    (s, tx)
}

fn frame(msg: &ClientMsg) -> Result<Message, std::io::Error> {
    Ok(Message::Binary(codec::encode(msg).into()))
}

fn decode_server(m: &Message) -> ServerMsg {
    match m {
        Message::Binary(b) => codec::decode(b, codec::HARD_LIMIT).unwrap(),
        other => panic!("expected a binary frame, got {other:?}"),
    }
}

#[tokio::test(start_paused = true)]
async fn poses_coalesce_while_the_window_is_full_and_silence_times_out() {
    let dir = tempfile::tempdir().unwrap();
    let limits = Limits {
        max_in_flight: 1,
        idle_timeout: Duration::from_secs(60),
        ..Limits::default()
    };
    let (state, _draining) = state(dir.path(), limits);
    let (to_server, rx) = mpsc::unbounded_channel();
    let (tx, mut from_server) = mpsc::unbounded_channel();
    let permit = SlotLimits::new(1, 1)
        .admit("127.0.0.1".parse().unwrap())
        .unwrap();
    let peer = "127.0.0.1:1".parse().unwrap();
    let task = tokio::spawn(run(Duplex { rx, tx }, state.clone(), peer, permit));

    let lens = relief_proto::view::Lens::STANDARD.into();
    let hello = ClientMsg::Hello(Hello {
        version: PROTOCOL_VERSION,
        kind: StreamKind::Vertex,
        lens,
        tau: 1.0,
        budget: None,
        resume: None,
    });
    to_server.send(frame(&hello)).unwrap();
    assert!(matches!(
        decode_server(&from_server.recv().await.unwrap()),
        ServerMsg::Welcome(_)
    ));
    // Three poses before any acknowledgement: the first is answered, the next two wait for
    // the window and coalesce into the newest.
    let info = state.terrain().unwrap().info.clone();
    let cam = |i: u64| relief_proto::msg::WireCamera {
        eye: [9000.0 + 100.0 * i as f32, 9000.0, 4000.0],
        yaw: 0.5,
        pitch: -0.3,
    };
    assert!(info.width > 0);
    for seq in 1..=3 {
        to_server
            .send(frame(&ClientMsg::Pose {
                seq,
                camera: cam(seq),
            }))
            .unwrap();
    }
    let ServerMsg::Delta(first) = decode_server(&from_server.recv().await.unwrap()) else {
        panic!("expected a delta");
    };
    assert_eq!(first.pose_seq, 1);
    tokio::time::sleep(Duration::from_secs(1)).await;
    assert!(from_server.try_recv().is_err(), "a delta beyond the window");
    to_server.send(frame(&ClientMsg::Ack { seq: 1 })).unwrap();
    let ServerMsg::Delta(second) = decode_server(&from_server.recv().await.unwrap()) else {
        panic!("expected a delta");
    };
    assert_eq!(second.pose_seq, 3, "pose 2 should have been coalesced away");
    to_server.send(frame(&ClientMsg::Ack { seq: 2 })).unwrap();
    // Then silence: a minute later (of paused time) the session closes as idle.
    let close = from_server.recv().await.unwrap();
    let Message::Close(Some(f)) = close else {
        panic!("expected a close frame, got {close:?}");
    };
    assert_eq!(f.code, CloseReason::Idle.code());
    task.await.unwrap();
    assert!(
        state
            .metrics
            .render()
            .contains("relief_errors_total{kind=\"idle\"} 1")
    );
}
