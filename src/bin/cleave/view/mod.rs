//! `cleave view`: the simulation runs here, natively, and a page served from this
//! program draws it in the browser and drives it — orbit, cut with a stroke, grab and
//! drag. The page (`page.html`, `page.js`, written here and built into the program)
//! talks to one WebSocket: commands go up as JSON ([`protocol`]), frames come down as
//! a status (JSON) and the surfaces' positions and topology (binary,
//! [`cleave::io::stream`]). Every page sees the one simulation.
//!
//! Routes: `/` the page, `/page.js` its script, `/status` the latest status (JSON),
//! `/ws` the WebSocket. Every request passes the [`guard`] first: only the page this
//! server serves may drive it.

mod guard;
mod protocol;
mod refusals;
mod runner;
mod snapshot;

use axum::Router;
use axum::extract::State;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::http::header::CONTENT_TYPE;
use axum::response::{Html, IntoResponse};
use axum::routing::get;
use cleave::io::scene::{BUILTIN_SCENES, builtin};
use guard::Guard;
use protocol::{Command, MAX_MESSAGE_BYTES, parse};
use refusals::Refusals;
use runner::{Offered, Runner};
use snapshot::Published;
use std::sync::Arc;
use std::sync::mpsc::{SyncSender, TrySendError};
use tokio::sync::watch;

const PAGE: &str = include_str!("page.html");
const SCRIPT: &str = include_str!("page.js");

/// Commands waiting for the simulation thread beyond which a page's commands are
/// dropped (with a log line) rather than queued without end.
const COMMAND_QUEUE: usize = 256;

/// Arguments of `cleave view`.
pub struct ViewArgs {
    /// A built-in scene's name or a scene file (default: `slice`).
    pub scene: Option<String>,
    /// Port (0: any free one).
    pub port: u16,
    /// Address to listen on.
    pub host: String,
    /// Seed of the built-in scenes.
    pub seed: u64,
    /// Worker threads of the simulation.
    pub threads: usize,
    /// The token `/status` and `/ws` need (made up when `host` is not a loopback
    /// address and none is given).
    pub token: Option<String>,
    /// Carry out the test-only `panic` command.
    pub test_panic: bool,
}

#[derive(Clone)]
struct Shared {
    commands: SyncSender<Command>,
    frames: watch::Receiver<Arc<Published>>,
    refusals: Arc<Refusals>,
}

/// Serves the page until interrupted; an error (a scene that will not load, a port in
/// use) is a line for the user.
pub fn view(args: ViewArgs) -> Result<(), String> {
    let mut offered: Vec<Offered> = BUILTIN_SCENES
        .iter()
        .filter_map(|b| {
            Some(Offered {
                name: b.name.to_string(),
                scene: builtin(b.name, args.seed)?,
            })
        })
        .collect();
    let name = args.scene.unwrap_or_else(|| "slice".into());
    let current = match offered.iter().position(|o| o.name == name) {
        Some(i) => i,
        None => {
            // the one file a page may show: the one named here
            let scene = crate::run::load_scene(&name, None)?;
            offered.push(Offered { name, scene });
            offered.len() - 1
        }
    };
    let mut runner = Runner::new(offered, current, args.test_panic)?;
    let (frames_in, frames) = watch::channel(runner.publish());
    let (commands, commands_out) = std::sync::mpsc::sync_channel(COMMAND_QUEUE);
    let refusals = Arc::new(Refusals::default());
    let shared = Shared {
        commands,
        frames,
        refusals: refusals.clone(),
    };
    let app = Router::new()
        .route("/", get(|| async { Html(PAGE) }))
        .route(
            "/page.js",
            get(|| async { ([(CONTENT_TYPE, "text/javascript")], SCRIPT) }),
        )
        .route("/status", get(status))
        .route("/ws", get(socket))
        .with_state(shared);
    let token = match args.token {
        Some(token) => Some(token),
        None if !Guard::is_loopback(&args.host) => Some(format!("{:032x}", rand::random::<u128>())),
        None => None,
    };
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .map_err(|e| format!("cannot start the server: {e}"))?;
    runtime.block_on(async move {
        let (host, port) = (args.host.as_str(), args.port);
        let listener = tokio::net::TcpListener::bind((host, port))
            .await
            .map_err(|e| format!("cannot listen on {host}:{port}: {e}"))?;
        let address = listener
            .local_addr()
            .map_err(|e| format!("cannot listen on {host}:{port}: {e}"))?;
        let guard = Arc::new(Guard::new(address.port(), host, token.clone()));
        let app = app.layer(axum::middleware::from_fn_with_state(guard, guard::check));
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(args.threads)
            .build()
            .map_err(|e| format!("cannot start {} threads: {e}", args.threads))?;
        std::thread::Builder::new()
            .name("simulation".into())
            .spawn({
                let refusals = refusals.clone();
                move || pool.install(|| runner.run(commands_out, frames_in, &refusals))
            })
            .map_err(|e| format!("cannot start the simulation: {e}"))?;
        tokio::spawn(async move {
            let mut every = tokio::time::interval(refusals::PERIOD);
            loop {
                every.tick().await;
                refusals.flush();
            }
        });
        if !Guard::is_loopback(host) {
            eprintln!(
                "cleave view: listening on {address}, beyond this machine: anyone on the network who has the URL below (with its token) can watch and drive the simulation"
            );
        }
        let query = token.map_or(String::new(), |t| format!("?token={t}"));
        println!("cleave view: http://{address}/{query} (Ctrl-C stops)");
        use std::io::Write;
        let _ = std::io::stdout().flush();
        axum::serve(listener, app)
            .with_graceful_shutdown(async {
                let _ = tokio::signal::ctrl_c().await;
            })
            .await
            .map_err(|e| format!("server: {e}"))
    })
}

async fn status(State(shared): State<Shared>) -> impl IntoResponse {
    let status = shared.frames.borrow().status.clone();
    ([(CONTENT_TYPE, "application/json")], status)
}

async fn socket(upgrade: WebSocketUpgrade, State(shared): State<Shared>) -> impl IntoResponse {
    // messages past the protocol's limit are read (and refused with a log line) up to
    // a hard cap, past which the connection closes
    upgrade
        .max_message_size(64 * MAX_MESSAGE_BYTES)
        .max_frame_size(64 * MAX_MESSAGE_BYTES)
        .on_upgrade(move |ws| session(ws, shared))
}

/// One page: its commands go to the simulation; the latest frame goes to it whenever
/// it has taken the last one (frames in between are dropped, never queued).
async fn session(mut ws: WebSocket, shared: Shared) {
    let mut frames = shared.frames.clone();
    frames.mark_changed();
    let mut sent_topology: Vec<u64> = Vec::new();
    loop {
        tokio::select! {
            incoming = ws.recv() => match incoming {
                Some(Ok(Message::Text(text))) => match parse(text.as_str()) {
                    Ok(command) => match shared.commands.try_send(command) {
                        Ok(()) => {}
                        Err(TrySendError::Full(_)) => {
                            shared.refusals.note("the simulation is busy")
                        }
                        Err(TrySendError::Disconnected(_)) => return,
                    },
                    Err(e) => shared.refusals.note(&e),
                },
                Some(Ok(Message::Binary(_))) => {
                    shared.refusals.note("a binary message (commands are JSON text)")
                }
                Some(Ok(Message::Close(_))) | None => return,
                Some(Err(e)) => {
                    eprintln!("cleave view: closed a connection: {e}");
                    return;
                }
                Some(Ok(_)) => {}
            },
            changed = frames.changed() => {
                if changed.is_err() {
                    return;
                }
                let frame = frames.borrow_and_update().clone();
                if frame.topology_key != sent_topology {
                    if ws.send(Message::Binary(frame.topology.clone())).await.is_err() {
                        return;
                    }
                    sent_topology = frame.topology_key.clone();
                }
                if ws.send(Message::Binary(frame.positions.clone())).await.is_err()
                    || ws.send(Message::Text(frame.status.clone().into())).await.is_err()
                {
                    return;
                }
            }
        }
    }
}
