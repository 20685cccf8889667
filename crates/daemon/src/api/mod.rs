//! footscand's HTTP API (docs/API.md): axum over the [`Daemon`] service. JSON everywhere,
//! errors as `{"error": "..."}` naming the input and what is valid, bodies limited to 16 KiB,
//! ids and file names validated before any path is built, and a bearer token on every request
//! but the health check and the static dashboard when one is configured.

mod calibration;
mod confirm;
mod error;
mod fleet;
mod guard;
mod insoles;
mod lasts;
mod live;
mod report;
mod scanjobs;
mod scans;
pub mod server;
pub mod tls;
mod visits;

use crate::daemon::insolejob::InsoleJob;
use crate::daemon::lastjob::LastJob;
use crate::daemon::Daemon;
use axum::extract::{Request, State};
use axum::http::{header, Method};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use std::future::Future;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::watch;

pub use error::{ApiError, BodyError, Refused};

/// Largest request body accepted (the JSON bodies of the API are far smaller).
pub const BODY_LIMIT: usize = 16 * 1024;

/// Shared by the handlers: the service and the shutdown signal (ends event streams).
#[derive(Clone)]
pub struct AppState {
    pub daemon: Arc<Daemon>,
    pub shutdown: watch::Receiver<bool>,
    /// The last preview PNG, shared by every viewer of the same frame at the same width.
    pub preview_png: Arc<std::sync::Mutex<Option<live::CachedPng>>>,
}

/// Run archive or daemon work (file I/O, locks, CPU) on the runtime's blocking threads.
pub(crate) async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> Result<T, ApiError> + Send + 'static,
) -> Result<T, ApiError> {
    tokio::task::spawn_blocking(f).await?
}

/// The whole API and the dashboard.
pub fn router(daemon: Arc<Daemon>, shutdown: watch::Receiver<bool>) -> Router {
    let state = AppState {
        daemon,
        shutdown,
        preview_png: Default::default(),
    };
    Router::new()
        .route("/", get(dashboard_index))
        .route("/app.js", get(dashboard_js))
        .route("/calibration.js", get(dashboard_calibration_js))
        .route("/visits.js", get(dashboard_visits_js))
        .route("/last.js", get(dashboard_last_js))
        .route("/style.css", get(dashboard_css))
        .route("/view.js", get(dashboard_view_js))
        .route("/vendor/three/{*path}", get(vendor_three))
        .route("/api/health", get(health))
        .route("/api/status", get(live::status))
        .route("/api/tls", get(tls_status))
        .route("/api/scans", get(scans::list).post(scans::start))
        .route("/api/scans/{id}", get(scans::show))
        .route("/api/scans/{id}/cancel", post(scans::cancel))
        .route("/api/scans/{id}/side", post(confirm::confirm_side))
        .route("/api/scans/{id}/report.pdf", get(report::report_pdf))
        .route("/api/scans/{id}/record", post(visits::correct))
        .route("/api/visits", get(visits::list).post(visits::create))
        .route("/api/visits/{id}", get(visits::show).delete(visits::delete))
        .route("/api/visits/{id}/notes", post(visits::set_notes))
        .route("/api/visits/{id}/scans", post(visits::add_scan))
        .route("/api/visits/{id}/report.pdf", get(visits::report_pdf))
        .route("/api/scans/{id}/files/{name}", get(scans::download))
        .route(
            "/api/scans/{id}/last",
            get(scanjobs::show::<LastJob>).post(scanjobs::start::<LastJob>),
        )
        .route("/api/scans/{id}/last/rank", post(lasts::rank))
        .route(
            "/api/scans/{id}/last/{name}",
            get(scanjobs::download::<LastJob>),
        )
        .route("/api/lasts", get(lasts::stock))
        .route(
            "/api/scans/{id}/insole",
            get(scanjobs::show::<InsoleJob>).post(scanjobs::start::<InsoleJob>),
        )
        .route(
            "/api/scans/{id}/insole/{name}",
            get(scanjobs::download::<InsoleJob>),
        )
        .route("/api/visits/{id}/insole", post(insoles::start_visit))
        .route("/api/insole/presets", get(insoles::presets))
        .route("/insole.js", get(dashboard_insole_js))
        .route("/api/preview.png", get(live::preview_png))
        .route("/api/preview/line", get(live::preview_line))
        .route("/api/events", get(live::events))
        .route("/api/fleet/scans", get(fleet::list))
        .route(
            "/api/calibrations",
            get(calibration::history).post(calibration::start_calibration),
        )
        .route("/api/calibrations/job", get(calibration::job))
        .route("/api/calibrations/{id}", get(calibration::show))
        .route("/api/calibrations/{id}/confirm", post(calibration::confirm))
        .route("/api/calibrations/{id}/repeat", post(calibration::repeat))
        .route("/api/calibrations/{id}/abort", post(calibration::abort))
        .route(
            "/api/verify",
            get(calibration::trend).post(calibration::start_verify),
        )
        .fallback(not_found)
        .method_not_allowed_fallback(method_not_allowed)
        .layer(axum::extract::DefaultBodyLimit::max(BODY_LIMIT))
        .layer(axum::middleware::from_fn_with_state(state.clone(), auth))
        .layer(axum::middleware::map_response(json_errors))
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            guard::guard,
        ))
        .with_state(state)
}

/// Serve until `signal` resolves, then: stop accepting, close idle connections, end event
/// streams, cancel the running scan (archived as cancelled, "daemon shutting down") and wait
/// for it to be archived; open downloads get up to 10 s to finish. The connection limits
/// and timeouts are in [`server`].
pub async fn serve(
    daemon: Arc<Daemon>,
    listener: tokio::net::TcpListener,
    signal: impl Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    serve_tls(daemon, listener, signal, None).await
}

/// Whether the API is served over HTTPS, and the certificate's fingerprint for the operator
/// to compare with the browser's (a self-signed certificate is trusted by that check).
async fn tls_status(State(st): State<AppState>) -> Json<serde_json::Value> {
    Json(match st.daemon.tls.get() {
        Some(t) => serde_json::json!({ "https": true, "certificate": t }),
        None => serde_json::json!({ "https": false }),
    })
}

/// [`serve`], over HTTPS when `tls` is given (its fingerprint goes to /api/tls).
pub async fn serve_tls(
    daemon: Arc<Daemon>,
    listener: tokio::net::TcpListener,
    signal: impl Future<Output = ()> + Send + 'static,
    tls: Option<tls::Tls>,
) -> std::io::Result<()> {
    if let Some(t) = &tls {
        let _ = daemon.tls.set(t.info.clone());
    }
    let (tx, rx) = watch::channel(false);
    let app = router(daemon.clone(), rx.clone());
    let c = &daemon.config;
    let limits = server::Limits {
        header_timeout: c.header_timeout,
        body_timeout: c.body_timeout,
        max_connections: server::connection_cap(c.max_connections)
            .map_err(std::io::Error::other)?,
        max_per_client: c.max_connections_per_client,
    };
    let mut server = tokio::spawn(server::run_tls(
        listener,
        app,
        limits,
        rx.clone(),
        Duration::from_secs(10),
        tls.map(|t| t.acceptor),
    ));
    tokio::select! {
        r = &mut server => return r.map_err(std::io::Error::other)?,
        _ = signal => {}
    }
    tracing::info!("shutting down: no new connections; cancelling the running scan");
    let _ = tx.send(true);
    let d = daemon.clone();
    let job = tokio::task::spawn_blocking(move || d.shutdown());
    let _ = server.await;
    let _ = job.await;
    tracing::info!("footscand stopped");
    Ok(())
}

/// The bearer token check: `Authorization: Bearer <token>` or `?access_token=<token>`,
/// compared in constant time. Health and the static dashboard files (the same bytes for
/// everyone; the page asks for the token) are open.
async fn auth(State(st): State<AppState>, req: Request, next: Next) -> Response {
    let Some(token) = st.daemon.config.token.as_deref() else {
        return next.run(req).await;
    };
    let path = req.uri().path();
    if req.method() == Method::GET
        && (matches!(
            path,
            "/api/health"
                | "/"
                | "/app.js"
                | "/calibration.js"
                | "/visits.js"
                | "/last.js"
                | "/insole.js"
                | "/style.css"
                | "/view.js"
        ) || path.starts_with("/vendor/three/"))
    {
        return next.run(req).await;
    }
    let from_header = req
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| {
            // The scheme is case-insensitive (RFC 9110): `bearer` works as well as `Bearer`.
            let (scheme, rest) = v.trim_start().split_once(' ')?;
            scheme.eq_ignore_ascii_case("bearer").then_some(rest)
        })
        .map(str::trim);
    let from_query = req.uri().query().and_then(|q| {
        q.split('&')
            .find_map(|kv| kv.strip_prefix("access_token="))
            .map(percent_decode)
    });
    let ok = [from_header.map(str::to_string), from_query]
        .into_iter()
        .flatten()
        .any(|given| token_eq(given.as_bytes(), token.as_bytes()));
    if ok {
        return next.run(req).await;
    }
    ApiError::from(Refused::Token).into_response()
}

/// axum's own rejections (a path that is not UTF-8, a malformed query) are plain text: wrap
/// every error that is not JSON yet as `{"error": "..."}`.
async fn json_errors(resp: Response) -> Response {
    let status = resp.status();
    let is_json = resp
        .headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|v| v.as_bytes().starts_with(b"application/json"));
    if !(status.is_client_error() || status.is_server_error()) || is_json {
        return resp;
    }
    let (parts, body) = resp.into_parts();
    let text = match axum::body::to_bytes(body, 4096).await {
        Ok(b) if !b.is_empty() => String::from_utf8_lossy(&b).into_owned(),
        _ => status
            .canonical_reason()
            .unwrap_or("request failed")
            .to_string(),
    };
    let mut out = error::json_error(status, text);
    for (k, v) in parts.headers.iter() {
        if k != header::CONTENT_TYPE && k != header::CONTENT_LENGTH {
            out.headers_mut().insert(k.clone(), v.clone());
        }
    }
    out
}

fn token_eq(a: &[u8], b: &[u8]) -> bool {
    use subtle::ConstantTimeEq;
    a.len() == b.len() && bool::from(a.ct_eq(b))
}

/// `%XX` and `+` decoding of a query value.
fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let hex = |c: u8| (c as char).to_digit(16).map(|d| d as u8);
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'%' if i + 2 < b.len() => match (hex(b[i + 1]), hex(b[i + 2])) {
                (Some(h), Some(l)) => {
                    out.push(h * 16 + l);
                    i += 3;
                    continue;
                }
                _ => out.push(b'%'),
            },
            b'+' => out.push(b' '),
            c => out.push(c),
        }
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

async fn health() -> Json<serde_json::Value> {
    Json(serde_json::json!({"ok": true, "version": env!("CARGO_PKG_VERSION")}))
}

async fn not_found(req: Request) -> ApiError {
    Refused::NoRoute {
        method: req.method().to_string(),
        path: req.uri().path().to_string(),
    }
    .into()
}

async fn method_not_allowed(req: Request) -> ApiError {
    Refused::Method {
        method: req.method().to_string(),
        path: req.uri().path().to_string(),
    }
    .into()
}

fn static_file(content_type: &'static str, body: &'static str) -> Response {
    (
        [
            (header::CONTENT_TYPE, content_type),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        body,
    )
        .into_response()
}

async fn dashboard_index() -> Response {
    static_file(
        "text/html; charset=utf-8",
        include_str!("dashboard/index.html"),
    )
}

async fn dashboard_js() -> Response {
    static_file(
        "text/javascript; charset=utf-8",
        include_str!("dashboard/app.js"),
    )
}

async fn dashboard_calibration_js() -> Response {
    static_file(
        "text/javascript; charset=utf-8",
        include_str!("dashboard/calibration.js"),
    )
}

async fn dashboard_visits_js() -> Response {
    static_file(
        "text/javascript; charset=utf-8",
        include_str!("dashboard/visits.js"),
    )
}

async fn dashboard_last_js() -> Response {
    static_file(
        "text/javascript; charset=utf-8",
        include_str!("dashboard/last.js"),
    )
}

async fn dashboard_insole_js() -> Response {
    static_file(
        "text/javascript; charset=utf-8",
        include_str!("dashboard/insole.js"),
    )
}

async fn dashboard_view_js() -> Response {
    static_file(
        "text/javascript; charset=utf-8",
        include_str!("dashboard/view.js"),
    )
}

/// three.js 0.187.0 from npm, embedded (dashboard/vendor/three/README.md): the 3D view
/// works without the internet.
async fn vendor_three(axum::extract::Path(path): axum::extract::Path<String>) -> Response {
    macro_rules! files {
        ($($p:literal),*) => {
            match path.as_str() {
                $($p => include_str!(concat!("dashboard/vendor/three/", $p)),)*
                _ => return error::ApiError::Missing(format!(
                    "/vendor/three/{path}: no such file of the embedded three.js"
                )).into_response(),
            }
        };
    }
    let body = files!(
        "build/three.module.js",
        "build/three.core.js",
        "examples/jsm/controls/OrbitControls.js",
        "examples/jsm/loaders/GLTFLoader.js",
        "examples/jsm/utils/BufferGeometryUtils.js",
        "examples/jsm/utils/SkeletonUtils.js",
        "LICENSE"
    );
    let ty = if path == "LICENSE" {
        "text/plain; charset=utf-8"
    } else {
        "text/javascript; charset=utf-8"
    };
    static_file(ty, body)
}

async fn dashboard_css() -> Response {
    static_file(
        "text/css; charset=utf-8",
        include_str!("dashboard/style.css"),
    )
}

#[cfg(test)]
mod tests {
    #[test]
    fn tokens_and_query_decoding() {
        assert!(super::token_eq(b"abc", b"abc"));
        assert!(!super::token_eq(b"abc", b"abd"));
        assert!(!super::token_eq(b"abc", b"abcd"));
        assert_eq!(super::percent_decode("a%2Bb+c%zz%4"), "a+b c%zz%4");
    }
}
