//! The routes (docs/live.md, "Routes"). Nothing is read from disk here but the run
//! file, through the report: the page's files are compiled in, and every other path
//! is a 404.

use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::extract::{Path as UrlPath, Request, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::sse::{Event as SseEvent, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use futures_util::Stream;
use tokio::sync::{broadcast, watch};

use crate::hub::{Hub, Numbered};
use crate::{Controls, ReportFn, Waker};

const INDEX: &str = include_str!("../assets/index.html");
const SCRIPT: &str = include_str!("../assets/app.js");
const STYLE: &str = include_str!("../assets/app.css");

/// The page's policy: its own files only; no inline script or style.
const PAGE_POLICY: &str = "default-src 'self'; style-src 'self'; img-src 'self' data:; \
     connect-src 'self'; font-src 'self'; frame-ancestors 'none'; base-uri 'none'; form-action 'none'";
/// The report's: it is one self-contained file with inline style and images.
const REPORT_POLICY: &str = "default-src 'none'; style-src 'unsafe-inline'; \
     img-src data:; font-src data:; frame-ancestors 'none'";
/// The header that carries the control token.
pub const TOKEN_HEADER: &str = "x-gonio-token";

/// What every handler shares.
pub(crate) struct App {
    pub hub: Arc<Hub>,
    pub waker: Arc<Waker>,
    pub control: Option<Controls>,
    pub token: Option<String>,
    pub report: Option<ReportFn>,
    pub run: std::path::PathBuf,
    /// Only loopback host names are accepted (the server listens on loopback).
    pub loopback: bool,
    pub shutdown: watch::Receiver<bool>,
    /// One report at a time, and the last one made: (done + failed, state, page).
    pub report_cache: tokio::sync::Mutex<Option<(u64, &'static str, Arc<str>)>>,
}

/// The router over `app`.
pub(crate) fn router(app: Arc<App>) -> Router {
    Router::new()
        .route(
            "/",
            get(|| async { page(INDEX, "text/html; charset=utf-8") }),
        )
        .route(
            "/app.js",
            get(|| async { page(SCRIPT, "text/javascript; charset=utf-8") }),
        )
        .route(
            "/app.css",
            get(|| async { page(STYLE, "text/css; charset=utf-8") }),
        )
        .route("/font.ttf", get(font))
        .route("/state", get(state))
        .route("/events", get(events))
        .route("/report.html", get(report))
        .route("/control/{action}", post(control))
        .fallback(|| async { refuse(StatusCode::NOT_FOUND, "no such page") })
        .layer(middleware::from_fn_with_state(app.clone(), guard))
        .with_state(app)
}

fn page(body: &'static str, kind: &'static str) -> Response {
    ([(header::CONTENT_TYPE, kind)], body).into_response()
}

/// A JSON error.
fn refuse(code: StatusCode, why: &str) -> Response {
    (code, axum::Json(serde_json::json!({ "error": why }))).into_response()
}

async fn font() -> Response {
    (
        [
            (header::CONTENT_TYPE, "font/ttf"),
            (header::CACHE_CONTROL, "public, max-age=86400, immutable"),
        ],
        gonio_io::plot::dejavu_sans(),
    )
        .into_response()
}

async fn state(State(app): State<Arc<App>>) -> Response {
    let (_, json) = app.hub.snapshot();
    (
        [(header::CONTENT_TYPE, "application/json")],
        json.to_string(),
    )
        .into_response()
}

/// The Host header's name without its port.
fn host_name(headers: &HeaderMap) -> Option<String> {
    let h = headers.get(header::HOST)?.to_str().ok()?;
    let name = if let Some(rest) = h.strip_prefix('[') {
        // [::1]:8080
        format!("[{}]", rest.split(']').next().unwrap_or_default())
    } else {
        h.split(':').next().unwrap_or_default().to_string()
    };
    Some(name.to_ascii_lowercase())
}

/// The Host check (DNS rebinding) and the headers every answer carries.
async fn guard(State(app): State<Arc<App>>, req: Request, next: Next) -> Response {
    if app.loopback
        && let Some(host) = host_name(req.headers())
        && !matches!(host.as_str(), "localhost" | "127.0.0.1" | "[::1]")
    {
        tracing::warn!(%host, "live view: refused a request for another host name");
        return refuse(
            StatusCode::MISDIRECTED_REQUEST,
            "this server answers only to localhost, 127.0.0.1 and [::1]",
        );
    }
    tracing::debug!(method = %req.method(), uri = %req.uri(), "live view: request");
    let mut r = next.run(req).await;
    let h = r.headers_mut();
    h.entry(header::CONTENT_SECURITY_POLICY)
        .or_insert(HeaderValue::from_static(PAGE_POLICY));
    h.entry(header::CACHE_CONTROL)
        .or_insert(HeaderValue::from_static("no-store"));
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    // The page's address may carry the control token: never send it on.
    h.insert(
        header::REFERRER_POLICY,
        HeaderValue::from_static("no-referrer"),
    );
    r
}

/// Where a page's stream stands.
struct Client {
    first: Option<Arc<str>>,
    seq: u64,
    rx: broadcast::Receiver<Numbered>,
    hub: Arc<Hub>,
    shutdown: watch::Receiver<bool>,
    /// Released when the page goes.
    _permit: tokio::sync::OwnedSemaphorePermit,
}

async fn events(State(app): State<Arc<App>>) -> Response {
    let Ok(permit) = app.hub.clients.clone().try_acquire_owned() else {
        tracing::warn!("live view: too many event streams; one refused");
        return refuse(
            StatusCode::SERVICE_UNAVAILABLE,
            "too many pages are open on this run",
        );
    };
    let (seq, json, rx) = app.hub.subscribe();
    tracing::debug!(
        open = crate::hub::MAX_CLIENTS - app.hub.clients.available_permits(),
        "live view: a page connected"
    );
    let client = Client {
        first: Some(json),
        seq,
        rx,
        hub: app.hub.clone(),
        shutdown: app.shutdown.clone(),
        _permit: permit,
    };
    Sse::new(stream(client))
        .keep_alive(KeepAlive::new().interval(Duration::from_secs(15)))
        .into_response()
}

/// The stream of one page: its snapshot, then the updates after it.
fn stream(client: Client) -> impl Stream<Item = Result<SseEvent, Infallible>> {
    futures_util::stream::unfold(client, |mut c| async move {
        if let Some(json) = c.first.take() {
            return Some((Ok(SseEvent::default().event("snapshot").data(&*json)), c));
        }
        loop {
            if *c.shutdown.borrow() {
                return None;
            }
            let next = tokio::select! {
                r = c.rx.recv() => r,
                _ = c.shutdown.changed() => return None,
            };
            match next {
                Ok((seq, json)) if seq > c.seq => {
                    c.seq = seq;
                    return Some((Ok(SseEvent::default().event("update").data(&*json)), c));
                }
                // Already in the snapshot it was sent.
                Ok(_) => {}
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    tracing::debug!(
                        missed = n,
                        "live view: a page fell behind; resending the snapshot"
                    );
                    let (seq, json) = c.hub.snapshot();
                    c.seq = seq;
                    return Some((Ok(SseEvent::default().event("snapshot").data(&*json)), c));
                }
                Err(broadcast::error::RecvError::Closed) => return None,
            }
        }
    })
}

async fn report(State(app): State<Arc<App>>) -> Response {
    let Some(make) = app.report.clone() else {
        return refuse(StatusCode::NOT_FOUND, "no report here");
    };
    let s = app.hub.state();
    let key = (s.status.done + s.status.failed, s.status.state);
    // One at a time: a report reduces and plots the whole run.
    let mut cache = app.report_cache.lock().await;
    if let Some((n, st, html)) = cache.as_ref()
        && (*n, *st) == key
    {
        return report_page(html.clone());
    }
    let run = app.run.clone();
    match tokio::task::spawn_blocking(move || make(&run)).await {
        Ok(Ok(html)) => {
            let html: Arc<str> = html.into();
            *cache = Some((key.0, key.1, html.clone()));
            report_page(html)
        }
        Ok(Err(why)) => {
            tracing::warn!("live view: the report failed: {why}");
            refuse(StatusCode::INTERNAL_SERVER_ERROR, &why)
        }
        Err(e) => refuse(StatusCode::INTERNAL_SERVER_ERROR, &e.to_string()),
    }
}

fn report_page(html: Arc<str>) -> Response {
    (
        [
            (header::CONTENT_TYPE, "text/html; charset=utf-8"),
            (header::CONTENT_SECURITY_POLICY, REPORT_POLICY),
        ],
        html.to_string(),
    )
        .into_response()
}

/// Equal, in time that does not depend on where they differ.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |d, (x, y)| d | (x ^ y)) == 0
}

async fn control(
    State(app): State<Arc<App>>,
    UrlPath(action): UrlPath<String>,
    headers: HeaderMap,
) -> Response {
    let (Some(ctl), Some(token)) = (&app.control, &app.token) else {
        tracing::warn!(%action, "live view: refused a control request (no --control)");
        return refuse(
            StatusCode::FORBIDDEN,
            "refused: this run's page was served without --control",
        );
    };
    let given = headers
        .get(TOKEN_HEADER)
        .map(HeaderValue::as_bytes)
        .unwrap_or_default();
    if !same(given, token.as_bytes()) {
        tracing::warn!(%action, "live view: refused a control request without the right token");
        return refuse(
            StatusCode::FORBIDDEN,
            "refused: missing or wrong token (open the address with ?token= that the terminal printed)",
        );
    }
    let ended = matches!(
        app.hub.state().status.state,
        "complete" | "interrupted" | "faulted" | "stale"
    );
    if app.waker.has_ended() || ended {
        return refuse(StatusCode::CONFLICT, "the session has ended");
    }
    match action.as_str() {
        "stop" => ctl.stopper.stop(),
        "pause" => ctl.pauser.pause(),
        "resume" => ctl.pauser.resume(),
        _ => return refuse(StatusCode::NOT_FOUND, "no such control"),
    }
    tracing::info!(%action, "live view: {action} requested from the page");
    app.waker.poke();
    axum::Json(serde_json::json!({ "ok": true, "action": action })).into_response()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn host_names_lose_their_port_and_case() {
        let h = |v: &str| {
            let mut m = HeaderMap::new();
            m.insert(header::HOST, HeaderValue::from_str(v).expect("header"));
            host_name(&m)
        };
        assert_eq!(h("LocalHost:8080").as_deref(), Some("localhost"));
        assert_eq!(h("127.0.0.1").as_deref(), Some("127.0.0.1"));
        assert_eq!(h("[::1]:41234").as_deref(), Some("[::1]"));
        assert_eq!(h("evil.example:80").as_deref(), Some("evil.example"));
        assert_eq!(host_name(&HeaderMap::new()), None);
    }

    #[test]
    fn tokens_compare_whole() {
        assert!(same(b"abc", b"abc"));
        assert!(!same(b"abc", b"abd"));
        assert!(!same(b"abc", b"ab"));
        assert!(!same(b"", b"a"));
    }
}
