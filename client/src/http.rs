//! A minimal HTTP/1.1 client for the server's HTTP endpoints (terrain metadata, heights, the
//! one-shot), on hyper's connection API: one request per connection, plain `http://` only.

use http_body_util::{BodyExt, Full};
use hyper::body::Bytes;
use hyper_util::rt::TokioIo;
use tokio::net::TcpStream;

use crate::server_url::{ServerUrl, UrlError, io_reason};

/// A request that failed.
#[derive(Debug, thiserror::Error)]
pub enum HttpError {
    /// The server's URL is not one this client takes.
    #[error(transparent)]
    Url(#[from] UrlError),
    /// No TCP connection to the server.
    #[error("cannot connect to {authority}: {reason}")]
    Connect {
        /// `host:port`.
        authority: String,
        /// Why, in words.
        reason: String,
    },
    /// Connecting, sending or reading failed.
    #[error("request to {url} failed: {message}")]
    Io {
        /// The URL.
        url: String,
        /// What failed.
        message: String,
    },
    /// The server answered with an error status.
    #[error("{url} answered {status}: {body}")]
    Status {
        /// The URL.
        url: String,
        /// The status code.
        status: u16,
        /// The body, as text.
        body: String,
    },
}

/// `(authority, path)` of a URL on the server's HTTP base (`http://host:port/...`, as
/// [`ServerUrl::base`] makes them).
pub fn split_url(url: &str) -> Result<(String, String), HttpError> {
    let bad = |why: &str| UrlError {
        input: url.to_string(),
        why: why.to_string(),
    };
    let rest = url
        .strip_prefix("http://")
        .ok_or_else(|| bad("not an http:// URL"))?;
    let (authority, path) = match rest.find('/') {
        Some(i) => (&rest[..i], &rest[i..]),
        None => (rest, "/"),
    };
    if authority.is_empty() {
        return Err(bad("no host").into());
    }
    Ok((authority.to_string(), path.to_string()))
}

/// The HTTP base (`http://host:port`) of a server URL in any form [`ServerUrl`] takes.
pub fn base_of(url: &str) -> Result<String, HttpError> {
    Ok(ServerUrl::parse(url)?.base())
}

/// Sends one request and returns the body of a 2xx answer.
pub async fn request(
    method: &str,
    url: &str,
    content_type: &str,
    body: Vec<u8>,
) -> Result<Bytes, HttpError> {
    let (authority, path) = split_url(url)?;
    let io_err = |e: &dyn std::fmt::Display| HttpError::Io {
        url: url.to_string(),
        message: e.to_string(),
    };
    let tcp = TcpStream::connect(&authority)
        .await
        .map_err(|e| HttpError::Connect {
            authority: authority.clone(),
            reason: io_reason(&e),
        })?;
    let (mut send, conn) = hyper::client::conn::http1::handshake(TokioIo::new(tcp))
        .await
        .map_err(|e| io_err(&e))?;
    tokio::spawn(conn);
    let req = hyper::Request::builder()
        .method(method)
        .uri(path)
        .header(hyper::header::HOST, &authority)
        .header(hyper::header::CONTENT_TYPE, content_type)
        .body(Full::new(Bytes::from(body)))
        .map_err(|e| io_err(&e))?;
    let resp = send.send_request(req).await.map_err(|e| io_err(&e))?;
    let status = resp.status();
    let bytes = resp
        .into_body()
        .collect()
        .await
        .map_err(|e| io_err(&e))?
        .to_bytes();
    if !status.is_success() {
        return Err(HttpError::Status {
            url: url.to_string(),
            status: status.as_u16(),
            body: summary(&String::from_utf8_lossy(&bytes), status.as_u16()),
        });
    }
    Ok(bytes)
}

/// An error body in one line: the server's own message (its first line, at most 200
/// characters), or, for an HTML page or an empty 404, a hint that this may be some other server.
fn summary(body: &str, status: u16) -> String {
    let line = body.trim().lines().next().unwrap_or("").trim();
    let other = "is it a relief-server?";
    if line.starts_with('<') {
        return format!("an HTML page; {other}");
    }
    let line: String = line.chars().take(200).collect();
    match (line.is_empty(), status == 404) {
        (true, true) => other.to_string(),
        (true, false) => "(no message)".to_string(),
        (false, _) => line,
    }
}

/// `GET url`, parsed as JSON.
pub async fn get_json(url: &str) -> Result<serde_json::Value, HttpError> {
    let b = request("GET", url, "application/json", Vec::new()).await?;
    serde_json::from_slice(&b).map_err(|e| HttpError::Io {
        url: url.to_string(),
        message: format!("bad JSON: {e}"),
    })
}

/// `POST url` with a JSON body, parsed as JSON.
pub async fn post_json(
    url: &str,
    body: &serde_json::Value,
) -> Result<serde_json::Value, HttpError> {
    let b = request(
        "POST",
        url,
        "application/json",
        body.to_string().into_bytes(),
    )
    .await?;
    serde_json::from_slice(&b).map_err(|e| HttpError::Io {
        url: url.to_string(),
        message: format!("bad JSON: {e}"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls_split() {
        assert_eq!(
            split_url("http://127.0.0.1:8080/v1/terrain").unwrap(),
            ("127.0.0.1:8080".into(), "/v1/terrain".into())
        );
        assert_eq!(base_of("ws://h:1/v1/stream").unwrap(), "http://h:1");
        assert_eq!(base_of("http://h:1").unwrap(), "http://h:1");
        assert_eq!(split_url("http://h:2").unwrap().1, "/");
        assert!(split_url("wss://h/x").is_err());
        assert!(split_url("ws://h:1/x").is_err());
        assert!(split_url("http:///x").is_err());
    }

    #[test]
    fn error_bodies_fit_one_line() {
        assert_eq!(
            summary("<!DOCTYPE HTML>\n<html>", 404),
            "an HTML page; is it a relief-server?"
        );
        assert_eq!(summary("", 404), "is it a relief-server?");
        assert_eq!(
            summary("tau must be positive\n", 400),
            "tau must be positive"
        );
    }
}
