//! The configuration turned into what the actors take: the GCS link's settings
//! ([`Config::gcs`]), the Zenoh session's ([`Config::bus`]), the engine parameters and the
//! [`Deployment`] ([`Config::deployment`]), and the guidance loop's settings.

use std::path::Path;

use harrier_engine::{Deployment, Params};
use harrier_link::bus::{BusConfig, Mode, TlsConfig};

use super::error::ConfigError;
use super::file::Config;

impl Config {
    /// The MAVLink link's settings, or `None` when `mavlink.gcs` is empty. `session` names the
    /// default `.tlog` beside the recording.
    pub fn gcs(&self, session: Option<i64>) -> Result<Option<crate::gcs::GcsConfig>, ConfigError> {
        let m = &self.mavlink;
        if m.gcs.is_empty() {
            return Ok(None);
        }
        let parse = |v: &[String]| {
            v.iter()
                .map(|e| harrier_link::frame::Endpoint::parse(e))
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| ConfigError::Invalid(format!("mavlink: {e}")))
        };
        let tlog = if !m.tlog.is_empty() {
            Some(std::path::PathBuf::from(&m.tlog))
        } else if let (false, Some(id)) = (self.recorder.path.is_empty(), session) {
            let p = Path::new(&self.recorder.path);
            let stem = p
                .file_stem()
                .map_or_else(|| "harrier".into(), |s| s.to_string_lossy());
            Some(p.with_file_name(format!("{stem}-session-{id}.tlog")))
        } else {
            None
        };
        Ok(Some(crate::gcs::GcsConfig {
            gcs: parse(&m.gcs)?,
            router: parse(&m.router)?,
            system_id: m.system_id,
            component_id: m.component_id,
            lost_after: std::time::Duration::from_secs_f64(m.lost_after_s),
            command_timeout: std::time::Duration::from_millis(m.command_timeout_ms),
            command_attempts: m.command_attempts,
            frame: harrier_link::geo::LocalFrame::new(self.frame.origin),
            tlog,
            signing: m.signing.resolve()?,
            router_heartbeat: m.router_heartbeat,
            router_filters: m.router_filters()?,
        }))
    }

    /// The Zenoh session configuration.
    pub fn bus(&self) -> Result<BusConfig, ConfigError> {
        let z = &self.zenoh;
        let mode: Mode = z.mode.parse().map_err(ConfigError::Invalid)?;
        let path = |p: &String| (!p.is_empty()).then(|| p.clone());
        if z.enable_mtls
            && z.connect.iter().any(|e| e.starts_with("tls/"))
            && (z.connect_certificate.is_empty() || z.connect_private_key.is_empty())
        {
            return Err(ConfigError::Invalid(
                "zenoh.enable_mtls with a tls/ connect endpoint needs zenoh.connect_certificate \
                 and zenoh.connect_private_key"
                    .into(),
            ));
        }
        Ok(BusConfig {
            mode,
            connect: z.connect.clone(),
            listen: z.listen.clone(),
            multicast_scouting: z.multicast_scouting,
            tls: TlsConfig {
                root_ca_certificate: path(&z.root_ca_certificate),
                listen_certificate: path(&z.listen_certificate),
                listen_private_key: path(&z.listen_private_key),
                connect_certificate: path(&z.connect_certificate),
                connect_private_key: path(&z.connect_private_key),
                enable_mtls: z.enable_mtls,
            },
        })
    }

    /// The engine parameters.
    pub fn params(&self) -> Params {
        Params::from(&self.tracker.params)
    }

    /// The deployment: planar targets on the ground plane `frame.plane_z`, the motion models,
    /// roads and scan period of `[tracker]`, one sensor (scans bring their own models), the
    /// registered sensors of `[registration]`.
    pub fn deployment(&self) -> Deployment {
        let t = &self.tracker;
        Deployment {
            dims: 2,
            plane_z: self.frame.plane_z,
            motion: Some(t.motion.clone()),
            roads: t.roads.clone(),
            scan_period_s: t.scan_period_s,
            sensors: 1,
            detection: None,
            sensor_pd: t.pd.clone(),
            // Checked by `Config::check` (a configuration built in code with a bad block runs
            // without registration).
            registration: self.registration.registered().unwrap_or_default(),
        }
    }
}

impl From<&Config> for crate::guidance::GuidanceSettings {
    /// The guidance loop's settings (`[guidance]`): the multirotor envelope, the fixed wing's from
    /// its airspeed band and bank limit (climbing 5 m/s), the obstacles as discs, and the
    /// server's frame.
    fn from(c: &Config) -> Self {
        use harrier_core::guidance::{Limits, obstacle::Obstacle};
        let g = &c.guidance;
        let [v_min, v_max] = g.fixed_wing_speed_m_s;
        Self {
            rate_hz: g.rate_hz,
            multirotor: Limits::multirotor(),
            fixed_wing: Limits::bank_limited(v_min, v_max, g.fixed_wing_bank_deg.to_radians(), 5.0),
            speed: g.speed_m_s,
            takeoff_height: g.takeoff_height_m,
            obstacles: g
                .obstacles
                .iter()
                .map(|o| Obstacle {
                    center: nalgebra::Vector2::new(o.x_m, o.y_m),
                    radius: o.radius_m,
                })
                .collect(),
            frame: harrier_link::geo::LocalFrame::new(c.frame.origin),
        }
    }
}
