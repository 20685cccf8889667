//! Checks every request passes before the API sees it, against a hostile web page in the
//! operator's browser and against slow clients:
//!
//! - Host must name this daemon: an IP address it listens on (any address when bound to
//!   0.0.0.0 or ::), `localhost`, or a name listed in `allowed_hosts`. A page on another
//!   name that DNS-rebinds to the daemon's address sends its own name and is refused.
//! - A state-changing request (anything but GET and HEAD) must carry
//!   `Content-Type: application/json`, which a cross-site form or a no-preflight fetch cannot
//!   send, and an Origin, if any, that is the daemon's own (`http(s)://<Host>`).
//! - The request body must arrive within the body timeout (and within the body limit); a
//!   Content-Length over the limit is 413 at once, before any of the body is waited for.
//! - A request target over 8 KiB is 414 and headers over 32 KiB are 431, as JSON errors.
//! - Every response says X-Content-Type-Options: nosniff and refuses framing
//!   (X-Frame-Options: DENY, CSP frame-ancestors 'none').

use super::{ApiError, AppState, Refused};
use axum::body::Body;
use axum::extract::{Request, State};
use axum::http::{header, HeaderValue, Method};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use std::net::{IpAddr, SocketAddr};

/// The host part of a Host header value (`name`, `name:port`, `[v6]:port`), lowercased.
fn host_name(value: &str) -> String {
    let v = value.trim();
    let host = if let Some(rest) = v.strip_prefix('[') {
        rest.split(']').next().unwrap_or("")
    } else {
        match v.rsplit_once(':') {
            Some((h, p)) if p.bytes().all(|c| c.is_ascii_digit()) => h,
            _ => v,
        }
    };
    host.trim_end_matches('.').to_ascii_lowercase()
}

/// Whether `host` (a Host header value) names this daemon.
pub fn host_allowed(host: &str, bind: SocketAddr, allowed: &[String]) -> bool {
    let name = host_name(host);
    if name.is_empty() {
        return false;
    }
    if let Ok(ip) = name.parse::<IpAddr>() {
        // An address literal cannot be rebound by DNS; accept the ones we answer on.
        return ip == bind.ip() || ip.is_loopback() || bind.ip().is_unspecified();
    }
    name == "localhost"
        || name.ends_with(".localhost")
        || allowed.iter().any(|a| a.eq_ignore_ascii_case(&name))
}

fn refuse(r: Refused) -> Response {
    ApiError::from(r).into_response()
}

fn forbidden(msg: String) -> Response {
    ApiError::from(Refused::Foreign(msg)).into_response()
}

/// Longest request target (path and query) accepted.
pub const MAX_URI: usize = 8 * 1024;
/// Largest request head (all header names and values) accepted.
pub const MAX_HEADERS: usize = 32 * 1024;

pub async fn guard(State(st): State<AppState>, req: Request, next: Next) -> Response {
    let cfg = &st.daemon.config;
    let uri_len = req.uri().path_and_query().map_or(0, |p| p.as_str().len());
    if uri_len > MAX_URI {
        return refuse(Refused::UriTooLong {
            len: uri_len,
            max: MAX_URI,
        });
    }
    let head: usize = req
        .headers()
        .iter()
        .map(|(k, v)| k.as_str().len() + v.len() + 4)
        .sum();
    if head > MAX_HEADERS {
        return refuse(Refused::HeadersTooLarge {
            len: head,
            max: MAX_HEADERS,
        });
    }
    // A declared length over the limit is refused before waiting for the body: otherwise a
    // client announcing 10^15 bytes and sending none holds the connection until the body
    // timeout. (hyper has already refused a Content-Length that is not one number.)
    let declared = req
        .headers()
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<u64>().ok());
    if let Some(n) = declared.filter(|&n| n > super::BODY_LIMIT as u64) {
        return refuse(Refused::DeclaredTooLarge {
            len: n,
            max: super::BODY_LIMIT,
        });
    }
    let Some(host) = req
        .headers()
        .get(header::HOST)
        .and_then(|v| v.to_str().ok())
        .map(str::to_string)
    else {
        return refuse(Refused::NoHost);
    };
    if !host_allowed(&host, cfg.bind, &cfg.allowed_hosts) {
        return forbidden(format!(
            "Host {:?} is not this daemon: use its address, localhost, or add the name to \
             `allowed_hosts` in [daemon] of {}",
            host.chars().take(100).collect::<String>(),
            cfg.path.display()
        ));
    }
    let changes_state = !matches!(*req.method(), Method::GET | Method::HEAD | Method::OPTIONS);
    if changes_state {
        if let Some(origin) = req.headers().get(header::ORIGIN) {
            let origin = origin.to_str().unwrap_or("");
            let own = [format!("http://{host}"), format!("https://{host}")];
            if !own.iter().any(|o| o.eq_ignore_ascii_case(origin)) {
                return forbidden(format!(
                    "Origin {:?} is not this daemon ({}): cross-site requests may not change state",
                    origin.chars().take(100).collect::<String>(),
                    own[0]
                ));
            }
        }
        // POST is the one state-changing method a cross-site form or a no-preflight fetch
        // can send; DELETE (a visit) needs a CORS preflight, which this daemon never grants.
        let json = *req.method() != Method::POST
            || req
                .headers()
                .get(header::CONTENT_TYPE)
                .and_then(|v| v.to_str().ok())
                .is_some_and(|v| {
                    v.split(';')
                        .next()
                        .is_some_and(|m| m.trim().eq_ignore_ascii_case("application/json"))
                });
        if !json {
            return refuse(Refused::NotJson {
                method: req.method().to_string(),
                path: req.uri().path().to_string(),
            });
        }
    }
    let req = if changes_state {
        let (parts, body) = req.into_parts();
        let limit = super::BODY_LIMIT;
        match tokio::time::timeout(cfg.body_timeout, axum::body::to_bytes(body, limit)).await {
            Ok(Ok(bytes)) => Request::from_parts(parts, Body::from(bytes)),
            Ok(Err(_)) => return refuse(Refused::BodyTooLarge { limit }),
            Err(_) => {
                return refuse(Refused::BodyTimeout(cfg.body_timeout));
            }
        }
    } else {
        req
    };
    let mut resp = next.run(req).await;
    let h = resp.headers_mut();
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    h.insert(header::X_FRAME_OPTIONS, HeaderValue::from_static("DENY"));
    if !h.contains_key(header::CONTENT_SECURITY_POLICY) {
        h.insert(
            header::CONTENT_SECURITY_POLICY,
            HeaderValue::from_static("frame-ancestors 'none'"),
        );
    }
    resp
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hosts() {
        let lo: SocketAddr = "127.0.0.1:8470".parse().unwrap();
        let any: SocketAddr = "0.0.0.0:8470".parse().unwrap();
        let named = vec!["scanner.lab".to_string()];
        for ok in [
            "127.0.0.1:8470",
            "localhost:8470",
            "LOCALHOST",
            "[::1]:8470",
            "127.0.0.1",
        ] {
            assert!(host_allowed(ok, lo, &[]), "{ok}");
        }
        for bad in [
            "attacker.example:8470",
            "attacker.example",
            "10.0.0.5:8470",
            "",
            "localhost.attacker.example",
            "scanner.lab",
        ] {
            assert!(!host_allowed(bad, lo, &[]), "{bad}");
        }
        assert!(host_allowed("scanner.lab:8470", lo, &named));
        assert!(host_allowed("10.0.0.5:8470", any, &[]));
        assert!(!host_allowed("evil.example", any, &named));
    }
}
