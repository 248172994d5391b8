//! EUROCONTROL ASTERIX Category 062, *SDPS Track Messages*, edition 1.18
//! (EUROCONTROL-SPEC-0149-9, "ASTERIX Part 9 Category 062 SDPS Track Messages"): one system
//! track record per track ([`track_record`]), packed into data blocks of at most a UDP
//! datagram's worth ([`data_blocks`]). Pure: the track, the frame and the time of day in,
//! bytes out.
//!
//! A data block is `CAT = 62`, `LEN` (2 octets, the whole block) and records; a record is its
//! FSPEC (the UAP's field reference numbers present, 7 per octet, FX in bit 1) and the items in
//! UAP order:
//!
//! | FRN | item | octets | value |
//! |---|---|---|---|
//! | 1 | I062/010 data source identifier | 2 | SAC, SIC of `[asterix]` |
//! | 3 | I062/015 service identification | 1 | `asterix.service_id` |
//! | 4 | I062/070 time of track information | 3 | the estimate's time (`t`) as seconds since UTC midnight, LSB 1/128 s |
//! | 5 | I062/105 calculated position WGS-84 | 4 + 4 | the estimate's position converted from the server's ENU frame, LSB 180/2²⁵ ° |
//! | 6 | I062/100 calculated position Cartesian | 3 + 3 | x (east), y (north) of the estimate in the server's ENU frame, LSB 0.5 m: the system reference point is the frame origin (`frame.origin`) and the plane its tangent plane |
//! | 7 | I062/185 calculated velocity Cartesian | 2 + 2 | vx, vy of the estimate turned into the target's own east/north axes (y to geographic north at the target), LSB 0.25 m/s |
//! | 12 | I062/040 track number | 2 | the track id mod 2¹⁶ |
//! | 13 | I062/080 track status | 1–4 | MON 0 (a system track fused from every sensor's detections), MRH 1 and SRC (6 "default height": a planar track's ground plane; 3 "triangulation": a 3-D estimate) when I062/130 is sent, CNF (tentative 1); first extent: TSB on the track's first record of this feed, TSE on its last (sent once after the track left the snapshot: deleted, or no longer confirmed); third: CST when the last scan did not update the track (coasting). Extents are sent up to the last non-zero one |
//! | 18 | I062/130 calculated geometric altitude | 2 | the estimate's height above the WGS-84 ellipsoid, LSB 6.25 ft |
//! | 27 | I062/500 estimated accuracies | 1 + … | APC: σx, σy (LSB 0.5 m); COV: sign(Pxy)·√\|Pxy\| (LSB 0.5 m); APW: σ of latitude and longitude (LSB 180/2²³ °); AGA: σz of a 3-D estimate (LSB 6.25 ft); ATV: σvx, σvy (LSB 0.25 m/s), from the track's covariance |
//!
//! An item whose value does not fit its field (a position more than 4194 km from the origin in
//! I062/100, a speed over 8192 m/s, an altitude outside −1500…150 000 ft) is left out; a
//! standard deviation too large for its field is sent as the field's largest value. A track
//! whose estimate or position is not finite, or a time of day outside [0, 86400), gives no
//! record.

use harrier_engine::{TrackStatus, TrackView};
use harrier_link::geo::{Geodetic, LocalFrame};
use nalgebra::Vector3;

/// The category of system track messages.
pub const CATEGORY: u8 = 62;
/// The largest data block [`data_blocks`] makes by default: one per UDP datagram, under a
/// typical path MTU.
pub const MAX_BLOCK: usize = 1400;
/// Seconds in a day (I062/070 restarts at 0 at UTC midnight).
const DAY_S: f64 = 86_400.0;
/// Feet per metre.
const FT_PER_M: f64 = 1.0 / 0.3048;

/// Who sends the tracks: I062/010 and I062/015.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Source {
    /// System area code.
    pub sac: u8,
    /// System identification code.
    pub sic: u8,
    /// Service identification.
    pub service_id: u8,
}

/// The items of one record, by field reference number, in UAP order.
struct Record {
    items: Vec<(u8, Vec<u8>)>,
}

impl Record {
    fn push(&mut self, frn: u8, bytes: Vec<u8>) {
        self.items.push((frn, bytes));
    }

    /// FSPEC then the items.
    fn encode(mut self) -> Vec<u8> {
        self.items.sort_by_key(|(frn, _)| *frn);
        let last = self.items.last().map_or(1, |(frn, _)| *frn);
        let octets = usize::from(last.div_ceil(7));
        let mut fspec = vec![0_u8; octets];
        for (frn, _) in &self.items {
            let i = usize::from(frn - 1);
            fspec[i / 7] |= 0x80 >> (i % 7);
        }
        let n = fspec.len();
        for o in &mut fspec[..n - 1] {
            *o |= 1;
        }
        let mut out = fspec;
        for (_, b) in self.items {
            out.extend_from_slice(&b);
        }
        out
    }
}

/// `v / lsb` rounded, if it fits a signed field of `bits` bits.
fn signed(v: f64, lsb: f64, bits: u32) -> Option<i64> {
    let r = (v / lsb).round();
    let max = f64::from(1_u32 << (bits - 1));
    (r.is_finite() && r >= -max && r < max).then_some(r as i64)
}

/// `v / lsb` rounded, clamped to an unsigned field of `bits` bits.
fn unsigned_sat(v: f64, lsb: f64, bits: u32) -> u32 {
    let max = f64::from(((1_u64 << bits) - 1) as u32);
    // `as` maps NaN to 0; the clamp keeps the rest in the field.
    (v / lsb).round().clamp(0.0, max) as u32
}

/// The standard deviation of state index `i`.
fn sd(track: &TrackView, i: usize) -> Option<f64> {
    track.cov_at(i, i).filter(|v| *v >= 0.0).map(f64::sqrt)
}

/// Where a record stands in its track's life on this feed (I062/080 TSB and TSE).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lifecycle {
    /// The track's first record (TSB).
    First,
    /// A record between its first and its last.
    Update,
    /// Its last record: the track service ends (TSE).
    Last,
}

/// The CAT062 record of `track` at `time_of_day_s` (seconds since UTC midnight), `None` when
/// the estimate, its position or the time is not finite or the time is outside the day.
pub fn track_record(
    track: &TrackView,
    frame: &LocalFrame,
    source: Source,
    time_of_day_s: f64,
    life: Lifecycle,
) -> Option<Vec<u8>> {
    // The range refuses NaN too.
    if !(track.state.iter().all(|v| v.is_finite()) && (0.0..DAY_S).contains(&time_of_day_s)) {
        return None;
    }
    let [x, y, z, vx, vy, _] = track.state;
    let geo = frame.from_enu(&Vector3::new(x, y, z));
    if !(geo.lat_deg.is_finite() && geo.lon_deg.is_finite() && geo.alt_m.is_finite()) {
        return None;
    }
    let mut r = Record { items: Vec::new() };
    r.push(1, vec![source.sac, source.sic]);
    r.push(3, vec![source.service_id]);
    // 86 400 · 128 < 2²⁴; the last 1/256 s of the day rounds to the next midnight, 0.
    let tod = ((time_of_day_s * 128.0).round() as u32) % (86_400 * 128);
    r.push(4, tod.to_be_bytes()[1..].to_vec());
    let lsb_wgs = 180.0 / f64::from(1_u32 << 25);
    let lat = signed(geo.lat_deg, lsb_wgs, 32)?;
    let lon = signed(geo.lon_deg, lsb_wgs, 32)?;
    let mut wgs = (lat as i32).to_be_bytes().to_vec();
    wgs.extend_from_slice(&(lon as i32).to_be_bytes());
    r.push(5, wgs);
    if let (Some(cx), Some(cy)) = (signed(x, 0.5, 24), signed(y, 0.5, 24)) {
        let mut b = (cx as i32).to_be_bytes()[1..].to_vec();
        b.extend_from_slice(&(cy as i32).to_be_bytes()[1..]);
        r.push(6, b);
    }
    // The velocity in the target's own east/north axes.
    let v = frame.rotation_to(&LocalFrame::new(geo)) * Vector3::new(vx, vy, 0.0);
    if let (Some(ex), Some(ny)) = (signed(v.x, 0.25, 16), signed(v.y, 0.25, 16)) {
        let mut b = (ex as i16).to_be_bytes().to_vec();
        b.extend_from_slice(&(ny as i16).to_be_bytes());
        r.push(7, b);
    }
    r.push(12, ((track.id & 0xFFFF) as u16).to_be_bytes().to_vec());
    let three_d = track.cov_dims.contains(&2);
    let alt_ft = geo.alt_m * FT_PER_M;
    let altitude = signed(alt_ft, 6.25, 16).filter(|_| (-1500.0..=150_000.0).contains(&alt_ft));
    r.push(13, track_status(track, altitude.is_some(), three_d, life));
    if let Some(a) = altitude {
        r.push(18, (a as i16).to_be_bytes().to_vec());
    }
    if let Some(b) = accuracies(track, frame, &geo, altitude.is_some() && three_d) {
        r.push(27, b);
    }
    Some(r.encode())
}

/// I062/080: the first octet and the extents up to the last non-zero one.
fn track_status(track: &TrackView, altitude: bool, three_d: bool, life: Lifecycle) -> Vec<u8> {
    let mut octet = 0_u8; // MON 0: multisensor; SPI 0.
    if altitude {
        let src: u8 = if three_d { 3 } else { 6 };
        octet |= 0x20 | (src << 2); // MRH: geometric
    }
    if track.status == TrackStatus::Tentative {
        octet |= 0x02; // CNF
    }
    let ext1 = match life {
        Lifecycle::First => 0x20, // TSB
        Lifecycle::Update => 0,
        Lifecycle::Last => 0x40, // TSE
    };
    let ext3 = if track.updated { 0 } else { 0x80 }; // CST
    let mut out = vec![octet, ext1, 0, ext3];
    while out.len() > 1 && out.last() == Some(&0) {
        out.pop();
    }
    let n = out.len();
    for o in &mut out[..n - 1] {
        *o |= 1;
    }
    out
}

/// I062/500 from the covariance: APC, COV, APW, AGA (with `aga`), ATV; `None` without any.
fn accuracies(track: &TrackView, frame: &LocalFrame, geo: &Geodetic, aga: bool) -> Option<Vec<u8>> {
    let mut primary = 0_u8;
    let mut body = Vec::new();
    let (sx, sy) = (sd(track, 0), sd(track, 1));
    if let (Some(sx), Some(sy)) = (sx, sy) {
        primary |= 0x80;
        body.extend_from_slice(&(unsigned_sat(sx, 0.5, 16) as u16).to_be_bytes());
        body.extend_from_slice(&(unsigned_sat(sy, 0.5, 16) as u16).to_be_bytes());
        if let Some(c) = track.cov_at(0, 1) {
            primary |= 0x40;
            let v = c.signum() * c.abs().sqrt() / 0.5;
            body.extend_from_slice(&(v.round().clamp(-32_768.0, 32_767.0) as i16).to_be_bytes());
        }
        // Degrees per metre north and east at the target, through the frame.
        let p = frame.to_enu(geo);
        let north = frame.from_enu(&(p + Vector3::new(0.0, 1.0, 0.0)));
        let east = frame.from_enu(&(p + Vector3::new(1.0, 0.0, 0.0)));
        let lat_per_m = (north.lat_deg - geo.lat_deg).hypot(east.lat_deg - geo.lat_deg);
        let lon_per_m = (east.lon_deg - geo.lon_deg).hypot(north.lon_deg - geo.lon_deg);
        if lat_per_m.is_finite() && lon_per_m.is_finite() {
            primary |= 0x20;
            let lsb = 180.0 / f64::from(1_u32 << 23);
            body.extend_from_slice(&(unsigned_sat(sy * lat_per_m, lsb, 16) as u16).to_be_bytes());
            body.extend_from_slice(&(unsigned_sat(sx * lon_per_m, lsb, 16) as u16).to_be_bytes());
        }
    }
    if aga && let Some(sz) = sd(track, 2) {
        primary |= 0x10;
        body.push(unsigned_sat(sz * FT_PER_M, 6.25, 8) as u8);
    }
    if let (Some(svx), Some(svy)) = (sd(track, 3), sd(track, 4)) {
        primary |= 0x04;
        body.push(unsigned_sat(svx, 0.25, 8) as u8);
        body.push(unsigned_sat(svy, 0.25, 8) as u8);
    }
    (primary != 0).then(|| {
        let mut out = vec![primary];
        out.extend_from_slice(&body);
        out
    })
}

/// One CAT062 data block.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DataBlock {
    /// CAT, LEN and the records.
    pub bytes: Vec<u8>,
    /// How many records it holds.
    pub records: usize,
}

/// The records packed into CAT062 data blocks of at most `max_len` octets each (one per UDP
/// datagram), in order. A record that cannot fit a block of `max_len` is left out.
pub fn data_blocks(records: &[Vec<u8>], max_len: usize) -> Vec<DataBlock> {
    let max_len = max_len.min(usize::from(u16::MAX));
    let mut blocks = Vec::new();
    let mut block = DataBlock {
        bytes: Vec::new(),
        records: 0,
    };
    for r in records {
        if 3 + r.len() > max_len {
            continue;
        }
        if block.records > 0 && block.bytes.len() + r.len() > max_len {
            let full = std::mem::replace(
                &mut block,
                DataBlock {
                    bytes: Vec::new(),
                    records: 0,
                },
            );
            blocks.push(finish(full));
        }
        if block.records == 0 {
            block.bytes.extend_from_slice(&[CATEGORY, 0, 0]);
        }
        block.bytes.extend_from_slice(r);
        block.records += 1;
    }
    if block.records > 0 {
        blocks.push(finish(block));
    }
    blocks
}

/// Writes a block's LEN.
fn finish(mut block: DataBlock) -> DataBlock {
    let len = u16::try_from(block.bytes.len()).unwrap_or(u16::MAX);
    block.bytes[1..3].copy_from_slice(&len.to_be_bytes());
    block
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::DEFAULT_ORIGIN;

    const SOURCE: Source = Source {
        sac: 25,
        sic: 201,
        service_id: 7,
    };

    fn track(status: TrackStatus, state: [f64; 6]) -> TrackView {
        TrackView {
            id: 65_536 + 12,
            status,
            t: 100.0,
            state,
            // Planar: x, y, vx, vy.
            cov: vec![
                vec![4.0, 1.0, 0.0, 0.0],
                vec![1.0, 9.0, 0.0, 0.0],
                vec![0.0, 0.0, 0.25, 0.0],
                vec![0.0, 0.0, 0.0, 1.0],
            ],
            cov_dims: vec![0, 1, 3, 4],
            updated: true,
            age: 30,
            last_update: 100.0,
            mode_probabilities: Vec::new(),
            existence: None,
        }
    }

    /// A tiny decoder of what this module writes (the e2e test decodes with aviconv-asterix).
    struct Decoded {
        tod: f64,
        lat: f64,
        lon: f64,
        x: f64,
        y: f64,
        vx: f64,
        vy: f64,
        track_number: u16,
        status: Vec<u8>,
    }

    fn be(b: &[u8]) -> i64 {
        let mut v: i64 = if b[0] & 0x80 != 0 { -1 } else { 0 };
        for &o in b {
            v = (v << 8) | i64::from(o);
        }
        v
    }

    fn decode(rec: &[u8]) -> Decoded {
        let mut at = 0;
        let mut frns = Vec::new();
        loop {
            let o = rec[at];
            for bit in 0..7 {
                if o & (0x80 >> bit) != 0 {
                    frns.push(at * 7 + bit + 1);
                }
            }
            at += 1;
            if o & 1 == 0 {
                break;
            }
        }
        let mut d = Decoded {
            tod: f64::NAN,
            lat: f64::NAN,
            lon: f64::NAN,
            x: f64::NAN,
            y: f64::NAN,
            vx: f64::NAN,
            vy: f64::NAN,
            track_number: 0,
            status: Vec::new(),
        };
        let lsb = 180.0 / f64::from(1_u32 << 25);
        for frn in frns {
            let len = match frn {
                1 => 2,
                3 => 1,
                4 => 3,
                5 => 8,
                6 => 6,
                7 | 12 => {
                    if frn == 7 {
                        4
                    } else {
                        2
                    }
                }
                13 => rec[at..].iter().position(|o| o & 1 == 0).unwrap() + 1,
                18 => 2,
                27 => {
                    let p = rec[at];
                    1 + [(0x80, 4), (0x40, 2), (0x20, 4), (0x10, 1), (0x04, 2)]
                        .iter()
                        .filter(|(m, _)| p & m != 0)
                        .map(|(_, n)| n)
                        .sum::<usize>()
                }
                _ => panic!("unexpected FRN {frn}"),
            };
            let b = &rec[at..at + len];
            match frn {
                4 => {
                    d.tod = (u32::from(b[0]) << 16 | u32::from(b[1]) << 8 | u32::from(b[2])) as f64
                        / 128.0
                }
                5 => {
                    d.lat = be(&b[..4]) as f64 * lsb;
                    d.lon = be(&b[4..]) as f64 * lsb;
                }
                6 => {
                    d.x = be(&b[..3]) as f64 * 0.5;
                    d.y = be(&b[3..]) as f64 * 0.5;
                }
                7 => {
                    d.vx = be(&b[..2]) as f64 * 0.25;
                    d.vy = be(&b[2..]) as f64 * 0.25;
                }
                12 => d.track_number = u16::from_be_bytes([b[0], b[1]]),
                13 => d.status = b.to_vec(),
                _ => {}
            }
            at += len;
        }
        assert_eq!(at, rec.len(), "trailing octets");
        d
    }

    #[test]
    fn a_known_record_byte_for_byte() {
        let frame = LocalFrame::new(Geodetic {
            lat_deg: 0.0,
            lon_deg: 0.0,
            alt_m: 0.0,
        });
        // At the origin of a frame on the equator: lat = lon = 0, alt 0 ft.
        let t = track(TrackStatus::Confirmed, [0.0, 0.0, 0.0, 3.0, -4.5, 0.0]);
        let rec = track_record(&t, &frame, SOURCE, 3600.5, Lifecycle::First).unwrap();
        #[rustfmt::skip]
        let expected: Vec<u8> = vec![
            0xBF, 0x0D, 0x11, 0x04,             // FSPEC: FRN 1,3-7 | 12,13 | 18 | 27
            25, 201,                            // I062/010
            7,                                  // I062/015
            0x07, 0x08, 0x40,                   // I062/070: 3600.5 · 128 = 460 864
            0, 0, 0, 0, 0, 0, 0, 0,             // I062/105
            0, 0, 0, 0, 0, 0,                   // I062/100
            0x00, 0x0C, 0xFF, 0xEE,             // I062/185: 12, −18 (0.25 m/s)
            0x00, 12,                           // I062/040: (65 536 + 12) mod 2¹⁶
            0x39, 0x20,                         // I062/080: MRH, SRC 6, FX | TSB
            0, 0,                               // I062/130: 0 ft
            0xE4,                               // I062/500: APC, COV, APW, ATV
            0, 4, 0, 6,                         //   σx 2 m, σy 3 m
            0, 2,                               //   √1 m
            0, 1, 0, 1,                         //   σ 3 m, 2 m in 180/2²³ ° (2.4 m)
            2, 4,                               //   σv 0.5, 1 m/s
        ];
        assert_eq!(rec, expected);
        // Tentative, coasting, not first: CNF, and extents up to CST.
        let mut t = track(TrackStatus::Tentative, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        t.updated = false;
        let d = decode(&track_record(&t, &frame, SOURCE, 0.0, Lifecycle::Update).unwrap());
        assert_eq!(d.status, vec![0x3B, 0x01, 0x01, 0x80]);
        // The last record: TSE in the first extent.
        let t = track(TrackStatus::Confirmed, [0.0; 6]);
        let d = decode(&track_record(&t, &frame, SOURCE, 0.0, Lifecycle::Last).unwrap());
        assert_eq!(d.status, vec![0x39, 0x40]);
    }

    #[test]
    fn a_record_decodes_to_the_track() {
        let frame = LocalFrame::new(DEFAULT_ORIGIN);
        let state = [1234.4, -567.8, 0.0, 3.0, 4.0, 0.0];
        let t = track(TrackStatus::Confirmed, state);
        let rec = track_record(&t, &frame, SOURCE, 86_399.999, Lifecycle::Update).unwrap();
        let d = decode(&rec);
        // The last 1/256 s of the day is the next midnight.
        assert_eq!(d.tod, 0.0);
        assert_eq!(d.track_number, 12);
        assert!((d.x - state[0]).abs() <= 0.25 && (d.y - state[1]).abs() <= 0.25);
        let back = frame.to_enu(&Geodetic {
            lat_deg: d.lat,
            lon_deg: d.lon,
            alt_m: frame.origin().alt_m,
        });
        assert!((back.x - state[0]).hypot(back.y - state[1]) < 0.5, "{back}");
        // 1.2 km from the origin, north turns by ~0.01°: 4 mm/s.
        assert!((d.vx - 3.0).abs() <= 0.125 && (d.vy - 4.0).abs() <= 0.125);
        let d = decode(&track_record(&t, &frame, SOURCE, 12.3, Lifecycle::Update).unwrap());
        assert!((d.tod - 12.3).abs() <= 1.0 / 256.0);
        // A 3-D estimate: SRC 3 (triangulation), and AGA (σz 2 m = 6.6 ft: 1) in I062/500.
        let mut t = track(TrackStatus::Confirmed, [0.0, 0.0, 50.0, 0.0, 0.0, 0.0]);
        t.cov_dims = (0..6).collect();
        t.cov = (0..6)
            .map(|i| (0..6).map(|j| if i == j { 4.0 } else { 0.0 }).collect())
            .collect();
        let rec = track_record(&t, &frame, SOURCE, 0.0, Lifecycle::Update).unwrap();
        assert_eq!(decode(&rec).status, vec![0x2C]);
        // I062/500 last: primary APC|COV|APW|AGA|ATV, …, AGA, ATV x, ATV y.
        let n = rec.len();
        assert_eq!(rec[n - 14], 0xF4);
        assert_eq!(&rec[n - 3..], &[1, 8, 8]);
    }

    #[test]
    fn non_finite_tracks_and_times_give_no_record() {
        let frame = LocalFrame::new(DEFAULT_ORIGIN);
        for i in 0..6 {
            for bad in [f64::NAN, f64::INFINITY] {
                let mut s = [0.0; 6];
                s[i] = bad;
                let t = track(TrackStatus::Confirmed, s);
                assert!(track_record(&t, &frame, SOURCE, 0.0, Lifecycle::Update).is_none());
            }
        }
        let t = track(TrackStatus::Confirmed, [0.0; 6]);
        for tod in [f64::NAN, -1.0, 86_400.0] {
            assert!(track_record(&t, &frame, SOURCE, tod, Lifecycle::Update).is_none());
        }
        // Too far for I062/100 and too fast for I062/185: those items are left out.
        let far = track(TrackStatus::Confirmed, [5e6, 0.0, 0.0, 2e4, 0.0, 0.0]);
        let d = decode(&track_record(&far, &frame, SOURCE, 0.0, Lifecycle::Update).unwrap());
        assert!(d.x.is_nan() && d.vx.is_nan() && d.lat.is_finite());
        // A non-finite covariance leaves I062/500's subfields out, not the record.
        let mut t = track(TrackStatus::Confirmed, [0.0; 6]);
        t.cov[0][0] = f64::NAN;
        t.cov[2][2] = f64::INFINITY;
        assert!(track_record(&t, &frame, SOURCE, 0.0, Lifecycle::Update).is_some());
    }

    #[test]
    fn blocks_stay_within_their_size() {
        let frame = LocalFrame::new(DEFAULT_ORIGIN);
        let records: Vec<Vec<u8>> = (0_u32..100)
            .map(|i| {
                let mut t = track(
                    TrackStatus::Confirmed,
                    [f64::from(i), 0.0, 0.0, 0.0, 0.0, 0.0],
                );
                t.id = u64::from(i);
                track_record(&t, &frame, SOURCE, 0.0, Lifecycle::Update).unwrap()
            })
            .collect();
        let blocks = data_blocks(&records, MAX_BLOCK);
        assert!(blocks.len() > 1);
        let mut n = 0;
        for block in &blocks {
            let b = &block.bytes;
            assert!(b.len() <= MAX_BLOCK);
            let before = n;
            assert_eq!(b[0], CATEGORY);
            assert_eq!(usize::from(u16::from_be_bytes([b[1], b[2]])), b.len());
            let mut at = 3;
            while at < b.len() {
                let r = &records[n];
                assert_eq!(&b[at..at + r.len()], r.as_slice());
                at += r.len();
                n += 1;
            }
            assert_eq!(block.records, n - before);
        }
        assert_eq!(n, records.len());
        assert!(data_blocks(&records, 10).is_empty());
        assert!(data_blocks(&[], MAX_BLOCK).is_empty());
    }
}
