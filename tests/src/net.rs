//! Processes and networks for the multi-host tests (`zenoh_router`, `mesh`): child processes
//! with their output in a file ([`Proc`]), the pinned `zenohd` ([`zenohd`]), network namespaces
//! ([`Netns`]) joined by veth pairs ([`Veth`]), and the series of a server's `/api/v1/metrics`.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The pinned `zenohd`: `$HARRIER_ZENOHD`, else where `scripts/setup` installs it.
pub fn zenohd_bin() -> PathBuf {
    let bin = std::env::var_os("HARRIER_ZENOHD").map_or_else(
        || {
            let home = std::env::var_os("HOME").unwrap_or_default();
            Path::new(&home).join(".cache/harrier/zenohd/bin/zenohd")
        },
        PathBuf::from,
    );
    assert!(
        bin.is_file(),
        "{} not found: install the router with `cargo install zenohd --version =1.10.2 --locked \
         --no-default-features --features \"zenoh/transport_tcp zenoh/transport_tls\" --root \
         ~/.cache/harrier/zenohd` (scripts/setup does), or set HARRIER_ZENOHD",
        bin.display()
    );
    bin
}

/// Runs a setup command, returning its stderr on failure.
pub fn run(cmd: &[&str]) -> Result<(), String> {
    let out = Command::new(cmd[0])
        .args(&cmd[1..])
        .stdin(Stdio::null())
        .output()
        .map_err(|e| format!("{}: {e}", cmd.join(" ")))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "{}: {}",
            cmd.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        ))
    }
}

/// A network namespace of this test process, `harrier-<pid>-<tag>`, its loopback up; deleted
/// (with the veth ends in it) when dropped.
#[derive(Debug)]
pub struct Netns {
    /// Its name (for `ip netns exec`).
    pub name: String,
}

impl Netns {
    /// Makes namespace `tag`.
    pub fn new(tag: &str) -> Result<Self, String> {
        let name = format!("harrier-{}-{tag}", std::process::id());
        run(&["ip", "netns", "add", &name])?;
        let ns = Self { name };
        run(&["ip", "-n", &ns.name, "link", "set", "lo", "up"])?;
        Ok(ns)
    }

    /// `program` run in this namespace (`ip netns exec`, which then execs it: the child's pid is
    /// the program's).
    pub fn command(&self, program: &Path) -> Command {
        let mut c = Command::new("ip");
        c.args(["netns", "exec", &self.name]).arg(program);
        c
    }
}

impl Drop for Netns {
    fn drop(&mut self) {
        let _ = run(&["ip", "netns", "del", &self.name]);
    }
}

/// A veth pair between two namespaces (`None`: the root namespace), on a `/30` of its own: the
/// `a` side is `.1`, the `b` side `.2`. Deleted when dropped.
#[derive(Debug)]
pub struct Veth {
    /// The `a` side's address.
    pub a_addr: String,
    /// The `b` side's address.
    pub b_addr: String,
    a_ns: Option<String>,
    a_dev: String,
}

impl Veth {
    /// Pair `k` (< 256) of this test process between `a` and `b`: on
    /// `10.(200 + pid mod 50).(4 ((pid / 50) mod 64) + k / 64).(4 (k mod 64))/30`, the same for
    /// no two test processes running at once (unless their pids collide mod 3 200).
    pub fn new(a: Option<&Netns>, b: &Netns, k: u32) -> Result<Self, String> {
        assert!(k < 256, "veth pair {k}: at most 256 per test process");
        let pid = std::process::id();
        let net = format!(
            "10.{}.{}.{}",
            200 + pid % 50,
            (pid / 50) % 64 * 4 + k / 64,
            (k % 64) * 4
        );
        let base = net.rsplit('.').next().and_then(|s| s.parse::<u32>().ok());
        let prefix = net.rsplit_once('.').map(|(p, _)| p.to_owned());
        let (Some(base), Some(prefix)) = (base, prefix) else {
            return Err(format!("bad network {net}"));
        };
        let a_addr = format!("{prefix}.{}", base + 1);
        let b_addr = format!("{prefix}.{}", base + 2);
        let a_dev = format!("hv{}a{k}", pid % 100_000);
        let b_dev = format!("hv{}b{k}", pid % 100_000);
        let a_cidr = format!("{a_addr}/30");
        let b_cidr = format!("{b_addr}/30");
        // The pair is made here with its `b` end in `b`, then its `a` end moved where it belongs.
        run(&[
            "ip", "link", "add", &a_dev, "type", "veth", "peer", "name", &b_dev, "netns", &b.name,
        ])?;
        if let Some(a) = a {
            if let Err(e) = run(&["ip", "link", "set", &a_dev, "netns", &a.name]) {
                let _ = run(&["ip", "link", "del", &a_dev]);
                return Err(e);
            }
        }
        let veth = Self {
            a_addr,
            b_addr,
            a_ns: a.map(|n| n.name.clone()),
            a_dev,
        };
        let in_a = |args: &[&str]| -> Result<(), String> {
            let mut cmd = vec!["ip"];
            if let Some(ns) = &veth.a_ns {
                cmd.extend(["-n", ns.as_str()]);
            }
            cmd.extend(args);
            run(&cmd)
        };
        in_a(&["addr", "add", &a_cidr, "dev", &veth.a_dev])?;
        in_a(&["link", "set", &veth.a_dev, "up"])?;
        run(&["ip", "-n", &b.name, "addr", "add", &b_cidr, "dev", &b_dev])?;
        run(&["ip", "-n", &b.name, "link", "set", &b_dev, "up"])?;
        Ok(veth)
    }
}

impl Drop for Veth {
    fn drop(&mut self) {
        let mut cmd = vec!["ip"];
        if let Some(ns) = &self.a_ns {
            cmd.extend(["-n", ns.as_str()]);
        }
        cmd.extend(["link", "del", self.a_dev.as_str()]);
        let _ = run(&cmd);
    }
}

/// A child process with its output in a file; SIGKILLed and reaped when dropped.
#[derive(Debug)]
pub struct Proc {
    /// What it is, for messages.
    pub what: String,
    /// The process.
    pub child: Child,
    log: PathBuf,
}

impl Proc {
    /// Starts `cmd` (stdin null, stdout and stderr to `log`).
    pub fn spawn(what: &str, mut cmd: Command, log: PathBuf) -> Self {
        let file = std::fs::File::create(&log).expect("log file");
        let child = cmd
            .stdin(Stdio::null())
            .stdout(file.try_clone().expect("log file"))
            .stderr(file)
            .spawn()
            .unwrap_or_else(|e| panic!("start {what}: {e}"));
        Self {
            what: what.into(),
            child,
            log,
        }
    }

    /// Its output so far.
    pub fn log(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// Panics with the log when the process has exited.
    pub fn assert_running(&mut self) {
        if let Some(status) = self.child.try_wait().expect("wait for a child") {
            panic!("{} exited ({status}):\n{}", self.what, self.log());
        }
    }

    /// Waits for a log line containing `needle`; returns that line.
    pub fn wait_for_line(&mut self, needle: &str, timeout: Duration) -> String {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(line) = self.log().lines().find(|l| l.contains(needle)) {
                return line.to_owned();
            }
            self.assert_running();
            assert!(
                Instant::now() < deadline,
                "{}: no line with {needle:?} within {timeout:?}:\n{}",
                self.what,
                self.log()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// SIGKILLs and reaps it.
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    /// CPU time (user + system) it has used so far (s), from `/proc/<pid>/stat`.
    pub fn cpu_s(&self) -> f64 {
        let stat =
            std::fs::read_to_string(format!("/proc/{}/stat", self.child.id())).unwrap_or_default();
        // The fields after the command name (which may hold spaces) in parentheses.
        let fields: Vec<&str> = stat
            .rsplit_once(')')
            .map_or("", |(_, rest)| rest)
            .split_whitespace()
            .collect();
        let ticks = |i: usize| fields.get(i).and_then(|s| s.parse::<f64>().ok());
        // utime and stime are fields 14 and 15 of the line, 12 and 13 after the name.
        match (ticks(11), ticks(12)) {
            (Some(u), Some(s)) => (u + s) / 100.0,
            _ => 0.0,
        }
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        self.kill();
    }
}

/// `zenohd` with `args` (run by `cmd`, e.g. [`Netns::command`] of [`zenohd_bin`]), once it says
/// where it can be reached; its output in `dir/log`.
pub fn zenohd_in(mut cmd: Command, dir: &Path, log: &str, args: &[String]) -> Proc {
    cmd.args(args)
        .arg("--no-multicast-scouting")
        .env("RUST_LOG", "info");
    let mut p = Proc::spawn("zenohd", cmd, dir.join(log));
    p.wait_for_line("Zenoh can be reached at", Duration::from_secs(20));
    p
}

/// `zenohd` in this namespace with `args`, once it says where it can be reached.
pub fn zenohd(dir: &Path, log: &str, args: &[String]) -> Proc {
    zenohd_in(Command::new(zenohd_bin()), dir, log, args)
}

/// `harrier serve --config config --listen ip:0` run by `cmd` (e.g. [`Netns::command`] of the
/// `harrier` binary), once it prints its ready line; its output in `dir/name.log`. Returns the
/// process and the API's address from that line.
pub fn harrier_serve_in(
    mut cmd: Command,
    name: &str,
    config: &Path,
    ip: &str,
    dir: &Path,
) -> (Proc, std::net::SocketAddr) {
    cmd.arg("serve")
        .arg("--config")
        .arg(config)
        .args(["--listen", &format!("{ip}:0")])
        .env("RUST_LOG", "info,zenoh=warn");
    let mut proc = Proc::spawn(
        &format!("harrier serve ({name})"),
        cmd,
        dir.join(format!("{name}.log")),
    );
    let line = proc.wait_for_line("harrier serve: ready: http://", Duration::from_secs(30));
    let api = line
        .split("http://")
        .nth(1)
        .and_then(|s| s.split('/').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no API address in {line:?}"));
    (proc, api)
}

/// The value of one series of a `/metrics` text, e.g. `harrier_seq_lost_total{vehicle="1"}`
/// (0 when absent).
pub fn metric_value(text: &str, series: &str) -> f64 {
    text.lines()
        .find_map(|l| l.strip_prefix(series)?.strip_prefix(' ')?.parse().ok())
        .unwrap_or(0.0)
}
