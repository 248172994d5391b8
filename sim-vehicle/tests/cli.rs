//! The `harrier-sim` program's command line (this test also makes `cargo test` build the binary
//! that the workspace's end-to-end tests start as a process).

use std::process::Command;

#[test]
fn help_names_the_links_and_the_subcommands() {
    let out = Command::new(env!("CARGO_BIN_EXE_harrier-sim"))
        .arg("--help")
        .output()
        .expect("run harrier-sim --help");
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for word in ["--gcs", "--api", "--no-zenoh", "record"] {
        assert!(text.contains(word), "{word} missing in\n{text}");
    }
    let out = Command::new(env!("CARGO_BIN_EXE_harrier-sim"))
        .args(["--gcs", "serial:/dev/null"])
        .output()
        .expect("run harrier-sim with a bad link");
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("tcpout:HOST:PORT"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
