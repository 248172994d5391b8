//! Mode S / ADS-B decoding of what the aircraft tracker uses, from the messages a Beast frame
//! carries ([`crate::wire::beast`]), into the same per-aircraft reports as the SBS-1 text
//! ([`SbsReport`]), so both formats feed the same tracks.
//!
//! Following ICAO Doc 9871, *Technical Provisions for Mode S Services and Extended Squitter*
//! (2nd ed., 2012; the ADS-B message formats of its appendix C, version 2), and Junzi Sun, *The
//! 1090 Megahertz Riddle* (2nd ed., TU Delft OPEN, 2021; mode-s.org), whose worked examples are
//! the unit tests here.
//!
//! | message | used | becomes |
//! |---|---|---|
//! | DF17 (extended squitter), DF18 with CF 0 (non-transponder, ICAO address) or CF 1 (anonymous address, kept apart like SBS-1's `~`) | 112 bits whose 24-bit parity ([`crc`]) is 0; the address AA | the aircraft |
//! | TC 1–4, identification | the 8 characters | callsign ([`SbsReport::callsign`], trailing spaces trimmed) |
//! | TC 9–18, airborne position, barometric altitude | 25 ft altitude (Q = 1); CPR latitude, longitude | position and altitude, [`SbsReport::position`], [`SbsReport::altitude_ft`] |
//! | TC 20–22, airborne position, GNSS height | height (m, above the ellipsoid); CPR latitude, longitude | the same |
//! | TC 19, subtypes 1 and 2, airborne velocity over ground | east, north (kt; ×4 in subtype 2), vertical rate (64 ft/min) | [`SbsReport::ground_speed_kt`], [`SbsReport::track_deg`], [`SbsReport::vertical_rate_fpm`] |
//!
//! Not used (valid, [`Decoded::Other`]): every other downlink format (DF0/4/5/11/16/20/21,
//! whose parity is overlaid with the address or the interrogator and cannot be checked
//! alone; so no squawk), DF18 CF 2–7 (TIS-B and ADS-R), surface positions (TC 5–8), velocity
//! subtypes 3–4 (airspeed and heading), the status and operational messages (TC 23–31), and a
//! position without its latitude and longitude. Q = 0 altitudes (Gillham code, 100 ft, above
//! 50 175 ft) are not decoded: such a position keeps the aircraft's last altitude. No bit error
//! is corrected: a message whose parity is not 0 is refused ([`ModeSError::Crc`]).
//!
//! Positions are Compact Position Reporting (CPR, Doc 9871 C.2.6; Riddle ch. 5), 17 bits of
//! latitude and longitude within a zone, an even and an odd zone grid. [`AdsbDecoder`] keeps
//! each aircraft's last even and odd message: the first position is decoded *globally* from
//! an even/odd pair received within [`PAIR_S`] of each other (refused when the two fall in
//! different longitude-zone counts, [`ModeSError::Cpr`]); every later one *locally*, against
//! the aircraft's last decoded position while that is under [`REFERENCE_S`] old (an aircraft
//! flies far less than the half zone, ≥ 333 km, that local decoding allows). The times are the
//! arrival times the caller gives, not the Beast time stamps.
//!
//! Written here rather than taken from a crate: `adsb_deku` 0.8 (MIT, MSRV 1.84) builds on
//! `deku`'s derive macros (a second `darling`, `bitvec`) and decodes CPR globally only;
//! `rs1090` 0.7 (MIT, MSRV not stated) also pulls `rayon`, `regex`, `tokio` and `futures`
//! unconditionally. What the tracker needs is the few hundred lines below.

use std::collections::HashMap;
use std::f64::consts::PI;

use super::sbs::SbsReport;

/// Mode S parity generator polynomial (x²⁴ + … + 1: 0x1FFF409, its low 24 bits).
const GENERATOR: u32 = 0xFF_F409;
/// CPR fraction denominator (17 bits).
const CPR_MAX: f64 = 131_072.0;
/// Longest time between the even and odd message of a global decoding, s.
pub const PAIR_S: f64 = 10.0;
/// Oldest last position a local decoding is made against, s.
pub const REFERENCE_S: f64 = 60.0;
/// The ADS-B identification character set (6 bits; `#`: not a character).
const CHARSET: &[u8; 64] = b"#ABCDEFGHIJKLMNOPQRSTUVWXYZ##### ###############0123456789######";

const fn crc_table() -> [u32; 256] {
    let mut table = [0_u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = (i as u32) << 16;
        let mut k = 0;
        while k < 8 {
            c = if c & 0x80_0000 != 0 {
                (c << 1) ^ GENERATOR
            } else {
                c << 1
            };
            k += 1;
        }
        table[i] = c & 0xFF_FFFF;
        i += 1;
    }
    table
}

static CRC_TABLE: [u32; 256] = crc_table();

/// The Mode S 24-bit parity remainder of `bytes` (Doc 9871 / Annex 10 vol. IV 3.1.2.3.3): 0
/// over a whole DF17/DF18 message when it is intact; over a message without its last 3 bytes,
/// the parity to append.
pub fn crc(bytes: &[u8]) -> u32 {
    bytes.iter().fold(0_u32, |c, &b| {
        ((c << 8) ^ CRC_TABLE[(((c >> 16) ^ u32::from(b)) & 0xFF) as usize]) & 0xFF_FFFF
    })
}

/// Why a message was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ModeSError {
    /// An extended squitter (DF17/18) in a short (56-bit) frame.
    #[error("DF{0} in a 56-bit message")]
    Length(u8),
    /// The parity is not 0: a bit error (the counters' `crc_failed`).
    #[error("parity check failed")]
    Crc,
    /// An identification with a code that is not a character.
    #[error("callsign character code {0}")]
    Character(u8),
    /// An even/odd pair in different longitude-zone counts, or a latitude beyond ±90°.
    #[error("CPR position not decodable")]
    Cpr,
}

/// What a message became.
#[derive(Debug, Clone, PartialEq)]
pub enum Decoded {
    /// A report of the aircraft (transmission type 1: callsign; 3: position and altitude; 4:
    /// velocity, as SBS-1's).
    Report(SbsReport),
    /// A position message whose position cannot be decoded yet (no pair, no recent position):
    /// the report has the altitude only.
    Pending(SbsReport),
    /// A valid message of a kind not used.
    Other,
}

/// ME bits `first..first + len` (numbered from 1, as in Doc 9871).
fn field(me: u64, first: u32, len: u32) -> u64 {
    (me >> (57 - first - len)) & ((1 << len) - 1)
}

/// One aircraft's CPR memory.
#[derive(Debug, Clone, Default)]
struct Cpr {
    /// The last even and odd messages: latitude, longitude (17 bits), arrival time.
    even: Option<(u32, u32, f64)>,
    odd: Option<(u32, u32, f64)>,
    /// The last decoded position: latitude, longitude (degrees), time.
    position: Option<(f64, f64, f64)>,
    heard: f64,
}

/// Decodes messages into reports, keeping what CPR decoding needs of each aircraft.
#[derive(Debug, Clone, Default)]
pub struct AdsbDecoder {
    /// By the key the feed tracks with: the address, bit 24 set for an anonymous one.
    aircraft: HashMap<u32, Cpr>,
}

impl AdsbDecoder {
    /// Decodes one Mode S message (7 or 14 bytes) that arrived at `now` (s).
    pub fn decode(&mut self, message: &[u8], now: f64) -> Result<Decoded, ModeSError> {
        let Some(&first) = message.first() else {
            return Ok(Decoded::Other);
        };
        let df = first >> 3;
        if df != 17 && df != 18 {
            return Ok(Decoded::Other);
        }
        if message.len() != 14 {
            return Err(ModeSError::Length(df));
        }
        if crc(message) != 0 {
            return Err(ModeSError::Crc);
        }
        let non_icao = match (df, first & 7) {
            (17, _) | (18, 0) => false,
            (18, 1) => true,
            _ => return Ok(Decoded::Other),
        };
        let icao = u32::from_be_bytes([0, message[1], message[2], message[3]]);
        let me = message[4..11]
            .iter()
            .fold(0_u64, |m, &b| (m << 8) | u64::from(b));
        let blank = |transmission| SbsReport {
            transmission,
            icao,
            non_icao,
            callsign: None,
            altitude_ft: None,
            ground_speed_kt: None,
            track_deg: None,
            position: None,
            vertical_rate_fpm: None,
            squawk: None,
            on_ground: None,
        };
        let tc = field(me, 1, 5);
        match tc {
            1..=4 => {
                let mut callsign = String::with_capacity(8);
                for i in 0..8 {
                    let code = field(me, 9 + 6 * i, 6) as u8;
                    match CHARSET[usize::from(code)] {
                        b'#' => return Err(ModeSError::Character(code)),
                        c => callsign.push(char::from(c)),
                    }
                }
                let callsign = callsign.trim_end();
                if callsign.is_empty() {
                    return Ok(Decoded::Other);
                }
                Ok(Decoded::Report(SbsReport {
                    callsign: Some(callsign.to_owned()),
                    ..blank(1)
                }))
            }
            9..=18 | 20..=22 => {
                let alt = field(me, 9, 12);
                let altitude_ft = match tc {
                    _ if alt == 0 => None,
                    20..=22 => Some(alt as f64 / 0.3048),
                    // Q = 1: 25 ft steps from −1 000 ft, the Q bit taken out.
                    _ if alt & 0x10 != 0 => {
                        Some((((alt & 0xFE0) >> 1) | (alt & 0xF)) as f64 * 25.0 - 1_000.0)
                    }
                    _ => None,
                };
                let odd = field(me, 22, 1) == 1;
                let (lat, lon) = (field(me, 23, 17) as u32, field(me, 40, 17) as u32);
                let report = SbsReport {
                    altitude_ft,
                    on_ground: Some(false),
                    ..blank(3)
                };
                let key = icao | (u32::from(non_icao) << 24);
                match self.position(key, odd, lat, lon, now)? {
                    Some(p) => Ok(Decoded::Report(SbsReport {
                        position: Some(p),
                        ..report
                    })),
                    None => Ok(Decoded::Pending(report)),
                }
            }
            19 => {
                let factor = match field(me, 6, 3) {
                    1 => 1.0,
                    2 => 4.0,
                    _ => return Ok(Decoded::Other),
                };
                let (vew, vns) = (field(me, 15, 10), field(me, 26, 10));
                if vew == 0 || vns == 0 {
                    return Ok(Decoded::Other);
                }
                let sign = |bit: u64| if bit == 1 { -1.0 } else { 1.0 };
                let east = sign(field(me, 14, 1)) * (vew - 1) as f64 * factor;
                let north = sign(field(me, 25, 1)) * (vns - 1) as f64 * factor;
                let vr = field(me, 38, 9);
                let vertical_rate_fpm =
                    (vr != 0).then(|| sign(field(me, 37, 1)) * (vr - 1) as f64 * 64.0);
                Ok(Decoded::Report(SbsReport {
                    ground_speed_kt: Some(east.hypot(north)),
                    track_deg: Some(east.atan2(north).to_degrees().rem_euclid(360.0)),
                    vertical_rate_fpm,
                    ..blank(4)
                }))
            }
            _ => Ok(Decoded::Other),
        }
    }

    /// Keeps a CPR message and decodes the position it can give: locally against a recent
    /// position, else globally with a recent message of the other parity.
    fn position(
        &mut self,
        key: u32,
        odd: bool,
        lat: u32,
        lon: u32,
        now: f64,
    ) -> Result<Option<(f64, f64)>, ModeSError> {
        let a = self.aircraft.entry(key).or_default();
        a.heard = now;
        if odd {
            a.odd = Some((lat, lon, now));
        } else {
            a.even = Some((lat, lon, now));
        }
        let decoded = match (a.position, a.even, a.odd) {
            (Some((rlat, rlon, t)), ..) if now - t <= REFERENCE_S => {
                cpr_local(rlat, rlon, odd, lat, lon)
            }
            (_, Some(e), Some(o)) if (e.2 - o.2).abs() <= PAIR_S => {
                cpr_global((e.0, e.1), (o.0, o.1), odd)
            }
            _ => return Ok(None),
        };
        let (lat, lon) = decoded.ok_or(ModeSError::Cpr)?;
        a.position = Some((lat, lon, now));
        Ok(Some((lat, lon)))
    }

    /// Forgets the aircraft not heard since `since` (s).
    pub fn forget_before(&mut self, since: f64) {
        self.aircraft.retain(|_, a| a.heard >= since);
    }
}

/// The number of longitude zones at a latitude, NL (Doc 9871 C.2.6.2; Riddle 5.1, NZ = 15).
fn nl(lat: f64) -> f64 {
    let lat = lat.abs();
    if lat < 1e-9 {
        59.0
    } else if lat >= 87.0 {
        if lat == 87.0 { 2.0 } else { 1.0 }
    } else {
        let a = 1.0 - (PI / 30.0).cos();
        let c = lat.to_radians().cos();
        (2.0 * PI / (1.0 - a / (c * c)).clamp(-1.0, 1.0).acos()).floor()
    }
}

/// `lon` in [−180, 180).
fn wrap_lon(lon: f64) -> f64 {
    (lon + 180.0).rem_euclid(360.0) - 180.0
}

/// Global airborne CPR decoding of an even and an odd message (17-bit latitude, longitude);
/// the position of the later one (`odd_latest`). `None` when the pair straddles a change of NL.
fn cpr_global(even: (u32, u32), odd: (u32, u32), odd_latest: bool) -> Option<(f64, f64)> {
    let (lat_e, lon_e) = (f64::from(even.0) / CPR_MAX, f64::from(even.1) / CPR_MAX);
    let (lat_o, lon_o) = (f64::from(odd.0) / CPR_MAX, f64::from(odd.1) / CPR_MAX);
    let j = (59.0 * lat_e - 60.0 * lat_o + 0.5).floor();
    let southern = |lat: f64| if lat >= 270.0 { lat - 360.0 } else { lat };
    let rlat_e = southern(360.0 / 60.0 * (j.rem_euclid(60.0) + lat_e));
    let rlat_o = southern(360.0 / 59.0 * (j.rem_euclid(59.0) + lat_o));
    if nl(rlat_e) != nl(rlat_o) {
        return None;
    }
    let (lat, lon_cpr, i) = if odd_latest {
        (rlat_o, lon_o, 1.0)
    } else {
        (rlat_e, lon_e, 0.0)
    };
    if lat.abs() > 90.0 {
        return None;
    }
    let nl = nl(lat);
    let m = (lon_e * (nl - 1.0) - lon_o * nl + 0.5).floor();
    let n = (nl - i).max(1.0);
    Some((lat, wrap_lon(360.0 / n * (m.rem_euclid(n) + lon_cpr))))
}

/// Local airborne CPR decoding of one message against a reference position within half a zone.
fn cpr_local(ref_lat: f64, ref_lon: f64, odd: bool, lat: u32, lon: u32) -> Option<(f64, f64)> {
    let i = if odd { 1.0 } else { 0.0 };
    let (yz, xz) = (f64::from(lat) / CPR_MAX, f64::from(lon) / CPR_MAX);
    let dlat = 360.0 / (60.0 - i);
    let j = (ref_lat / dlat).floor() + (ref_lat.rem_euclid(dlat) / dlat - yz + 0.5).floor();
    let lat = dlat * (j + yz);
    if lat.abs() > 90.0 {
        return None;
    }
    let dlon = 360.0 / (nl(lat) - i).max(1.0);
    let m = (ref_lon / dlon).floor() + (ref_lon.rem_euclid(dlon) / dlon - xz + 0.5).floor();
    Some((lat, wrap_lon(dlon * (m + xz))))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn hex(s: &str) -> Vec<u8> {
        (0..s.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
            .collect()
    }

    fn report(d: Decoded) -> SbsReport {
        match d {
            Decoded::Report(r) => r,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn the_riddles_identification_and_parity() {
        let msg = hex("8D4840D6202CC371C32CE0576098");
        assert_eq!(crc(&msg), 0);
        assert_eq!(crc(&msg[..11]), 0x57_6098);
        let r = report(AdsbDecoder::default().decode(&msg, 0.0).unwrap());
        assert_eq!((r.transmission, r.icao, r.non_icao), (1, 0x48_40D6, false));
        assert_eq!(r.callsign.as_deref(), Some("KLM1023"));
        // Any one bit flipped after the DF fails the parity.
        for bit in 5..112 {
            let mut m = msg.clone();
            m[bit / 8] ^= 0x80 >> (bit % 8);
            assert_eq!(
                AdsbDecoder::default().decode(&m, 0.0),
                Err(ModeSError::Crc),
                "bit {bit}"
            );
        }
    }

    #[test]
    fn the_riddles_positions_global_then_local() {
        let even = hex("8D40621D58C382D690C8AC2863A7");
        let odd = hex("8D40621D58C386435CC412692AD6");
        let mut d = AdsbDecoder::default();
        let first = d.decode(&odd, 100.0).unwrap();
        let Decoded::Pending(p) = first else {
            panic!("{first:?}")
        };
        assert_eq!(p.altitude_ft, Some(38_000.0));
        let r = report(d.decode(&even, 102.0).unwrap());
        let (lat, lon) = r.position.unwrap();
        assert!(
            (lat - 52.257_20).abs() < 1e-5 && (lon - 3.919_37).abs() < 1e-5,
            "{lat} {lon}"
        );
        assert_eq!((r.altitude_ft, r.on_ground), (Some(38_000.0), Some(false)));
        // The Riddle's local example: the even message against 52.258, 3.918.
        let (lat, lon) = cpr_local(52.258, 3.918, false, 93_000, 51_372).unwrap();
        assert!(
            (lat - 52.257_20).abs() < 1e-5 && (lon - 3.919_37).abs() < 1e-5,
            "{lat} {lon}"
        );
        // A pair further apart than PAIR_S waits.
        let mut d = AdsbDecoder::default();
        d.decode(&odd, 100.0).unwrap();
        assert!(matches!(d.decode(&even, 111.0), Ok(Decoded::Pending(_))));
        // Forgotten: the pair starts again.
        let mut d = AdsbDecoder::default();
        d.decode(&odd, 100.0).unwrap();
        d.forget_before(101.0);
        assert!(matches!(d.decode(&even, 102.0), Ok(Decoded::Pending(_))));
    }

    #[test]
    fn the_riddles_velocity() {
        let r = report(
            AdsbDecoder::default()
                .decode(&hex("8D485020994409940838175B284F"), 0.0)
                .unwrap(),
        );
        assert_eq!(r.transmission, 4);
        assert!((r.ground_speed_kt.unwrap() - 159.20).abs() < 0.01);
        assert!((r.track_deg.unwrap() - 182.88).abs() < 0.01);
        assert_eq!(r.vertical_rate_fpm, Some(-832.0));
        // Subtype 3 (airspeed, heading): not used.
        assert_eq!(
            AdsbDecoder::default().decode(&hex("8DA05F219B06B6AF189400CBC33F"), 0.0),
            Ok(Decoded::Other)
        );
    }

    #[test]
    fn other_formats_are_valid_and_unused_short_squitters_refused() {
        let mut d = AdsbDecoder::default();
        // DF11 all-call reply, DF4 altitude reply, an empty message.
        assert_eq!(d.decode(&hex("5D484FDEA248F5"), 0.0), Ok(Decoded::Other));
        assert_eq!(d.decode(&hex("20001838CA3804"), 0.0), Ok(Decoded::Other));
        assert_eq!(d.decode(&[], 0.0), Ok(Decoded::Other));
        assert_eq!(
            d.decode(&hex("8D4840D6202CC3"), 0.0),
            Err(ModeSError::Length(17))
        );
    }

    /// Encodes a position the way a transponder does (Doc 9871 C.2.6.7).
    fn cpr_encode(lat: f64, lon: f64, odd: bool) -> (u32, u32) {
        let i = if odd { 1.0 } else { 0.0 };
        let dlat = 360.0 / (60.0 - i);
        let yz = (CPR_MAX * lat.rem_euclid(dlat) / dlat + 0.5).floor();
        let rlat = dlat * (yz / CPR_MAX + (lat / dlat).floor());
        let dlon = 360.0 / (nl(rlat) - i).max(1.0);
        let xz = (CPR_MAX * lon.rem_euclid(dlon) / dlon + 0.5).floor();
        ((yz as u32) % (1 << 17), (xz as u32) % (1 << 17))
    }

    #[test]
    fn cpr_round_trips_over_the_globe_within_a_resolution_step() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9871);
        let mut worst = 0.0_f64;
        let mut refused = 0;
        for _ in 0..20_000 {
            let lat = rng.random_range(-86.0..86.0);
            let lon = rng.random_range(-180.0..180.0);
            let e = cpr_encode(lat, lon, false);
            let o = cpr_encode(lat, lon, true);
            for odd_latest in [false, true] {
                let Some((la, lo)) = cpr_global(e, o, odd_latest) else {
                    refused += 1;
                    continue;
                };
                let dlon = wrap_lon(lo - lon).abs() * lat.to_radians().cos();
                worst = worst.max((la - lat).abs().max(dlon) * 111_320.0);
            }
            // Locally against a reference 100 km off.
            let (rlat, rlon) = (lat + 0.9, wrap_lon(lon - 0.9));
            let (la, lo) = cpr_local(rlat, rlon, true, o.0, o.1).unwrap();
            let dlon = wrap_lon(lo - lon).abs() * lat.to_radians().cos();
            worst = worst.max((la - lat).abs().max(dlon) * 111_320.0);
        }
        // 17 bits of a 6° zone: 5.1 m of latitude.
        assert!(worst < 6.0, "{worst} m");
        // Only pairs right at a zone count's change are refused.
        assert!(refused < 200, "{refused}");
    }

    #[test]
    fn random_messages_never_panic() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        let mut d = AdsbDecoder::default();
        for i in 0..100_000 {
            let len = [0, 2, 7, 14, 14, 14][rng.random_range(0..6)];
            let mut m: Vec<u8> = (0..len).map(|_| rng.random()).collect();
            if len == 14 {
                // An extended squitter with a good parity, so that its content is decoded.
                m[0] = if rng.random_bool(0.5) { 0x88 } else { 0x90 } | (m[0] & 0x07);
                let p = crc(&m[..11]).to_be_bytes();
                m[11..].copy_from_slice(&p[1..]);
            }
            if let Ok(Decoded::Report(r)) = d.decode(&m, f64::from(i) * 0.01) {
                if let Some((lat, lon)) = r.position {
                    assert!(lat.abs() <= 90.0 && (-180.0..180.0).contains(&lon));
                }
                assert!(
                    r.ground_speed_kt
                        .is_none_or(|g| g.is_finite() && g < 6_000.0)
                );
            }
        }
    }
}
