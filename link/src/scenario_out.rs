//! Writing `gcs-scenario/1` directories from detection scans: what harrier-sim's `record` and the
//! server's session export (`harrier sessions export`) share, so that a simulated recording and a
//! recorded live session come out the same way — sensor and platform ids, measurement lines,
//! truth rows, and the atomic write of the directory.
//!
//! Everything here is pure formatting except [`write_dir`], which writes files.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use harrier_core::scenario::{Measurement, PlatformPose};

use crate::detections::FrameScan;

/// Header of a single-target `truth.csv` (FORMAT.md §4).
pub const TRUTH_HEADER: &str = "t,x,y,z,vx,vy,vz,mode\n";
/// Header of a multi-target `truth.csv` (FORMAT-MULTI.md §3).
pub const MULTI_TRUTH_HEADER: &str = "t,target,x,y,z,vx,vy,vz,mode\n";

/// Scenario sensor id of sensor `sensor` of vehicle `vehicle`: `cam` of vehicle 1 is `cam1`.
pub fn sensor_id(sensor: &str, vehicle: u8) -> String {
    format!("{sensor}{vehicle}")
}

/// Scenario platform id of vehicle `vehicle`: `uav1`.
pub fn platform_id(vehicle: u8) -> String {
    format!("uav{vehicle}")
}

/// The measurement line (FORMAT.md §3) of detection `z` of `scan` (a scan already in the
/// scenario's frame), at scenario time `t`, for the scenario sensor `sensor`.
pub fn measurement(scan: &FrameScan, t: f64, sensor: &str, z: Vec<f64>) -> Measurement {
    Measurement {
        t,
        sensor: sensor.to_owned(),
        kind: scan.kind,
        platform: PlatformPose {
            pos: scan.platform_pos.into(),
            vel: scan.platform_vel.into(),
        },
        z,
    }
}

/// Appends one `truth.csv` row: `t,x,y,z,vx,vy,vz,mode` (FORMAT.md §4), or with `target` the
/// multi-target row `t,target,x,…` (FORMAT-MULTI.md §3); numbers with 6 decimals.
pub fn push_truth_row(out: &mut String, t: f64, target: Option<&str>, s: &[f64; 6], mode: &str) {
    let id = target.map(|id| format!("{id},")).unwrap_or_default();
    // Writing to a String cannot fail.
    let _ = writeln!(
        out,
        "{t:.6},{id}{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{mode}",
        s[0], s[1], s[2], s[3], s[4], s[5]
    );
}

/// A scenario directory that could not be written.
#[derive(Debug, thiserror::Error)]
#[error("writing {}: {source}", path.display())]
pub struct WriteError {
    /// The directory or file.
    pub path: PathBuf,
    /// Why.
    pub source: std::io::Error,
}

/// Writes `files` (name, contents) into the directory `out` atomically: they go to a temporary
/// directory beside it (each file synced), which is then renamed to `out`. `out` must not exist
/// or be an empty directory; its parents are created. On failure nothing is left behind.
pub fn write_dir(out: &Path, files: &[(&str, &str)]) -> Result<(), WriteError> {
    let werr = |path: &Path| {
        let path = path.to_path_buf();
        move |source| WriteError { path, source }
    };
    if out.exists() {
        let empty = out.is_dir() && std::fs::read_dir(out).map_err(werr(out))?.next().is_none();
        if !empty {
            return Err(WriteError {
                path: out.to_path_buf(),
                source: std::io::Error::new(
                    std::io::ErrorKind::AlreadyExists,
                    "already exists and is not an empty directory",
                ),
            });
        }
    }
    let parent = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(werr(parent))?;
    let name = out
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scenario".into());
    let tmp = parent.join(format!(".{name}.tmp-{}", std::process::id()));
    let result = (|| {
        if tmp.exists() {
            std::fs::remove_dir_all(&tmp)?;
        }
        std::fs::create_dir(&tmp)?;
        for (file, text) in files {
            let mut f = std::fs::File::create(tmp.join(file))?;
            f.write_all(text.as_bytes())?;
            f.sync_all()?;
        }
        if out.exists() {
            std::fs::remove_dir(out)?;
        }
        std::fs::rename(&tmp, out)
    })();
    if result.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    result.map_err(werr(out))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truth_rows_have_six_decimals_and_the_optional_target() {
        let mut s = String::from(TRUTH_HEADER);
        push_truth_row(&mut s, 1.5, None, &[1.0, 2.0, 0.0, 0.5, -0.25, 0.0], "CV");
        push_truth_row(&mut s, 2.0, Some("T1"), &[0.0; 6], "");
        assert_eq!(
            s,
            "t,x,y,z,vx,vy,vz,mode\n1.500000,1.000000,2.000000,0.000000,0.500000,-0.250000,\
             0.000000,CV\n2.000000,T1,0.000000,0.000000,0.000000,0.000000,0.000000,0.000000,\n"
        );
        assert_eq!(
            (sensor_id("cam", 2), platform_id(2)),
            ("cam2".into(), "uav2".into())
        );
    }

    #[test]
    fn a_directory_is_written_whole_or_not_at_all() {
        let dir = std::env::temp_dir().join(format!("harrier-scenario-out-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("full")).expect("mkdir");
        std::fs::write(dir.join("full/x"), "x").expect("write");
        let e = write_dir(&dir.join("full"), &[("a", "1")]).expect_err("not empty");
        assert!(e.to_string().contains("full"), "{e}");
        write_dir(&dir.join("new/run"), &[("a", "1"), ("b", "2")]).expect("write");
        assert_eq!(
            std::fs::read_to_string(dir.join("new/run/b")).expect("b"),
            "2"
        );
        assert_eq!(std::fs::read_dir(dir.join("new")).expect("dir").count(), 1);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
