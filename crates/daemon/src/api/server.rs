//! The HTTP/1.1 server loop under the API: hyper connections with a header-read timeout
//! (which also closes idle keep-alive connections), a bounded number of open connections
//! derived from the file-descriptor limit so the scan pipeline always keeps descriptors for
//! its files, a per-client-address share, and shutdown that closes idle connections at once.
//!
//! When the connection cap is reached, the oldest connection with no request in flight
//! (idle, or still sending its headers) is closed to make room, so idle or half-sent
//! connections can never lock real requests out; only when every connection is busy is a
//! new one answered 503 and closed.

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

/// The connection cap the descriptor limit allows: the soft RLIMIT_NOFILE less the
/// descriptors open now, the reserve and the overflow.
pub fn connection_cap(configured: usize) -> Result<usize, String> {
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
        return Err(format!(
            "the file-descriptor limit ({soft}, {open} open) leaves room for {cap} connections \
             after keeping {RESERVED_FDS} for the scan pipeline; at least {MIN_CONNECTIONS} are \
             needed: raise it (ulimit -n, or LimitNOFILE= in the systemd unit)"
        ));
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
                c.busy.fetch_add(1 << 20, Ordering::AcqRel); // evicted once
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
    mut stop: watch::Receiver<bool>,
    drain: Duration,
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
        tasks.spawn(async move {
            let _ = stream.set_nodelay(true);
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
                .serve_connection(TokioIo::new(stream), svc);
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
