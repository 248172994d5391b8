//! Cost of MAVLink 2 signing per frame: encoding a GLOBAL_POSITION_INT unsigned and signed, and
//! parsing one with and without the signature check (fresh timestamps: the accepted path).
//!
//! Run with `cargo bench -p harrier-link --bench signing`; BENCHMARKS.md records the figures.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use harrier_link::frame::{encode, parse_datagram};
use harrier_link::mavlink::MavHeader;
use harrier_link::mavlink::dialects::common::{GLOBAL_POSITION_INT_DATA, MavMessage};
use harrier_link::signing::{Signing, SigningKey, SigningMode};

fn signing(c: &mut Criterion) {
    let settings = Signing {
        key: SigningKey::new([42; 32]),
        mode: SigningMode::SignedOnly,
        link_id: 0,
    };
    let (vehicle, gcs) = (
        settings.signer().expect("signer"),
        settings.signer().expect("signer"),
    );
    let msg = MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
        time_boot_ms: 1000,
        lat: 473_977_420,
        lon: 85_455_940,
        alt: 488_000,
        relative_alt: 30_000,
        vx: 300,
        vy: -20,
        vz: 5,
        hdg: 9000,
    });
    let header = MavHeader {
        system_id: 1,
        component_id: 1,
        sequence: 0,
    };
    c.bench_function("encode unsigned", |b| {
        b.iter(|| encode(black_box(header), black_box(&msg)))
    });
    c.bench_function("encode signed", |b| {
        b.iter(|| vehicle.encode(black_box(header), black_box(&msg)))
    });
    let unsigned = encode(header, &msg).expect("frame");
    c.bench_function("parse unsigned", |b| {
        b.iter(|| parse_datagram(black_box(&unsigned)))
    });
    // Each iteration checks a frame signed just before (a replayed one would fail early).
    c.bench_function("sign + parse + check", |b| {
        b.iter(|| {
            let bytes = vehicle.encode(header, &msg).expect("frame");
            let parsed = parse_datagram(black_box(&bytes));
            parsed.frames.iter().all(|f| gcs.check(f).is_ok())
        })
    });
}

criterion_group!(benches, signing);
criterion_main!(benches);
