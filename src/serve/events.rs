//! The event stream of one page (`GET /api/ws`, a WebSocket): the server pushes the page state
//! when it changes and each new preview frame, and watches that the page is still there.
//!
//! Pacing (a page costs its browser CPU for every message it draws, and on a shared host that
//! CPU comes out of the capture): a change the person acts on (the phase, a new instruction,
//! who controls) goes out at once; other changes are coalesced, at most one state every
//! [`STATE_EVERY`], or every [`STATE_EVERY_RUNNING`] while shots are being taken (the
//! progress of a run: one update a second is what a person reads). A page that falls behind
//! gets the newest state, never a queue of old ones.
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
use super::state::{PageState, Phase};

/// The state goes out at most this often per page (changes that are not urgent).
pub const STATE_EVERY: Duration = Duration::from_millis(250);
/// The same while a capture is taking shots.
pub const STATE_EVERY_RUNNING: Duration = Duration::from_secs(1);
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

/// What, in a state, a person acts on: when it differs from the last state sent, the new one
/// goes out at once.
#[derive(Clone, Debug, PartialEq)]
pub struct Urgent {
    phase: Phase,
    instruction: Option<u64>,
    controller: Option<u64>,
    controlling: bool,
}

impl Urgent {
    pub fn of(state: &PageState, controlling: bool) -> Urgent {
        Urgent {
            phase: state.capture.phase,
            instruction: state.capture.instruction.as_ref().map(|i| i.seq),
            controller: state.control.controller.as_ref().map(|c| c.number),
            controlling,
        }
    }
}

/// How long after the last state sent the next one may go, given the current state.
pub fn state_interval(state: &PageState) -> Duration {
    if state.capture.phase == Phase::Running {
        STATE_EVERY_RUNNING
    } else {
        STATE_EVERY
    }
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
    let mut ping = interval(PING_EVERY);
    let mut state_pending = true;
    // the last state sent: when, and what in it is urgent (`None`: nothing sent yet)
    let mut last_sent: Option<(Instant, Urgent)> = None;
    let mut state_due = Instant::now();
    let mut last_heard = Instant::now();
    loop {
        tokio::select! {
            _ = closing.changed() => return "was dropped: the server is stopping",
            changed = states.changed() => {
                if changed.is_err() {
                    return "was dropped: the server is stopping";
                }
                let state = states.borrow();
                let urgent = Urgent::of(&state, hub.is_controller(key));
                state_pending = true;
                state_due = match &last_sent {
                    Some((at, was)) if *was == urgent => *at + state_interval(&state),
                    _ => Instant::now(),
                };
            }
            _ = tokio::time::sleep_until(state_due), if state_pending => {
                state_pending = false;
                let (text, urgent) = {
                    let state = states.borrow_and_update();
                    let controlling = hub.is_controller(key);
                    let text = serde_json::json!({
                        "type": "state",
                        "you": {"number": number, "controlling": controlling},
                        "state": &*state,
                    })
                    .to_string();
                    (text, Urgent::of(&state, controlling))
                };
                if let Err(why) = send(socket, Message::Text(text.into()), lost_after).await {
                    return why;
                }
                last_sent = Some((Instant::now(), urgent));
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serve::state::{ClientInfo, Instruction};

    #[test]
    fn progress_is_paced_but_what_a_person_acts_on_is_urgent() {
        let mut s = PageState::default();
        s.capture.phase = Phase::Running;
        let running = Urgent::of(&s, true);
        assert_eq!(state_interval(&s), STATE_EVERY_RUNNING);
        // a shot done: progress only, the same urgency key (coalesced)
        s.capture.done += 1;
        s.capture.eta_secs = Some(12.0);
        assert_eq!(Urgent::of(&s, true), running);
        // the run waits for the operator: a new instruction goes out at once
        s.capture.phase = Phase::Waiting;
        s.capture.instruction = Some(Instruction {
            seq: 1,
            steps: vec!["Place the black glossy sphere".into()],
        });
        let waiting = Urgent::of(&s, true);
        assert_ne!(waiting, running);
        assert_eq!(state_interval(&s), STATE_EVERY);
        s.capture.instruction = Some(Instruction {
            seq: 2,
            steps: vec!["Place the black glossy sphere".into()],
        });
        assert_ne!(Urgent::of(&s, true), waiting, "the next instruction");
        // control changes hands
        let before = Urgent::of(&s, true);
        s.control.controller = Some(ClientInfo {
            number: 3,
            ..ClientInfo::default()
        });
        assert_ne!(Urgent::of(&s, true), before);
        assert_ne!(Urgent::of(&s, false), Urgent::of(&s, true));
    }
}
