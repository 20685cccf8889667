//! The HTTP/1.1 server loop under the API: hyper connections with a header-read timeout
//! (which also closes idle keep-alive connections), a bounded number of open connections
//! derived from the file-descriptor limit so the scan pipeline always keeps descriptors for
//! its files, a per-client-address share, and shutdown that closes idle connections at once.
//!
//! When the connection cap is reached, the oldest connection with no request in flight
//! (idle, or still sending its headers) is closed to make room, so idle or half-sent
//! connections can never lock real requests out; only when every connection is busy is a
//! new one answered 503 and closed. An evicted connection is dropped outright, not shut down
//! gracefully: hyper's graceful shutdown waits for a half-read head to complete, which is
//! exactly what a slow-header flood never does.
//!
//! hyper answers a head it cannot parse (a duplicate Content-Length, a bad header line)
//! itself, with an empty body; [`JsonErrors`] rewrites those answers into the API's JSON
//! error so every client sees one error format.

use axum::body::Body;
use axum::http::Request;
use axum::Router;
use hyper_util::rt::{TokioIo, TokioTimer};
use std::collections::HashMap;
use std::convert::Infallible;
use std::net::{IpAddr, SocketAddr};
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};
use std::time::{Duration, Instant};
use tokio::sync::{watch, Notify, Semaphore};

/// File descriptors kept free for everything but connections: the scan's output files,
/// the camera and serial devices, the index, the runtime's own.
pub const RESERVED_FDS: u64 = 64;
/// Descriptors a connection may briefly hold beyond the cap: to evict an idle one or
/// answer 503.
const OVERFLOW: usize = 8;
/// Fewest connections worth serving with; a lower descriptor limit is a start-up error.
const MIN_CONNECTIONS: usize = 8;
/// Added to a connection's busy count when it is chosen for eviction, so it is chosen once;
/// the bits below count requests in flight.
const EVICTED: usize = 1 << 20;

/// The server's limits (from the [daemon] config).
#[derive(Clone, Debug)]
pub struct Limits {
    /// Whole request head (and, on a kept-alive connection, the wait for the next one).
    pub header_timeout: Duration,
    /// Whole request body.
    pub body_timeout: Duration,
    /// Open connections at most (lowered to what the descriptor limit allows).
    pub max_connections: usize,
    /// Open connections from one client address at most.
    pub max_per_client: usize,
}

/// Pending connections the kernel may queue for accept (capped by net.core.somaxconn).
/// Deeper than the default 1024 so that a flood of connections reopened as fast as they are
/// evicted does not fill the queue: a full queue drops new SYNs, and the client's retry after
/// 1 s is what a legitimate request would then wait.
pub const LISTEN_BACKLOG: u32 = 4096;

/// Listen on `addr` with [`LISTEN_BACKLOG`].
pub fn listen(addr: SocketAddr) -> std::io::Result<tokio::net::TcpListener> {
    let socket = if addr.is_ipv4() {
        tokio::net::TcpSocket::new_v4()?
    } else {
        tokio::net::TcpSocket::new_v6()?
    };
    socket.set_reuseaddr(true)?;
    socket.bind(addr)?;
    socket.listen(LISTEN_BACKLOG)
}

/// The descriptor limit leaves too few connections for the daemon to serve.
#[derive(Debug, thiserror::Error)]
#[error(
    "the file-descriptor limit ({soft}, {open} open) leaves room for {cap} connections after \
     keeping {reserved} for the scan pipeline; at least {min} are needed: raise it (ulimit -n, \
     or LimitNOFILE= in the systemd unit)",
    reserved = RESERVED_FDS,
    min = MIN_CONNECTIONS
)]
pub struct TooFewDescriptors {
    soft: u64,
    open: u64,
    cap: usize,
}

/// The connection cap the descriptor limit allows: the soft RLIMIT_NOFILE less the
/// descriptors open now, the reserve and the overflow.
pub fn connection_cap(configured: usize) -> Result<usize, TooFewDescriptors> {
    let mut rl = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit writes into the struct we own.
    let soft = if unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut rl) } == 0 {
        rl.rlim_cur
    } else {
        1024
    };
    let open = std::fs::read_dir("/proc/self/fd").map_or(16, |d| d.count() as u64);
    let room = soft.saturating_sub(open + RESERVED_FDS + OVERFLOW as u64) as usize;
    let cap = configured.min(room);
    if cap < MIN_CONNECTIONS {
        return Err(TooFewDescriptors { soft, open, cap });
    }
    Ok(cap)
}

/// One open connection, as the cap sees it.
struct Conn {
    peer: IpAddr,
    opened: Instant,
    /// Requests in flight (from the head read until the response body is done).
    busy: Arc<AtomicUsize>,
    close: Arc<Notify>,
}

#[derive(Default)]
struct Registry {
    conns: HashMap<u64, Conn>,
}

impl Registry {
    fn count(&self, peer: Option<IpAddr>) -> usize {
        match peer {
            None => self.conns.len(),
            Some(p) => self.conns.values().filter(|c| c.peer == p).count(),
        }
    }

    /// Ask the oldest connection with nothing in flight (of `peer`, if given) to close.
    fn evict_idle(&self, peer: Option<IpAddr>) -> bool {
        let victim = self
            .conns
            .values()
            .filter(|c| peer.is_none_or(|p| c.peer == p))
            .filter(|c| c.busy.load(Ordering::Acquire) == 0)
            .min_by_key(|c| c.opened);
        match victim {
            Some(c) => {
                c.busy.fetch_add(EVICTED, Ordering::AcqRel); // evicted once
                c.close.notify_one();
                true
            }
            None => false,
        }
    }
}

/// Counts a request in flight until dropped (with its response body).
struct Busy(Arc<AtomicUsize>);

impl Busy {
    fn new(c: &Arc<AtomicUsize>) -> Busy {
        c.fetch_add(1, Ordering::AcqRel);
        Busy(c.clone())
    }
}

impl Drop for Busy {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::AcqRel);
    }
}

/// A response body that keeps its connection counted busy while it streams.
struct Tracked {
    inner: Body,
    _busy: Busy,
}

impl http_body::Body for Tracked {
    type Data = axum::body::Bytes;
    type Error = axum::Error;
    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<http_body::Frame<Self::Data>, Self::Error>>> {
        Pin::new(&mut self.inner).poll_frame(cx)
    }
    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }
    fn size_hint(&self) -> http_body::SizeHint {
        self.inner.size_hint()
    }
}

/// Resolves once `w` is true (or its sender is gone).
async fn stopped(w: &mut watch::Receiver<bool>) {
    let _ = w.wait_for(|s| *s).await;
}

/// A JSON 503 written straight onto a connection the server has no room for.
async fn refuse(mut stream: tokio::net::TcpStream, why: &str) {
    use tokio::io::AsyncWriteExt;
    let body = serde_json::json!({ "error": why }).to_string();
    let resp = format!(
        "HTTP/1.1 503 Service Unavailable\r\ncontent-type: application/json\r\n\
         content-length: {}\r\nretry-after: 1\r\nconnection: close\r\n\r\n{body}",
        body.len()
    );
    let _ = tokio::time::timeout(Duration::from_secs(1), async {
        let _ = stream.write_all(resp.as_bytes()).await;
        let _ = stream.shutdown().await;
    })
    .await;
}

/// Serve `app` on `listener` until `stop` turns true; then close idle connections at once,
/// let busy ones finish their response (up to `drain`), and return.
pub async fn run(
    listener: tokio::net::TcpListener,
    app: Router,
    limits: Limits,
    stop: watch::Receiver<bool>,
    drain: Duration,
) -> std::io::Result<()> {
    run_tls(listener, app, limits, stop, drain, None).await
}

/// A connection's byte stream, plain TCP or TLS over it.
trait Io: tokio::io::AsyncRead + tokio::io::AsyncWrite + Unpin + Send {}
impl<T: tokio::io::AsyncRead + tokio::io::AsyncWrite + Unpin + Send> Io for T {}

/// The first byte of every TLS connection: a handshake record.
const TLS_HANDSHAKE: u8 = 0x16;

/// The TLS session on `stream`, within `timeout`; a client speaking plain HTTP to the TLS
/// port gets a plain-text 400 saying to use https (instead of a TLS alert it cannot read),
/// and None is returned for any failure (logged at debug: scanners of the network do this).
async fn accept_tls(
    stream: tokio::net::TcpStream,
    tls: &tokio_rustls::TlsAcceptor,
    timeout: Duration,
    peer: SocketAddr,
) -> Option<tokio_rustls::server::TlsStream<tokio::net::TcpStream>> {
    let mut first = [0u8; 1];
    match tokio::time::timeout(timeout, stream.peek(&mut first)).await {
        Ok(Ok(1)) if first[0] == TLS_HANDSHAKE => {}
        Ok(Ok(1)) => {
            refuse_plain(stream).await;
            tracing::debug!("connection from {peer}: plain HTTP on the HTTPS port");
            return None;
        }
        _ => return None,
    }
    match tokio::time::timeout(timeout, tls.accept(stream)).await {
        Ok(Ok(s)) => Some(s),
        Ok(Err(e)) => {
            tracing::debug!("TLS handshake with {peer}: {e}");
            None
        }
        Err(_) => {
            tracing::debug!("TLS handshake with {peer}: no handshake within {timeout:?}");
            None
        }
    }
}

/// The answer to plain HTTP on the HTTPS port.
async fn refuse_plain(mut stream: tokio::net::TcpStream) {
    use tokio::io::AsyncWriteExt;
    let body = serde_json::json!({
        "error": "this port speaks HTTPS only: use https:// (the [daemon] tls setting)"
    })
    .to_string();
    let resp = format!(
        "HTTP/1.1 400 Bad Request\r\ncontent-type: application/json\r\n\
         content-length: {}\r\nconnection: close\r\n\r\n{body}",
        body.len()
    );
    let _ = tokio::time::timeout(Duration::from_secs(1), async {
        let _ = stream.write_all(resp.as_bytes()).await;
        let _ = stream.shutdown().await;
    })
    .await;
}

/// [`run`], over TLS when `tls` is given.
pub async fn run_tls(
    listener: tokio::net::TcpListener,
    app: Router,
    limits: Limits,
    mut stop: watch::Receiver<bool>,
    drain: Duration,
    tls: Option<tokio_rustls::TlsAcceptor>,
) -> std::io::Result<()> {
    let cap = limits.max_connections;
    let per_client = limits.max_per_client.min(cap);
    let permits = Arc::new(Semaphore::new(cap + OVERFLOW));
    let registry = Arc::new(Mutex::new(Registry::default()));
    let next_id = AtomicU64::new(0);
    let (closing_tx, closing_rx) = watch::channel(false);
    let mut tasks = tokio::task::JoinSet::new();
    tracing::info!(
        "serving at most {cap} connections ({per_client} per client address), header timeout \
         {:?}, body timeout {:?}",
        limits.header_timeout,
        limits.body_timeout
    );
    loop {
        let permit = tokio::select! {
            p = permits.clone().acquire_owned() => p.expect("semaphore open"),
            _ = stopped(&mut stop) => break,
        };
        let (stream, peer): (tokio::net::TcpStream, SocketAddr) = tokio::select! {
            r = listener.accept() => match r {
                Ok(x) => x,
                Err(e) => {
                    // EMFILE and friends: wait for descriptors instead of spinning.
                    tracing::warn!("accept: {e}");
                    tokio::time::sleep(Duration::from_millis(100)).await;
                    continue;
                }
            },
            _ = stopped(&mut stop) => break,
        };
        while tasks.try_join_next().is_some() {}
        let admitted = {
            let reg = registry.lock().unwrap();
            let client_full = reg.count(Some(peer.ip())) >= per_client;
            let full = reg.count(None) >= cap;
            if client_full {
                reg.evict_idle(Some(peer.ip()))
            } else if full {
                reg.evict_idle(None)
            } else {
                true
            }
        };
        if !admitted {
            tasks.spawn(async move {
                refuse(
                    stream,
                    "too many connections, every one with a request in flight: retry shortly",
                )
                .await;
                drop(permit);
            });
            continue;
        }
        let id = next_id.fetch_add(1, Ordering::Relaxed);
        let busy = Arc::new(AtomicUsize::new(0));
        let close = Arc::new(Notify::new());
        registry.lock().unwrap().conns.insert(
            id,
            Conn {
                peer: peer.ip(),
                opened: Instant::now(),
                busy: busy.clone(),
                close: close.clone(),
            },
        );
        let (app, registry, limits) = (app.clone(), registry.clone(), limits.clone());
        let mut closing = closing_rx.clone();
        let tls = tls.clone();
        tasks.spawn(async move {
            let _ = stream.set_nodelay(true);
            let stream: Box<dyn Io> = match &tls {
                None => Box::new(stream),
                Some(acceptor) => {
                    match accept_tls(stream, acceptor, limits.header_timeout, peer).await {
                        Some(s) => Box::new(s),
                        None => {
                            registry.lock().unwrap().conns.remove(&id);
                            drop(permit);
                            return;
                        }
                    }
                }
            };
            let svc_busy = busy.clone();
            let svc = hyper::service::service_fn(move |req: Request<hyper::body::Incoming>| {
                let guard = Busy::new(&svc_busy);
                let app = app.clone();
                async move {
                    use tower_service::Service;
                    let mut app = app;
                    let resp = app
                        .call(req.map(Body::new))
                        .await
                        .unwrap_or_else(|e| match e {});
                    Ok::<_, Infallible>(resp.map(|b| {
                        Body::new(Tracked {
                            inner: b,
                            _busy: guard,
                        })
                    }))
                }
            });
            let conn = hyper::server::conn::http1::Builder::new()
                .timer(TokioTimer::new())
                .header_read_timeout(limits.header_timeout)
                // Room for heads up to the API's own limits (guard.rs answers 414 and 431
                // with JSON); beyond this hyper refuses them itself, without a body.
                .max_buf_size(256 * 1024)
                .serve_connection(TokioIo::new(JsonErrors::new(stream)), svc);
            let mut conn = std::pin::pin!(conn);
            let mut shutting = false;
            loop {
                tokio::select! {
                    r = conn.as_mut() => {
                        if let Err(e) = r {
                            tracing::debug!("connection from {peer}: {e}");
                        }
                        break;
                    }
                    _ = close.notified(), if !shutting => {
                        // No request in flight (the eviction mark aside): at most part of a
                        // head was read, and nothing is lost by dropping the connection. The
                        // check runs on this task, which alone polls `conn`, so no request
                        // can start between it and the drop.
                        if busy.load(Ordering::Acquire) & (EVICTED - 1) == 0 {
                            break;
                        }
                        shutting = true;
                        conn.as_mut().graceful_shutdown();
                    }
                    _ = stopped(&mut closing), if !shutting => {
                        shutting = true;
                        conn.as_mut().graceful_shutdown();
                    }
                }
            }
            registry.lock().unwrap().conns.remove(&id);
            drop(permit);
        });
    }
    drop(listener);
    let _ = closing_tx.send(true);
    let open = registry.lock().unwrap().conns.len();
    if open > 0 {
        tracing::info!("shutdown: {open} connections open; idle ones close now");
    }
    let drained =
        tokio::time::timeout(drain, async { while tasks.join_next().await.is_some() {} }).await;
    if drained.is_err() {
        tracing::warn!("shutdown: connections still open after {drain:?}; closing them");
        tasks.abort_all();
    }
    Ok(())
}

/// A connection's stream that turns hyper's own empty-bodied error answers (to heads it
/// could not parse) into the API's `{"error": ...}` form. hyper writes such an answer as one
/// head with `content-length: 0` and nothing after it; the API never answers an error with
/// an empty body (see `json_errors` in api/mod.rs), so the pattern is hyper's alone.
struct JsonErrors<S> {
    inner: S,
    /// The rewritten answer still to be written, and the length of hyper's buffer it stands
    /// for (reported written once all of it is).
    pending: Option<(Vec<u8>, usize)>,
}

impl<S> JsonErrors<S> {
    fn new(inner: S) -> Self {
        JsonErrors {
            inner,
            pending: None,
        }
    }
}

/// The JSON answer for hyper's own error head `buf`, if that is what it is.
fn json_error_for(buf: &[u8]) -> Option<Vec<u8>> {
    let text = std::str::from_utf8(buf).ok()?;
    let rest = text.strip_prefix("HTTP/1.1 ")?;
    let head = text.strip_suffix("\r\n\r\n")?;
    if head.contains("\r\n\r\n") {
        return None;
    }
    let code: u16 = rest.get(..3)?.parse().ok()?;
    if !(400..600).contains(&code) {
        return None;
    }
    let lower = head.to_ascii_lowercase();
    if !lower.contains("\r\ncontent-length: 0") || lower.contains("\r\ncontent-type:") {
        return None;
    }
    let why = match code {
        400 => {
            "malformed request head: a duplicate or invalid Content-Length, a bad header line \
             or request line (RFC 9112)"
        }
        414 => "request target too long",
        431 => "request headers too large",
        _ => "request refused by the HTTP layer",
    };
    let body = serde_json::json!({ "error": why }).to_string();
    let status_line = head.split("\r\n").next()?;
    Some(
        format!(
            "{status_line}\r\ncontent-type: application/json\r\ncontent-length: {}\r\n\
             connection: close\r\nx-content-type-options: nosniff\r\n\r\n{body}",
            body.len()
        )
        .into_bytes(),
    )
}

impl<S: tokio::io::AsyncRead + Unpin> tokio::io::AsyncRead for JsonErrors<S> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut tokio::io::ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.inner).poll_read(cx, buf)
    }
}

impl<S: tokio::io::AsyncWrite + Unpin> tokio::io::AsyncWrite for JsonErrors<S> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        let me = &mut *self;
        if me.pending.is_none() {
            match json_error_for(buf) {
                Some(json) => me.pending = Some((json, buf.len())),
                None => return Pin::new(&mut me.inner).poll_write(cx, buf),
            }
        }
        let (bytes, stands_for) = me.pending.as_mut().expect("set above");
        while !bytes.is_empty() {
            match Pin::new(&mut me.inner).poll_write(cx, bytes) {
                Poll::Ready(Ok(0)) => {
                    me.pending = None;
                    return Poll::Ready(Err(std::io::ErrorKind::WriteZero.into()));
                }
                Poll::Ready(Ok(n)) => {
                    bytes.drain(..n);
                }
                Poll::Ready(Err(e)) => {
                    me.pending = None;
                    return Poll::Ready(Err(e));
                }
                Poll::Pending => return Poll::Pending,
            }
        }
        let n = *stands_for;
        me.pending = None;
        Poll::Ready(Ok(n))
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }
}

#[cfg(test)]
mod tests {
    use super::json_error_for;

    #[test]
    fn hypers_own_error_heads_become_json() {
        let hyper = b"HTTP/1.1 400 Bad Request\r\ncontent-length: 0\r\ndate: Fri, 27 Nov 2026 12:00:00 GMT\r\n\r\n";
        let out = String::from_utf8(json_error_for(hyper).unwrap()).unwrap();
        assert!(out.starts_with("HTTP/1.1 400 Bad Request\r\n"), "{out}");
        let (_, body) = out.split_once("\r\n\r\n").unwrap();
        let v: serde_json::Value = serde_json::from_str(body).unwrap();
        assert!(v["error"].as_str().unwrap().contains("Content-Length"));
        // The API's own answers pass untouched.
        for own in [
            &b"HTTP/1.1 400 Bad Request\r\ncontent-type: application/json\r\ncontent-length: 0\r\n\r\n"[..],
            b"HTTP/1.1 200 OK\r\ncontent-length: 0\r\n\r\n",
            b"HTTP/1.1 404 Not Found\r\ncontent-type: application/json\r\ncontent-length: 12\r\n\r\n{\"error\":1}",
        ] {
            assert!(json_error_for(own).is_none());
        }
    }
}
