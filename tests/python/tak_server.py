#!/usr/bin/env python3
"""Runs FreeTAKServer 2.2.1 (a real TAK server, from PyPI) headless for tests/tests/it/field_tak.rs,
with every file it writes under --dir and every port it opens on loopback, free ones.

Run it with the interpreter of FreeTAKServer's own venv (scripts/setup: HARRIER_TAK_PYTHON,
tests/python/tak-server.lock), in a process group of its own: FreeTAKServer forks a process per
service (CoT, SSL CoT, data packages, REST API, routing, …), and killing the group ends them all.

FreeTAKServer cannot be told to bind port 0 (it takes fixed ports from its configuration and does
not report what it bound), so this picks free ports by binding port 0 on 127.0.0.1 and releasing
them (all held at once, so that they differ), then passes them in FreeTAKServer's own settings
(its `FTS_*` environment variables and command-line options). Its configuration and data (the
SQLite databases, generated CA and certificates, logs) go to --dir; its output goes to
--dir/fts.log (what it prints is not JSON, and it prints a lot).

Prints `{"ready": {"cot": PORT, "ssl_cot": PORT, "api": PORT, "log": PATH, "seconds": S}}` once the
CoT service answers FreeTAKServer's own connection test (`TEST`, answered `success`) on its TCP
port, or `{"error": ...}` and exits 1 when it does not within --timeout seconds. Then runs until
killed.

    $HARRIER_TAK_PYTHON tests/python/tak_server.py --dir /tmp/fts --timeout 60
"""

import argparse
import json
import os
import socket
import sys
import threading
import time

# FreeTAKServer's settings that name a file or directory, each under --dir.
PATHS = {
    "FTS_PERSISTENCE_PATH": "",
    "FTS_CONFIG_PATH": "FTSConfig.yaml",
    "FTS_DB_PATH": "FTSDataBase.db",
    "FTS_LOGFILE_PATH": "Logs",
    "FTS_DATAPACKAGE_PATH": "FreeTAKServerDataPackageFolder",
    "FTS_EXCHECK_PATH": "ExCheck",
    "FTS_EXCHECK_TEMPLATE_PATH": "ExCheck/template",
    "FTS_EXCHECK_CHECKLIST_PATH": "ExCheck/checklist",
    "FTS_CERTS_PATH": "certs",
    "FTS_CLIENT_PACKAGES_PATH": "certs/clientPackages",
    "FTS_SERVER_KEYDIR": "certs/server.key",
    "FTS_SERVER_PEMDIR": "certs/server.pem",
    "FTS_TESTCLIENT_PEMDIR": "certs/Client.pem",
    "FTS_TESTCLIENT_KEYDIR": "certs/Client.key",
    "FTS_UNENCRYPTED_KEYDIR": "certs/server.key.unencrypted",
    "FTS_SERVER_P12DIR": "certs/server.p12",
    "FTS_CADIR": "certs/ca.pem",
    "FTS_CAKEYDIR": "certs/ca.key",
    "FTS_FEDERATION_CERTDIR": "certs/server.pem",
    "FTS_FEDERATION_KEYDIR": "certs/server.key",
    "FTS_CRLDIR": "certs/FTS_CRL.json",
}
# The ports FreeTAKServer takes from its environment (beside those of its command line below).
PORT_VARS = [
    "FTS_FED_PORT",
    "FTS_ROUTING_PROXY_SUBSCRIBE_PORT",
    "FTS_ROUTING_PROXY_PUBLISHER_PORT",
    "FTS_ROUTING_PROXY_SERVER_PORT",
    "FTS_INTEGRATION_MANAGER_PULLER_PORT",
    "FTS_INTEGRATION_MANAGER_PUBLISHER_PORT",
]
# FreeTAKServer's command-line options that take a port.
PORT_ARGS = ["-CoTPort", "-SSLCoTPort", "-DataPackagePort", "-SSLDataPackagePort", "-RestAPIPort"]
LOOPBACK = "127.0.0.1"


def free_ports(n):
    """n distinct free TCP ports on loopback (bound to port 0 together, then released)."""
    socks = []
    try:
        for _ in range(n):
            s = socket.socket()
            s.bind((LOOPBACK, 0))
            socks.append(s)
        return [s.getsockname()[1] for s in socks]
    finally:
        for s in socks:
            s.close()


def answers_test(port):
    """Whether FreeTAKServer's CoT service on port answers its connection test: a client that
    sends `TEST` and nothing more gets `success` (ReceiveConnections.receive_connection_data)."""
    try:
        with socket.create_connection((LOOPBACK, port), timeout=2) as s:
            s.settimeout(10)
            s.sendall(b"TEST")
            s.shutdown(socket.SHUT_WR)
            return s.recv(16) == b"success"
    except OSError:
        return False


def emit(out, obj):
    out.write(json.dumps(obj) + "\n")
    out.flush()


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--dir", required=True, help="FreeTAKServer's configuration and data")
    p.add_argument("--timeout", type=float, default=60.0, help="seconds to wait for its CoT port")
    args = p.parse_args()
    d = os.path.abspath(args.dir)
    os.makedirs(d, exist_ok=True)
    t0 = time.monotonic()

    ports = free_ports(len(PORT_VARS) + len(PORT_ARGS))
    env_ports, arg_ports = ports[: len(PORT_VARS)], ports[len(PORT_VARS) :]
    for var, rel in PATHS.items():
        os.environ[var] = os.path.join(d, rel) if rel else d
    for var, port in zip(PORT_VARS, env_ports):
        os.environ[var] = str(port)
    os.environ.update(
        {
            # No first-start wizard (it asks questions on stdin).
            "FTS_FIRST_START": "false",
            "FTS_DP_ADDRESS": LOOPBACK,
            "FTS_USER_ADDRESS": LOOPBACK,
            "FTS_API_ADDRESS": LOOPBACK,
            "FTS_CONNECTION_MESSAGE": "harrier test",
        }
    )
    cot_port, ssl_cot_port, api_port = arg_ports[0], arg_ports[1], arg_ports[4]

    # Our JSON lines on the real stdout; FreeTAKServer's output (and its services', forked from
    # this process) into the log.
    out = os.fdopen(os.dup(1), "w")
    log = os.path.join(d, "fts.log")
    fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)
    sys.stdout = os.fdopen(1, "w", buffering=1)
    sys.stderr = os.fdopen(2, "w", buffering=1)

    # FreeTAKServer 2.2.1 creates /opt/fts when its configuration module is imported (a hard-coded
    # PERSISTENCE_PATH, before any setting is read; it exits when it cannot, as a user other than
    # root), and three of its databases are put there from that module constant. Here that import
    # is told /opt/fts exists, and the constant is pointed at --dir before anything reads it.
    real_exists = os.path.exists
    os.path.exists = lambda path: path == "/opt/fts" or real_exists(path)
    try:
        from FreeTAKServer.core.configuration import MainConfig
    finally:
        os.path.exists = real_exists
    MainConfig.PERSISTENCE_PATH = d
    # Its registry of connected clients is a pickle inside the installed digitalpy package,
    # shared by every FreeTAKServer of the venv and kept across runs: one per run, in --dir.
    # (Its components' DEBUG logs still go into the package's directories.)
    from digitalpy.core.IAM.controllers import iam_users_controller

    iam_users_controller.CONNECTIONS_PERSISTENCE = os.path.join(d, "connections.json")

    def ready():
        deadline = t0 + args.timeout
        while time.monotonic() < deadline:
            if answers_test(cot_port):
                emit(
                    out,
                    {
                        "ready": {
                            "cot": cot_port,
                            "ssl_cot": ssl_cot_port,
                            "api": api_port,
                            "log": log,
                            "seconds": round(time.monotonic() - t0, 1),
                        }
                    },
                )
                return
            time.sleep(0.2)
        error = f"FreeTAKServer's CoT port {cot_port} did not answer within {args.timeout} s"
        emit(out, {"error": f"{error}; see {log}"})
        os._exit(1)

    threading.Thread(target=ready, daemon=True).start()

    import runpy

    sys.argv = ["FreeTAKServer", "-CoTIP", LOOPBACK, "-SSLCoTIP", LOOPBACK]
    sys.argv += ["-DataPackageIP", LOOPBACK, "-SSLDataPackageIP", LOOPBACK, "-RestAPIIP", LOOPBACK]
    for opt, port in zip(PORT_ARGS, arg_ports):
        sys.argv += [opt, str(port)]
    runpy.run_module("FreeTAKServer.controllers.services.FTS", run_name="__main__", alter_sys=True)
    # FreeTAKServer's main returns only when its start fails (it prints the exception).
    emit(out, {"error": f"FreeTAKServer exited; see {log}"})
    sys.exit(1)


if __name__ == "__main__":
    main()
