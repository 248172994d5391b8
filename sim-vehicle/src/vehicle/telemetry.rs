//! Telemetry: the streamed messages, their intervals (SET_MESSAGE_INTERVAL, and ArduPilot's
//! REQUEST_DATA_STREAM) and the current value of any message the vehicle can send
//! (REQUEST_MESSAGE; also GIMBAL_MANAGER_INFORMATION: the autopilot is the gimbal manager of
//! its camera's gimbal).

use harrier_link::autopilot::{Autopilot, ardupilot_base_mode};
use harrier_link::geo::enu_to_ned;
use harrier_link::px4::base_mode;
use mavlink::MessageData;
use mavlink::dialects::common::{
    ATTITUDE_DATA, AUTOPILOT_VERSION_DATA, BATTERY_STATUS_DATA, EXTENDED_SYS_STATE_DATA,
    GIMBAL_MANAGER_INFORMATION_DATA, GLOBAL_POSITION_INT_DATA, GPS_RAW_INT_DATA,
    GimbalManagerCapFlags, GpsFixType, HEARTBEAT_DATA, HOME_POSITION_DATA, LOCAL_POSITION_NED_DATA,
    MISSION_CURRENT_DATA, MavBatteryFunction, MavBatteryType, MavMessage, MavProtocolCapability,
    MavResult, MavState, MavSysStatusSensor, MavVtolState, SYS_STATUS_DATA, VFR_HUD_DATA,
};

use super::modes::Behaviour;
use super::tables::data_stream;
use super::wire::Outgoing;
use super::{GIMBAL_DEVICE_ID, Vehicle};

impl Vehicle {
    pub(super) fn set_message_interval(
        &mut self,
        now: f64,
        id: f32,
        interval_us: f32,
    ) -> MavResult {
        if !(id.is_finite() && interval_us.is_finite() && id >= 0.0) {
            return MavResult::MAV_RESULT_DENIED;
        }
        let Some(s) = self.streams.iter_mut().find(|s| s.id == id as u32) else {
            return MavResult::MAV_RESULT_DENIED;
        };
        s.interval = if interval_us == -1.0 {
            None
        } else if interval_us == 0.0 {
            Some(s.default_interval)
        } else if interval_us >= 1_000.0 {
            Some(f64::from(interval_us) * 1e-6)
        } else {
            return MavResult::MAV_RESULT_DENIED;
        };
        s.next_due = now;
        MavResult::MAV_RESULT_ACCEPTED
    }

    /// ArduPilot's REQUEST_DATA_STREAM: the messages of stream `req_stream_id` at
    /// `req_message_rate` Hz, or off (`start_stop` 0, or rate 0). PX4 does not implement it.
    #[allow(deprecated)]
    pub(super) fn request_data_stream(
        &mut self,
        now: f64,
        r: &mavlink::dialects::common::REQUEST_DATA_STREAM_DATA,
    ) {
        if self.personality.autopilot != Autopilot::ArduPilot {
            return;
        }
        let interval = (r.start_stop != 0 && r.req_message_rate > 0)
            .then(|| 1.0 / f64::from(r.req_message_rate));
        let ids = data_stream(r.req_stream_id as u8);
        for s in self.streams.iter_mut().filter(|s| ids.contains(&s.id)) {
            s.interval = interval;
            s.next_due = now;
        }
    }

    /// Stream interval of a message id (s), `None` when disabled or not streamed.
    pub fn stream_interval(&self, id: u32) -> Option<f64> {
        self.streams
            .iter()
            .find(|s| s.id == id)
            .and_then(|s| s.interval)
    }

    /// Telemetry due at wall time `now` (advances the flight first), without components and
    /// extension fields.
    pub fn telemetry(&mut self, now: f64) -> Vec<MavMessage> {
        self.telemetry_frames(now)
            .into_iter()
            .map(|o| o.message)
            .collect()
    }

    /// Telemetry due at wall time `now` (advances the flight first): the streams, the mission
    /// protocol's retries and what happened since the last pass (MISSION_ITEM_REACHED, …).
    pub fn telemetry_frames(&mut self, now: f64) -> Vec<Outgoing> {
        self.advance(now);
        let mut out = std::mem::take(&mut self.outbox);
        out.extend(self.mission_tick(now));
        let mut due = Vec::new();
        for s in &mut self.streams {
            if let Some(iv) = s.interval {
                if now >= s.next_due {
                    due.push(s.id);
                    // Keep the cadence, but never burst after a stall.
                    s.next_due = (s.next_due + iv).max(now);
                }
            }
        }
        out.extend(
            due.into_iter()
                .filter_map(|id| self.message(id))
                .map(Outgoing::from),
        );
        out
    }

    fn time_boot_ms(&self) -> u32 {
        (self.sim_time * 1000.0) as u32
    }

    /// The current value of a message the vehicle can send, by id.
    pub fn message(&self, id: u32) -> Option<MavMessage> {
        let ned = enu_to_ned(&self.state.position);
        let vned = enu_to_ned(&self.state.velocity);
        let g = self.position();
        let home = self.config.origin;
        let deg7 = |d: f64| (d * 1e7).round() as i32;
        let mm = |m: f64| (m * 1000.0).round() as i32;
        let cms = |v: f64| (v * 100.0).round().clamp(-32768.0, 32767.0) as i16;
        let hdg_cdeg = (self.yaw.to_degrees().rem_euclid(360.0) * 100.0) as u16 % 36000;
        Some(match id {
            HEARTBEAT_DATA::ID => MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                custom_mode: self.mode.custom_mode(),
                mavtype: self.personality.frame.mav_type(),
                autopilot: self.personality.mav_autopilot(),
                base_mode: match self.personality.autopilot {
                    Autopilot::Px4 => base_mode(self.armed),
                    Autopilot::ArduPilot => {
                        let position_control = !matches!(self.behaviour(), Behaviour::Pilot);
                        ardupilot_base_mode(self.armed, position_control)
                    }
                },
                system_status: if self.battery_failsafe() {
                    // PX4: armed with a failsafe in force; ArduPilot: `any_failsafe_triggered`.
                    MavState::MAV_STATE_CRITICAL
                } else if match self.personality.autopilot {
                    Autopilot::Px4 => self.armed,
                    // ArduPilot: STANDBY while landed (`land_complete`), armed or not.
                    Autopilot::ArduPilot => self.armed && (self.taking_off || !self.on_ground()),
                } {
                    MavState::MAV_STATE_ACTIVE
                } else {
                    MavState::MAV_STATE_STANDBY
                },
                mavlink_version: 3,
            }),
            GIMBAL_MANAGER_INFORMATION_DATA::ID => {
                use GimbalManagerCapFlags as F;
                MavMessage::GIMBAL_MANAGER_INFORMATION(GIMBAL_MANAGER_INFORMATION_DATA {
                    time_boot_ms: self.time_boot_ms(),
                    cap_flags: F::GIMBAL_MANAGER_CAP_FLAGS_HAS_PITCH_AXIS
                        | F::GIMBAL_MANAGER_CAP_FLAGS_HAS_YAW_AXIS
                        | F::GIMBAL_MANAGER_CAP_FLAGS_HAS_YAW_LOCK
                        | F::GIMBAL_MANAGER_CAP_FLAGS_CAN_POINT_LOCATION_GLOBAL,
                    roll_min: 0.0,
                    roll_max: 0.0,
                    pitch_min: -std::f32::consts::FRAC_PI_2,
                    pitch_max: 0.0,
                    yaw_min: -std::f32::consts::PI,
                    yaw_max: std::f32::consts::PI,
                    gimbal_device_id: GIMBAL_DEVICE_ID,
                })
            }
            VFR_HUD_DATA::ID => {
                let speed = self.state.horizontal_velocity().norm() as f32;
                MavMessage::VFR_HUD(VFR_HUD_DATA {
                    airspeed: speed,
                    groundspeed: speed,
                    alt: g.alt_m as f32,
                    climb: self.state.velocity.z as f32,
                    heading: (hdg_cdeg / 100) as i16,
                    throttle: if self.armed { 50 } else { 0 },
                })
            }
            GLOBAL_POSITION_INT_DATA::ID => {
                MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
                    time_boot_ms: self.time_boot_ms(),
                    lat: deg7(g.lat_deg),
                    lon: deg7(g.lon_deg),
                    alt: mm(g.alt_m),
                    relative_alt: mm(self.state.position.z),
                    vx: cms(vned.x),
                    vy: cms(vned.y),
                    vz: cms(vned.z),
                    hdg: hdg_cdeg,
                })
            }
            LOCAL_POSITION_NED_DATA::ID => {
                MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
                    time_boot_ms: self.time_boot_ms(),
                    x: ned.x as f32,
                    y: ned.y as f32,
                    z: ned.z as f32,
                    vx: vned.x as f32,
                    vy: vned.y as f32,
                    vz: vned.z as f32,
                })
            }
            ATTITUDE_DATA::ID => {
                let [roll, pitch, yaw] = self.attitude();
                MavMessage::ATTITUDE(ATTITUDE_DATA {
                    time_boot_ms: self.time_boot_ms(),
                    roll: roll as f32,
                    pitch: pitch as f32,
                    yaw: yaw as f32,
                    rollspeed: 0.0,
                    pitchspeed: 0.0,
                    yawspeed: 0.0,
                })
            }
            SYS_STATUS_DATA::ID => {
                use MavSysStatusSensor as S;
                let sensors = S::MAV_SYS_STATUS_SENSOR_3D_GYRO
                    | S::MAV_SYS_STATUS_SENSOR_3D_ACCEL
                    | S::MAV_SYS_STATUS_SENSOR_3D_MAG
                    | S::MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
                    | S::MAV_SYS_STATUS_SENSOR_GPS
                    | S::MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
                    | S::MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
                    | S::MAV_SYS_STATUS_SENSOR_YAW_POSITION
                    | S::MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
                    | S::MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
                    | S::MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
                    | S::MAV_SYS_STATUS_AHRS
                    | S::MAV_SYS_STATUS_SENSOR_BATTERY
                    | S::MAV_SYS_STATUS_PREARM_CHECK;
                MavMessage::SYS_STATUS(SYS_STATUS_DATA {
                    onboard_control_sensors_present: sensors,
                    onboard_control_sensors_enabled: sensors,
                    onboard_control_sensors_health: sensors,
                    load: 100,
                    voltage_battery: self.voltage_mv(),
                    current_battery: if self.armed { 1000 } else { 50 },
                    drop_rate_comm: 0,
                    errors_comm: 0,
                    errors_count1: 0,
                    errors_count2: 0,
                    errors_count3: 0,
                    errors_count4: 0,
                    battery_remaining: self.battery_percent(),
                })
            }
            EXTENDED_SYS_STATE_DATA::ID => {
                MavMessage::EXTENDED_SYS_STATE(EXTENDED_SYS_STATE_DATA {
                    vtol_state: MavVtolState::MAV_VTOL_STATE_UNDEFINED,
                    landed_state: self.landed_state(),
                })
            }
            GPS_RAW_INT_DATA::ID => MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
                time_usec: (self.sim_time * 1e6) as u64,
                lat: deg7(g.lat_deg),
                lon: deg7(g.lon_deg),
                alt: mm(g.alt_m),
                eph: 80,
                epv: 120,
                vel: (self.state.horizontal_velocity().norm() * 100.0).round() as u16,
                cog: hdg_cdeg,
                fix_type: GpsFixType::GPS_FIX_TYPE_3D_FIX,
                satellites_visible: 12,
            }),
            HOME_POSITION_DATA::ID => MavMessage::HOME_POSITION(HOME_POSITION_DATA {
                latitude: deg7(home.lat_deg),
                longitude: deg7(home.lon_deg),
                altitude: mm(home.alt_m),
                x: 0.0,
                y: 0.0,
                z: 0.0,
                q: [1.0, 0.0, 0.0, 0.0],
                approach_x: 0.0,
                approach_y: 0.0,
                approach_z: 0.0,
            }),
            BATTERY_STATUS_DATA::ID => {
                let mut voltages = [u16::MAX; 10];
                voltages[0] = self.voltage_mv();
                MavMessage::BATTERY_STATUS(BATTERY_STATUS_DATA {
                    current_consumed: ((1.0 - self.battery) * self.capacity_mah()) as i32,
                    energy_consumed: -1,
                    temperature: i16::MAX,
                    voltages,
                    current_battery: if self.armed { 1000 } else { 50 },
                    id: 0,
                    battery_function: MavBatteryFunction::MAV_BATTERY_FUNCTION_ALL,
                    mavtype: MavBatteryType::MAV_BATTERY_TYPE_LIPO,
                    battery_remaining: self.battery_percent(),
                })
            }
            MISSION_CURRENT_DATA::ID => self.mission_current(),
            AUTOPILOT_VERSION_DATA::ID => MavMessage::AUTOPILOT_VERSION(AUTOPILOT_VERSION_DATA {
                capabilities: self.capabilities(),
                uid: u64::from(self.config.id),
                // major << 24 | minor << 16 | patch << 8 | type (0xFF: official release): PX4
                // 1.15.0, ArduCopter 4.5.7, ArduPlane 4.5.7.
                flight_sw_version: match self.personality.autopilot {
                    Autopilot::Px4 => (1 << 24) | (15 << 16) | 0xFF,
                    Autopilot::ArduPilot => (4 << 24) | (5 << 16) | (7 << 8) | 0xFF,
                },
                middleware_sw_version: 0,
                os_sw_version: 0,
                board_version: 0,
                vendor_id: 0,
                product_id: 0,
                flight_custom_version: [0; 8],
                middleware_custom_version: [0; 8],
                os_custom_version: [0; 8],
            }),
            _ => return None,
        })
    }

    /// AUTOPILOT_VERSION's capabilities: both take the mission protocol with MISSION_ITEM_INT
    /// for missions, geofences and rally points, and COMMAND_INT; PX4 encodes parameters
    /// bytewise, ArduPilot C-cast and takes SET_POSITION_TARGET_GLOBAL_INT
    /// (`GCS_MAVLINK_Copter::capabilities`).
    fn capabilities(&self) -> MavProtocolCapability {
        use MavProtocolCapability as C;
        let common = C::MAV_PROTOCOL_CAPABILITY_MAVLINK2
            | C::MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
            | C::MAV_PROTOCOL_CAPABILITY_COMMAND_INT
            | C::MAV_PROTOCOL_CAPABILITY_MISSION_INT
            | C::MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
            | C::MAV_PROTOCOL_CAPABILITY_MISSION_RALLY;
        match self.personality.autopilot {
            Autopilot::Px4 => common | C::MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE,
            Autopilot::ArduPilot => {
                common
                    | C::MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST
                    | C::MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
            }
        }
    }

    fn battery_percent(&self) -> i8 {
        (self.battery * 100.0).round() as i8
    }

    fn voltage_mv(&self) -> u16 {
        (self.voltage() * 1000.0) as u16
    }
}
