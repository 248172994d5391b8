//! The HTTP API under a flood of half-sent requests (a "slow loris"), real parts only: the real
//! `harrier` binary (`harrier serve`: no MAVLink, no recording, the default `[api]` limits) runs
//! under `ulimit -n 1024`, the common default. 5 000 TCP connections on loopback each send half a
//! request head (`GET / HTTP/1.1`, `Host: x`, no blank line) and wait: 8 `half_open.py` processes
//! (tests/python, standard library only) of 625 connections each, so that no process needs more
//! than 1 024 open files and this one raises no limit.
//!
//! Meanwhile a normal client asks `GET /api/v1/health` 20 times a second, each on a new
//! connection (as a page loading would), from the flood's start until 3 s after the server has
//! accepted all of it (its `/metrics`), while it holds all it can of the flood. Checked: every
//! answer is 200 within 2 s; the server holds `api.max_connections` connections then, never more
//! (its `/metrics`; its open files are printed); every flood connection is closed by the server
//! (the client reads EOF or a reset, never an answer), none later than `api.header_timeout_s`
//! (+ 3 s) after it connected, those held to the end at about `api.header_timeout_s` (hyper's
//! header read timeout, counted from the accept: the client's figure also holds its wait in the
//! kernel's accept queue), the others earlier, evicted to make room; the server's counters agree.
//! Then three half-sent requests are held, SIGINT stops the server within the header timeout
//! (waiting connections do not hold the stop) and the three are closed. The figures are printed
//! (BENCHMARKS.md, "HTTP limits").
//!
//! The binary is `target/<profile>/harrier`, next to this test's directory: build it first with
//! `cargo build -p harrier-cli` (`cargo test --workspace` does). Every wait is on a real event
//! (a line printed, a reply, a close) under a deadline; the processes are killed if the test
//! fails.

use std::io::{BufRead as _, BufReader, Read as _, Write as _};
use std::net::{SocketAddr, TcpStream};
use std::os::unix::process::CommandExt as _;
use std::process::{Child, ChildStdout, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use harrier_server::config::ApiConfig;
use harrier_tests::{free_tcp_port, kill_group, python_script, target_bin, wait_with_deadline};

/// Processes the flood is spread over.
const FLOOD_PROCESSES: usize = 8;
/// Half-open connections of each (well under 1 024 open files).
const PER_PROCESS: usize = 625;
/// Half-open connections of the flood.
const FLOOD: usize = FLOOD_PROCESSES * PER_PROCESS;
/// The normal client's pace.
const CLIENT_PERIOD: Duration = Duration::from_millis(50);
/// How long the normal client goes on after the server has accepted the whole flood.
const HOLD: Duration = Duration::from_secs(3);
/// Longest answer the normal client accepts.
const ANSWER_BOUND: Duration = Duration::from_secs(2);
/// Longest the flood may take to be accepted.
const FLOOD_DEADLINE: Duration = Duration::from_secs(90);

/// A child process killed (its process group) and reaped when dropped.
struct Proc(Child);

impl Drop for Proc {
    fn drop(&mut self) {
        kill_group(&mut self.0);
    }
}

/// `harrier serve` under `ulimit -n 1024`, its API on a free loopback port; returns once it has
/// printed its ready line, with the API's address.
fn harrier_serve(dir: &std::path::Path) -> (Proc, SocketAddr, mpsc::Receiver<String>) {
    let config = dir.join("harrier.toml");
    std::fs::write(
        &config,
        format!(
            "[zenoh]\nlisten = [\"tcp/127.0.0.1:{}\"]\ntracks_key = \"\"\n\
             [mavlink]\ngcs = []\nrouter = []\n",
            free_tcp_port()
        ),
    )
    .expect("write the configuration");
    let mut child = Command::new("bash")
        .args(["-c", "ulimit -n 1024 && exec \"$0\" \"$@\""])
        .arg(target_bin("harrier"))
        .args(["serve", "--config"])
        .arg(&config)
        .args(["--listen", "127.0.0.1:0"])
        .env("RUST_LOG", "info,zenoh=warn")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .process_group(0)
        .spawn()
        .expect("start harrier serve");
    let stderr = child.stderr.take().expect("stderr");
    let (tx, lines) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let proc = Proc(child);
    let deadline = Instant::now() + Duration::from_secs(30);
    let mut log = String::new();
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match lines.recv_timeout(left) {
            Ok(line) => {
                if let Some(rest) = line.split("harrier serve: ready: http://").nth(1) {
                    let addr = rest
                        .split('/')
                        .next()
                        .and_then(|a| a.parse().ok())
                        .unwrap_or_else(|| panic!("no API address in {line:?}"));
                    return (proc, addr, lines);
                }
                log.push_str(&line);
                log.push('\n');
            }
            Err(e) => panic!("harrier serve not ready ({e}):\n{log}"),
        }
    }
}

/// `GET path` on a new connection (`Connection: close`): status, body, and how long the whole
/// exchange took.
fn get(addr: SocketAddr, path: &str) -> (u16, String, Duration) {
    let t0 = Instant::now();
    let mut s = TcpStream::connect_timeout(&addr, Duration::from_secs(5))
        .unwrap_or_else(|e| panic!("connect {addr}: {e}"));
    s.set_read_timeout(Some(Duration::from_secs(5)))
        .expect("read timeout");
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .expect("send the request");
    let mut raw = String::new();
    s.read_to_string(&mut raw)
        .unwrap_or_else(|e| panic!("GET {path}: {e} after {:?}", t0.elapsed()));
    let elapsed = t0.elapsed();
    let (head, body) = raw.split_once("\r\n\r\n").expect("an HTTP head");
    let status = head
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .expect("a status");
    (status, body.to_owned(), elapsed)
}

/// The value of the series `name` (with its labels, as printed) in Prometheus text.
fn metric(text: &str, name: &str) -> f64 {
    text.lines()
        .find_map(|l| l.strip_prefix(name)?.strip_prefix(' ')?.parse().ok())
        .unwrap_or_else(|| panic!("{name} not in /metrics:\n{text}"))
}

/// Files the process `pid` holds open.
fn open_files(pid: u32) -> usize {
    std::fs::read_dir(format!("/proc/{pid}/fd")).map_or(0, Iterator::count)
}

/// One flood process: its stdout lines as JSON.
struct Flood {
    _proc: Proc,
    out: BufReader<ChildStdout>,
}

impl Flood {
    fn start(addr: SocketAddr, count: usize, timeout_s: f64) -> Self {
        let mut child = python_script("half_open.py")
            .args(["--host", &addr.ip().to_string()])
            .args(["--port", &addr.port().to_string()])
            .args(["--count", &count.to_string()])
            .args(["--timeout", &timeout_s.to_string()])
            .stdout(Stdio::piped())
            .spawn()
            .expect("start half_open.py");
        let out = BufReader::new(child.stdout.take().expect("stdout"));
        Self {
            _proc: Proc(child),
            out,
        }
    }

    /// Its next line (blocks; the process has a deadline of its own).
    fn line(&mut self) -> serde_json::Value {
        let mut line = String::new();
        self.out.read_line(&mut line).expect("read half_open.py");
        serde_json::from_str(&line).unwrap_or_else(|e| panic!("half_open.py said {line:?}: {e}"))
    }
}

/// The `q` quantile of sorted `v`.
fn quantile(v: &[f64], q: f64) -> f64 {
    v[((v.len() - 1) as f64 * q).round() as usize]
}

#[test]
fn a_flood_of_half_sent_requests_locks_nobody_out_and_is_closed_at_the_header_timeout() {
    let api = ApiConfig::default();
    let header_timeout = api.header_timeout_s;
    let dir = tempfile::tempdir().expect("tempdir");
    let (mut server, addr, _log) = harrier_serve(dir.path());
    let pid = server.0.id();
    let (status, text, _) = get(addr, "/metrics");
    assert_eq!(status, 200);
    let max = api.max_connections;
    assert_eq!(metric(&text, "harrier_http_connections_max"), max as f64);
    let files_before = open_files(pid);

    // The flood, in processes that each read their `opened` line then their `closed` line.
    let flood_started = Instant::now();
    let (opened_tx, opened_rx) = mpsc::channel();
    let floods: Vec<_> = (0..FLOOD_PROCESSES)
        .map(|_| {
            let mut f = Flood::start(addr, PER_PROCESS, header_timeout + 20.0);
            let tx = opened_tx.clone();
            std::thread::spawn(move || {
                let opened = f.line();
                let _ = tx.send(opened);
                let closed = f.line();
                (f, closed)
            })
        })
        .collect();
    drop(opened_tx);

    // The normal client, until HOLD after the server has accepted the whole flood.
    let mut latencies = Vec::new();
    let mut opened = Vec::new();
    let mut ours = 1; // connections of this test so far: the first /metrics
    let mut held_max = 0.0f64;
    let mut files_max = 0;
    let mut flood_accepted_s = None;
    let mut hold_until = None;
    let mut next = Instant::now();
    while hold_until.is_none_or(|t| Instant::now() < t) {
        assert!(
            flood_started.elapsed() < FLOOD_DEADLINE,
            "the flood was not accepted within {FLOOD_DEADLINE:?}: {opened:?}"
        );
        let (status, body, took) = get(addr, "/api/v1/health");
        ours += 1;
        assert!(
            status == 200 && took <= ANSWER_BOUND,
            "GET /api/v1/health during the flood: {status} after {took:?} ({} answered before): {body}",
            latencies.len()
        );
        latencies.push(took.as_secs_f64());
        while let Ok(o) = opened_rx.try_recv() {
            opened.push(o);
        }
        if latencies.len() % 5 == 0 || (hold_until.is_none() && opened.len() == FLOOD_PROCESSES) {
            let (_, text, _) = get(addr, "/metrics");
            ours += 1;
            held_max = held_max.max(metric(&text, "harrier_http_connections"));
            files_max = files_max.max(open_files(pid));
            let accepted = metric(&text, "harrier_http_connections_accepted_total");
            if hold_until.is_none() && accepted >= (FLOOD + ours) as f64 {
                flood_accepted_s = Some(flood_started.elapsed().as_secs_f64());
                hold_until = Some(Instant::now() + HOLD);
            }
        }
        next += CLIENT_PERIOD;
        std::thread::sleep(next.saturating_duration_since(Instant::now()));
    }
    let flood_open_s = opened
        .iter()
        .map(|o| o["open_s"].as_f64().expect("open_s"))
        .fold(0.0, f64::max);
    let opened_total: u64 = opened
        .iter()
        .map(|o| o["opened"].as_u64().expect("opened"))
        .sum();
    assert_eq!(
        opened_total, FLOOD as u64,
        "flood connections opened: {opened:?}"
    );
    assert_eq!(
        held_max, max as f64,
        "the server held at most {held_max} connections (api.max_connections = {max})"
    );

    // Every flood connection closed by the server, none later than the header timeout (+ 3 s).
    let mut close_s = Vec::new();
    let mut hows = std::collections::BTreeMap::<String, usize>::new();
    for t in floods {
        let (f, closed) = t.join().expect("a flood reader");
        assert_eq!(closed["still_open"], 0, "{closed}");
        for c in closed["closed"].as_array().expect("closed") {
            close_s.push(c[0].as_f64().expect("seconds"));
            *hows
                .entry(c[1].as_str().expect("how").to_owned())
                .or_default() += 1;
        }
        drop(f);
    }
    assert_eq!(close_s.len(), FLOOD);
    assert_eq!(
        hows.get("data"),
        None,
        "the server answered a half-sent request: {hows:?}"
    );
    close_s.sort_by(f64::total_cmp);
    let last = *close_s.last().expect("closes");
    assert!(
        last <= header_timeout + 3.0,
        "a connection was closed {last:.2} s after it opened (header timeout {header_timeout} s)"
    );
    let at_timeout: Vec<f64> = close_s
        .iter()
        .copied()
        .filter(|&s| s >= header_timeout - 0.25)
        .collect();
    let evicted: Vec<f64> = close_s
        .iter()
        .copied()
        .filter(|&s| s < header_timeout - 0.25)
        .collect();
    assert!(
        !at_timeout.is_empty() && at_timeout.len() <= max,
        "{} closed at the header timeout (max {max})",
        at_timeout.len()
    );

    // The server's own count agrees, and it is back to the normal client alone.
    let (_, text, _) = get(addr, "/metrics");
    let closed = |reason: &str| {
        metric(
            &text,
            &format!("harrier_http_connections_closed_total{{reason=\"{reason}\"}}"),
        )
    };
    let (timed_out, evicted_n, refused) = (
        closed("header_timeout"),
        closed("evicted"),
        closed("refused"),
    );
    assert_eq!(timed_out + evicted_n + refused, FLOOD as f64, "{text}");
    assert_eq!(timed_out as usize, at_timeout.len(), "{text}");
    assert_eq!(metric(&text, "harrier_http_connections"), 1.0, "{text}");

    latencies.sort_by(f64::total_cmp);
    println!(
        "flood: {FLOOD} half-sent requests from {FLOOD_PROCESSES} processes, all connected after \
         {flood_open_s:.2} s and accepted by {:.2} s; the server (ulimit -n 1024, {files_before} files open before) held \
         at most {held_max} connections and {files_max} open files (api.max_connections {max})",
        flood_accepted_s.unwrap_or(f64::NAN)
    );
    println!(
        "closed by the server: {} at the header timeout ({header_timeout} s), {:.3}-{:.3} s \
         after they opened; {} earlier to make room (evicted {evicted_n}, refused {refused}), \
         median {:.3} s, max {:.3} s; seen as {hows:?}",
        at_timeout.len(),
        at_timeout.first().copied().unwrap_or(f64::NAN),
        at_timeout.last().copied().unwrap_or(f64::NAN),
        evicted.len(),
        if evicted.is_empty() {
            f64::NAN
        } else {
            quantile(&evicted, 0.5)
        },
        evicted.last().copied().unwrap_or(f64::NAN),
    );
    println!(
        "normal client: {} GET /api/v1/health during the flood, all 200; latency p50 {:.1} ms, \
         p99 {:.1} ms, max {:.1} ms",
        latencies.len(),
        quantile(&latencies, 0.5) * 1e3,
        quantile(&latencies, 0.99) * 1e3,
        latencies.last().copied().unwrap_or(f64::NAN) * 1e3
    );
    println!("test run: {:.1} s", flood_started.elapsed().as_secs_f64());

    // A stop is not held up by waiting connections: they are closed, the server exits.
    let waiting: Vec<TcpStream> = (0..3)
        .map(|_| {
            let mut s = TcpStream::connect(addr).expect("connect");
            s.write_all(b"GET / HTTP/1.1\r\nHost: x\r\n")
                .expect("half a request");
            s
        })
        .collect();
    // Accepted in order: once this is answered, the three are the server's.
    let (_, text, _) = get(addr, "/metrics");
    assert_eq!(metric(&text, "harrier_http_connections"), 4.0, "{text}");
    let stop = Instant::now();
    let status = Command::new("kill")
        .args(["-INT", &pid.to_string()])
        .status()
        .expect("kill -INT");
    assert!(status.success());
    let exit = wait_with_deadline(
        &mut server.0,
        Duration::from_secs_f64(header_timeout - 1.0),
        "harrier serve after SIGINT",
    );
    assert!(exit.success(), "harrier serve exited {exit}");
    for mut s in waiting {
        s.set_read_timeout(Some(Duration::from_secs(1)))
            .expect("read timeout");
        let mut rest = Vec::new();
        match s.read_to_end(&mut rest) {
            Ok(_) => assert!(rest.is_empty(), "{rest:?}"),
            Err(e) => assert_eq!(e.kind(), std::io::ErrorKind::ConnectionReset, "{e}"),
        }
    }
    println!("stopped by SIGINT in {:.2} s", stop.elapsed().as_secs_f64());
}
