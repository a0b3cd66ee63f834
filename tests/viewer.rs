//! `cleave view` as a user meets it: the page driven in headless Chromium
//! (`tests/browser/view.mjs`, playwright-core on Debian's `chromium`; `tests/browser/install`
//! installs both), a panic in the simulation shown on the page, the server's own
//! errors, and requests from anywhere but the page refused (raw HTTP).
//!
//! Set `CLEAVE_CHROMIUM` to use another Chromium than `/usr/bin/chromium`.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// One test's servers (and browser) at a time: they share the machine's cores.
static BROWSER: Mutex<()> = Mutex::new(());

/// A running `cleave view` and the address it printed.
struct Server {
    child: Child,
    url: String,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn serve(args: &[&str]) -> Server {
    let mut child = Command::new(env!("CARGO_BIN_EXE_cleave"))
        .arg("view")
        .args(args)
        .args(["--port", "0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start cleave view");
    let mut line = String::new();
    BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("read the address");
    let url = line
        .split_whitespace()
        .find(|w| w.starts_with("http://"))
        .unwrap_or_else(|| panic!("no address in {line:?}"))
        .to_string();
    Server { child, url }
}

/// Runs the browser script in `mode`; its JSON figures line.
fn browse(mode: &str, url: &str, out: &Path) -> String {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/browser");
    assert!(
        dir.join("node_modules/playwright-core").is_dir(),
        "the browser test needs playwright-core and chromium: run tests/browser/install"
    );
    let output = Command::new("node")
        .arg(dir.join("view.mjs"))
        .args([mode, url])
        .arg(out)
        .current_dir(&dir)
        .output()
        .expect("run node (tests/browser/install installs what the browser test needs)");
    let stdout = String::from_utf8_lossy(&output.stdout).to_string();
    assert!(
        output.status.success(),
        "{mode}: {stdout}{}",
        String::from_utf8_lossy(&output.stderr)
    );
    stdout
}

fn log_of(mut server: Server) -> String {
    // refusals are summed up in a line a second: let the last line out
    std::thread::sleep(Duration::from_millis(1500));
    let _ = server.child.kill();
    let mut log = String::new();
    if let Some(err) = server.child.stderr.take() {
        for line in BufReader::new(err).lines().map_while(Result::ok) {
            log.push_str(&line);
            log.push('\n');
        }
    }
    log
}

#[test]
fn the_page_draws_cuts_grabs_pauses_and_survives_bad_messages_in_chromium() {
    let _one = BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let out = std::env::temp_dir().join(format!("cleave-view-{}", std::process::id()));
    std::fs::create_dir_all(&out).unwrap();
    let server = serve(&["slice"]);
    let figures = browse("check", &server.url, &out);
    println!("{figures}");
    assert!(out.join("view.png").is_file());
    // every bad message the page sent was refused with a line in the log
    let log = log_of(server);
    for reason in [
        "expected value",
        "unknown variant `explode`",
        "no scene `../../etc/passwd` is offered",
        "100000 bytes",
        "binary message",
        "parallel or opposite",
        "nothing under the pointer",
        "is not a direction",
    ] {
        assert!(
            log.contains(reason),
            "no log line for `{reason}` in:\n{log}"
        );
    }
    assert!(!log.contains("panicked"), "{log}");
    // a flood of bad messages is logged at most once a second, with its count
    let lines: Vec<&str> = log
        .lines()
        .filter(|l| l.starts_with("cleave view: ignored"))
        .collect();
    assert!(lines.len() < 40, "{} refusal lines", lines.len());
    let counts: Vec<u64> = lines
        .iter()
        .filter_map(|l| l.split_whitespace().nth(3)?.parse().ok())
        .collect();
    assert!(
        counts.iter().sum::<u64>() >= 500 && counts.iter().any(|&c| c >= 100),
        "{lines:?}"
    );
}

#[test]
fn a_panic_in_the_simulation_shows_on_the_page_and_a_reset_recovers() {
    let _one = BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let out = std::env::temp_dir().join(format!("cleave-view-stop-{}", std::process::id()));
    std::fs::create_dir_all(&out).unwrap();
    let server = serve(&["slice", "--test-panic"]);
    println!("{}", browse("stopped", &server.url, &out));
    let log = log_of(server);
    assert!(
        log.contains("the simulation stopped: the test-only panic command"),
        "{log}"
    );
}

/// The status code of a raw `GET path` to the server at `url` with `headers`.
fn status_of(url: &str, path: &str, headers: &[(&str, &str)]) -> u16 {
    let address = url.trim_start_matches("http://").split('/').next().unwrap();
    let mut stream = TcpStream::connect(address).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    let mut request = format!("GET {path} HTTP/1.1\r\n");
    for (k, v) in headers {
        request.push_str(&format!("{k}: {v}\r\n"));
    }
    request.push_str("\r\n");
    stream.write_all(request.as_bytes()).unwrap();
    let mut line = Vec::new();
    let mut byte = [0u8];
    while stream.read(&mut byte).unwrap_or(0) == 1 && byte[0] != b'\n' {
        line.push(byte[0]);
    }
    let line = String::from_utf8_lossy(&line);
    line.split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or_else(|| panic!("no status in {line:?}"))
}

/// The headers of a WebSocket upgrade to `host` from `origin`.
fn upgrade<'a>(host: &'a str, origin: Option<&'a str>) -> Vec<(&'a str, &'a str)> {
    let mut h = vec![
        ("Host", host),
        ("Upgrade", "websocket"),
        ("Connection", "Upgrade"),
        ("Sec-WebSocket-Key", "dGhlIHNhbXBsZSBub25jZQ=="),
        ("Sec-WebSocket-Version", "13"),
    ];
    h.extend(origin.map(|o| ("Origin", o)));
    h
}

#[test]
fn only_the_page_itself_may_drive_the_viewer() {
    // (its servers simulate too: not beside a browser test, whose timing they would take)
    let _one = BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let server = serve(&["slice", "--threads", "1"]);
    let own = server
        .url
        .trim_start_matches("http://")
        .trim_end_matches('/')
        .to_string();
    let port = own.rsplit(':').next().unwrap().to_string();
    let localhost = format!("localhost:{port}");
    let (page_origin, local_origin) = (format!("http://{own}"), format!("http://{localhost}"));
    // the page's own origin, and this machine's other spellings of it
    assert_eq!(status_of(&server.url, "/status", &[("Host", &own)]), 200);
    assert_eq!(status_of(&server.url, "/", &[("Host", &localhost)]), 200);
    for (host, origin) in [
        (&own, Some(&page_origin)),
        (&own, Some(&local_origin)),
        (&own, None),
    ] {
        let code = status_of(
            &server.url,
            "/ws",
            &upgrade(host, origin.map(|o| o.as_str())),
        );
        assert_eq!(code, 101, "{host} from {origin:?}");
    }
    // another page's origin, `null`, and a name that is not this server (DNS rebinding)
    for origin in ["http://evil.example", "null", "http://evil.example:80"] {
        let code = status_of(&server.url, "/ws", &upgrade(&own, Some(origin)));
        assert_eq!(code, 403, "{origin}");
    }
    let rebound = format!("evil.example:{port}");
    for path in ["/", "/status", "/page.js"] {
        assert_eq!(status_of(&server.url, path, &[("Host", &rebound)]), 403);
    }
    let code = status_of(
        &server.url,
        "/ws",
        &upgrade(&rebound, Some("http://evil.example")),
    );
    assert_eq!(code, 403);
    drop(server);
    // beyond this machine: a warning, and a token in the printed URL that the data
    // routes require
    let mut server = serve(&["slice", "--threads", "1", "--host", "0.0.0.0"]);
    let token = server
        .url
        .split("?token=")
        .nth(1)
        .expect("a token")
        .to_string();
    assert!(token.len() >= 16, "{token}");
    let base = server.url.split('?').next().unwrap().to_string();
    let host = base
        .trim_start_matches("http://")
        .trim_end_matches('/')
        .to_string();
    assert_eq!(status_of(&base, "/status", &[("Host", &host)]), 403);
    let with = format!("/status?token={token}");
    assert_eq!(status_of(&base, &with, &[("Host", &host)]), 200);
    assert_eq!(status_of(&base, "/", &[("Host", &host)]), 200);
    let _ = server.child.kill();
    let mut err = String::new();
    server
        .child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    assert!(err.contains("anyone on the network"), "{err}");
}

#[test]
fn a_port_in_use_or_a_missing_scene_is_a_clear_error() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = taken.local_addr().unwrap().port().to_string();
    let missing = std::env::temp_dir().join("cleave-no-such-scene.ron");
    for (args, says) in [
        (
            vec!["view", "slice", "--port", port.as_str()],
            "cannot listen on 127.0.0.1",
        ),
        (
            vec!["view", missing.to_str().unwrap(), "--port", "0"],
            "cleave-no-such-scene.ron",
        ),
        (
            vec!["view", "no_such_scene", "--port", "0"],
            "unknown scene",
        ),
    ] {
        let start = Instant::now();
        let out = Command::new(env!("CARGO_BIN_EXE_cleave"))
            .args(&args)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert!(start.elapsed() < Duration::from_secs(30));
    }
}
