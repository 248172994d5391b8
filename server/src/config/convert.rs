//! The configuration turned into what the lower crates take: the Zenoh session's
//! ([`Config::bus`]), the engine parameters and the [`Deployment`] ([`Config::deployment`]). The
//! actors read their own sections (`GcsConfig::from_config`, `GuidanceSettings::from`): the
//! configuration imports no actor.

use harrier_engine::{Deployment, Params};
use harrier_link::bus::{BusConfig, Mode, TlsConfig};

use super::error::ConfigError;
use super::file::Config;

impl Config {
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
            // Checked by `Config::check` (a configuration built in code with a bad block runs
            // without registration).
            registration: self.registration.registered().unwrap_or_default(),
        }
    }
}
