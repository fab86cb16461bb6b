//! The event stream of one page (`GET /api/ws`, a WebSocket): the server pushes the page state
//! when it changes (at most every [`STATE_EVERY`]; a page that falls behind gets the newest
//! state, never a queue of old ones) and each new preview frame, and watches that the page is
//! still there.
//!
//! Messages to the page:
//! - text `{"type": "hello", "client": KEY, "number": N}` once: the page's secret key, which it
//!   sends back in `X-Client` with every action, and its public number;
//! - text `{"type": "state", "you": {"number": N, "controlling": bool}, "state": PageState}`;
//! - binary: a preview frame, `u32` little-endian length of a JSON header
//!   (`preview::FrameInfo`), the header, then the JPEG bytes.
//!
//! Liveness: the server pings every [`PING_EVERY`]; the browser's network stack answers by
//! itself (no page script, so a page in a background tab answers too). A page that closes,
//! crashes or loses the network ends its stream at once or stops answering; after
//! `lost_after` without a word, or a send that cannot finish in that time, the page is gone,
//! and if it controlled a capture the capture pauses.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use axum::extract::ws::{Message, WebSocket};
use tokio::time::{Instant, interval, timeout};

use super::hub::Hub;

/// The state goes out at most this often per page.
pub const STATE_EVERY: Duration = Duration::from_millis(100);
/// The server pings each page this often.
pub const PING_EVERY: Duration = Duration::from_millis(250);

/// A preview frame as one binary message.
pub fn frame_message(frame: &super::preview::Frame) -> Vec<u8> {
    let header = serde_json::to_vec(&frame.info).unwrap_or_default();
    let mut out = Vec::with_capacity(4 + header.len() + frame.jpeg.len());
    out.extend_from_slice(&(header.len() as u32).to_le_bytes());
    out.extend_from_slice(&header);
    out.extend_from_slice(&frame.jpeg);
    out
}

/// Serves one page until it goes away.
pub async fn serve_page(
    mut socket: WebSocket,
    hub: Arc<Hub>,
    address: SocketAddr,
    lost_after: Duration,
) {
    let (key, number) = hub.join(address);
    let why = run(&mut socket, &hub, &key, number, lost_after).await;
    hub.leave(&key, number, why);
    let _ = socket.send(Message::Close(None)).await;
}

async fn send(
    socket: &mut WebSocket,
    msg: Message,
    lost_after: Duration,
) -> Result<(), &'static str> {
    match timeout(lost_after, socket.send(msg)).await {
        Ok(Ok(())) => Ok(()),
        Ok(Err(_)) => Err("closed its connection"),
        Err(_) => Err("stopped reading (network lost?)"),
    }
}

async fn run(
    socket: &mut WebSocket,
    hub: &Hub,
    key: &str,
    number: u64,
    lost_after: Duration,
) -> &'static str {
    let hello = serde_json::json!({"type": "hello", "client": key, "number": number});
    if let Err(why) = send(socket, Message::Text(hello.to_string().into()), lost_after).await {
        return why;
    }
    let mut closing = hub.subscribe_closing();
    let mut states = hub.subscribe_state();
    let mut frames = hub.subscribe_preview();
    states.mark_changed();
    let mut state_tick = interval(STATE_EVERY);
    let mut ping = interval(PING_EVERY);
    let mut state_pending = true;
    let mut last_heard = Instant::now();
    loop {
        tokio::select! {
            _ = closing.changed() => return "was dropped: the server is stopping",
            changed = states.changed() => {
                if changed.is_err() {
                    return "was dropped: the server is stopping";
                }
                state_pending = true;
            }
            _ = state_tick.tick() => {
                if state_pending {
                    state_pending = false;
                    let text = {
                        let state = states.borrow_and_update();
                        serde_json::json!({
                            "type": "state",
                            "you": {"number": number, "controlling": hub.is_controller(key)},
                            "state": &*state,
                        })
                        .to_string()
                    };
                    if let Err(why) = send(socket, Message::Text(text.into()), lost_after).await {
                        return why;
                    }
                }
            }
            changed = frames.changed() => {
                if changed.is_err() {
                    return "was dropped: the server is stopping";
                }
                let frame = frames.borrow_and_update().clone();
                if let Some(frame) = frame {
                    if let Err(why) = send(socket, Message::Binary(frame_message(&frame).into()), lost_after).await {
                        return why;
                    }
                    hub.count_frame_sent(number);
                }
            }
            _ = ping.tick() => {
                if last_heard.elapsed() > lost_after {
                    return "stopped answering (network lost?)";
                }
                if let Err(why) = send(socket, Message::Ping(Vec::new().into()), lost_after).await {
                    return why;
                }
            }
            msg = socket.recv() => {
                match msg {
                    None | Some(Err(_)) | Some(Ok(Message::Close(_))) => return "closed its connection",
                    Some(Ok(_)) => last_heard = Instant::now(),
                }
            }
        }
    }
}
