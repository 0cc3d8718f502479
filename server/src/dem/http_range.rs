//! [`RangeReader`]: a remote file read by HTTP range requests (RFC 9110 section 14), the way
//! S3, GCS, MinIO and nginx serve files, so that a Cloud-Optimized GeoTIFF costs its directory
//! and the tiles read rather than a download of the whole file.
//!
//! - The file is read in aligned blocks ([`RangeOptions::block_size`], 64 KiB: a COG's
//!   directory usually fits the first), kept in a small least-recently-used cache. A chunk the
//!   TIFF reader announces ([`Source::will_read`]) is fetched in one request, however many
//!   blocks it spans.
//! - The first request, for block 0, learns the file's size from its `Content-Range`
//!   (`bytes 0-N/TOTAL`); every answer's `Content-Range` must be the range asked for, of that
//!   size.
//! - The first answer's `ETag` (or, without one, its `Last-Modified`) names the file's version
//!   ([`RangeReader::version`]); a later answer for another version is an error, so that a
//!   file replaced while it is read never mixes the bytes of two files.
//! - Errors name the URL without its query string (which may hold a presigned URL's
//!   credentials): a 4xx or 5xx status, a server that ignores ranges (200 with the whole file,
//!   [`DemError::NoRanges`]), an answer for another range, a body shorter than the range, a
//!   connection that drops. A failed connection or a dropped body is tried again
//!   ([`RangeOptions::retries`]); connecting and each read time out
//!   ([`RangeOptions::timeout`]), so that a silent server is an error, not a hang.
//! - Bodies are asked for uncompressed (`Accept-Encoding: identity`): a range of a compressed
//!   body would not be the file's bytes.

use super::cog::Source;
use super::{DemError, IoStats};
use std::io::{self, Read, Seek, SeekFrom};
use std::ops::Range;
use std::time::Duration;

/// How a [`RangeReader`] fetches.
#[derive(Clone, Debug)]
pub struct RangeOptions {
    /// Bytes per block: the least a request fetches, and the unit of the cache.
    pub block_size: u64,
    /// Blocks the cache keeps (besides those of the chunk being read), so that the directory
    /// and neighbouring reads are not fetched again.
    pub cache_blocks: usize,
    /// Limit on connecting and on each read from the connection.
    pub timeout: Duration,
    /// How many times a request is tried again after its connection failed or dropped.
    pub retries: u32,
}

impl Default for RangeOptions {
    /// 64 KiB blocks, 64 of them cached (4 MiB), 30 s timeouts, 2 retries.
    fn default() -> Self {
        RangeOptions {
            block_size: 64 * 1024,
            cache_blocks: 64,
            timeout: Duration::from_secs(30),
            retries: 2,
        }
    }
}

/// `url` without its query string and fragment, as messages and stores name it: a presigned
/// URL's query holds its credentials.
pub fn without_query(url: &str) -> &str {
    url.split(['?', '#']).next().unwrap_or(url)
}

/// A remote file as `Read + Seek`, by HTTP range requests; see the module docs.
pub struct RangeReader {
    /// The URL requests go to.
    url: String,
    /// The URL without its query string, for messages.
    shown: String,
    /// The HTTP client, with its timeouts and connection pool.
    agent: ureq::Agent,
    /// Block size, cache size, timeouts, retries.
    opts: RangeOptions,
    /// The file's size, from the first answer's `Content-Range`.
    size: u64,
    /// The file's version, from the first answer's `ETag` or `Last-Modified`.
    version: Option<String>,
    /// The read position.
    pos: u64,
    /// Cached blocks (index, bytes), least recently used first.
    blocks: Vec<(u64, Vec<u8>)>,
    /// Blocks of the chunk announced last, kept whatever the cache's size until the next.
    pinned: Range<u64>,
    /// Body bytes received, for [`IoStats`].
    fetched: u64,
    /// Requests that got an answer, for benchmarks.
    requests: u64,
}

/// An answer: the file's size, the bytes asked for, and the file's version if the server named
/// it.
type Answer = (u64, Vec<u8>, Option<String>);

/// A failed request: whether trying again may help, and the error.
enum Failure {
    /// The connection failed or dropped: worth another try.
    Transport(String),
    /// The server answered, wrongly: final.
    Final(DemError),
}

impl RangeReader {
    /// Opens `url` with the default [`RangeOptions`]: fetches its first block, learning its
    /// size.
    pub fn open(url: &str) -> Result<RangeReader, DemError> {
        RangeReader::open_with(url, RangeOptions::default())
    }

    /// Opens `url` with `opts`.
    pub fn open_with(url: &str, opts: RangeOptions) -> Result<RangeReader, DemError> {
        let shown = without_query(url).to_string();
        let config = ureq::Agent::config_builder()
            .timeout_connect(Some(opts.timeout))
            .timeout_per_read(Some(opts.timeout))
            .timeout_recv_response(Some(opts.timeout))
            .http_status_as_error(false)
            .build();
        let mut r = RangeReader {
            url: url.into(),
            shown,
            agent: ureq::Agent::new_with_config(config),
            opts: RangeOptions {
                block_size: opts.block_size.max(1),
                ..opts
            },
            size: 0,
            version: None,
            pos: 0,
            blocks: Vec::new(),
            pinned: 0..0,
            fetched: 0,
            requests: 0,
        };
        let (total, body, version) = r.get(0, r.opts.block_size - 1, None)?;
        r.size = total;
        r.version = version;
        r.insert(0, body);
        Ok(r)
    }

    /// The file's size in bytes.
    pub fn size(&self) -> u64 {
        self.size
    }

    /// The file's version as the server named it (its `ETag`, or its `Last-Modified`), if it
    /// did.
    pub fn version(&self) -> Option<&str> {
        self.version.as_deref()
    }

    /// The URL without its query string, as messages name it.
    pub fn shown_url(&self) -> &str {
        &self.shown
    }

    /// Requests answered so far.
    pub fn requests(&self) -> u64 {
        self.requests
    }

    /// An error about this URL.
    fn error(&self, detail: String) -> DemError {
        DemError::Http {
            url: self.shown.clone(),
            detail,
        }
    }

    /// Fetches blocks `first..=last` in one request and caches them.
    fn fetch(&mut self, first: u64, last: u64) -> Result<(), DemError> {
        let bs = self.opts.block_size;
        let end = ((last + 1) * bs).min(self.size);
        let (_, body, _) = self.get(first * bs, end - 1, Some(self.size))?;
        let mut body = body.as_slice();
        for index in first..=last {
            let (block, rest) = body.split_at((bs as usize).min(body.len()));
            self.insert(index, block.to_vec());
            body = rest;
        }
        Ok(())
    }

    /// Bytes `a..=b` (clamped to the file's end where its size is known), tried again on
    /// transport failures; returns the file's size, the bytes and the file's version.
    fn get(&mut self, a: u64, b: u64, size: Option<u64>) -> Result<Answer, DemError> {
        let mut tries = 0;
        loop {
            match self.request(a, b, size) {
                Ok(answer) => {
                    self.requests += 1;
                    self.fetched += answer.1.len() as u64;
                    return Ok(answer);
                }
                Err(Failure::Transport(why)) if tries < self.opts.retries => {
                    tries += 1;
                    tracing::debug!("{}: {why}; trying again ({tries})", self.shown);
                    std::thread::sleep(Duration::from_millis(50 << tries));
                }
                Err(Failure::Transport(why)) => {
                    let attempts = tries + 1;
                    return Err(self.error(format!(
                        "{why} (tried {attempts} time{})",
                        if attempts == 1 { "" } else { "s" }
                    )));
                }
                Err(Failure::Final(e)) => return Err(e),
            }
        }
    }

    /// One request for bytes `a..=b`: checks the status, the `Content-Range` and the version
    /// (after the first), and reads the body whole.
    fn request(&self, a: u64, b: u64, size: Option<u64>) -> Result<Answer, Failure> {
        let asked = format!("bytes {a}-{b}");
        let fail = |detail: String| Failure::Final(self.error(detail));
        let mut resp = match self
            .agent
            .get(&self.url)
            .header("Range", format!("bytes={a}-{b}"))
            .header("Accept-Encoding", "identity")
            .call()
        {
            Ok(r) => r,
            Err(
                e @ (ureq::Error::Io(_) | ureq::Error::ConnectionFailed | ureq::Error::Protocol(_)),
            ) => {
                return Err(Failure::Transport(format!(
                    "the request for {asked} failed: {e}"
                )));
            }
            Err(e) => return Err(fail(format!("the request for {asked} failed: {e}"))),
        };
        let status = resp.status();
        let header = |name: &str| {
            resp.headers()
                .get(name)
                .and_then(|v| v.to_str().ok())
                .map(str::to_string)
        };
        let range = header("content-range");
        match status.as_u16() {
            206 => {}
            200 => {
                return Err(Failure::Final(DemError::NoRanges {
                    url: self.shown.clone(),
                }));
            }
            416 if range.as_deref().is_some_and(|r| r.trim().ends_with("/0")) => {
                return Err(fail("the file is empty (0 bytes)".into()));
            }
            code => {
                let hint = match code {
                    404 | 410 => " (no such file)",
                    401 | 403 => " (access denied: a private bucket needs a presigned URL)",
                    416 => " (the range lies beyond the file's end: did the file change?)",
                    500.. => " (a server error)",
                    _ => "",
                };
                return Err(fail(format!(
                    "the server answered {status}{hint} to a request for {asked}"
                )));
            }
        }
        let Some(range) = range else {
            return Err(fail(format!(
                "the server answered 206 to a request for {asked} without a Content-Range \
                 header"
            )));
        };
        let Some((start, end, total)) = parse_content_range(&range) else {
            return Err(fail(format!(
                "the server answered {range:?} to a request for {asked}: not a byte range of a \
                 file of known size"
            )));
        };
        if let Some(size) = size.filter(|&s| s != total) {
            return Err(fail(format!(
                "the file changed while it was read: it was {size} bytes and is now {total}"
            )));
        }
        let version = header("etag").or_else(|| header("last-modified"));
        if let (Some(was), Some(now)) = (&self.version, &version)
            && size.is_some()
            && was != now
        {
            return Err(fail(format!(
                "the file changed while it was read: its version was {was}, now {now}"
            )));
        }
        if start != a || end != b.min(total.saturating_sub(1)) || end < start {
            return Err(fail(format!(
                "the server answered {range:?} to a request for {asked}"
            )));
        }
        let want = end - start + 1;
        let mut body = vec![0u8; want as usize];
        let mut reader = resp.body_mut().as_reader();
        let mut got = 0;
        while got < body.len() {
            match reader.read(&mut body[got..]) {
                Ok(0) => {
                    return Err(fail(format!(
                        "the server sent {got} bytes for {asked} ({want} bytes): the answer was \
                         cut short"
                    )));
                }
                Ok(n) => got += n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => {
                    return Err(Failure::Transport(format!(
                        "the connection dropped after {got} of the {want} bytes of {asked}: {e}"
                    )));
                }
            }
        }
        Ok((total, body, version))
    }

    /// Caches block `index`, evicting the least recently used blocks beyond the cache's size
    /// (but not those of the announced chunk).
    fn insert(&mut self, index: u64, data: Vec<u8>) {
        self.blocks.retain(|(i, _)| *i != index);
        self.blocks.push((index, data));
        while self.blocks.len() > self.opts.cache_blocks.max(1) {
            let pinned = &self.pinned;
            match self.blocks.iter().position(|(i, _)| !pinned.contains(i)) {
                Some(p) => {
                    self.blocks.remove(p);
                }
                None => break,
            }
        }
    }

    /// Where block `index` is in the cache, marking it used.
    fn touch(&mut self, index: u64) -> Option<usize> {
        let p = self.blocks.iter().position(|(i, _)| *i == index)?;
        let entry = self.blocks.remove(p);
        self.blocks.push(entry);
        Some(self.blocks.len() - 1)
    }
}

/// `bytes START-END/TOTAL` as numbers; `None` for anything else (`*` totals included).
fn parse_content_range(v: &str) -> Option<(u64, u64, u64)> {
    let rest = v.trim().strip_prefix("bytes")?.trim_start();
    let (span, total) = rest.split_once('/')?;
    let (start, end) = span.split_once('-')?;
    Some((
        start.trim().parse().ok()?,
        end.trim().parse().ok()?,
        total.trim().parse().ok()?,
    ))
}

impl Read for RangeReader {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if buf.is_empty() || self.pos >= self.size {
            return Ok(0);
        }
        let bs = self.opts.block_size;
        let index = self.pos / bs;
        let slot = match self.touch(index) {
            Some(s) => s,
            None => {
                self.fetch(index, index).map_err(io::Error::other)?;
                self.touch(index)
                    .ok_or_else(|| io::Error::other("a fetched block is not in the cache"))?
            }
        };
        let block = &self.blocks[slot].1;
        let from = (self.pos - index * bs) as usize;
        let n = buf.len().min(block.len().saturating_sub(from));
        buf[..n].copy_from_slice(&block[from..from + n]);
        self.pos += n as u64;
        Ok(n)
    }
}

impl Seek for RangeReader {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        let to = match pos {
            SeekFrom::Start(p) => Some(p),
            SeekFrom::End(d) => self.size.checked_add_signed(d),
            SeekFrom::Current(d) => self.pos.checked_add_signed(d),
        };
        self.pos = to.ok_or_else(|| {
            io::Error::new(io::ErrorKind::InvalidInput, "seek before the file's start")
        })?;
        Ok(self.pos)
    }
}

impl Source for RangeReader {
    fn io(&self) -> IoStats {
        IoStats {
            bytes_read: self.fetched,
            source_bytes: self.size,
        }
    }

    fn will_read(&mut self, range: Range<u64>) -> Result<(), DemError> {
        let end = range.end.min(self.size);
        if range.start >= end {
            return Ok(());
        }
        let bs = self.opts.block_size;
        let (first, last) = (range.start / bs, (end - 1) / bs);
        self.pinned = first..last + 1;
        // Fetch each run of missing blocks in one request.
        let mut index = first;
        while index <= last {
            if self.touch(index).is_some() {
                index += 1;
                continue;
            }
            let mut run_end = index;
            while run_end < last && !self.blocks.iter().any(|(i, _)| *i == run_end + 1) {
                run_end += 1;
            }
            self.fetch(index, run_end)?;
            index = run_end + 1;
        }
        Ok(())
    }
}

#[cfg(test)]
#[path = "tests/remote.rs"]
mod tests;
