//! The write timeout: a connection whose client reads nothing of what it is sent for longer
//! than a limit fails with `TimedOut`, so that hyper drops it and the response it holds.
//!
//! hyper has a header-read timeout but none for writes: a client that posts a query whose
//! answer is megabytes and never reads it would pin the answer for as long as the connection
//! lives. [`StallIo`] wraps the socket; the clock runs only while a write or flush waits for the
//! socket, and any progress resets it. A WebSocket session upgraded from the connection turns
//! it off through [`WriteStall`], because a session bounds its own sends (a slow reader is
//! closed with `slow_reader`, 4007, after the idle timeout).

use std::io;
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::task::{Context, Poll, ready};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::time::Sleep;

/// The limit of one connection, in milliseconds (0: none), shared with its requests.
#[derive(Clone, Debug)]
pub struct WriteStall(Arc<AtomicU64>);

impl WriteStall {
    /// A limit of `d`.
    pub fn new(d: Duration) -> WriteStall {
        WriteStall(Arc::new(AtomicU64::new(d.as_millis() as u64)))
    }

    /// Turns the limit off: whoever holds the connection now bounds its writes itself.
    pub fn disable(&self) {
        self.0.store(0, Relaxed);
    }
}

/// A socket whose writes fail once they have waited longer than the limit.
pub struct StallIo<T> {
    /// The socket.
    inner: T,
    /// The limit.
    limit: WriteStall,
    /// Started when a write first waits; cleared when one goes through.
    timer: Option<Pin<Box<Sleep>>>,
}

impl<T> StallIo<T> {
    /// Wraps `inner` with `limit`.
    pub fn new(inner: T, limit: WriteStall) -> StallIo<T> {
        StallIo {
            inner,
            limit,
            timer: None,
        }
    }

    /// Called when a write is not ready: `Pending` until the limit has passed, then the error.
    fn stalled<R>(&mut self, cx: &mut Context<'_>) -> Poll<io::Result<R>> {
        let ms = self.limit.0.load(Relaxed);
        if ms == 0 {
            self.timer = None;
            return Poll::Pending;
        }
        let timer = self
            .timer
            .get_or_insert_with(|| Box::pin(tokio::time::sleep(Duration::from_millis(ms))));
        ready!(timer.as_mut().poll(cx));
        Poll::Ready(Err(io::Error::new(
            io::ErrorKind::TimedOut,
            format!("the client read nothing for {:.0} s", ms as f64 / 1e3),
        )))
    }

    /// Passes a write's outcome on, and resets the clock when it went through.
    fn progress<R>(&mut self, cx: &mut Context<'_>, p: Poll<io::Result<R>>) -> Poll<io::Result<R>> {
        match p {
            Poll::Pending => self.stalled(cx),
            done => {
                self.timer = None;
                done
            }
        }
    }
}

impl<T: AsyncRead + Unpin> AsyncRead for StallIo<T> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_read(cx, buf)
    }
}

impl<T: AsyncWrite + Unpin> AsyncWrite for StallIo<T> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        let p = Pin::new(&mut self.inner).poll_write(cx, buf);
        self.progress(cx, p)
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        let p = Pin::new(&mut self.inner).poll_write_vectored(cx, bufs);
        self.progress(cx, p)
    }

    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let p = Pin::new(&mut self.inner).poll_flush(cx);
        self.progress(cx, p)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let p = Pin::new(&mut self.inner).poll_shutdown(cx);
        self.progress(cx, p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tokio::io::AsyncWriteExt;

    #[tokio::test]
    async fn a_write_nobody_reads_fails_after_the_limit_and_one_that_is_read_does_not() {
        // A pipe of 64 bytes: the writer waits as soon as the reader stops.
        let (a, mut b) = tokio::io::duplex(64);
        let mut w = StallIo::new(a, WriteStall::new(Duration::from_millis(200)));
        let t = std::time::Instant::now();
        let err = w.write_all(&[7u8; 4096]).await.unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::TimedOut);
        assert!(
            t.elapsed() >= Duration::from_millis(200),
            "{:?}",
            t.elapsed()
        );
        // A reader that keeps reading, slowly, never trips it.
        let (a, mut b2) = tokio::io::duplex(64);
        let mut w = StallIo::new(a, WriteStall::new(Duration::from_millis(200)));
        let reader = tokio::spawn(async move {
            let mut buf = [0u8; 64];
            let mut n = 0;
            while n < 4096 {
                tokio::time::sleep(Duration::from_millis(20)).await;
                n += tokio::io::AsyncReadExt::read(&mut b2, &mut buf)
                    .await
                    .unwrap();
            }
        });
        w.write_all(&[7u8; 4096]).await.unwrap();
        reader.await.unwrap();
        // Turned off, it waits for ever (here: longer than the limit).
        let (a, _b3) = tokio::io::duplex(64);
        let stall = WriteStall::new(Duration::from_millis(100));
        stall.disable();
        let mut w = StallIo::new(a, stall);
        let r = tokio::time::timeout(Duration::from_millis(400), w.write_all(&[7u8; 4096])).await;
        assert!(r.is_err(), "a disabled limit fired");
        drop(b.write_all(b"").await);
    }
}
