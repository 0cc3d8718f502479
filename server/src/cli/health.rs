//! `relief-server health`: one plain HTTP/1.1 GET over a socket, for container health checks in
//! an image that holds nothing but the server.

use anyhow::Context;
use std::io::{Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

/// The status code `url` (`http://host:port/path`) answers within `timeout`.
pub fn get_status(url: &str, timeout: Duration) -> anyhow::Result<u16> {
    let rest = url
        .strip_prefix("http://")
        .with_context(|| format!("{url:?} is not an http:// URL"))?;
    let (authority, path) = match rest.find('/') {
        Some(i) => (&rest[..i], &rest[i..]),
        None => (rest, "/"),
    };
    let addr = authority
        .to_socket_addrs()
        .with_context(|| format!("cannot resolve {authority:?} (want host:port)"))?
        .next()
        .with_context(|| format!("{authority:?} resolves to no address"))?;
    let mut sock = TcpStream::connect_timeout(&addr, timeout)
        .with_context(|| format!("cannot connect to {authority}"))?;
    sock.set_read_timeout(Some(timeout))?;
    sock.set_write_timeout(Some(timeout))?;
    // One write: `write!` on an unbuffered socket sends each piece of the format on its own.
    let request = format!("GET {path} HTTP/1.1\r\nHost: {authority}\r\nConnection: close\r\n\r\n");
    sock.write_all(request.as_bytes())?;
    let head = read_status_line(&mut sock).with_context(|| format!("{url} did not answer"))?;
    let line = String::from_utf8_lossy(&head);
    line.split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .with_context(|| format!("{url} answered something other than HTTP: {line:?}"))
}

/// The bytes up to the first line end (or the first 256, or what came before the peer closed):
/// a status line may arrive over several reads.
fn read_status_line(sock: &mut impl Read) -> std::io::Result<Vec<u8>> {
    let mut head = Vec::with_capacity(64);
    let mut buf = [0u8; 64];
    while !head.contains(&b'\n') && head.len() < 256 {
        let n = sock.read(&mut buf)?;
        if n == 0 {
            break;
        }
        head.extend_from_slice(&buf[..n]);
    }
    Ok(head)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_urls_and_dead_ports_are_errors() {
        let t = Duration::from_millis(500);
        assert!(get_status("https://x/", t).is_err());
        assert!(get_status("http://no-such-host.invalid:1/", t).is_err());
        let free = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let port = free.local_addr().unwrap().port();
        drop(free);
        let e = get_status(&format!("http://127.0.0.1:{port}/healthz"), t).unwrap_err();
        assert!(e.to_string().contains("cannot connect"), "{e}");
    }

    #[test]
    fn a_status_line_is_read() {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let url = format!("http://{}/readyz", l.local_addr().unwrap());
        let server = std::thread::spawn(move || {
            let (mut s, _) = l.accept().unwrap();
            // The whole request, however many reads it takes.
            let mut req = Vec::new();
            let mut buf = [0u8; 256];
            while !req.ends_with(b"\r\n\r\n") {
                let n = s.read(&mut buf).unwrap();
                assert!(n > 0, "the request ended early: {req:?}");
                req.extend_from_slice(&buf[..n]);
            }
            assert!(String::from_utf8_lossy(&req).starts_with("GET /readyz HTTP/1.1\r\n"));
            // The status line in two pieces, as a slow peer may send it.
            s.write_all(b"HTTP/1.1 50").unwrap();
            s.flush().unwrap();
            std::thread::sleep(Duration::from_millis(50));
            s.write_all(b"3 Service Unavailable\r\n\r\n").unwrap();
        });
        assert_eq!(get_status(&url, Duration::from_secs(2)).unwrap(), 503);
        server.join().unwrap();
    }
}
