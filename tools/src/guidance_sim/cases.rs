//! The built-in cases of `harrier guidance-sim`: their names, durations, geometry and the vehicles'
//! starting points.

use harrier_core::guidance::obstacle::Obstacle;
use nalgebra::{Vector2, Vector3};

use super::error::SimError;

/// A built-in scenario.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Case {
    /// \[CIMM\] §5.2 static target, one UAV.
    CimmStatic,
    /// \[CIMM\] §5.1 moving target, one UAV.
    CimmMoving,
    /// Three UAVs on the static target.
    ThreeStatic,
    /// Three UAVs on the moving target.
    ThreeMoving,
    /// \[BOT\] leader + 3 followers with four obstacles.
    BotFormation,
    /// \[BOT\] bearings-only follower, with and without the observability maneuver.
    BotObservability,
}

impl Case {
    /// Every case with its command-line name.
    pub const ALL: [(&'static str, Case); 6] = [
        ("cimm-static", Case::CimmStatic),
        ("cimm-moving", Case::CimmMoving),
        ("three-static", Case::ThreeStatic),
        ("three-moving", Case::ThreeMoving),
        ("bot-formation", Case::BotFormation),
        ("bot-observability", Case::BotObservability),
    ];
    /// The case called `name`.
    pub fn parse(name: &str) -> Result<Self, SimError> {
        Self::ALL
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, c)| *c)
            .ok_or_else(|| {
                let names: Vec<_> = Self::ALL.iter().map(|(n, _)| *n).collect();
                SimError::Setup(format!(
                    "unknown case {name:?}; one of {}",
                    names.join(", ")
                ))
            })
    }
    /// Command-line name.
    pub fn name(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(_, c)| *c == self)
            .map_or("?", |(n, _)| n)
    }
    /// Default duration (s).
    pub fn default_duration(self) -> f64 {
        match self {
            Case::CimmStatic => 200.0,
            Case::ThreeStatic => 400.0,
            Case::CimmMoving | Case::ThreeMoving => 700.0,
            Case::BotFormation => 420.0,
            Case::BotObservability => 300.0,
        }
    }
    /// Whether the target moves (the \[CIMM\] §5.1 road target).
    pub fn moving(self) -> bool {
        matches!(self, Case::CimmMoving | Case::ThreeMoving)
    }
    /// Start positions of the UAVs of a standoff case.
    pub fn standoff_starts(self) -> Vec<Vector3<f64>> {
        match self {
            Case::CimmStatic => vec![Vector3::from(STATIC_START)],
            Case::ThreeStatic => vec![
                Vector3::from(STATIC_START),
                Vector3::new(2300.0, 1300.0, 350.0),
                Vector3::new(900.0, 2500.0, 450.0),
            ],
            Case::CimmMoving => vec![Vector3::new(-500.0, -500.0, 400.0)],
            _ => vec![
                Vector3::new(-500.0, -500.0, 400.0),
                Vector3::new(800.0, -300.0, 350.0),
                Vector3::new(-300.0, 1100.0, 450.0),
            ],
        }
    }
}

/// Standoff radius and height of the \[CIMM\] cases (m).
pub const R: f64 = 300.0;
/// Observation height (m).
pub const H: f64 = 300.0;
/// Nominal relative speed v₀ (m/s).
pub const V0: f64 = 25.0;
/// Static target of \[CIMM\] §5.2.
pub const STATIC_TARGET: [f64; 3] = [1500.0, 1800.0, 0.0];
/// UAV start of \[CIMM\] §5.2.
pub const STATIC_START: [f64; 3] = [1100.0, 1000.0, 400.0];

/// The four obstacles of the formation case.
pub fn formation_obstacles() -> Vec<Obstacle> {
    [
        (Vector2::new(-60.0, 900.0), 80.0),
        (Vector2::new(420.0, 1900.0), 90.0),
        (Vector2::new(-350.0, 2700.0), 70.0),
        (Vector2::new(250.0, 3600.0), 100.0),
    ]
    .into_iter()
    .map(|(center, radius)| Obstacle { center, radius })
    .collect()
}

/// Formation shape: follower offsets from the leader (m); ranges between all pairs are regulated.
pub(super) const SHAPE: [[f64; 2]; 4] =
    [[0.0, 0.0], [-100.0, -80.0], [100.0, -80.0], [0.0, -180.0]];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn case_names_round_trip() {
        for (n, c) in Case::ALL {
            assert_eq!(Case::parse(n).unwrap(), c);
            assert_eq!(c.name(), n);
        }
        assert!(Case::parse("nope").is_err());
    }
}
