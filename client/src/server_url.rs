//! Where a Relief server is, from what the user typed after `--server`: one parse that gives the
//! stream's WebSocket URL and the HTTP base of the same server, so that every command derives
//! both the same way, and errors that name what was typed.
//!
//! Accepted: `ws://HOST[:PORT]`, `http://HOST[:PORT]` or a bare `HOST:PORT`, each with or without
//! the stream's path `/v1/stream` (and a trailing `/`). The port defaults to 80, as in any URL.

/// The stream's path on every Relief server.
pub const STREAM_PATH: &str = "/v1/stream";

/// A server's address, normalised.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ServerUrl {
    /// `host:port`, the port always present: what a TCP connection dials and what errors name.
    authority: String,
}

/// What is wrong with a `--server` value, in the user's terms.
#[derive(Debug, thiserror::Error)]
#[error(
    "--server {input:?}: {why}; give e.g. ws://127.0.0.1:8080/v1/stream or http://127.0.0.1:8080"
)]
pub struct UrlError {
    /// What the user typed.
    pub input: String,
    /// What is wrong with it.
    pub why: String,
}

impl ServerUrl {
    /// Parses `input` (see the module's docs for what is accepted).
    pub fn parse(input: &str) -> Result<ServerUrl, UrlError> {
        let err = |why: String| UrlError {
            input: input.to_string(),
            why,
        };
        let s = input.trim();
        let schemed = s.contains("://");
        let rest = match s.split_once("://") {
            Some(("ws" | "http", rest)) => rest,
            Some(("wss" | "https", _)) => {
                return Err(err(
                    "TLS is not supported: relief-server serves plain ws:// and http://; put a TLS proxy in front of it and point this client at the server itself".into(),
                ));
            }
            Some((scheme, _)) => {
                return Err(err(format!(
                    "the scheme {scheme}:// is not one of ws:// and http://"
                )));
            }
            None => s,
        };
        let (authority, path) = match rest.find(['/', '?', '#']) {
            Some(i) => (&rest[..i], &rest[i..]),
            None => (rest, ""),
        };
        let path = path.strip_suffix('/').unwrap_or(path);
        if !path.is_empty() && path != STREAM_PATH {
            return Err(err(format!(
                "the path {path:?} is not the stream's; the stream is at {STREAM_PATH} (or leave the path out)"
            )));
        }
        if authority.is_empty() {
            return Err(err("no host".into()));
        }
        if authority.contains('@') {
            return Err(err("user names and passwords are not supported".into()));
        }
        // The port: after the last ':' unless that is inside an IPv6 literal `[...]`.
        let port_at = authority
            .rfind(':')
            .filter(|&i| !authority[i..].contains(']'));
        let authority = match port_at {
            Some(i) => {
                let (host, port) = (&authority[..i], &authority[i + 1..]);
                if host.is_empty() {
                    return Err(err("no host".into()));
                }
                if port.parse::<u16>().is_err() {
                    return Err(err(format!(
                        "the port {port:?} is not a number up to 65535"
                    )));
                }
                authority.to_string()
            }
            None if schemed => format!("{authority}:80"),
            None => {
                return Err(err(
                    "no port (without ws:// or http://, give HOST:PORT)".into()
                ));
            }
        };
        Ok(ServerUrl { authority })
    }

    /// `host:port`.
    pub fn authority(&self) -> &str {
        &self.authority
    }

    /// The stream's WebSocket URL: `ws://host:port/v1/stream`.
    pub fn stream(&self) -> String {
        format!("ws://{}{STREAM_PATH}", self.authority)
    }

    /// The server's HTTP base, with no trailing `/`: `http://host:port`.
    pub fn base(&self) -> String {
        format!("http://{}", self.authority)
    }
}

/// An I/O error's reason in words, without Rust's `(os error N)` suffix and lower-cased, with a
/// hint for the common ones.
pub fn io_reason(e: &std::io::Error) -> String {
    use std::io::ErrorKind::*;
    match e.kind() {
        ConnectionRefused => {
            "connection refused; is `relief-server serve` running there?".to_string()
        }
        TimedOut => "timed out; is the host reachable and the port open?".to_string(),
        ConnectionReset | ConnectionAborted | UnexpectedEof => {
            "the connection was closed at once; is it a Relief server?".to_string()
        }
        _ if e.to_string().contains("failed to lookup address") => {
            "the host name does not resolve (no such host)".to_string()
        }
        _ => {
            let s = e.to_string();
            let s = match s.find(" (os error") {
                Some(i) => s[..i].to_string(),
                None => s,
            };
            let mut c = s.chars();
            match c.next() {
                Some(f) => f.to_lowercase().chain(c).collect(),
                None => s,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn norm(s: &str) -> (String, String) {
        let u = ServerUrl::parse(s).unwrap();
        (u.stream(), u.base())
    }

    #[test]
    fn every_accepted_form_names_the_same_stream_and_base() {
        let want = (
            "ws://127.0.0.1:8080/v1/stream".to_string(),
            "http://127.0.0.1:8080".to_string(),
        );
        for s in [
            "ws://127.0.0.1:8080/v1/stream",
            "ws://127.0.0.1:8080/v1/stream/",
            "ws://127.0.0.1:8080",
            "ws://127.0.0.1:8080/",
            "http://127.0.0.1:8080",
            "http://127.0.0.1:8080/",
            "http://127.0.0.1:8080/v1/stream",
            "127.0.0.1:8080",
            " 127.0.0.1:8080/v1/stream ",
        ] {
            assert_eq!(norm(s), want, "{s}");
        }
    }

    #[test]
    fn host_names_ipv6_and_the_default_port() {
        assert_eq!(norm("ws://localhost:9").0, "ws://localhost:9/v1/stream");
        assert_eq!(norm("http://relief.example").1, "http://relief.example:80");
        assert_eq!(norm("ws://[::1]:8080").0, "ws://[::1]:8080/v1/stream");
        assert_eq!(norm("ws://[::1]").1, "http://[::1]:80");
    }

    #[test]
    fn errors_say_what_is_wrong() {
        let why = |s: &str| ServerUrl::parse(s).unwrap_err().to_string();
        assert!(why("wss://h:1").contains("TLS is not supported"));
        assert!(why("https://h:1/v1/stream").contains("TLS is not supported"));
        assert!(why("ftp://h:1").contains("ftp:// is not one of"));
        assert!(why("ws://h:1/v2/stream").contains("the stream is at /v1/stream"));
        assert!(why("ws://h:1/v1/stream?x=1").contains("not the stream's"));
        assert!(why("ws://:8080").contains("no host"));
        assert!(why("http://").contains("no host"));
        assert!(why("ws://h:80a").contains("port \"80a\""));
        assert!(why("ws://h:99999").contains("up to 65535"));
        assert!(why("ws://u@h:1").contains("passwords"));
        assert!(why("x").starts_with("--server \"x\": no port"));
    }

    #[test]
    fn io_reasons_read_as_words() {
        use std::io::{Error, ErrorKind};
        assert!(
            io_reason(&Error::from(ErrorKind::ConnectionRefused))
                .starts_with("connection refused; is `relief-server serve` running")
        );
        assert_eq!(
            io_reason(&Error::other("Permission denied (os error 13)")),
            "permission denied"
        );
        assert!(
            io_reason(&Error::other(
                "failed to lookup address information: Name or service not known"
            ))
            .contains("does not resolve")
        );
    }
}
