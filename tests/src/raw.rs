//! Raw sockets for the hostile-input tests: connections from a chosen loopback address, a
//! WebSocket handshake by hand, frames built bit by bit (so that they can break RFC 6455),
//! the server's close frame parsed from the wire, and HTTP requests written byte by byte.

use std::net::{IpAddr, SocketAddr};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpSocket, TcpStream};

/// A TCP connection to `server` from `from` (any 127.0.0.0/8 address works on Linux, so tests
/// can play several clients).
pub async fn connect_from(from: IpAddr, server: SocketAddr) -> std::io::Result<TcpStream> {
    let s = TcpSocket::new_v4()?;
    s.bind(SocketAddr::new(from, 0))?;
    s.connect(server).await
}

/// Reads until the end of the HTTP head; returns the head.
async fn read_head(tcp: &mut TcpStream) -> std::io::Result<String> {
    let mut head = Vec::new();
    let mut byte = [0u8; 1];
    while !head.ends_with(b"\r\n\r\n") {
        if tcp.read(&mut byte).await? == 0 {
            return Err(std::io::ErrorKind::UnexpectedEof.into());
        }
        head.push(byte[0]);
    }
    Ok(String::from_utf8_lossy(&head).into_owned())
}

/// Opens a WebSocket on `/v1/stream` by hand from `from`; returns the socket after the 101.
pub async fn ws_open(from: IpAddr, server: SocketAddr) -> TcpStream {
    let mut tcp = connect_from(from, server).await.expect("connect");
    let req = format!(
        "GET /v1/stream HTTP/1.1\r\nHost: {server}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
         Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n"
    );
    tcp.write_all(req.as_bytes()).await.expect("handshake");
    let head = read_head(&mut tcp).await.expect("handshake response");
    assert!(head.starts_with("HTTP/1.1 101"), "{head}");
    tcp
}

/// One frame, any bits: `first` is the FIN/RSV/opcode byte; masked with a fixed key when
/// `masked`.
pub fn frame(first: u8, masked: bool, payload: &[u8]) -> Vec<u8> {
    let mut f = vec![first];
    let m = if masked { 0x80 } else { 0 };
    match payload.len() {
        n if n < 126 => f.push(m | n as u8),
        n if n < 65536 => {
            f.push(m | 126);
            f.extend_from_slice(&(n as u16).to_be_bytes());
        }
        n => {
            f.push(m | 127);
            f.extend_from_slice(&(n as u64).to_be_bytes());
        }
    }
    if masked {
        let key = [0x37, 0xfa, 0x21, 0x3d];
        f.extend_from_slice(&key);
        f.extend(payload.iter().enumerate().map(|(i, b)| b ^ key[i % 4]));
    } else {
        f.extend_from_slice(payload);
    }
    f
}

/// A masked binary frame holding `msg`.
pub fn binary(msg: &[u8]) -> Vec<u8> {
    frame(0x82, true, msg)
}

/// What the server's last frame said.
#[derive(Debug, PartialEq, Eq)]
pub enum Closed {
    /// A close frame with a code and its text.
    Code(u16, String),
    /// A close frame with no code (`88 00`).
    NoCode,
    /// The connection ended without a close frame.
    NoFrame,
    /// The server sent the data frames waited for, and no close.
    Open,
}

/// Reads server frames until a close frame (binary frames are skipped), within 20 s.
pub async fn read_close(tcp: &mut (impl AsyncRead + Unpin)) -> Closed {
    read_close_or(tcp, usize::MAX).await
}

/// Reads server frames until a close frame, or until `data` data frames came ([`Closed::Open`]),
/// within 20 s.
pub async fn read_close_or(tcp: &mut (impl AsyncRead + Unpin), data: usize) -> Closed {
    let mut seen = 0;
    let read = async {
        loop {
            let mut h = [0u8; 2];
            if tcp.read_exact(&mut h).await.is_err() {
                return Closed::NoFrame;
            }
            let mut len = u64::from(h[1] & 0x7f);
            if len == 126 {
                let mut b = [0u8; 2];
                if tcp.read_exact(&mut b).await.is_err() {
                    return Closed::NoFrame;
                }
                len = u64::from(u16::from_be_bytes(b));
            } else if len == 127 {
                let mut b = [0u8; 8];
                if tcp.read_exact(&mut b).await.is_err() {
                    return Closed::NoFrame;
                }
                len = u64::from_be_bytes(b);
            }
            let mut payload = vec![0u8; len as usize];
            if tcp.read_exact(&mut payload).await.is_err() {
                return Closed::NoFrame;
            }
            if h[0] & 0x0f == 0x8 {
                return match payload.len() {
                    0 => Closed::NoCode,
                    _ => Closed::Code(
                        u16::from_be_bytes([payload[0], payload.get(1).copied().unwrap_or(0)]),
                        String::from_utf8_lossy(&payload[2.min(payload.len())..]).into_owned(),
                    ),
                };
            }
            seen += 1;
            if seen >= data {
                return Closed::Open;
            }
        }
    };
    tokio::time::timeout(Duration::from_secs(20), read)
        .await
        .unwrap_or(Closed::NoFrame)
}

/// Starts a `POST` to `path` from `from` that declares a body of `declared` bytes and sends
/// only `body` of it; the connection is returned open, the request unfinished.
pub async fn partial_post(
    from: IpAddr,
    server: SocketAddr,
    path: &str,
    declared: usize,
    body: &[u8],
) -> std::io::Result<TcpStream> {
    let mut tcp = connect_from(from, server).await?;
    let head = format!(
        "POST {path} HTTP/1.1\r\nHost: {server}\r\nContent-Type: application/json\r\n\
         Content-Length: {declared}\r\n\r\n"
    );
    tcp.write_all(head.as_bytes()).await?;
    tcp.write_all(body).await?;
    Ok(tcp)
}

/// Reads an HTTP response's status code and body (`Content-Length` bodies), within `limit`.
pub async fn read_response(tcp: &mut TcpStream, limit: Duration) -> Option<(u16, String)> {
    let read = async {
        let head = read_head(tcp).await.ok()?;
        let status = head.get(9..12)?.parse().ok()?;
        let len = head
            .lines()
            .find_map(|l| {
                let (k, v) = l.split_once(':')?;
                k.eq_ignore_ascii_case("content-length")
                    .then(|| v.trim().parse::<usize>().ok())?
            })
            .unwrap_or(0);
        let mut body = vec![0u8; len];
        tcp.read_exact(&mut body).await.ok()?;
        Some((status, String::from_utf8_lossy(&body).into_owned()))
    };
    tokio::time::timeout(limit, read).await.ok()?
}

/// A `GET` of `path` from `from` on a fresh connection: status and body, within 5 s.
pub async fn get_from(from: IpAddr, server: SocketAddr, path: &str) -> Option<(u16, String)> {
    let mut tcp = connect_from(from, server).await.ok()?;
    let req = format!("GET {path} HTTP/1.1\r\nHost: {server}\r\nConnection: close\r\n\r\n");
    tcp.write_all(req.as_bytes()).await.ok()?;
    read_response(&mut tcp, Duration::from_secs(5)).await
}

/// The loopback address `127.0.0.n`.
pub fn lo(n: u8) -> IpAddr {
    IpAddr::from([127, 0, 0, n])
}
