#!/usr/bin/env python3
"""Reads an MCAP file with the `mcap` package's reader and decodes every message against the
protobuf schema the file carries for its channel (a FileDescriptorSet, through google.protobuf's
descriptor pool). Prints one JSON line: the messages per topic, each topic's schema name and
message encoding, the total, and every decoding error.

    python3 mcap_check.py session.mcap
"""

import json
import sys

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from mcap.reader import make_reader


def main():
    classes = {}
    counts, schemas, errors = {}, {}, []
    with open(sys.argv[1], "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            topic = channel.topic
            schemas[topic] = {"schema": schema.name, "schema_encoding": schema.encoding,
                              "encoding": channel.message_encoding}
            try:
                if schema.id not in classes:
                    fds = descriptor_pb2.FileDescriptorSet.FromString(schema.data)
                    pool = descriptor_pool.DescriptorPool()
                    for fd in fds.file:
                        pool.Add(fd)
                    classes[schema.id] = message_factory.GetMessageClass(pool.FindMessageTypeByName(schema.name))
                classes[schema.id].FromString(message.data)
            except Exception as e:  # noqa: BLE001 - every failure is reported
                errors.append(f"{topic}: {e}")
                continue
            counts[topic] = counts.get(topic, 0) + 1
    print(json.dumps({"counts": counts, "schemas": schemas, "total": sum(counts.values()), "errors": errors}))


if __name__ == "__main__":
    sys.exit(main())
