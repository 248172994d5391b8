#!/usr/bin/env python3
"""A TAK end point for harrier's CoT feed: listens on UDP and TCP (loopback, port 0: the OS
picks) and decodes every event with takproto (the TAK protocol library of pytak):
`takproto.parse_proto` takes a TAK protocol version 1 mesh datagram (`0xbf 0x01 0xbf`) or a
stream frame (`0xbf`, varint length), and its `xml2message` a CoT XML document, with or without
its `<?xml` declaration (which it parses with xml.etree into the same TakMessage). On TCP the
frames are cut from the stream: XML at each `</event>`, protobuf by its varint length.

Prints one JSON line `{"ready": {"udp": PORT, "tcp": PORT}}` once it listens, then one JSON line
per decoded event (`via`, `encoding`, `uid`, `type`, `how`, `lat`, `lon`, `hae`, `ce`, `le`,
`time_ms`, `start_ms`, `stale_ms`, `callsign`, `course`, `speed`, `remarks`) and one
`{"error": ...}` line per frame it cannot decode. With --tls-cert/--tls-key it also listens
for TLS (a TAK server's 8089; events `via` "tls"), with --tls-ca requiring a client certificate
signed by that CA, as TAK servers do. With --multicast GROUP it also joins GROUP
(events `via` "multicast"); with --drop-tcp-after N it closes the first TCP connection after N
events (`{"closed": N}`), as a TAK server that restarts. Exits after --timeout seconds.

    python3 cot_listen.py --timeout 60 --multicast 239.2.3.1
"""

import argparse
import json
import select
import socket
import ssl
import sys
import time

import takproto
from takproto.functions import xml2message

MESH = b"\xbf\x01\xbf"


def emit(obj):
    sys.stdout.write(json.dumps(obj) + "\n")
    sys.stdout.flush()


def report(frame, via):
    # XML starts with its declaration or, from some servers, the <event> element itself.
    encoding = "xml" if frame.startswith(b"<") else "protobuf"
    try:
        # parse_proto takes XML only with its declaration (`<?xml`); xml2message is what it calls.
        if encoding == "xml":
            msg = xml2message(bytearray(frame))
        else:
            msg = takproto.parse_proto(bytearray(frame))
    except Exception as e:  # noqa: BLE001 - any decoder failure is reported
        emit({"error": f"{via} {encoding}: {e!r}", "frame": frame[:80].hex()})
        return
    if msg is None or not msg.HasField("cotEvent"):
        emit({"error": f"{via} {encoding}: not a TAK message", "frame": frame[:80].hex()})
        return
    ev = msg.cotEvent
    d = ev.detail
    emit(
        {
            "via": via,
            "encoding": encoding,
            "uid": ev.uid,
            "type": ev.type,
            "how": ev.how,
            "lat": ev.lat,
            "lon": ev.lon,
            "hae": ev.hae,
            "ce": ev.ce,
            "le": ev.le,
            "time_ms": ev.sendTime,
            "start_ms": ev.startTime,
            "stale_ms": ev.staleTime,
            "callsign": d.contact.callsign,
            "course": d.track.course,
            "speed": d.track.speed,
            "remarks": d.xmlDetail,
        }
    )


def read_varint(buf, i):
    """(value, next index) of the varint at buf[i], or None when it is not complete."""
    value, shift = 0, 0
    while i < len(buf):
        b = buf[i]
        value |= (b & 0x7F) << shift
        i += 1
        if not b & 0x80:
            return value, i
        shift += 7
        if shift > 63:
            raise ValueError("varint too long")
    return None


def frames(buf):
    """Cuts the complete frames off the front of a TCP stream buffer: (frames, rest)."""
    out = []
    while buf:
        if buf.startswith(b"<"):
            end = buf.find(b"</event>")
            if end < 0:
                break
            end += len(b"</event>")
            out.append(bytes(buf[:end]))
            buf = buf[end:].lstrip()
        elif buf[0] == 0xBF:
            v = read_varint(buf, 1)
            if v is None or len(buf) < v[1] + v[0]:
                break
            out.append(bytes(buf[: v[1] + v[0]]))
            buf = buf[v[1] + v[0] :]
        else:
            raise ValueError(f"not a TAK frame: {bytes(buf[:16]).hex()}")
    return out, buf


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--multicast", help="also join this group (on a port of its own)")
    ap.add_argument(
        "--drop-tcp-after",
        type=int,
        default=0,
        help="close the first TCP connection after this many events (0: never)",
    )
    ap.add_argument("--tls-cert", help="also listen for TLS with this certificate (PEM)")
    ap.add_argument("--tls-key", help="its private key (PEM)")
    ap.add_argument("--tls-ca", help="require a client certificate signed by this CA (PEM)")
    args = ap.parse_args()

    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    udp.bind(("127.0.0.1", 0))
    tcp = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    tcp.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    tcp.bind(("127.0.0.1", 0))
    tcp.listen(4)
    mcast, mcast_port = None, None
    if args.multicast:
        try:
            mcast = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            mcast.bind((args.multicast, 0))
            group = socket.inet_aton(args.multicast) + socket.inet_aton("0.0.0.0")
            mcast.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, group)
            mcast_port = mcast.getsockname()[1]
        except OSError as e:
            emit({"multicast_unavailable": repr(e)})
            mcast = None
    tls, tls_port, tls_ctx = None, None, None
    if args.tls_cert:
        tls_ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
        tls_ctx.load_cert_chain(args.tls_cert, args.tls_key)
        if args.tls_ca:
            tls_ctx.verify_mode = ssl.CERT_REQUIRED
            tls_ctx.load_verify_locations(args.tls_ca)
        tls = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        tls.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        tls.bind(("127.0.0.1", 0))
        tls.listen(4)
        tls_port = tls.getsockname()[1]
    emit(
        {
            "ready": {
                "udp": udp.getsockname()[1],
                "tcp": tcp.getsockname()[1],
                "multicast": mcast_port,
                "tls": tls_port,
            }
        }
    )

    peers = {}
    tcp_events, dropped = 0, False
    sockets = [udp, tcp] + ([mcast] if mcast else []) + ([tls] if tls else [])
    via = {}
    deadline = time.monotonic() + args.timeout
    while time.monotonic() < deadline:
        ready, _, _ = select.select([*sockets, *peers], [], [], 0.2)
        for s in ready:
            if s is udp:
                data, _ = udp.recvfrom(65536)
                report(data, "udp")
            elif s is mcast:
                data, _ = mcast.recvfrom(65536)
                report(data, "multicast")
            elif s is tcp:
                conn, _ = tcp.accept()
                peers[conn] = bytearray()
                via[conn] = "tcp"
                emit({"connected": True})
            elif s is tls:
                conn, _ = tls.accept()
                try:
                    conn = tls_ctx.wrap_socket(conn, server_side=True)
                except (ssl.SSLError, OSError) as e:
                    emit({"error": f"TLS handshake: {e!r}"})
                    continue
                peers[conn] = bytearray()
                via[conn] = "tls"
                cert = conn.getpeercert()
                emit({"tls_connected": True, "client_cert": bool(cert)})
            else:
                data = s.recv(65536)
                # TLS may hold decrypted bytes select() does not see.
                while data and isinstance(s, ssl.SSLSocket) and s.pending():
                    data += s.recv(65536)
                if not data:
                    s.close()
                    del peers[s]
                    continue
                buf = peers[s] + data
                try:
                    done, buf = frames(buf)
                except ValueError as e:
                    emit({"error": f"tcp: {e}"})
                    buf = bytearray()
                    done = []
                peers[s] = bytearray(buf)
                for f in done:
                    report(f, via[s])
                    tcp_events += via[s] == "tcp"
                if via[s] == "tcp" and not dropped and 0 < args.drop_tcp_after <= tcp_events:
                    # The peer goes away: the server must connect again.
                    dropped = True
                    s.close()
                    del peers[s]
                    emit({"closed": tcp_events})


if __name__ == "__main__":
    main()
