//! The HTTP side of the lab page: the page itself, the JSON API and the event stream.
//!
//! ```text
//! GET  /                           the page (one self-contained HTML file, built in)
//! GET  /api/state                  the page state (JSON)
//! GET  /api/ws                     the event stream (events.rs)
//! GET  /api/clients                connected pages and preview frames sent to each
//! GET  /sessions/NAME/report       the session's HTML report (as `brdf-rig report` makes it)
//! POST /api/control                take control            {"name": "bench PC"}
//! POST /api/control/release        give it up
//! POST /api/capture/start          {"plan": ID, "session": NAME, "mode": "guided"|"unattended"}
//! POST /api/capture/resume         {"session": NAME, "mode": ...}
//! POST /api/capture/continue       {"seq": N}   the operator did instruction N
//! POST /api/capture/pause          stop at the next safe point, light off; resumable
//! POST /api/capture/abort          the same, and leave the session
//! POST /api/light                  {"on": true, "channel": 0, "level": 1.0} | {"on": false}
//! POST /api/turntable              {"action": "home"} | {"action": "move", "angle_deg": 90}
//! POST /api/preview                {"exposure_secs": 0.02, "gain": 1.0}
//! ```
//! Every POST needs `X-Client: KEY` of the controlling page (403 otherwise) and, when the server
//! has a token, `Authorization: Bearer TOKEN` (401 otherwise); reading needs neither. Errors are
//! `{"error": "..."}` with 400 (bad input), 401, 403, 404, 409 (not now: a capture runs, the
//! folder exists, the instruction is no longer current) or 500 (the rig failed).
//!
//! Handlers never touch a device: they check, then send a command to the rig's thread (hub).

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::body::Bytes;
use axum::extract::{ConnectInfo, Path as UrlPath, Request, State, WebSocketUpgrade};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{Html, IntoResponse, Json, Response};
use axum::routing::{get, post};
use serde_json::json;

use super::control::{Refusal, is_local_host};
use super::hub::{Command, CommandError, Hub, StopKind};
use super::requests::{
    ClaimRequest, ContinueRequest, LightRequest, PreviewRequest, ResumeRequest, RigLimits,
    StartRequest, TurntableRequest, parse, session_name,
};
use super::state::SessionInfo;

/// The page, built into the binary.
pub const PAGE: &str = include_str!("page.html");

/// What the handlers share.
#[derive(Clone)]
pub struct App {
    pub hub: Arc<Hub>,
    pub lost_after: Duration,
    /// Bound to loopback: only local `Host` names are served.
    pub local_only: bool,
    pub limits: RigLimits,
    pub sessions_dir: PathBuf,
}

/// An error answer.
#[derive(Debug)]
pub struct ApiError {
    status: StatusCode,
    message: String,
}

impl ApiError {
    fn new(status: StatusCode, message: impl Into<String>) -> Self {
        Self {
            status,
            message: message.into(),
        }
    }
    fn bad(message: impl Into<String>) -> Self {
        Self::new(StatusCode::BAD_REQUEST, message)
    }
    fn conflict(message: impl Into<String>) -> Self {
        Self::new(StatusCode::CONFLICT, message)
    }
}

impl From<Refusal> for ApiError {
    fn from(r: Refusal) -> Self {
        let status = match r {
            Refusal::Token => StatusCode::UNAUTHORIZED,
            Refusal::UnknownClient | Refusal::ReadOnly(_) | Refusal::NobodyControls => {
                StatusCode::FORBIDDEN
            }
        };
        ApiError::new(status, r.to_string())
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let mut r = (self.status, Json(json!({"error": self.message}))).into_response();
        if self.status == StatusCode::UNAUTHORIZED {
            r.headers_mut().insert(
                header::WWW_AUTHENTICATE,
                HeaderValue::from_static("Bearer realm=\"brdf-rig\""),
            );
        }
        r
    }
}

type Answer = Result<Json<serde_json::Value>, ApiError>;

fn header_str<'a>(headers: &'a HeaderMap, name: &str) -> Option<&'a str> {
    headers.get(name).and_then(|v| v.to_str().ok())
}

impl App {
    /// Token first (401), then control (403).
    fn authorize(&self, headers: &HeaderMap) -> Result<(), ApiError> {
        self.hub
            .authorize(
                header_str(headers, "authorization"),
                header_str(headers, "x-client"),
            )
            .map_err(ApiError::from)
    }

    fn refuse_while_capturing(&self) -> Result<(), ApiError> {
        if self.hub.phase().is_active() {
            return Err(ApiError::conflict(
                "a capture is running: pause or abort it first",
            ));
        }
        Ok(())
    }

    /// Sends a command to the rig's thread and waits for its answer.
    async fn ask(&self, command: Command) -> Result<String, CommandError> {
        match self.hub.send(command).await {
            Ok(r) => r,
            Err(_) => Err(CommandError::Stopped),
        }
    }
}

pub fn router(app: App) -> Router {
    Router::new()
        .route("/", get(page))
        .route("/api/state", get(state))
        .route("/api/ws", get(socket))
        .route("/api/clients", get(clients))
        .route("/sessions/{name}/report", get(report))
        .route("/api/control", post(claim))
        .route("/api/control/release", post(release))
        .route("/api/capture/start", post(start))
        .route("/api/capture/resume", post(resume))
        .route("/api/capture/continue", post(continue_))
        .route("/api/capture/pause", post(pause))
        .route("/api/capture/abort", post(abort))
        .route("/api/light", post(light))
        .route("/api/turntable", post(turntable))
        .route("/api/preview", post(preview))
        .layer(middleware::from_fn_with_state(app.clone(), check_host))
        .with_state(app)
}

/// Bound to loopback, a request must name a local host (see `control`).
async fn check_host(State(app): State<App>, req: Request, next: Next) -> Response {
    if app.local_only {
        let host = header_str(req.headers(), "host").unwrap_or("");
        if !is_local_host(host) {
            return ApiError::new(
                StatusCode::MISDIRECTED_REQUEST,
                format!("host {host:?} is not served here: this server answers to localhost only"),
            )
            .into_response();
        }
    }
    next.run(req).await
}

async fn page() -> impl IntoResponse {
    ([(header::CACHE_CONTROL, "no-store")], Html(PAGE))
}

async fn state(State(app): State<App>) -> Json<super::state::PageState> {
    Json(app.hub.snapshot())
}

async fn clients(State(app): State<App>) -> Json<serde_json::Value> {
    let sent: Vec<_> = app
        .hub
        .frames_sent()
        .into_iter()
        .map(|(number, frames)| json!({"number": number, "frames_sent": frames}))
        .collect();
    Json(json!({"frames_made": app.hub.frames_made(), "clients": sent}))
}

async fn socket(
    State(app): State<App>,
    ConnectInfo(address): ConnectInfo<SocketAddr>,
    ws: WebSocketUpgrade,
) -> Response {
    let hub = app.hub.clone();
    let lost_after = app.lost_after;
    ws.on_upgrade(move |socket| super::events::serve_page(socket, hub, address, lost_after))
}

async fn claim(State(app): State<App>, headers: HeaderMap, body: Bytes) -> Answer {
    app.hub.token.check(header_str(&headers, "authorization"))?;
    let req: ClaimRequest = parse(&body).map_err(ApiError::bad)?;
    let key = header_str(&headers, "x-client").ok_or(Refusal::UnknownClient)?;
    app.hub.claim(key, &req.name)?;
    Ok(Json(json!({"controlling": true})))
}

async fn release(State(app): State<App>, headers: HeaderMap) -> Answer {
    app.authorize(&headers)?;
    let key = header_str(&headers, "x-client").unwrap_or("");
    app.hub.release(key)?;
    Ok(Json(json!({"controlling": false})))
}

async fn start(State(app): State<App>, headers: HeaderMap, body: Bytes) -> Answer {
    app.authorize(&headers)?;
    let spec = parse::<StartRequest>(&body)
        .and_then(|r| r.check())
        .map_err(ApiError::bad)?;
    app.refuse_while_capturing()?;
    let session = app
        .ask(Command::Start(spec))
        .await
        .map_err(|e| ApiError::conflict(e.to_string()))?;
    Ok(Json(json!({"session": session})))
}

async fn resume(State(app): State<App>, headers: HeaderMap, body: Bytes) -> Answer {
    app.authorize(&headers)?;
    let command = parse::<ResumeRequest>(&body)
        .and_then(|r| r.check())
        .map_err(ApiError::bad)?;
    app.refuse_while_capturing()?;
    let session = app
        .ask(command)
        .await
        .map_err(|e| ApiError::conflict(e.to_string()))?;
    Ok(Json(json!({"session": session})))
}

async fn continue_(State(app): State<App>, headers: HeaderMap, body: Bytes) -> Answer {
    app.authorize(&headers)?;
    let req: ContinueRequest = parse(&body).map_err(ApiError::bad)?;
    let current = app.hub.snapshot().capture.instruction.map(|i| i.seq);
    match current {
        Some(seq) if seq == req.seq => {
            app.hub.send_continue(seq);
            Ok(Json(json!({"continued": seq})))
        }
        Some(seq) => Err(ApiError::conflict(format!(
            "instruction {} is no longer current (now {seq})",
            req.seq
        ))),
        None => Err(ApiError::conflict("no instruction is waiting")),
    }
}

async fn stop(app: &App, headers: &HeaderMap, kind: StopKind) -> Answer {
    app.authorize(headers)?;
    if !app.hub.phase().is_active() {
        return Err(ApiError::conflict("no capture is running"));
    }
    let who = app
        .hub
        .snapshot()
        .control
        .controller
        .map(|c| c.name)
        .unwrap_or_else(|| "the page".into());
    let what = match kind {
        StopKind::Pause => "paused",
        StopKind::Abort => "aborted",
    };
    app.hub
        .request_stop(kind, format!("{what} from the page by {who}"));
    Ok(Json(json!({"stopping": true})))
}

async fn pause(State(app): State<App>, headers: HeaderMap) -> Answer {
    stop(&app, &headers, StopKind::Pause).await
}

async fn abort(State(app): State<App>, headers: HeaderMap) -> Answer {
    stop(&app, &headers, StopKind::Abort).await
}

async fn rig_command(app: &App, command: Command) -> Answer {
    app.refuse_while_capturing()?;
    let done = app
        .ask(command)
        .await
        .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?;
    Ok(Json(json!({"done": done})))
}

async fn light(State(app): State<App>, headers: HeaderMap, body: Bytes) -> Answer {
    app.authorize(&headers)?;
    let command = parse::<LightRequest>(&body)
        .and_then(|r| r.check(&app.limits))
        .map_err(ApiError::bad)?;
    rig_command(&app, command).await
}

async fn turntable(State(app): State<App>, headers: HeaderMap, body: Bytes) -> Answer {
    app.authorize(&headers)?;
    let command = parse::<TurntableRequest>(&body)
        .and_then(|r| r.check(&app.limits))
        .map_err(ApiError::bad)?;
    rig_command(&app, command).await
}

async fn preview(State(app): State<App>, headers: HeaderMap, body: Bytes) -> Answer {
    app.authorize(&headers)?;
    let (exposure_secs, gain) = parse::<PreviewRequest>(&body)
        .and_then(|r| r.check())
        .map_err(ApiError::bad)?;
    app.hub.update(|s| {
        s.preview.exposure_secs = exposure_secs;
        s.preview.gain = gain;
    });
    Ok(Json(json!({"exposure_secs": exposure_secs, "gain": gain})))
}

async fn report(State(app): State<App>, UrlPath(name): UrlPath<String>) -> Response {
    let name = match session_name(&name) {
        Ok(n) => n,
        Err(e) => return ApiError::bad(e).into_response(),
    };
    let dir = app.sessions_dir.join(&name);
    if SessionInfo::read(&dir).is_none() {
        return ApiError::new(StatusCode::NOT_FOUND, format!("no session {name:?}"))
            .into_response();
    }
    let made = tokio::task::spawn_blocking(move || {
        let opts = crate::report::options::ReportOptions::default();
        crate::report::gather::gather(&dir, &opts)
            .map(|data| crate::report::html::render_html(&data))
            .map_err(|e| format!("making the report of {}: {e}", dir.display()))
    })
    .await;
    match made {
        Ok(Ok(html)) => Html(html).into_response(),
        Ok(Err(e)) => ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e).into_response(),
        Err(e) => ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).into_response(),
    }
}
