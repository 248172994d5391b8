//! MAVLink decoding throughput of [`StreamParser::push`], against pymavlink on the same bytes.
//!
//! The stream is a file of 100 000 MAVLink 2 frames of three PX4-like vehicles and a ground
//! station (ATTITUDE, LOCAL_POSITION_NED, GLOBAL_POSITION_INT, SYS_STATUS, HEARTBEAT,
//! COMMAND_LONG), written by `scripts/pymavlink_decode_bench.py`, which times pymavlink's
//! `parse_buffer` on the same file. Each iteration decodes the whole file with a fresh parser, fed
//! in 4096-byte pieces (one socket read each) as the script feeds pymavlink, every frame decoded
//! into its message and kept with its bytes as the GCS link does. Criterion reports the time per
//! file and, with the frame count as throughput, frames per second; BENCHMARKS.md ("MAVLink
//! decoding vs pymavlink") records both and the ratio.
//!
//! ```sh
//! python3 scripts/pymavlink_decode_bench.py --write-only   # target/mavlink-stream.bin, once
//! cargo bench -p harrier-link --bench decode
//! ```
//!
//! `HARRIER_MAVLINK_STREAM=PATH` reads another file.

use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use harrier_link::frame::StreamParser;

/// Bytes handed to the parser at a time, as the Python script hands them to pymavlink.
const CHUNK: usize = 4096;

/// The stream file: `$HARRIER_MAVLINK_STREAM`, else the workspace's `target/mavlink-stream.bin`.
fn stream_path() -> PathBuf {
    std::env::var_os("HARRIER_MAVLINK_STREAM").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/mavlink-stream.bin"),
        PathBuf::from,
    )
}

/// Decodes `data` with a fresh parser; returns (frames, malformed).
fn decode(data: &[u8]) -> (usize, u64) {
    let mut parser = StreamParser::default();
    let (mut frames, mut malformed) = (0, 0);
    for chunk in data.chunks(CHUNK) {
        let parsed = parser.push(black_box(chunk));
        frames += parsed.frames.len();
        malformed += parsed.malformed;
        black_box(parsed);
    }
    (frames, malformed)
}

fn decode_stream(c: &mut Criterion) {
    let path = stream_path();
    let data = std::fs::read(&path).unwrap_or_else(|e| {
        panic!(
            "cannot read the MAVLink stream {}: {e}; write it first with \
             `python3 scripts/pymavlink_decode_bench.py --write-only`",
            path.display()
        )
    });
    let (frames, malformed) = decode(&data);
    assert!(frames > 0, "no MAVLink frame in {}", path.display());
    assert_eq!(malformed, 0, "malformed frames in {}", path.display());
    println!(
        "decode: {} ({} bytes, {frames} frames, {CHUNK}-byte pieces)",
        path.display(),
        data.len()
    );

    let mut g = c.benchmark_group("decode");
    g.throughput(Throughput::Elements(frames as u64));
    g.sampling_mode(SamplingMode::Flat);
    g.sample_size(20);
    g.measurement_time(Duration::from_secs(10));
    g.bench_function("stream_parser_4096", |b| {
        b.iter(|| decode(black_box(&data)));
    });
    g.finish();
}

criterion_group!(benches, decode_stream);
criterion_main!(benches);
