//! One tick of the guidance loop: each active assignment flown on the latest snapshot and
//! vehicle states ([`Tick::fly`]), its decisions collected in [`Decisions`] for the actor to carry
//! out; [`Ring`], the phase neighbours of a standoff ring.

use super::*;

/// What a tick reads: the link's clock, the tracker's snapshot, the vehicles and the settings.
pub(super) struct Tick<'a> {
    /// Now on the link's clock (s since its epoch).
    pub(super) t: f64,
    /// Wall time since the snapshot changed (s).
    pub(super) since_snapshot: f64,
    pub(super) snapshot: &'a Snapshot,
    pub(super) vehicles: &'a [VehicleSample],
    pub(super) settings: &'a GuidanceSettings,
}

/// What a tick decided, done once every assignment has been flown ([`Actor::carry_out`]).
#[derive(Debug, Default)]
pub(super) struct Decisions {
    /// Assignments to end, with the reason.
    pub(super) end: Vec<(u64, String)>,
    /// Messages to the vehicles.
    pub(super) send: Vec<(u8, MavMessage)>,
    /// Vehicles to send to Hold.
    pub(super) hold: Vec<u8>,
    /// Assignments whose vehicles changed state.
    pub(super) changed: Vec<u64>,
    /// Vehicles taken out of their slots this tick, by who (for the counters).
    pub(super) overridden: Vec<OverrideSource>,
    /// Vehicles the safety envelope sends home (battery below the floor).
    pub(super) rtl: Vec<u8>,
    /// Setpoints the safety envelope clipped.
    pub(super) clipped: u64,
    /// Vehicles the safety envelope took out: found outside the fence (sent to Hold).
    pub(super) fenced_out: u64,
}

/// How long before a change of mode a router client's command to the vehicle is taken as its
/// cause (s).
const CLIENT_COMMAND_WINDOW_S: f64 = 5.0;

impl<'a> Tick<'a> {
    /// Flies assignment `a` for one tick: its track predicted to the tracker's time, then for
    /// each vehicle its link state, or its range and phase, its command from the formation or
    /// the law with phase coordination, and its offboard sequence advanced. Ends the assignment
    /// when its track is gone.
    pub(super) fn fly(&self, a: &mut Assignment, out: &mut Decisions) {
        let Some(track) = self.snapshot.tracks.iter().find(|k| k.id == a.track) else {
            out.end.push((a.id, format!("track {} deleted", a.track)));
            return;
        };
        // To the tracker's latest scan time: its time line may run ahead of the wall clock
        // (a simulator with a speed-up), so the wall clock is not used.
        let t_track = self.snapshot.t.unwrap_or(track.t);
        let target = predict(track, t_track);
        let law = a.law();
        let states = self.measured(&a.slots);
        let envelope = |i: usize| -> &Limits {
            let frame = states[i]
                .as_ref()
                .and_then(|(_, v)| v.status)
                .map_or(Frame::Multirotor, |s| s.personality.frame);
            self.settings.limits(frame)
        };
        // Where the safety envelope finds a vehicle outside the fence, once per tick.
        let outside: Vec<Option<String>> = states
            .iter()
            .map(|s| {
                s.as_ref()
                    .and_then(|(u, _)| self.settings.envelope.outside(&u.position))
            })
            .collect();
        let ring = Ring::of(&states, &target, &a.plan);
        let flying = a.flying();
        let formation = (a.plan.law == Law::Formation).then(|| {
            let uavs: Vec<Option<UavState>> =
                states.iter().map(|s| s.as_ref().map(|(u, _)| *u)).collect();
            a.formation.commands(
                &uavs,
                &target,
                &a.plan,
                t_track,
                &self.settings.multirotor,
                &self.settings.obstacles,
            )
        });
        // The spacing once every vehicle flying the ring is on it: 360° over them unless the
        // request gave one.
        let spacing = (ring.slots.len() == flying).then(|| a.plan.spacing_of(flying));
        for (i, slot) in a.slots.iter_mut().enumerate() {
            if slot.is_out() {
                continue;
            }
            let before = (slot.state, slot.error.clone());
            slot.error = None;
            match (&states[i], self.vehicle(slot.vehicle)) {
                (None, Some(v)) if v.view.state == LinkState::Lost => {
                    if slot.state != SlotState::Lost {
                        slot.lost_in = v.status.map(|s| s.mode);
                    }
                    slot.state = SlotState::Lost;
                    slot.sequence = None;
                }
                (None, Some(v)) if !v.confirmed => {
                    // A new identity: whatever the vehicle left in, this one starts afresh once
                    // accepted.
                    slot.state = SlotState::Waiting;
                    slot.sequence = None;
                    slot.lost_in = None;
                    slot.error = Some(format!(
                        "heard from a new address ({}): waits for the operator to accept it",
                        v.view.address
                    ));
                }
                (None, _) => {
                    if slot.state != SlotState::Lost {
                        slot.state = SlotState::Waiting;
                    }
                }
                (Some((_, v)), _)
                    if slot.state == SlotState::Lost
                        && slot
                            .lost_in
                            .take()
                            .is_some_and(|m| v.status.map(|s| s.mode) != Some(m)) =>
                {
                    // Back in another mode than it was lost in, not its guided one: its
                    // failsafe (or its pilot) acted meanwhile. Someone else's.
                    let o = Override {
                        from: None,
                        to: v.status.and_then(|s| s.mode),
                        disarmed: false,
                        at: v.status.map_or(self.t, |s| s.at),
                    };
                    out.take_out(a.id, slot, v, o, "changed mode while its link was lost");
                }
                (Some((_, v)), _) if self.settings.envelope.battery_low(v.view.battery_pct) => {
                    let why = format!(
                        "safety envelope: battery {:.0} % below the floor of {:.0} %: sent home \
                         (RTL)",
                        v.view.battery_pct.unwrap_or(0.0),
                        self.settings.envelope.battery_floor_pct.unwrap_or(0.0)
                    );
                    out.safety_out(a.id, slot, why, true);
                }
                (Some(_), _) if outside[i].is_some() => {
                    let why = format!(
                        "safety envelope: {}: sent to Hold",
                        outside[i].as_deref().unwrap_or_default()
                    );
                    out.safety_out(a.id, slot, why, false);
                }
                (Some((uav, v)), _) => {
                    let (p, centre) = (uav.horizontal_position(), target.position.xy());
                    slot.range_error = Some((p - centre).norm() - a.plan.radius);
                    slot.phase = Some(phase_of(p, centre));
                    if a.plan.law.is_handoff() {
                        // The autopilot flies on what it was last sent: the track predicted to
                        // now, the tracker's time moved on by the wall time since its snapshot.
                        let now = predict(track, t_track + self.since_snapshot);
                        self.hand_off(a.id, slot, v, track, &now, &a.plan, out);
                        if before != (slot.state, slot.error.clone()) {
                            out.changed.push(a.id);
                        }
                        continue;
                    }
                    let limits = envelope(i);
                    let mut cmd = match formation.as_ref().and_then(|c| c[i]) {
                        Some(c) => c,
                        None => {
                            let neighbours = ring.neighbours(i, spacing);
                            law.command(uav, Some(&target), limits, neighbours.as_ref())
                                .or_hold(uav, limits)
                        }
                    };
                    // Every setpoint within the safety envelope.
                    let fence = &self.settings.envelope;
                    let (velocity, clipped) = fence.clip(&uav.position, &cmd.velocity);
                    cmd.velocity = velocity;
                    out.clipped += u64::from(clipped);
                    // ArduPlane holds an altitude rather than a climb rate: H over the target,
                    // within the floor and the ceiling.
                    let mut goal = target.position.z + a.plan.height;
                    if let (Some(f), Some(c)) = (fence.floor_m, fence.ceiling_m) {
                        goal = goal.clamp(f, c);
                    }
                    let altitude = v.view.geodetic.map(|g| g.alt_m + goal - uav.position.z);
                    self.advance(a.id, slot, v, cmd, altitude, out);
                }
            }
            if before != (slot.state, slot.error.clone()) {
                out.changed.push(a.id);
            }
        }
    }

    /// One tick of a hand-off slot: the orbit, follow or camera messages due; `handed_off` once
    /// in the air (the camera at once); `overridden` when its vehicle left the hand-off's mode.
    #[allow(clippy::too_many_arguments)]
    fn hand_off(
        &self,
        assignment: u64,
        slot: &mut Slot,
        v: &VehicleSample,
        track: &TrackView,
        target: &TargetEstimate,
        plan: &Plan,
        out: &mut Decisions,
    ) {
        let frame = &self.settings.frame;
        let msgs = match slot.handoff.step(self.t, v, target, track, plan, frame) {
            Ok(msgs) => msgs,
            Err(o) => {
                out.take_out(assignment, slot, v, o, "left the hand-off");
                return;
            }
        };
        out.send.extend(msgs.into_iter().map(|m| (slot.vehicle, m)));
        slot.state = if plan.law == Law::HandoffCamera || airborne(v) {
            SlotState::HandedOff
        } else {
            SlotState::Waiting
        };
    }

    /// The vehicle `id`, when the link knows it.
    fn vehicle(&self, id: u8) -> Option<&'a VehicleSample> {
        self.vehicles.iter().find(|v| v.view.id == id)
    }

    /// The measured state of each slot's vehicle: while the slot is not out of the assignment
    /// and its vehicle is connected, confirmed (gcs::identity) and has sent its position and
    /// velocity.
    fn measured(&self, slots: &[Slot]) -> Vec<Option<(UavState, &'a VehicleSample)>> {
        slots
            .iter()
            .map(|s| {
                let v = self.vehicle(s.vehicle)?;
                if s.is_out() || v.view.state != LinkState::Connected || !v.confirmed {
                    return None;
                }
                let p = v.view.position?;
                let vel = v.view.velocity?;
                Some((UavState::new(p.into(), vel.into()), v))
            })
            .collect()
    }

    /// Advances `slot`'s launch sequence in its autopilot's order (PX4: arm, take off, stream
    /// setpoints, OFFBOARD; ArduPilot: GUIDED, arm, take off, targets) with `cmd` (and, for an
    /// ArduPlane, the `altitude` AMSL to hold); a sequence that fails leaves the vehicle
    /// `failed`, sent to its hold mode; one whose vehicle someone else took (its mode or arming
    /// changed by no command of the sequence's) leaves it `overridden`, sent nothing.
    fn advance(
        &self,
        assignment: u64,
        slot: &mut Slot,
        v: &VehicleSample,
        cmd: Command,
        altitude: Option<f64>,
        out: &mut Decisions,
    ) {
        let status = v.status.unwrap_or_else(VehicleStatus::unknown);
        let takeoff_height = self.settings.takeoff_height as f32;
        if slot
            .sequence
            .as_ref()
            .is_some_and(|s| s.personality() != status.personality)
        {
            // Another autopilot answers under this id now: start over in its sequence.
            slot.sequence = None;
        }
        let seq = slot.sequence.get_or_insert_with(|| {
            let config = OffboardConfig::new(Some(takeoff_height), v.home_amsl.map(|h| h as f32));
            OffboardSequence::new(slot.vehicle, status.personality, config)
        });
        let steer = Steer {
            velocity: cmd.velocity,
            altitude_amsl_m: altitude,
        };
        match seq.next(self.t, &status, v.view.relative_alt_m, Some(steer)) {
            Ok(msgs) => {
                out.send.extend(msgs.into_iter().map(|m| (slot.vehicle, m)));
                slot.state = match seq.phase() {
                    Phase::Arming => SlotState::Arming,
                    Phase::TakingOff | Phase::Climbing => SlotState::TakingOff,
                    Phase::Offboard => SlotState::Offboard,
                };
                slot.commanded = Some(cmd.velocity);
            }
            Err(OffboardError::Overridden(o)) => {
                out.take_out(assignment, slot, v, o, "its mode or arming changed");
            }
            Err(e) => {
                slot.state = SlotState::Failed;
                slot.error = Some(e.to_string());
                slot.sequence = None;
                out.hold.push(slot.vehicle);
            }
        }
    }
}

impl Decisions {
    /// Takes `slot` (of assignment `assignment`) out for the safety envelope (`why`, in words):
    /// `failed`, its vehicle sent home (`rtl`) or to Hold.
    fn safety_out(&mut self, assignment: u64, slot: &mut Slot, why: String, rtl: bool) {
        tracing::warn!(vehicle = slot.vehicle, assignment, "guidance: {why}");
        slot.state = SlotState::Failed;
        slot.error = Some(why);
        slot.sequence = None;
        slot.handoff = Handoff::default();
        if rtl {
            self.rtl.push(slot.vehicle);
        } else {
            self.fenced_out += 1;
            self.hold.push(slot.vehicle);
        }
    }

    /// Takes `slot` (of assignment `assignment`) out: its vehicle `v` is someone else's, as `o`
    /// shows (`what`: in words). Who: the router client whose command to the vehicle passed
    /// within [`CLIENT_COMMAND_WINDOW_S`] before, else the vehicle itself (its RC switch, a
    /// failsafe, its autopilot).
    fn take_out(
        &mut self,
        assignment: u64,
        slot: &mut Slot,
        v: &VehicleSample,
        o: Override,
        what: &str,
    ) {
        let name = |m: Option<Mode>| m.map(|m| m.name().to_owned());
        let client = v
            .client_command
            .as_ref()
            .filter(|c| c.at <= o.at + 0.05 && o.at - c.at <= CLIENT_COMMAND_WINDOW_S);
        let (by, who) = match client {
            Some(c) => (
                OverrideSource::RouterClient,
                format!("{} from {}", c.command, c.from),
            ),
            None => (
                OverrideSource::Vehicle,
                "no command through Harrier: its RC switch, a failsafe or its autopilot".into(),
            ),
        };
        let view = OverrideView {
            from_mode: name(o.from),
            to_mode: name(o.to).or_else(|| v.view.mode.clone()),
            disarmed: o.disarmed,
            by,
            detail: format!("{what} ({o}); {who}"),
            time_unix: unix_now(),
        };
        tracing::warn!(
            vehicle = slot.vehicle,
            assignment,
            by = by.as_str(),
            detail = view.detail,
            "guidance: vehicle taken out of its slot by someone else; not commanded again until \
             the operator resumes it"
        );
        slot.take_out(view);
        self.overridden.push(by);
        self.changed.push(assignment);
    }
}

/// The ring of the phase coordination (\[CIMM\] §4.3): the slots whose vehicle is on the
/// circle (within [`ON_CIRCLE`] of R), in their order along the orbit, with their phases. A
/// vehicle still on its way flies the law alone, at full speed: its phase error would only slow
/// its approach (\[CIMM\] coordinates UAVs already on the limit cycle).
#[derive(Debug)]
struct Ring {
    /// Slot indices in ring order.
    slots: Vec<usize>,
    /// Their phases (rad).
    phases: Vec<f64>,
}

impl Ring {
    fn of(
        states: &[Option<(UavState, &VehicleSample)>],
        target: &TargetEstimate,
        plan: &Plan,
    ) -> Self {
        let mut ring: Vec<(usize, f64)> = states
            .iter()
            .enumerate()
            .filter_map(|(i, s)| {
                let (u, _) = s.as_ref()?;
                let d = u.horizontal_position() - target.position.xy();
                ((d.norm() - plan.radius).abs() <= ON_CIRCLE * plan.radius)
                    .then(|| (i, d.y.atan2(d.x)))
            })
            .collect();
        let sign = Orbit::from(plan.orbit).sign();
        ring.sort_by(|x, y| (sign * x.1).total_cmp(&(sign * y.1)));
        Self {
            slots: ring.iter().map(|r| r.0).collect(),
            phases: ring.iter().map(|r| r.1).collect(),
        }
    }

    /// The phase neighbours of slot `i` when it is on the ring, `spacing` apart when given (the
    /// assignment's, once every vehicle is on the ring).
    fn neighbours(&self, i: usize, spacing: Option<f64>) -> Option<PhaseNeighbours> {
        let k = self.slots.iter().position(|&s| s == i)?;
        PhaseNeighbours::ring(&self.phases, k).map(|mut nb| {
            if let Some(s) = spacing {
                nb.spacing = s;
            }
            nb
        })
    }
}
