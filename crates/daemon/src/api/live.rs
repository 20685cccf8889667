//! Live endpoints: status, the preview frame and line, the event stream.

use super::{ApiError, AppState};
use crate::archive::Status;
use crate::daemon::Event;
use axum::extract::{Query, State};
use axum::http::header;
use axum::response::sse::{Event as SseEvent, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::Json;
use footscan::scan::config::Backend;
use footscan::scan::{DeviceRole, FaultKind};
use futures_util::stream::Stream;
use serde::Deserialize;
use serde_json::{json, Value};
use std::convert::Infallible;
use std::time::Duration;
use tokio::sync::broadcast::error::RecvError;

pub async fn status(State(st): State<AppState>) -> Json<Value> {
    let d = &st.daemon;
    let cfg = &d.scanner.config;
    let backend = serde_json::to_value(cfg.scanner.backend).unwrap_or(Value::Null);
    let sim = cfg.scanner.backend == Backend::Sim;
    let scan = d.scan_progress();
    let running = scan.as_ref().is_some_and(|s| s.state == Status::Running);
    // What the last scan learnt about the devices: a scan that lost one says so until the
    // next scan starts.
    let fault = scan
        .as_ref()
        .filter(|s| s.state == Status::Failed)
        .and_then(|s| s.fault.clone());
    let lost = |role: DeviceRole| {
        fault.as_ref().is_some_and(|f| {
            f.role == role && matches!(f.fault.kind, FaultKind::Disconnected | FaultKind::Timeout)
        })
    };
    let missing = crate::daemon::preflight::missing_devices(&d.scanner);
    let absent = |role: &str| missing.iter().any(|(r, _)| *r == role);
    let camera_lost = lost(DeviceRole::Camera) || absent("camera");
    let slider_alarm = fault.as_ref().is_some_and(|f| {
        f.role == DeviceRole::Slider && matches!(f.fault.kind, FaultKind::Alarm(_))
    });
    let slider_lost = lost(DeviceRole::Slider) || absent("slider");
    let line = d.preview.line();
    let hw = cfg.hardware.as_ref().filter(|_| !sim);
    let (cam_name, mut w, mut h, format, slider_name) = match hw {
        Some(hw) => (
            format!("V4L2 camera {}", hw.camera.device.display()),
            hw.camera.width,
            hw.camera.height,
            Value::from(hw.camera.pixel_format.to_lowercase()),
            format!("GRBL controller on {}", hw.slider.port),
        ),
        None => (
            "simulated camera".to_string(),
            cfg.sim.optics.width,
            cfg.sim.optics.height,
            serde_json::to_value(cfg.sim.noise.format).unwrap_or(Value::Null),
            "GRBL emulator (pseudo-terminal)".to_string(),
        ),
    };
    if let Some(l) = &line {
        (w, h) = (l.width, l.height);
    }
    let slider_state = if running {
        "run"
    } else if slider_alarm {
        "alarm"
    } else {
        "idle"
    };
    Json(json!({
        "version": env!("CARGO_PKG_VERSION"),
        "backend": backend,
        "devices": {
            "camera": {
                "name": cam_name,
                "width": w,
                "height": h,
                "format": format,
                "connected": !camera_lost,
            },
            "slider": {
                "name": slider_name,
                "state": slider_state,
                "x_mm": d.preview.x_mm(),
                "connected": !slider_lost,
            },
        },
        "calibration": d.calibration().map(|c| {
            let age = crate::archive::calibrations::age_h(&c.date);
            json!({"id": c.id, "method": c.method, "date": c.date, "path": c.path, "age_h": age})
        }),
        "daily_check": crate::archive::calibrations::Calibrations::new(&d.config.archive)
            .check_status(cfg.calibration.verify_max_age_h),
        "scan": scan,
        "calibrating": d.calibrating(),
        "archive": {
            "notices": d.archive.notices(),
            "compact": d.config.archive_policy.compact,
            "retention": d.archive.last_retention(),
        },
        "fleet": d.fleet_status(),
    }))
}

#[derive(Deserialize)]
pub struct PreviewQuery {
    width: Option<String>,
    access_token: Option<String>,
}

/// An encoded preview: one per tap copy and width, however many viewers ask.
#[derive(Clone)]
pub struct CachedPng {
    generation: u64,
    width: u32,
    seq: u64,
    timestamp: footscan_hal::Timestamp,
    png: axum::body::Bytes,
}

/// The PNG of the latest frame at `width`: from the cache while the tap has copied nothing
/// newer, else downscaled and encoded once (concurrent viewers wait on the cache's lock and
/// then share the result, so 20 viewers cost one encode per copied frame, and the slot's
/// lock, which makes the tap skip frames while held, is taken once per frame, not per view).
fn cached_png(
    preview: &crate::daemon::preview::Preview,
    cache: &std::sync::Mutex<Option<CachedPng>>,
    width: u32,
) -> Option<Result<CachedPng, image::ImageError>> {
    let mut cache = cache.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(c) = cache.as_ref() {
        if c.generation == preview.generation() && c.width == width {
            return Some(Ok(c.clone()));
        }
    }
    let img = preview.image(width)?;
    let mut png = Vec::with_capacity(img.pixels.len() / 2 + 1024);
    let enc = image::codecs::png::PngEncoder::new_with_quality(
        &mut png,
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::Sub,
    );
    use image::ImageEncoder;
    if let Err(e) = enc.write_image(
        &img.pixels,
        img.width,
        img.height,
        image::ExtendedColorType::L8,
    ) {
        return Some(Err(e));
    }
    let c = CachedPng {
        generation: img.generation,
        width,
        seq: img.seq,
        timestamp: img.timestamp,
        png: png.into(),
    };
    *cache = Some(c.clone());
    Some(Ok(c))
}

pub async fn preview_png(
    State(st): State<AppState>,
    Query(q): Query<PreviewQuery>,
) -> Result<Response, ApiError> {
    let _ = q.access_token;
    let width = match q.width.as_deref() {
        None => 320,
        Some(w) => w
            .parse::<u32>()
            .ok()
            .filter(|w| (16..=1280).contains(w))
            .ok_or_else(|| {
                ApiError::invalid(format!(
                    "width {w:?}: must be an integer in 16..=1280 (default 320)"
                ))
            })?,
    };
    let preview = st.daemon.preview.clone();
    let cache = st.preview_png.clone();
    let out = tokio::task::spawn_blocking(move || cached_png(&preview, &cache, width)).await?;
    let Some(out) = out else {
        return Err(ApiError::missing(
            "no frame yet: the preview shows the running or last scan's frames",
        ));
    };
    let c = out?;
    let (png, seq, age_ms) = (c.png, c.seq, crate::daemon::preview::age_ms(c.timestamp));
    Ok((
        [
            (header::CONTENT_TYPE, "image/png".to_string()),
            (header::CACHE_CONTROL, "no-store".to_string()),
            (
                header::HeaderName::from_static("x-frame-seq"),
                seq.to_string(),
            ),
            (
                header::HeaderName::from_static("x-frame-age-ms"),
                format!("{age_ms:.1}"),
            ),
        ],
        png,
    )
        .into_response())
}

pub async fn preview_line(State(st): State<AppState>) -> Result<Response, ApiError> {
    let p = st.daemon.preview.clone();
    let line = tokio::task::spawn_blocking(move || p.line())
        .await?
        .ok_or_else(|| {
            ApiError::missing("no frame yet: the preview shows the running or last scan's frames")
        })?;
    Ok(([(header::CACHE_CONTROL, "no-store")], Json(line)).into_response())
}

fn sse(e: &Event) -> SseEvent {
    SseEvent::default().event(e.name()).data(e.json())
}

/// Server-sent events; the current scan's progress first (so a client that connects late
/// sees where it is, or that it has ended), then every event until the daemon stops. When
/// the daemon stops during a scan, the stream stays open until that scan's final state
/// (cancelled, "daemon shutting down") has been sent, so clients see how it ended.
pub async fn events(
    State(st): State<AppState>,
) -> Sse<impl Stream<Item = Result<SseEvent, Infallible>>> {
    let rx = st.daemon.subscribe();
    let first = st.daemon.scan_progress().map(Event::Progress);
    let shutdown = st.shutdown.clone();
    let daemon = st.daemon.clone();
    let stream = futures_util::stream::unfold(
        (rx, first, shutdown, daemon),
        |(mut rx, mut first, mut shutdown, daemon)| async move {
            if let Some(e) = first.take() {
                return Some((Ok(sse(&e)), (rx, None, shutdown, daemon)));
            }
            loop {
                if *shutdown.borrow() {
                    let running = daemon
                        .scan_progress()
                        .filter(|p| p.state == Status::Running)
                        .map(|p| p.id);
                    let id = running?;
                    // Draining: forward until the scan's final state, within a limit.
                    let end = tokio::time::timeout(Duration::from_secs(15), async {
                        loop {
                            match rx.recv().await {
                                Ok(e @ Event::State { .. }) => {
                                    if let Event::State {
                                        id: ref i, state, ..
                                    } = e
                                    {
                                        if *i == id && state != Status::Running {
                                            return Some(e);
                                        }
                                    }
                                }
                                Ok(_) | Err(RecvError::Lagged(_)) => {}
                                Err(RecvError::Closed) => return None,
                            }
                        }
                    })
                    .await;
                    let e = end.ok().flatten()?;
                    // Nothing follows: the next poll sees no running scan and ends.
                    return Some((Ok(sse(&e)), (rx, None, shutdown, daemon)));
                }
                tokio::select! {
                    r = rx.recv() => match r {
                        Ok(e) => return Some((Ok(sse(&e)), (rx, None, shutdown, daemon))),
                        Err(RecvError::Lagged(n)) => {
                            tracing::debug!("event stream lagged by {n} events");
                        }
                        Err(RecvError::Closed) => return None,
                    },
                    r = shutdown.changed() => if r.is_err() {
                        return None;
                    },
                }
            }
        },
    );
    Sse::new(stream).keep_alive(
        KeepAlive::new()
            .interval(Duration::from_secs(15))
            .text("keep-alive"),
    )
}
