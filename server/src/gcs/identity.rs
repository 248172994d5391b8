//! Who a vehicle is: its system id *and* where it speaks from (the GCS endpoint and peer of its
//! first frames), kept apart from what it says ([`super::vehicle`]).
//!
//! - A second source claiming a system id that is connected is a **conflict** (a second
//!   simulator, a misconfigured airframe, anyone on the network): its frames are not the
//!   vehicle's (not decoded, not routed to clients, not in the ACKs; counted), nothing is ever
//!   sent to it, and the conflict is logged, shown (`identity.conflict` on `GET
//!   /api/v1/vehicles`, a red banner on the page) and counted
//!   (`harrier_mavlink_identity_conflicts_total`, `harrier_mavlink_impostor_frames_total`). It
//!   is over once the second source has been silent for the loss timeout.
//! - A vehicle that was lost and speaks again from another address is a **new identity**
//!   (`unconfirmed`): shown, answered (its telemetry, the operator's commands), but the
//!   guidance neither arms nor commands it until the operator accepts it
//!   (`POST /api/v1/vehicles/{id}/accept`).
//!
//! Pure: the actor passes the clock.

use std::time::Instant;

use serde::Serialize;
use utoipa::ToSchema;

use super::transport::Peer;

/// Whether the guidance may command a vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum IdentityState {
    /// The address it was first heard from, or one the operator accepted.
    Confirmed,
    /// Heard again from a new address after it was lost: not commanded by the guidance until
    /// the operator accepts it.
    Unconfirmed,
}

/// A second source claiming a vehicle's system id.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Conflict {
    peer: Peer,
    first: Instant,
    last: Instant,
    frames: u64,
}

/// A vehicle's identity (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct Identity {
    state: IdentityState,
    /// The address it spoke from before it moved, while unconfirmed.
    previous: Option<Peer>,
    conflict: Option<Conflict>,
}

impl Default for Identity {
    fn default() -> Self {
        Self {
            state: IdentityState::Confirmed,
            previous: None,
            conflict: None,
        }
    }
}

impl Identity {
    /// Whether the guidance may command it.
    pub fn confirmed(&self) -> bool {
        self.state == IdentityState::Confirmed
    }

    /// A frame of its id from `peer`, not its own address, while it is connected, at `now`.
    /// Returns whether this is a new conflict (the first frame of that source, or of another
    /// one than the conflict's).
    pub fn impostor(&mut self, peer: Peer, now: Instant) -> bool {
        match &mut self.conflict {
            Some(c) if c.peer == peer => {
                c.last = now;
                c.frames += 1;
                false
            }
            _ => {
                self.conflict = Some(Conflict {
                    peer,
                    first: now,
                    last: now,
                    frames: 1,
                });
                true
            }
        }
    }

    /// It was lost and speaks again from a new address (it spoke from `previous`): unconfirmed.
    pub fn moved(&mut self, previous: Peer) {
        if self.state == IdentityState::Confirmed {
            self.previous = Some(previous);
        }
        self.state = IdentityState::Unconfirmed;
        self.conflict = None;
    }

    /// The operator accepts its address; whether there was anything to accept.
    pub fn accept(&mut self) -> bool {
        let was = self.state == IdentityState::Unconfirmed;
        self.state = IdentityState::Confirmed;
        self.previous = None;
        was
    }

    /// Ends the conflict when its source has been silent for `after_s` at `now`; returns the
    /// source and the frames refused when it ended.
    pub fn expire(&mut self, now: Instant, after_s: f64) -> Option<(Peer, u64)> {
        let c = self.conflict?;
        if now.saturating_duration_since(c.last).as_secs_f64() <= after_s {
            return None;
        }
        self.conflict = None;
        Some((c.peer, c.frames))
    }

    /// The API view at `now`.
    pub fn view(&self, now: Instant) -> IdentityView {
        let ago = |t: Instant| now.saturating_duration_since(t).as_secs_f64();
        IdentityView {
            state: self.state,
            previous_address: self.previous.map(|p| p.to_string()),
            conflict: self.conflict.map(|c| ConflictView {
                address: c.peer.to_string(),
                frames: c.frames,
                since_s: ago(c.first),
                last_heard_s: ago(c.last),
            }),
        }
    }
}

/// A vehicle's identity as the API shows it.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct IdentityView {
    /// `confirmed`, or `unconfirmed` (back from a new address after it was lost; accept it with
    /// `POST /api/v1/vehicles/{id}/accept`).
    pub state: IdentityState,
    /// Where it spoke from before it moved, while unconfirmed.
    pub previous_address: Option<String>,
    /// A second source claiming its system id, while that source is heard.
    pub conflict: Option<ConflictView>,
}

/// A second source claiming a vehicle's system id.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct ConflictView {
    /// Where its frames come from (`udp:ADDR` or `tcp#N`).
    pub address: String,
    /// Its frames refused so far.
    pub frames: u64,
    /// Seconds since it was first heard.
    pub since_s: f64,
    /// Seconds since it was last heard.
    pub last_heard_s: f64,
}

#[cfg(test)]
mod tests {
    use std::net::SocketAddr;
    use std::time::Duration;

    use super::*;

    fn udp(port: u16) -> Peer {
        Peer::Udp(SocketAddr::from(([127, 0, 0, 1], port)))
    }

    #[test]
    fn an_impostor_is_a_conflict_until_silent_and_a_moved_vehicle_waits_for_acceptance() {
        let t0 = Instant::now();
        let mut id = Identity::default();
        assert!(id.confirmed());
        assert!(id.impostor(udp(2), t0), "a new conflict");
        assert!(!id.impostor(udp(2), t0 + Duration::from_secs(1)));
        assert!(
            id.impostor(udp(3), t0 + Duration::from_secs(1)),
            "another source"
        );
        let v = id.view(t0 + Duration::from_secs(2));
        let c = v.conflict.expect("conflict shown");
        assert_eq!((c.address.as_str(), c.frames), ("udp:127.0.0.1:3", 1));
        assert!(id.confirmed(), "the vehicle itself is still its own");
        assert_eq!(id.expire(t0 + Duration::from_secs(3), 3.0), None);
        assert_eq!(
            id.expire(t0 + Duration::from_secs(5), 3.0),
            Some((udp(3), 1))
        );
        assert!(id.view(t0).conflict.is_none());
        id.moved(udp(1));
        assert!(!id.confirmed());
        assert_eq!(
            id.view(t0).previous_address.as_deref(),
            Some("udp:127.0.0.1:1")
        );
        // Moved again before acceptance: the address it was confirmed at is kept.
        id.moved(udp(4));
        assert_eq!(
            id.view(t0).previous_address.as_deref(),
            Some("udp:127.0.0.1:1")
        );
        assert!(id.accept());
        assert!(id.confirmed() && !id.accept());
        assert_eq!(id.view(t0).state, IdentityState::Confirmed);
    }
}
