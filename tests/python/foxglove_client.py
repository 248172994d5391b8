#!/usr/bin/env python3
"""A Foxglove WebSocket client (subprotocol foxglove.sdk.v1, the SDK's name of the Foxglove WebSocket
protocol, spoken with the `websockets`
package) for harrier's `[foxglove]` feed: it subscribes to every advertised channel, decodes each
message against the protobuf schema the server advertised for its channel (a FileDescriptorSet,
through google.protobuf's descriptor pool), and decodes it a second time with Foxglove's own
published classes (foxglove-schemas-protobuf) to check that both agree.

Prints one JSON line, after `--seconds` or once every channel (but those named by
`--quiet-topic`, which may stay silent) has `--min` messages: the
channels (topic, schema name, encoding), the count of messages per topic, and the last location
fix of each track (`frame_id`, latitude, longitude, altitude, receive time).

    python3 foxglove_client.py ws://127.0.0.1:8765 --seconds 20 --min 3
"""

import argparse
import asyncio
import base64
import json
import struct
import sys
import time

import websockets
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.LocationFix_pb2 import LocationFix
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

PUBLISHED = {
    "foxglove.SceneUpdate": SceneUpdate,
    "foxglove.LocationFix": LocationFix,
    "foxglove.FrameTransforms": FrameTransforms,
}


def message_class(schema_name, schema_b64):
    """The class of `schema_name` from the advertised FileDescriptorSet."""
    fds = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(schema_b64))
    pool = descriptor_pool.DescriptorPool()
    for f in fds.file:
        pool.Add(f)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(schema_name))


async def run(url, seconds, minimum, quiet):
    channels = {}  # channel id → advertisement
    subs = {}  # subscription id → (channel, class)
    counts = {}
    fixes = {}
    errors = []
    async with websockets.connect(url, subprotocols=["foxglove.sdk.v1"], max_size=None) as ws:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            try:
                raw = await asyncio.wait_for(ws.recv(), timeout=max(0.1, deadline - time.monotonic()))
            except asyncio.TimeoutError:
                break
            if isinstance(raw, str):
                msg = json.loads(raw)
                if msg.get("op") == "advertise":
                    new = []
                    for ch in msg["channels"]:
                        channels[ch["id"]] = ch
                        if ch.get("schemaEncoding") != "protobuf" or ch.get("encoding") != "protobuf":
                            errors.append(f"{ch['topic']}: not protobuf: {ch}")
                            continue
                        sub_id = len(subs) + 1
                        subs[sub_id] = (ch, message_class(ch["schemaName"], ch["schema"]))
                        new.append({"id": sub_id, "channelId": ch["id"]})
                    if new:
                        await ws.send(json.dumps({"op": "subscribe", "subscriptions": new}))
                continue
            if raw[0] != 0x01:  # only message data
                continue
            sub_id, _log_time = struct.unpack_from("<IQ", raw, 1)
            payload = raw[13:]
            ch, cls = subs[sub_id]
            topic = ch["topic"]
            try:
                m = cls.FromString(payload)
                ref = PUBLISHED[ch["schemaName"]].FromString(payload)
                if m.SerializeToString(deterministic=True) != ref.SerializeToString(deterministic=True):
                    errors.append(f"{topic}: the advertised and the published schema disagree")
            except Exception as e:  # noqa: BLE001 - every failure is reported
                errors.append(f"{topic}: {e}")
                continue
            counts[topic] = counts.get(topic, 0) + 1
            if topic == "/harrier/tracks/location":
                fixes[m.frame_id] = {
                    "lat": m.latitude,
                    "lon": m.longitude,
                    "alt": m.altitude,
                    "received_unix": time.time(),
                    "stamp": m.timestamp.seconds + m.timestamp.nanos * 1e-9,
                }
            waited = [c["topic"] for c, _ in subs.values() if c["topic"] not in quiet]
            if waited and all(counts.get(t, 0) >= minimum for t in waited):
                break
    print(
        json.dumps(
            {
                "channels": [
                    {"topic": c["topic"], "schema": c["schemaName"], "encoding": c["encoding"]}
                    for c in channels.values()
                ],
                "counts": counts,
                "fixes": fixes,
                "errors": errors,
            }
        ),
        flush=True,
    )


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("url")
    p.add_argument("--seconds", type=float, default=20.0)
    p.add_argument("--min", type=int, default=3, help="messages per channel before stopping")
    p.add_argument("--quiet-topic", action="append", default=[], help="a topic not waited for")
    a = p.parse_args()
    asyncio.run(run(a.url, a.seconds, a.min, set(a.quiet_topic)))


if __name__ == "__main__":
    sys.exit(main())
