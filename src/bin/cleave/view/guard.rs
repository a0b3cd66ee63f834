//! Who may talk to `cleave view`. A web page the user visits while the viewer runs can
//! make the browser send requests to it, so every request is checked before a route
//! sees it:
//!
//! - its `Host` must name the server as this machine's pages do: an address literal
//!   (IPv4 or bracketed IPv6, which DNS rebinding cannot produce), `localhost`, or
//!   the `--host` name given, with the server's port;
//! - the WebSocket upgrade's `Origin`, when the client sends one (browsers always
//!   do), must be the page's own: `http://` and the request's `Host`, or another
//!   spelling of this machine's loopback at the same port. `null` and every other
//!   origin are refused;
//! - with a token (`--token`, or one made up when the server listens beyond this
//!   machine), `/status` and `/ws` also need `?token=` with it; the page passes its
//!   own URL's token on.
//!
//! Refusals answer 403 Forbidden with the reason.

use axum::extract::{Request, State};
use axum::http::StatusCode;
use axum::http::header::{HOST, ORIGIN};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use std::net::IpAddr;
use std::sync::Arc;

/// The rules of one server (see the module docs).
#[derive(Clone, Debug)]
pub struct Guard {
    /// The port the server answers on.
    port: u16,
    /// The `--host` name, lower case.
    name: String,
    /// The token `/status` and `/ws` need, if any.
    token: Option<String>,
}

impl Guard {
    /// The rules for a server listening on `port` as `--host name`, with `token`.
    pub fn new(port: u16, name: &str, token: Option<String>) -> Self {
        Guard {
            port,
            name: name.to_ascii_lowercase(),
            token,
        }
    }

    /// Splits `host[:port]` (an IPv6 address in brackets) into host and port.
    fn split(authority: &str) -> Option<(&str, u16)> {
        let (host, port) = authority.rsplit_once(':')?;
        if host.contains(':') && !(host.starts_with('[') && host.ends_with(']')) {
            return None;
        }
        Some((host, port.parse().ok()?))
    }

    /// Whether `host` (no port; `--host` as given) is this machine's loopback by any
    /// spelling: only this machine can reach it.
    pub fn is_loopback(host: &str) -> bool {
        let bare = host.trim_start_matches('[').trim_end_matches(']');
        host.eq_ignore_ascii_case("localhost")
            || bare.parse::<IpAddr>().is_ok_and(|ip| ip.is_loopback())
    }

    /// Whether a `Host` header names this server (see the module docs).
    fn host_ok(&self, authority: &str) -> bool {
        let Some((host, port)) = Self::split(authority) else {
            return false;
        };
        let bare = host.trim_start_matches('[').trim_end_matches(']');
        let literal = bare.parse::<IpAddr>().is_ok();
        port == self.port
            && (literal
                || host.eq_ignore_ascii_case("localhost")
                || host.eq_ignore_ascii_case(&self.name))
    }

    /// Whether a WebSocket upgrade from `origin` to `host` comes from the page itself.
    fn origin_ok(origin: &str, host: &str) -> bool {
        let Some(authority) = origin.strip_prefix("http://") else {
            return false;
        };
        if authority.eq_ignore_ascii_case(host) {
            return true;
        }
        match (Self::split(authority), Self::split(host)) {
            (Some((a, a_port)), Some((h, h_port))) => {
                a_port == h_port && Self::is_loopback(a) && Self::is_loopback(h)
            }
            _ => false,
        }
    }

    /// Why a request is refused, or `None` to let it through.
    pub fn refusal(
        &self,
        host: Option<&str>,
        origin: Option<&str>,
        path: &str,
        query: Option<&str>,
    ) -> Option<&'static str> {
        let host = match host {
            Some(h) if self.host_ok(h) => h,
            _ => return Some("the Host header does not name this server"),
        };
        if path == "/ws"
            && let Some(origin) = origin
            && !Self::origin_ok(origin, host)
        {
            return Some("the WebSocket comes from another page's origin");
        }
        if let Some(token) = &self.token
            && (path == "/ws" || path == "/status")
        {
            let given = query
                .unwrap_or_default()
                .split('&')
                .find_map(|pair| pair.strip_prefix("token="));
            if given != Some(token.as_str()) {
                return Some("the request lacks the server's token (open the URL it printed)");
            }
        }
        None
    }
}

/// Checks a request against the server's [`Guard`]: 403 with the reason, or on to its
/// route.
pub async fn check(State(guard): State<Arc<Guard>>, request: Request, next: Next) -> Response {
    let refusal = {
        let headers = request.headers();
        let header = |name| headers.get(name).and_then(|v| v.to_str().ok());
        guard.refusal(
            header(HOST),
            header(ORIGIN),
            request.uri().path(),
            request.uri().query(),
        )
    };
    match refusal {
        Some(reason) => (StatusCode::FORBIDDEN, reason).into_response(),
        None => next.run(request).await,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hosts_origins_and_tokens_are_checked_as_the_docs_say() {
        let guard = Guard::new(7878, "127.0.0.1", None);
        let ok = |host, origin, path| guard.refusal(Some(host), origin, path, None).is_none();
        for host in [
            "127.0.0.1:7878",
            "localhost:7878",
            "[::1]:7878",
            "192.168.1.9:7878",
        ] {
            assert!(ok(host, None, "/status"), "{host}");
        }
        for host in [
            "evil.example:7878",
            "127.0.0.1:7879",
            "127.0.0.1",
            "::1:7878",
            "",
        ] {
            assert!(!ok(host, None, "/status"), "{host}");
        }
        assert!(guard.refusal(None, None, "/", None).is_some());
        let ws = |host, origin| ok(host, Some(origin), "/ws");
        assert!(ws("127.0.0.1:7878", "http://127.0.0.1:7878"));
        assert!(ws("127.0.0.1:7878", "http://localhost:7878"));
        assert!(ws("localhost:7878", "http://[::1]:7878"));
        for origin in [
            "null",
            "http://evil.example",
            "http://evil.example:7878",
            "https://127.0.0.1:7878",
            "http://127.0.0.1:7879",
            "http://192.168.1.9:7878",
        ] {
            assert!(!ws("127.0.0.1:7878", origin), "{origin}");
        }
        // a name given with --host is the page's own
        let named = Guard::new(80, "Box.Local", Some("s3cret".into()));
        let with = |query| named.refusal(Some("box.local:80"), None, "/ws", query);
        assert!(with(Some("token=s3cret")).is_none());
        assert!(with(Some("a=1&token=s3cret")).is_none());
        assert!(with(Some("token=wrong")).is_some());
        assert!(with(None).is_some());
        // the page itself needs no token: it carries its URL's on to the socket
        assert!(
            named
                .refusal(Some("box.local:80"), None, "/", None)
                .is_none()
        );
    }
}
