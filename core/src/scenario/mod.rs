//! The `gcs-scenario/1` format (`shared/scenarios/FORMAT.md`): `scenario.json`,
//! `measurements.jsonl`, `truth.csv` and the estimator output `estimates.jsonl`.
//!
//! Parsing works on strings (the caller reads the files) and every error says which file, which
//! line and what is wrong ([`FormatError`]). Unknown keys are ignored, as FORMAT.md requires.
//! Readers never look at the `generator` block.
//!
//! Split by concern: `types` holds [`Scenario`] and its blocks, `lines` the line-oriented files
//! (measurement lines, truth rows, estimate lines, [`ScenarioData`]), `parse` the parsers and
//! their errors, and `document` the [`ScenarioDocument`] a generator writes.

mod document;
mod lines;
mod parse;
mod types;

pub use document::{Frame, Generator, ScenarioDocument};
pub use lines::{
    Estimate, Measurement, PlatformPose, PredictionOut, Reference, ReferenceObject, ScenarioData,
    TruthRow, group_by_time, truth_at,
};
pub use parse::{FormatError, ScenarioFile, parse_measurements, parse_references, parse_truth};
pub(crate) use parse::{err, finite_cell, header_columns};
pub use types::{
    DetectionSpec, EllipsoidSpec, FORMAT_ID, LinearSystem, Motion, MotionModelSpec, Noise,
    Platform, Prior, Region, Road, Scenario, Scoring, Segment, Sensor, SizePrior, Target, TimeSpec,
    default_cov_dims,
};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::MeasKind;

    const SC: &str = r#"{"format":"gcs-scenario/1","name":"t","dims":2,"plane_z":0.0,
 "time":{"t0":0,"dt":1,"t_end":2},"target":{"id":"tgt"},
 "sensors":[{"id":"r","platform":"p","kind":"range_bearing","noise":{"type":"gaussian","std":[5,0.005]}}],
 "generator":{"whatever":1}}"#;

    #[test]
    fn documents_parse_back_and_keep_frame_extensions_and_generator() {
        let scenario = Scenario::parse(SC).unwrap();
        let mut extensions = serde_json::Map::new();
        extensions.insert("detection".into(), serde_json::json!({"pd": 0.9}));
        let origin = crate::detection::GeoPoint::new(47.0, 8.0, 400.0);
        let doc = ScenarioDocument {
            scenario: scenario.clone(),
            frame: Frame::enu(Some(origin)),
            extensions,
            generator: Generator {
                family: "test".into(),
                seed: 3,
                params: serde_json::json!({"k": 1}),
            },
        };
        let text = doc.to_json().unwrap();
        assert!(text.ends_with("}\n"));
        // The `detection` extension is the multi-target one (FORMAT-MULTI.md): read back too.
        let back = Scenario::parse(&text).unwrap();
        assert_eq!(back.detection.as_ref().map(|d| d.pd), Some(0.9));
        assert_eq!(
            Scenario {
                detection: None,
                ..back
            },
            scenario
        );
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(v["frame"]["type"], "ENU");
        assert_eq!(v["frame"]["origin_geodetic"]["lat_deg"], 47.0);
        assert_eq!(v["detection"]["pd"], 0.9);
        assert_eq!(v["generator"]["seed"], 3);
    }

    #[test]
    fn parses_minimal_scenario_and_ignores_unknown_keys() {
        let sc = Scenario::parse(SC).unwrap();
        assert_eq!(sc.sensors[0].kind, MeasKind::RangeBearing);
        assert_eq!(sc.active_dims(), &[0, 1, 3, 4]);
        for k in [
            MeasKind::Position,
            MeasKind::RangeBearing,
            MeasKind::AzEl,
            MeasKind::BearingSize,
        ] {
            assert_eq!(serde_json::to_value(k).unwrap(), k.as_str());
        }
    }

    #[test]
    fn measurement_errors_name_the_line() {
        let sc = Scenario::parse(SC).unwrap();
        let good =
            r#"{"t":0,"sensor":"r","kind":"range_bearing","platform":{"pos":[0,0,0]},"z":[1,2]}"#;
        let text = format!("{good}\n{{\"t\":1,\"sensor\":\"x\"\n");
        let e = parse_measurements(&text, &sc).unwrap_err();
        assert_eq!((e.file, e.line), (ScenarioFile::Measurements, Some(2)));
        let text = format!(
            "{good}\n{}",
            good.replace("\"sensor\":\"r\"", "\"sensor\":\"q\"")
        );
        let e = parse_measurements(&text, &sc).unwrap_err();
        assert_eq!(e.to_string(), "measurements.jsonl:2: unknown sensor \"q\"");
        let text = good.replace("[1,2]", "[1,2,3]");
        assert!(
            parse_measurements(&text, &sc)
                .unwrap_err()
                .message
                .contains("3 components")
        );
        let text = good.replace("[1,2]", "[null,2]");
        assert!(!parse_measurements(&text, &sc).unwrap()[0].is_finite());
    }

    #[test]
    fn reference_lines_are_checked_and_errors_name_the_line() {
        let sc = Scenario::parse(SC).unwrap();
        let good = r#"{"t":0,"sensor":"r","kind":"range_bearing","platform":{"pos":[0,0,0]},"z":[1,2],"object":{"id":"uav1","pos":[1,2,3],"std":[1,1,2]}}"#;
        let r = parse_references(good, &sc).unwrap();
        assert_eq!(
            (r[0].object.id.as_str(), r[0].object.vel),
            ("uav1", [0.0; 3])
        );
        for (bad, what) in [
            (good.replace("[1,1,2]", "[1,0,2]"), "std > 0"),
            (good.replace("[1,2]", "[null,2]"), "z is not finite"),
            (good.replace("\"r\"", "\"q\""), "unknown sensor"),
            (
                good.replace(
                    ",\"object\":{\"id\":\"uav1\",\"pos\":[1,2,3],\"std\":[1,1,2]}",
                    "",
                ),
                "object",
            ),
        ] {
            let e = parse_references(&format!("{good}\n{bad}\n"), &sc).unwrap_err();
            assert_eq!(
                (e.file, e.line),
                (ScenarioFile::References, Some(2)),
                "{bad}"
            );
            assert!(e.message.contains(what), "{}: {what}", e.message);
        }
    }

    #[test]
    fn scenario_errors_name_the_line() {
        let e = Scenario::parse("{\n\"format\": \"gcs-scenario/1\",\n\"name\": 3\n}").unwrap_err();
        assert_eq!((e.file, e.line), (ScenarioFile::Scenario, Some(3)));
        let e = Scenario::parse(&SC.replace("gcs-scenario/1", "gcs-scenario/9")).unwrap_err();
        assert!(e.message.contains("expected \"gcs-scenario/1\""));
    }

    #[test]
    fn truth_parsing_and_interpolation() {
        let t = parse_truth("t,x,y,z,vx,vy,vz,mode\n0,0,0,0,1,0,0,CV\n2,2,0,0,1,0,0,CT\n").unwrap();
        let (s, mode, exact) = truth_at(&t, 1.0).unwrap();
        assert_eq!((s[0], mode, exact), (1.0, "CV", false));
        assert!(truth_at(&t, 2.0 + 1e-7).unwrap().2);
        assert!(truth_at(&t, 3.0).is_none());
        let e = parse_truth("t,x,y,z,vx,vy,vz,mode\n0,0,0,0,1,abc,0,CV\n").unwrap_err();
        assert_eq!(e.line, Some(2));
    }
}
