//! Opening a session's connection: dialling, the hello and welcome, retries with exponential
//! backoff within the reconnect deadline, and the reconnect that resumes from the mirrored cut
//! or tile set (or starts again from scratch).

use super::Session;
use super::stream::StreamState;
use super::types::{ClientError, Link, SessionConfig};
use futures_util::{SinkExt, StreamExt};
use relief_proto::close::CloseReason;
use relief_proto::codec;
use relief_proto::msg::{ClientMsg, Hello, PROTOCOL_VERSION, Resume, ServerMsg, StreamKind};
use std::time::{Duration, Instant};
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::protocol::WebSocketConfig;
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream};

/// A session's WebSocket.
pub(crate) type Ws = WebSocketStream<MaybeTlsStream<TcpStream>>;

pub(crate) fn decode(bytes: &[u8]) -> Result<ServerMsg, ClientError> {
    codec::decode(bytes, codec::HARD_LIMIT).map_err(|e| ClientError::Protocol(e.to_string()))
}

/// Why a dial failed, in words, and whether trying again could help.
struct DialError {
    /// The reason, in the user's terms.
    text: String,
    /// The server answered, but not as a Relief stream (or the URL is unusable): retrying
    /// cannot help, so the session fails at once.
    permanent: bool,
}

impl From<tokio_tungstenite::tungstenite::Error> for DialError {
    fn from(e: tokio_tungstenite::tungstenite::Error) -> DialError {
        use tokio_tungstenite::tungstenite::Error as E;
        match e {
            E::Io(io) => DialError {
                text: crate::server_url::io_reason(&io),
                permanent: false,
            },
            E::Http(resp) if resp.status().is_client_error() => DialError {
                text: format!(
                    "the server answered {} to the WebSocket upgrade: there is no Relief stream at this URL; is it a relief-server?",
                    resp.status()
                ),
                permanent: true,
            },
            E::Http(resp) => DialError {
                text: format!("the server answered {}", resp.status()),
                permanent: false,
            },
            E::Url(u) => DialError {
                text: u.to_string(),
                permanent: true,
            },
            E::Protocol(p) => DialError {
                text: format!("not a WebSocket server ({p}); is it a relief-server?"),
                permanent: true,
            },
            other => DialError {
                text: other.to_string(),
                permanent: false,
            },
        }
    }
}

async fn dial(url: &str) -> Result<Ws, DialError> {
    // tungstenite zero-fills up to a read buffer's worth of spare capacity before every read:
    // 16 KiB instead of the default 128 KiB cut a 2,000-session load client's CPU by a third
    // (it was 39 % memset).
    let cfg = WebSocketConfig::default()
        .read_buffer_size(16 * 1024)
        .max_message_size(Some(codec::HARD_LIMIT))
        .max_frame_size(Some(codec::HARD_LIMIT));
    tokio_tungstenite::connect_async_with_config(url, Some(cfg), true)
        .await
        .map(|(ws, _)| ws)
        .map_err(DialError::from)
}

/// One step of the handshake's outcome.
enum Opened {
    /// Welcomed on this connection.
    Welcome(Box<Ws>, relief_proto::msg::Welcome, usize),
    /// Closed for a reason worth retrying.
    Retry(String),
}

async fn handshake(config: &SessionConfig, resume: Option<Resume>) -> Result<Opened, ClientError> {
    let mut ws = match dial(&config.url).await {
        Ok(ws) => ws,
        Err(e) if e.permanent => {
            return Err(ClientError::Connect {
                url: config.url.clone(),
                last: e.text,
            });
        }
        Err(e) => return Ok(Opened::Retry(e.text)),
    };
    let hello = ClientMsg::Hello(Hello {
        version: PROTOCOL_VERSION,
        kind: config.stream,
        lens: config.lens.into(),
        tau: config.tau,
        budget: config.budget,
        resume,
    });
    if let Err(e) = ws.send(Message::Binary(codec::encode(&hello).into())).await {
        return Ok(Opened::Retry(e.to_string()));
    }
    loop {
        match ws.next().await {
            Some(Ok(Message::Binary(b))) => match decode(&b)? {
                ServerMsg::Welcome(w) => return Ok(Opened::Welcome(Box::new(ws), w, b.len())),
                other => {
                    return Err(ClientError::Protocol(format!(
                        "expected a welcome, got {other:?}"
                    )));
                }
            },
            Some(Ok(Message::Close(frame))) => {
                let (code, text) = frame
                    .map(|f| (u16::from(f.code), f.reason.to_string()))
                    .unwrap_or((1005, String::new()));
                return closed(code, text).map(Opened::Retry);
            }
            Some(Ok(_)) => continue,
            Some(Err(e)) => return Ok(Opened::Retry(e.to_string())),
            None => return Ok(Opened::Retry("connection closed".into())),
        }
    }
}

/// Opens a query session (`StreamKind::Query`) on `url`: one attempt, no retries (a load
/// generator or a test wants to see a refusal, not hide it).
pub(crate) async fn open_query(url: &str) -> Result<(Ws, relief_proto::msg::Welcome), ClientError> {
    let config = SessionConfig {
        stream: StreamKind::Query,
        ..SessionConfig::new(url)
    };
    match handshake(&config, None).await? {
        Opened::Welcome(ws, w, _) => Ok((*ws, w)),
        Opened::Retry(last) => Err(ClientError::Connect {
            url: url.to_string(),
            last,
        }),
    }
}

/// The idle timeout a welcome announces (at least 100 ms, so pings never flood).
pub(super) fn idle_of(w: &relief_proto::msg::Welcome) -> Duration {
    Duration::from_millis(u64::from(w.idle_timeout_ms).max(100))
}

/// A close worth retrying gives its text; any other is the session's end.
pub(crate) fn closed(code: u16, text: String) -> Result<String, ClientError> {
    match CloseReason::from_code(code) {
        Some(r) if !r.retry() => Err(ClientError::Closed { code, text }),
        _ => Ok(format!("closed ({code}): {text}")),
    }
}

impl Session {
    pub(super) async fn establish(
        config: &SessionConfig,
        resume: Option<Resume>,
        link: &Link,
    ) -> Result<(Ws, relief_proto::msg::Welcome, usize), ClientError> {
        let started = Instant::now();
        let mut wait = config.backoff_initial;
        loop {
            let last = match handshake(config, resume.clone()).await? {
                Opened::Welcome(ws, w, bytes) => {
                    if w.version != PROTOCOL_VERSION {
                        return Err(ClientError::Protocol(format!(
                            "server speaks protocol {}, this client {PROTOCOL_VERSION}",
                            w.version
                        )));
                    }
                    return Ok((*ws, w, bytes));
                }
                Opened::Retry(e) => e,
            };
            link.set(Some(format!("{last}; reconnecting")));
            if started.elapsed() + wait > config.reconnect_deadline {
                return Err(ClientError::Connect {
                    url: config.url.clone(),
                    last,
                });
            }
            tracing::debug!("connect failed ({last}); retrying in {wait:?}");
            tokio::time::sleep(wait).await;
            wait = (wait * 2).min(config.backoff_max);
        }
    }

    /// Reconnects, resuming from the mirror's cut unless `fresh`, and sends the last pose again.
    pub(super) async fn reconnect(&mut self, fresh: bool) -> Result<(), ClientError> {
        let dropped = Instant::now();
        self.ws = None;
        self.counters.reconnects += 1;
        self.link.set(Some("connection lost; reconnecting".into()));
        let resume = if fresh {
            None
        } else {
            self.stream.snapshot(&self.geom).map(|snapshot| Resume {
                terrain_id: self.info.id,
                snapshot,
            })
        };
        let (ws, w, bytes) = match Self::establish(&self.config, resume, &self.link).await {
            // The server refused the snapshot (e.g. it now holds another terrain): start afresh.
            Err(ClientError::Closed { code, text }) if code == CloseReason::BadSnapshot.code() => {
                tracing::info!("resume refused ({text}); starting from the root");
                Self::establish(&self.config, None, &self.link).await?
            }
            r => r?,
        };
        let same = w.terrain == self.info && self.stream.same_pyramid(&w);
        if w.resumed && same && w.digest == self.stream.digest() {
            self.stream.resumed();
            self.counters.resumes += 1;
        } else {
            // Start again from scratch (after a desync, or on a server with another terrain).
            self.info = w.terrain.clone();
            self.geom = self
                .info
                .geometry()
                .map_err(|e| ClientError::Protocol(format!("bad terrain in welcome: {e}")))?;
            self.stream =
                StreamState::fresh(&w, &self.geom, tile_params(&self.config), self.config.mesh)?;
            self.generation += 1;
        }
        self.counters.bytes_in += bytes as u64;
        self.max_in_flight = w.max_in_flight;
        self.idle_timeout = idle_of(&w);
        self.ws = Some(ws);
        self.link.set(None);
        self.gaps_ms.push(dropped.elapsed().as_secs_f64() * 1e3);
        if let Some((_, cam)) = self.last_pose {
            self.send_pose(cam).await?;
        }
        Ok(())
    }
}

/// The tile stream's parameters, for a tile session's config.
pub(super) fn tile_params(config: &SessionConfig) -> Option<relief_proto::msg::TileStreamParams> {
    match config.stream {
        StreamKind::Vertex | StreamKind::Query => None,
        StreamKind::Tiles(p) => Some(p),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn protocol_and_invalid_text_closes_are_fatal_and_a_bare_close_is_retried() {
        // The hardened server closes RFC 6455 violations with 1002 and invalid UTF-8 with
        // 1007; retrying would only repeat the fault. A close with no code (1005), or a
        // restart (1012), is worth retrying.
        for code in [1002, 1007, 4009] {
            let e = closed(code, "protocol: x".into()).unwrap_err();
            assert!(matches!(e, ClientError::Closed { code: c, .. } if c == code));
        }
        for code in [1005, 1012, 1013, 4006] {
            assert!(closed(code, String::new()).is_ok(), "{code}");
        }
    }
}
