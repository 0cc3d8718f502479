//! A query session (`docs/protocol.md` section 12): batches of terrain queries sent on one
//! WebSocket, answered in order. [`QueryClient::ask`] sends one batch and waits for its
//! answers; [`QueryClient::split`] gives a sender and a receiver, so that batches can be
//! pipelined (the load generator sends on a clock and matches answers by id).

use crate::session::{ClientError, Socket, closed, decode, open_query};
use futures_util::stream::{SplitSink, SplitStream};
use futures_util::{SinkExt, StreamExt};
use relief_proto::codec;
use relief_proto::msg::{ClientMsg, ServerMsg, Welcome};
use relief_proto::query::{AnswerBatch, BatchRefused, QueryBatch};
use tokio_tungstenite::tungstenite::Message;

/// What the server said to one batch.
#[derive(Clone, Debug, PartialEq)]
pub enum Reply {
    /// The answers, one per query.
    Answers(AnswerBatch),
    /// The batch was refused whole (over the limits).
    Refused(BatchRefused),
}

impl Reply {
    /// The id of the batch this answers.
    pub fn id(&self) -> u64 {
        match self {
            Reply::Answers(a) => a.id,
            Reply::Refused(r) => r.id,
        }
    }
}

/// A connected query session.
pub struct QueryClient {
    /// The connection.
    ws: Socket,
    /// The server's welcome (the terrain, the limits).
    pub welcome: Welcome,
}

/// The sending half of a query session.
pub struct QuerySender(SplitSink<Socket, Message>);

/// The receiving half of a query session.
pub struct QueryReceiver(SplitStream<Socket>);

impl QueryClient {
    /// Connects to the stream URL (`ws://host:port/v1/stream`) and opens a query session.
    pub async fn connect(url: &str) -> Result<QueryClient, ClientError> {
        let (ws, welcome) = open_query(url).await?;
        Ok(QueryClient { ws, welcome })
    }

    /// Sends `batch` and waits for the server's reply to it.
    pub async fn ask(&mut self, batch: &QueryBatch) -> Result<Reply, ClientError> {
        let bytes = codec::encode(&ClientMsg::Query(batch.clone()));
        self.ws
            .send(Message::Binary(bytes.into()))
            .await
            .map_err(|e| ClientError::Protocol(format!("cannot send: {e}")))?;
        next_reply(&mut self.ws).await.map(|(r, _)| r)
    }

    /// The two halves, for pipelining.
    pub fn split(self) -> (QuerySender, QueryReceiver) {
        let (tx, rx) = self.ws.split();
        (QuerySender(tx), QueryReceiver(rx))
    }
}

impl QuerySender {
    /// Sends one batch; returns the message's size in bytes.
    pub async fn send(&mut self, batch: &QueryBatch) -> Result<usize, ClientError> {
        self.send_encoded(codec::encode(&ClientMsg::Query(batch.clone())))
            .await
    }

    /// Sends a message already encoded (a `ClientMsg::Query`), as the load generator does to
    /// keep encoding out of its clock.
    pub async fn send_encoded(&mut self, bytes: Vec<u8>) -> Result<usize, ClientError> {
        let n = bytes.len();
        self.0
            .send(Message::Binary(bytes.into()))
            .await
            .map_err(|e| ClientError::Protocol(format!("cannot send: {e}")))?;
        Ok(n)
    }

    /// Closes the session.
    pub async fn close(mut self) {
        let _ = self.0.close().await;
    }
}

impl QueryReceiver {
    /// The next reply and its size in bytes.
    pub async fn next(&mut self) -> Result<(Reply, usize), ClientError> {
        next_reply(&mut self.0).await
    }
}

/// Reads until the next reply, skipping pings; a close or a non-query message is an error.
async fn next_reply<S>(ws: &mut S) -> Result<(Reply, usize), ClientError>
where
    S: futures_util::Stream<Item = Result<Message, tokio_tungstenite::tungstenite::Error>> + Unpin,
{
    loop {
        let msg = match ws.next().await {
            Some(Ok(m)) => m,
            Some(Err(e)) => return Err(ClientError::Protocol(format!("connection failed: {e}"))),
            None => return Err(ClientError::Protocol("the connection closed".into())),
        };
        match msg {
            Message::Binary(b) => {
                return match decode(&b)? {
                    ServerMsg::Answers(a) => Ok((Reply::Answers(a), b.len())),
                    ServerMsg::Refused(r) => Ok((Reply::Refused(r), b.len())),
                    other => Err(ClientError::Protocol(format!(
                        "expected query answers, got {}",
                        kind(&other)
                    ))),
                };
            }
            Message::Close(frame) => {
                let (code, text) = frame
                    .map(|f| (u16::from(f.code), f.reason.to_string()))
                    .unwrap_or((1005, String::new()));
                return Err(match closed(code, text) {
                    Err(e) => e,
                    Ok(text) => ClientError::Protocol(text),
                });
            }
            _ => continue,
        }
    }
}

/// A server message's kind, in words.
fn kind(m: &ServerMsg) -> &'static str {
    match m {
        ServerMsg::Welcome(_) => "a welcome",
        ServerMsg::Delta(_) => "a delta",
        ServerMsg::Reconnect { .. } => "a reconnect",
        ServerMsg::Answers(_) => "answers",
        ServerMsg::Refused(_) => "a refusal",
    }
}
