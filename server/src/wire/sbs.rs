//! The BaseStation "SBS-1" text format that dump1090, readsb and Kinetic's BaseStation serve on
//! TCP port 30003: one line of 22 comma-separated fields per decoded Mode S / ADS-B message.
//! [`parse`] reads one line into an [`SbsReport`] (pure; no clock: the receiver stamps the time).
//!
//! | field | name | kept as | in messages (`MSG,<n>`) |
//! |---|---|---|---|
//! | 1 | message type | `MSG` parsed; `SEL`, `ID`, `AIR`, `STA`, `CLK` are valid and skipped | |
//! | 2 | transmission type 1–8 | [`SbsReport::transmission`] | |
//! | 5 | hex ident (24-bit ICAO address; dump1090 prefixes a non-ICAO TIS-B address with `~`) | [`SbsReport::icao`], [`SbsReport::non_icao`] | all |
//! | 11 | callsign | [`SbsReport::callsign`] (trimmed) | 1 |
//! | 12 | altitude, ft (Mode C: pressure altitude against 1013.25 hPa) | [`SbsReport::altitude_ft`] | 2, 3, 5, 7 |
//! | 13 | ground speed, kt | [`SbsReport::ground_speed_kt`] | 2, 4 |
//! | 14 | track over ground, degrees from true north | [`SbsReport::track_deg`] | 2, 4 |
//! | 15, 16 | latitude, longitude, degrees WGS-84 | [`SbsReport::position`] | 2, 3 |
//! | 17 | vertical rate, ft/min (up) | [`SbsReport::vertical_rate_fpm`] | 4 |
//! | 18 | squawk (4 octal digits) | [`SbsReport::squawk`] | 5, 6 |
//! | 22 | on the ground (`-1` or `1` true, `0` false) | [`SbsReport::on_ground`] | 2, 3, 5, 6, 7 |
//!
//! Fields 3, 4 and 6–10 (session, aircraft and flight ids, the dates and times generated and
//! logged) are not used: the times are in the receiver's local time zone without one named,
//! so the service stamps each line with its arrival time instead. Fields 19–21 (alert,
//! emergency, SPI) are not kept. An empty field is unknown. Reference: Kinetic Avionics,
//! *BaseStation socket data* (the "barebones" description of port 30003), and dump1090's
//! `modesSendSBSOutput`.
//!
//! A line that breaks the format ([`SbsError`]: too few fields, an unknown message type, a bad
//! hex ident, a number that does not parse, is not finite or is out of its range, a latitude
//! without a longitude) is refused whole: nothing of it is used.

/// One `MSG` line.
#[derive(Debug, Clone, PartialEq)]
pub struct SbsReport {
    /// Transmission type 1–8 (`MSG,<n>`).
    pub transmission: u8,
    /// The 24-bit address.
    pub icao: u32,
    /// The address is not an ICAO one (dump1090's `~` prefix: TIS-B, anonymous).
    pub non_icao: bool,
    /// Flight identification (callsign), trimmed, when sent.
    pub callsign: Option<String>,
    /// Pressure altitude, ft.
    pub altitude_ft: Option<f64>,
    /// Ground speed, kt.
    pub ground_speed_kt: Option<f64>,
    /// Track over ground, degrees clockwise from true north, in [0, 360).
    pub track_deg: Option<f64>,
    /// Latitude and longitude, degrees WGS-84.
    pub position: Option<(f64, f64)>,
    /// Vertical rate, ft/min, positive up.
    pub vertical_rate_fpm: Option<f64>,
    /// Mode A code, 4 octal digits.
    pub squawk: Option<u16>,
    /// On the ground.
    pub on_ground: Option<bool>,
}

/// Why a line was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{reason}: {detail}")]
pub struct SbsError {
    /// A short label (the `reason` of the counters): `fields`, `type`, `hex`, `number`,
    /// `range`.
    pub reason: &'static str,
    /// What exactly, for the log.
    pub detail: String,
}

fn error(reason: &'static str, detail: impl Into<String>) -> SbsError {
    SbsError {
        reason,
        detail: detail.into(),
    }
}

/// Message types that are part of the format but carry no aircraft state.
const OTHER_TYPES: [&str; 5] = ["SEL", "ID", "AIR", "STA", "CLK"];

/// Parses one line (without its line end; a trailing `\r` is ignored). `Ok(None)`: a valid line
/// of another message type than `MSG`.
pub fn parse(line: &str) -> Result<Option<SbsReport>, SbsError> {
    let line = line.strip_suffix('\r').unwrap_or(line);
    let fields: Vec<&str> = line.split(',').map(str::trim).collect();
    let kind = fields[0];
    if OTHER_TYPES.contains(&kind) {
        return Ok(None);
    }
    if kind != "MSG" {
        return Err(error("type", format!("message type {kind:?}")));
    }
    if fields.len() < 22 {
        return Err(error(
            "fields",
            format!("{} fields, MSG has 22", fields.len()),
        ));
    }
    let Ok(transmission @ 1..=8) = fields[1].parse::<u8>() else {
        return Err(error("type", format!("transmission type {:?}", fields[1])));
    };
    let (non_icao, hex) = match fields[4].strip_prefix('~') {
        Some(h) => (true, h),
        None => (false, fields[4]),
    };
    if hex.len() != 6 {
        return Err(error("hex", format!("hex ident {:?}", fields[4])));
    }
    let icao = u32::from_str_radix(hex, 16)
        .map_err(|_| error("hex", format!("hex ident {:?}", fields[4])))?;
    let callsign = match fields[10] {
        "" => None,
        c if c.len() <= 8 && c.bytes().all(|b| b.is_ascii_alphanumeric() || b == b' ') => {
            Some(c.to_owned())
        }
        c => return Err(error("range", format!("callsign {c:?}"))),
    };
    let lat = number(fields[14], "latitude", -90.0, 90.0)?;
    let lon = number(fields[15], "longitude", -180.0, 180.0)?;
    let position = match (lat, lon) {
        (Some(lat), Some(lon)) => Some((lat, lon)),
        (None, None) => None,
        _ => return Err(error("range", "a latitude without a longitude or back")),
    };
    let squawk = match fields[17] {
        "" => None,
        s if s.len() == 4 && s.bytes().all(|b| (b'0'..=b'7').contains(&b)) => {
            u16::from_str_radix(s, 8).ok()
        }
        s => return Err(error("range", format!("squawk {s:?}"))),
    };
    let on_ground = match fields[21] {
        "" => None,
        "0" => Some(false),
        "-1" | "1" => Some(true),
        g => return Err(error("range", format!("on-ground flag {g:?}"))),
    };
    Ok(Some(SbsReport {
        transmission,
        icao,
        non_icao,
        callsign,
        altitude_ft: number(fields[11], "altitude", -2_000.0, 150_000.0)?,
        ground_speed_kt: number(fields[12], "ground speed", 0.0, 4_000.0)?,
        track_deg: number(fields[13], "track", -360.0, 360.0)?.map(|t| t.rem_euclid(360.0)),
        position,
        vertical_rate_fpm: number(fields[16], "vertical rate", -100_000.0, 100_000.0)?,
        squawk,
        on_ground,
    }))
}

/// An optional number in `[lo, hi]`.
fn number(text: &str, name: &str, lo: f64, hi: f64) -> Result<Option<f64>, SbsError> {
    if text.is_empty() {
        return Ok(None);
    }
    let v: f64 = text
        .parse()
        .map_err(|_| error("number", format!("{name} {text:?}")))?;
    if !v.is_finite() || v < lo || v > hi {
        return Err(error("range", format!("{name} {text} not in [{lo}, {hi}]")));
    }
    Ok(Some(v))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dump1090_lines_of_every_kind() {
        // From dump1090-fa's port 30003 output.
        let id = parse("MSG,1,1,1,4CA2D6,1,2024/05/01,12:00:00.000,2024/05/01,12:00:00.000,RYR4TX  ,,,,,,,,,,,0").unwrap().unwrap();
        assert_eq!(id.transmission, 1);
        assert_eq!(id.icao, 0x4C_A2D6);
        assert!(!id.non_icao);
        assert_eq!(id.callsign.as_deref(), Some("RYR4TX"));
        assert_eq!(id.on_ground, Some(false));
        let pos = parse("MSG,3,1,1,4CA2D6,1,2024/05/01,12:00:00.000,2024/05/01,12:00:00.000,,37000,,,51.45735,-1.02826,,,0,0,0,0").unwrap().unwrap();
        assert_eq!(pos.altitude_ft, Some(37_000.0));
        assert_eq!(pos.position, Some((51.45735, -1.02826)));
        assert_eq!(pos.callsign, None);
        let vel = parse("MSG,4,1,1,~4CA2D6,1,2024/05/01,12:00:00.000,2024/05/01,12:00:00.000,,,451,-12,,,-1088,,,,,0\r").unwrap().unwrap();
        assert!(vel.non_icao);
        assert_eq!(vel.ground_speed_kt, Some(451.0));
        assert_eq!(vel.track_deg, Some(348.0));
        assert_eq!(vel.vertical_rate_fpm, Some(-1088.0));
        let sq = parse("MSG,6,1,1,4CA2D6,1,,,,,,,,,,,,7700,0,1,0,-1")
            .unwrap()
            .unwrap();
        assert_eq!(sq.squawk, Some(0o7700));
        assert_eq!(sq.on_ground, Some(true));
        assert_eq!(
            parse("STA,,5,179,400AE7,10103,2008/11/28,14:58:51.153,2008/11/28,14:58:51.153,RM"),
            Ok(None)
        );
    }

    #[test]
    fn broken_lines_are_refused_with_a_reason() {
        let base = "MSG,3,1,1,4CA2D6,1,,,,,,37000,,,51.45735,-1.02826,,,0,0,0,0";
        let cases = [
            ("", "type"),
            ("garbage", "type"),
            ("MSG,3,1,1,4CA2D6", "fields"),
            ("MSG,9,1,1,4CA2D6,1,,,,,,,,,,,,,,,,", "type"),
            ("MSG,3,1,1,4CA2G6,1,,,,,,,,,,,,,,,,", "hex"),
            ("MSG,3,1,1,4CA2D,1,,,,,,,,,,,,,,,,", "hex"),
            ("MSG,3,1,1,4CA2D6,1,,,,,,NaN,,,,,,,,,,", "range"),
            ("MSG,3,1,1,4CA2D6,1,,,,,,inf,,,,,,,,,,", "range"),
            ("MSG,3,1,1,4CA2D6,1,,,,,,3e5,,,,,,,,,,", "range"),
            ("MSG,3,1,1,4CA2D6,1,,,,,,1x,,,,,,,,,,", "number"),
            ("MSG,3,1,1,4CA2D6,1,,,,,,,,,91.0,0,,,,,,", "range"),
            ("MSG,3,1,1,4CA2D6,1,,,,,,,,,51.0,,,,,,,", "range"),
            ("MSG,6,1,1,4CA2D6,1,,,,,,,,,,,,7800,,,,", "range"),
            ("MSG,1,1,1,4CA2D6,1,,,,,A<B>,,,,,,,,,,,", "range"),
            ("MSG,3,1,1,4CA2D6,1,,,,,,,,,,,,,,,,2", "range"),
        ];
        assert!(parse(base).unwrap().is_some());
        for (line, reason) in cases {
            let e = parse(line).expect_err(line);
            assert_eq!(e.reason, reason, "{line}: {e}");
        }
    }
}
