//! A minimal HTTP/1.1 client for the server's HTTP endpoints (terrain metadata, heights, the
//! one-shot), on hyper's connection API: one request per connection, plain `http://` only.

use http_body_util::{BodyExt, Full};
use hyper::body::Bytes;
use hyper_util::rt::TokioIo;
use tokio::net::TcpStream;

/// A request that failed.
#[derive(Debug, thiserror::Error)]
pub enum HttpError {
    /// The URL is not `http://host:port/...` (or `ws://`, which is mapped to `http://`).
    #[error("unsupported URL {0}: expected http://HOST:PORT/... or ws://HOST:PORT/...")]
    Url(String),
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

/// `(authority, path)` of an `http://` or `ws://` URL.
pub fn split_url(url: &str) -> Result<(String, String), HttpError> {
    let rest = url
        .strip_prefix("http://")
        .or_else(|| url.strip_prefix("ws://"))
        .ok_or_else(|| HttpError::Url(url.to_string()))?;
    let (authority, path) = match rest.find('/') {
        Some(i) => (&rest[..i], &rest[i..]),
        None => (rest, "/"),
    };
    if authority.is_empty() {
        return Err(HttpError::Url(url.to_string()));
    }
    Ok((authority.to_string(), path.to_string()))
}

/// The HTTP base (`http://host:port`) of a stream URL such as `ws://host:port/v1/stream`.
pub fn base_of(url: &str) -> Result<String, HttpError> {
    Ok(format!("http://{}", split_url(url)?.0))
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
        .map_err(|e| io_err(&e))?;
    let (mut send, conn) = hyper::client::conn::http1::handshake(TokioIo::new(tcp))
        .await
        .map_err(|e| io_err(&e))?;
    tokio::spawn(conn);
    let req = hyper::Request::builder()
        .method(method)
        .uri(path)
        .header(hyper::header::HOST, authority)
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
            body: String::from_utf8_lossy(&bytes).into_owned(),
        });
    }
    Ok(bytes)
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
            split_url("ws://127.0.0.1:8080/v1/stream").unwrap(),
            ("127.0.0.1:8080".into(), "/v1/stream".into())
        );
        assert_eq!(base_of("ws://h:1/v1/stream").unwrap(), "http://h:1");
        assert_eq!(split_url("http://h:2").unwrap().1, "/");
        assert!(split_url("wss://h/x").is_err());
        assert!(split_url("http:///x").is_err());
    }
}
