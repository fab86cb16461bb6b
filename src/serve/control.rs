//! Who may act on the rig through the lab page.
//!
//! - **Pages.** Every page that opens the event stream (`/api/ws`) is a client with a secret
//!   key (128 random bits, sent only on its own stream) and a public number. At most one client
//!   controls; it claims control when nobody holds it and keeps it while its stream lives. Every
//!   acting request names its client in the `X-Client` header; a client that does not control is
//!   read-only (403). A page that goes away (closed, crashed, network lost: its stream ends or
//!   stops answering) loses control at once, and a capture it was running pauses.
//! - **Token.** Bound beyond localhost, every acting request also needs
//!   `Authorization: Bearer TOKEN` (401 without it); reading stays open. The token is compared
//!   through SHA-256 digests, so the comparison's time says nothing about the token.
//! - **Host.** Bound to localhost, requests must name a local host (`127.0.0.1`, `localhost`,
//!   `[::1]`): a web page elsewhere cannot reach the server through a DNS name it re-points to
//!   127.0.0.1.
//!
//! A custom header on every acting request also means a browser cannot send one from another
//! site's page without a CORS preflight, which this server never grants.
//!
//! Pure bookkeeping: no I/O, no clock but the one passed in.

use std::collections::BTreeMap;
use std::net::SocketAddr;

use rand::RngCore;
use sha2::{Digest, Sha256};

use super::state::{ClientInfo, ControlInfo};

/// A client's secret key, as hex.
pub type ClientKey = String;

#[derive(Clone, Debug)]
struct Client {
    number: u64,
    name: String,
    address: SocketAddr,
    since_utc: String,
}

impl Client {
    fn info(&self) -> ClientInfo {
        ClientInfo {
            number: self.number,
            name: self.name.clone(),
            address: self.address.to_string(),
            since_utc: self.since_utc.clone(),
        }
    }
}

/// Why an acting request is refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Refusal {
    #[error(
        "this server needs its token for actions: send `Authorization: Bearer TOKEN` (the token is in the file given to `serve --token-file`)"
    )]
    Token,
    #[error("unknown page: reload it (its event stream is closed)")]
    UnknownClient,
    #[error("read-only: {0} controls the rig")]
    ReadOnly(String),
    #[error("nobody controls the rig: take control first")]
    NobodyControls,
}

/// The connected pages and which one controls.
#[derive(Debug, Default)]
pub struct Control {
    clients: BTreeMap<ClientKey, Client>,
    controller: Option<ClientKey>,
    next_number: u64,
}

fn new_key() -> ClientKey {
    let mut bytes = [0u8; 16];
    rand::rngs::OsRng.fill_bytes(&mut bytes);
    hex::encode(bytes)
}

impl Control {
    /// A page connected from `address`; returns its key and public number.
    pub fn join(&mut self, address: SocketAddr, now_utc: String) -> (ClientKey, u64) {
        self.next_number += 1;
        let key = new_key();
        self.clients.insert(
            key.clone(),
            Client {
                number: self.next_number,
                name: format!("page {}", self.next_number),
                address,
                since_utc: now_utc,
            },
        );
        (key, self.next_number)
    }

    /// A page went away; true when it was the controller.
    pub fn leave(&mut self, key: &str) -> bool {
        self.clients.remove(key);
        if self.controller.as_deref() == Some(key) {
            self.controller = None;
            return true;
        }
        false
    }

    /// `key` takes control when nobody holds it (or keeps it); `name` is shown to the others
    /// (trimmed to 40 characters of text; empty keeps the page's number).
    pub fn claim(&mut self, key: &str, name: &str) -> Result<(), Refusal> {
        let name: String = name
            .chars()
            .filter(|c| !c.is_control())
            .take(40)
            .collect::<String>()
            .trim()
            .to_string();
        let Some(client) = self.clients.get_mut(key) else {
            return Err(Refusal::UnknownClient);
        };
        if !name.is_empty() {
            client.name = name;
        }
        match &self.controller {
            Some(c) if c != key => Err(Refusal::ReadOnly(self.describe(c))),
            _ => {
                self.controller = Some(key.to_string());
                Ok(())
            }
        }
    }

    /// The controller gives control up; true when `key` was the controller.
    pub fn release(&mut self, key: &str) -> bool {
        if self.controller.as_deref() == Some(key) {
            self.controller = None;
            true
        } else {
            false
        }
    }

    /// Ok when `key` is the controlling page.
    pub fn check(&self, key: Option<&str>) -> Result<(), Refusal> {
        let Some(key) = key else {
            return Err(match &self.controller {
                Some(c) => Refusal::ReadOnly(self.describe(c)),
                None => Refusal::NobodyControls,
            });
        };
        if !self.clients.contains_key(key) {
            return Err(Refusal::UnknownClient);
        }
        match &self.controller {
            Some(c) if c == key => Ok(()),
            Some(c) => Err(Refusal::ReadOnly(self.describe(c))),
            None => Err(Refusal::NobodyControls),
        }
    }

    pub fn is_controller(&self, key: &str) -> bool {
        self.controller.as_deref() == Some(key)
    }

    pub fn is_connected(&self, key: &str) -> bool {
        self.clients.contains_key(key)
    }

    pub fn count(&self) -> usize {
        self.clients.len()
    }

    fn describe(&self, key: &str) -> String {
        match self.clients.get(key) {
            Some(c) => format!("{} ({})", c.name, c.address.ip()),
            None => "another page".into(),
        }
    }

    /// What every page may see: numbers, names, addresses; never the keys.
    pub fn info(&self) -> ControlInfo {
        let mut clients: Vec<ClientInfo> = self.clients.values().map(Client::info).collect();
        clients.sort_by_key(|c| c.number);
        ControlInfo {
            controller: self
                .controller
                .as_ref()
                .and_then(|k| self.clients.get(k))
                .map(Client::info),
            clients,
        }
    }
}

/// The server's token, if it has one.
#[derive(Clone, Debug)]
pub struct Token(Option<[u8; 32]>);

impl Token {
    pub fn new(token: Option<&str>) -> Token {
        Token(token.map(|t| Sha256::digest(t.as_bytes()).into()))
    }

    pub fn required(&self) -> bool {
        self.0.is_some()
    }

    /// Ok when no token is needed, or `authorization` is `Bearer TOKEN` with the right token.
    pub fn check(&self, authorization: Option<&str>) -> Result<(), Refusal> {
        let Some(want) = &self.0 else { return Ok(()) };
        let given = authorization
            .and_then(|h| h.strip_prefix("Bearer "))
            .map(str::trim)
            .ok_or(Refusal::Token)?;
        let got: [u8; 32] = Sha256::digest(given.as_bytes()).into();
        if got == *want {
            Ok(())
        } else {
            Err(Refusal::Token)
        }
    }
}

/// A token file that cannot serve; `origin` names the file.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TokenError {
    #[error("{origin}: the token (its first line) must have at least 12 characters")]
    Short { origin: String },
    #[error("{origin}: the token must be printable text")]
    NotPrintable { origin: String },
}

/// Reads a token file: its first line, trimmed; refuses an empty or short token.
pub fn read_token(text: &str, origin: &str) -> Result<String, TokenError> {
    let token = text.lines().next().unwrap_or("").trim().to_string();
    let origin = origin.to_owned();
    if token.chars().count() < 12 {
        return Err(TokenError::Short { origin });
    }
    if token.chars().any(char::is_control) {
        return Err(TokenError::NotPrintable { origin });
    }
    Ok(token)
}

/// Bound beyond the loopback interface: actions need a token.
pub fn needs_token(bind: &SocketAddr) -> bool {
    !bind.ip().is_loopback()
}

/// For a server bound to loopback: is `host` (the request's `Host` header) a local name?
pub fn is_local_host(host: &str) -> bool {
    let name = match host.strip_prefix('[') {
        Some(rest) => rest.split(']').next().unwrap_or(""),
        None => host.rsplit_once(':').map(|(h, _)| h).unwrap_or(host),
    };
    name.eq_ignore_ascii_case("localhost")
        || name
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_loopback())
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    fn addr(s: &str) -> SocketAddr {
        s.parse().unwrap()
    }

    #[test]
    fn one_page_controls_the_others_are_read_only_and_control_ends_with_the_page() {
        let mut c = Control::default();
        let (a, na) = c.join(addr("127.0.0.1:5000"), "t".into());
        let (b, nb) = c.join(addr("127.0.0.1:5001"), "t".into());
        assert_ne!(a, b);
        assert_eq!((na, nb), (1, 2));
        assert_eq!(a.len(), 32);
        assert_eq!(c.check(Some(&a)), Err(Refusal::NobodyControls));
        c.claim(&a, "bench PC").unwrap();
        c.check(Some(&a)).unwrap();
        let refused = c.claim(&b, "tablet").unwrap_err();
        assert_eq!(refused, Refusal::ReadOnly("bench PC (127.0.0.1)".into()));
        assert!(matches!(c.check(Some(&b)), Err(Refusal::ReadOnly(_))));
        assert!(matches!(c.check(None), Err(Refusal::ReadOnly(_))));
        assert_eq!(c.check(Some("forged")), Err(Refusal::UnknownClient));
        let info = c.info();
        assert_eq!(info.controller.as_ref().unwrap().name, "bench PC");
        assert_eq!(info.clients.len(), 2);
        assert!(
            !serde_json::to_string(&info).unwrap().contains(&a),
            "keys stay secret"
        );
        // the controller goes away: control is free and the other page may take it
        assert!(c.leave(&a));
        assert!(c.info().controller.is_none());
        c.claim(&b, "").unwrap();
        assert_eq!(c.info().controller.unwrap().name, "tablet");
        assert!(!c.leave(&a));
        assert!(c.release(&b));
        assert!(!c.release(&b));
    }

    #[test]
    fn the_token_is_needed_beyond_localhost_and_checked() {
        assert!(!needs_token(&addr("127.0.0.1:8080")));
        assert!(!needs_token(&addr("[::1]:8080")));
        assert!(needs_token(&addr("0.0.0.0:8080")));
        assert!(needs_token(&addr("192.0.2.7:8080")));
        let open = Token::new(None);
        assert!(open.check(None).is_ok());
        let t = Token::new(Some("correct horse battery"));
        assert!(t.required());
        assert_eq!(t.check(None), Err(Refusal::Token));
        assert_eq!(t.check(Some("Bearer wrong")), Err(Refusal::Token));
        assert_eq!(
            t.check(Some("Basic correct horse battery")),
            Err(Refusal::Token)
        );
        assert!(t.check(Some("Bearer correct horse battery")).is_ok());
        let e = read_token("short\n", "token.txt").unwrap_err();
        assert_eq!(
            e,
            TokenError::Short {
                origin: "token.txt".into()
            }
        );
        assert!(e.to_string().starts_with("token.txt: "), "{e}");
        assert_eq!(
            read_token("  a-long-enough-token \nsecond line", "f").unwrap(),
            "a-long-enough-token"
        );
    }

    #[test]
    fn only_local_host_names_pass_on_a_local_server() {
        for ok in [
            "127.0.0.1:8080",
            "localhost:8080",
            "LOCALHOST",
            "[::1]:80",
            "127.0.0.2",
        ] {
            assert!(is_local_host(ok), "{ok}");
        }
        for bad in [
            "evil.example:8080",
            "192.168.1.2:8080",
            "localhost.evil.example",
            "",
        ] {
            assert!(!is_local_host(bad), "{bad}");
        }
    }
}
