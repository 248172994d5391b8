//! Point-mass flight: harrier-core's guidance kinematics with the airframe's limits, what each
//! mode commands, ground contact, and the fall-back to Hold when offboard setpoints stop.

use harrier_core::guidance::Command;
use harrier_core::guidance::kinematics::step;
use harrier_link::command::Setpoint;
use nalgebra::{Vector2, Vector3};

use super::{CLIMB_SPEED, FW_CRUISE, FW_ORBIT_RADIUS, FlightMode, MAX_STEP, POS_GAIN, Vehicle};

impl Vehicle {
    /// Advances the flight to wall time `now` (simulated time runs `speedup` times faster).
    pub fn advance(&mut self, now: f64) {
        let wall_dt = now - self.last_advance;
        if !wall_dt.is_finite() || wall_dt <= 0.0 {
            return;
        }
        self.last_advance = now;
        // Offboard loss: back to Hold when setpoints stop (wall time, as a client streams them).
        if self.mode == FlightMode::Offboard && !self.setpoints_fresh(now) {
            self.setpoint = None;
            self.set_mode(FlightMode::Hold);
        }
        let mut remaining = (wall_dt * self.config.speedup).min(10.0);
        while remaining > 1e-9 {
            let dt = remaining.min(MAX_STEP);
            self.physics_step(dt);
            remaining -= dt;
        }
    }

    fn hold_command(&self, target: Vector3<f64>) -> Vector3<f64> {
        let err = target - self.state.position;
        if self.limits.can_hover() {
            err * POS_GAIN
        } else {
            // Fixed wing: orbit the target point at the cruise speed.
            let r = Vector2::new(-err.x, -err.y);
            let d = r.norm().max(1e-6);
            let radial = r / d;
            let tangent = Vector2::new(-radial.y, radial.x);
            let v = tangent * FW_CRUISE - radial * ((d - FW_ORBIT_RADIUS) * 0.1).clamp(-8.0, 8.0);
            Vector3::new(v.x, v.y, err.z * POS_GAIN)
        }
    }

    fn physics_step(&mut self, dt: f64) {
        self.sim_time += dt;
        if self.armed {
            self.battery = (self.battery - dt / 1800.0).max(0.0);
        }
        if !self.armed {
            self.state.velocity = Vector3::zeros();
            self.accel = Vector3::zeros();
            return;
        }
        let grounded = self.on_ground();
        let cmd = match self.mode {
            FlightMode::Takeoff => {
                let mut c = self.hold_command(Vector3::new(
                    self.hold_point.x,
                    self.hold_point.y,
                    self.takeoff_alt,
                ));
                c.z = ((self.takeoff_alt - self.state.position.z) * POS_GAIN * 2.0)
                    .clamp(-CLIMB_SPEED, CLIMB_SPEED);
                if grounded {
                    c.x = 0.0;
                    c.y = 0.0;
                }
                c
            }
            FlightMode::Land => {
                let mut c = self.hold_command(self.hold_point);
                c.z = -f64::from(self.param("MPC_LAND_SPEED").unwrap_or(0.7));
                c
            }
            FlightMode::Hold | FlightMode::Position => self.hold_command(self.hold_point),
            FlightMode::Offboard => match self.setpoint {
                Some(Setpoint::Velocity(v)) => v,
                Some(Setpoint::Position(p)) => self.hold_command(p),
                None => self.hold_command(self.hold_point),
            },
        };
        if grounded && cmd.z <= 0.0 {
            // Sitting on the ground: nothing moves until a climb is commanded.
            self.state.position.z = 0.0;
            self.state.velocity = Vector3::zeros();
            self.accel = Vector3::zeros();
            if self.mode == FlightMode::Land {
                self.armed = false;
                self.set_mode(FlightMode::Hold);
            }
            return;
        }
        let mut limits = self.limits;
        if grounded {
            // A fixed wing leaves the ground like a multirotor (catapult launch).
            limits.v_min = 0.0;
        }
        let prev = self.state;
        let mut next = step(&prev, &Command { velocity: cmd }, &limits, dt);
        if next.position.z < 0.0 {
            next.position.z = 0.0;
            next.velocity.z = next.velocity.z.max(0.0);
        }
        self.accel = (next.velocity - prev.velocity) / dt;
        let vh = next.horizontal_velocity();
        if vh.norm() > 0.3 {
            // NED yaw: clockwise from north.
            self.yaw = vh.x.atan2(vh.y);
        }
        self.state = next;
        if self.mode == FlightMode::Takeoff && self.state.position.z >= self.takeoff_alt - 0.1 {
            self.set_mode(FlightMode::Hold);
        }
    }
}
