//! The battery and the autopilots' low-battery failsafes.
//!
//! The charge drains while armed at [`VehicleConfig::battery_drain_pct_min`] (percent per
//! simulated minute); the voltage is a 4S pack's, 16.8 V full to 14.8 V empty, and the
//! consumption (mAh) the charge used of the capacity (ArduPilot BATT_CAPACITY; 5000 mAh for
//! PX4's BATTERY_STATUS).
//!
//! - **PX4** (`battery_status` warnings and the commander's failsafe): the remaining charge at or
//!   below BAT_LOW_THR (0.15) is *low*, BAT_CRIT_THR (0.07) *critical*, BAT_EMERGEN_THR (0.05)
//!   *emergency*. COM_LOW_BAT_ACT says what a level does when it is reached: 0 warning only
//!   (the default), 2 Land at critical, 3 Return (AUTO.RTL) at critical and Land at emergency.
//!   Each level acts once, when the charge falls to it, and only in the air.
//! - **ArduPilot** (`AP_BattMonitor`): *low* when the voltage is below BATT_LOW_VOLT (ArduCopter
//!   10.5 V, ArduPlane 0: off) or the remaining capacity below BATT_LOW_MAH (0: off), *critical*
//!   likewise with BATT_CRT_VOLT / BATT_CRT_MAH; the action of each is BATT_FS_LOW_ACT /
//!   BATT_FS_CRT_ACT (default 0: none). ArduCopter: 1 LAND, 2 RTL, 3 SMART_RTL, 4 SMART_RTL, 6
//!   RTL, 7 LAND (BRAKE-or-LAND); ArduPlane: 1 RTL, 2 RTL (its LAND without a landing sequence
//!   returns). Terminate (5 on Copter, 3 on Plane) and the QuadPlane actions are not simulated.
//!   The voltage is not filtered and BATT_LOW_TIMER's 10 s wait is not modelled: a level acts
//!   at once.
//!
//! While a failsafe has acted (PX4) or a battery failsafe is in force (ArduPilot:
//! `any_failsafe_triggered`), the armed vehicle's HEARTBEAT `system_status` is
//! `MAV_STATE_CRITICAL`; disarming clears it.

use harrier_link::autopilot::{Autopilot, Mode};
use harrier_link::px4::FlightMode;

use super::{Vehicle, VehicleConfig};

/// A battery warning level, in increasing severity.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord)]
pub enum BatteryLevel {
    /// Above every threshold.
    #[default]
    Normal,
    /// PX4 BAT_LOW_THR, ArduPilot BATT_LOW_*.
    Low,
    /// PX4 BAT_CRIT_THR, ArduPilot BATT_CRT_*.
    Critical,
    /// PX4 BAT_EMERGEN_THR.
    Emergency,
}

/// What the failsafe has seen and done.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct BatteryState {
    /// The highest level reached (and acted on) since arming.
    level: BatteryLevel,
    /// A failsafe is in force: the HEARTBEAT says CRITICAL while armed.
    failsafe: bool,
}

impl Vehicle {
    /// Remaining battery charge (0–1).
    pub fn battery_remaining(&self) -> f64 {
        self.battery
    }

    /// Sets the remaining battery charge (clamped to 0–1; a test's or an operator's shortcut to
    /// a drained battery); the failsafe acts on the next step.
    pub fn set_battery(&mut self, fraction: f64) {
        if fraction.is_finite() {
            self.battery = fraction.clamp(0.0, 1.0);
        }
    }

    /// The battery warning level (see the module documentation).
    pub fn battery_level(&self) -> BatteryLevel {
        match self.personality.autopilot {
            Autopilot::Px4 => {
                let r = self.battery;
                if r <= self.param_f64("BAT_EMERGEN_THR", 0.05) {
                    BatteryLevel::Emergency
                } else if r <= self.param_f64("BAT_CRIT_THR", 0.07) {
                    BatteryLevel::Critical
                } else if r <= self.param_f64("BAT_LOW_THR", 0.15) {
                    BatteryLevel::Low
                } else {
                    BatteryLevel::Normal
                }
            }
            Autopilot::ArduPilot => {
                let below = |volt: &str, mah: &str| {
                    let (v, m) = (self.param_f64(volt, 0.0), self.param_f64(mah, 0.0));
                    (v > 0.0 && self.voltage() < v) || (m > 0.0 && self.remaining_mah() < m)
                };
                if below("BATT_CRT_VOLT", "BATT_CRT_MAH") {
                    BatteryLevel::Critical
                } else if below("BATT_LOW_VOLT", "BATT_LOW_MAH") {
                    BatteryLevel::Low
                } else {
                    BatteryLevel::Normal
                }
            }
        }
    }

    /// Whether a battery failsafe is in force (HEARTBEAT `MAV_STATE_CRITICAL` while armed).
    pub fn battery_failsafe(&self) -> bool {
        self.armed && self.battery_state.failsafe
    }

    /// Pack voltage (V): 16.8 full, 14.8 empty.
    pub(super) fn voltage(&self) -> f64 {
        14.8 + 2.0 * self.battery
    }

    /// Capacity (mAh): ArduPilot BATT_CAPACITY, else 5000.
    pub(super) fn capacity_mah(&self) -> f64 {
        self.param_f64("BATT_CAPACITY", 5000.0)
    }

    /// Remaining capacity (mAh).
    fn remaining_mah(&self) -> f64 {
        self.battery * self.capacity_mah()
    }

    /// Drains the battery over `dt` simulated seconds (armed) and runs the failsafe.
    pub(super) fn battery_step(&mut self, dt: f64) {
        if !self.armed {
            self.battery_state = BatteryState::default();
            return;
        }
        let per_s = self.config.battery_drain_pct_min / 6000.0;
        self.battery = (self.battery - dt * per_s).max(0.0);
        let level = self.battery_level();
        if level <= self.battery_state.level {
            return;
        }
        self.battery_state.level = level;
        let action = match self.personality.autopilot {
            Autopilot::Px4 => self.px4_battery_action(level),
            Autopilot::ArduPilot => {
                // `AP_BattMonitor::has_failsafed`: in force whatever the action.
                self.battery_state.failsafe = true;
                self.ardupilot_battery_action(level)
            }
        };
        if let Some(mode) = action {
            let airborne = !self.on_ground() || self.taking_off;
            if airborne && mode != self.mode {
                self.battery_state.failsafe = true;
                self.set_mode(self.last_advance, mode);
            }
        }
    }

    /// PX4's COM_LOW_BAT_ACT at `level`.
    fn px4_battery_action(&self, level: BatteryLevel) -> Option<Mode> {
        let act = self.param_f64("COM_LOW_BAT_ACT", 0.0) as i32;
        match (act, level) {
            (2, BatteryLevel::Critical | BatteryLevel::Emergency)
            | (3, BatteryLevel::Emergency) => Some(Mode::Px4(FlightMode::Land)),
            (3, BatteryLevel::Critical) => Some(Mode::Px4(FlightMode::Rtl)),
            _ => None,
        }
    }

    /// ArduPilot's BATT_FS_LOW_ACT / BATT_FS_CRT_ACT at `level`.
    fn ardupilot_battery_action(&self, level: BatteryLevel) -> Option<Mode> {
        let name = match level {
            BatteryLevel::Low => "BATT_FS_LOW_ACT",
            _ => "BATT_FS_CRT_ACT",
        };
        let act = self.param_f64(name, 0.0) as i32;
        let mode = if self.is_plane() {
            match act {
                1 | 2 => "RTL",
                _ => return None,
            }
        } else {
            match act {
                1 | 7 => "LAND",
                2 | 6 => "RTL",
                3 | 4 => "SMART_RTL",
                _ => return None,
            }
        };
        self.personality.mode_named(mode)
    }
}

impl VehicleConfig {
    /// This configuration with a battery draining `pct_per_min` percent per simulated minute.
    pub fn with_battery_drain(self, pct_per_min: f64) -> Self {
        Self {
            battery_drain_pct_min: pct_per_min,
            ..self
        }
    }
}
