//! `cleave view` as a user meets it: the page driven in headless Chromium
//! (`tests/browser/view.mjs`, playwright-core on Debian's `chromium`; `tests/browser/install`
//! installs both), and the server's own errors.
//!
//! Set `CLEAVE_CHROMIUM` to use another Chromium than `/usr/bin/chromium`.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// One server and one browser at a time: they share the machine's cores.
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
