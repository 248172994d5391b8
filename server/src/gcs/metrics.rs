//! The link's counters ([`LinkMetrics`]), counted by the actor and the endpoint tasks and
//! written into `/metrics` with the vehicles' link state.

use std::collections::BTreeMap;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

use harrier_link::signing::Rejection;

use super::filter::{Direction, Filtered};
use super::messages::VehicleSample;
use super::transport::EndpointHandle;
use super::vehicle::LinkState;
use crate::prom::Family;

/// The link's counters, rendered into `/metrics`.
#[derive(Debug, Default)]
pub struct LinkMetrics {
    pub(super) frames_in: AtomicU64,
    pub(super) malformed_gcs: AtomicU64,
    pub(super) malformed_router: AtomicU64,
    pub(super) frames_from_clients: AtomicU64,
    pub(super) routed_to_clients: AtomicU64,
    pub(super) routed_to_vehicles: AtomicU64,
    pub(super) unroutable: AtomicU64,
    pub(super) frames_out: AtomicU64,
    pub(super) heartbeats: AtomicU64,
    pub(super) track_messages: AtomicU64,
    pub(super) commands: AtomicU64,
    pub(super) command_retries: AtomicU64,
    acks: Mutex<BTreeMap<&'static str, u64>>,
    pub(super) vehicles_lost: AtomicU64,
    /// Conflicts: a second source claiming a connected vehicle's system id (gcs::identity).
    pub(super) identity_conflicts: AtomicU64,
    /// Frames refused as an impostor's.
    pub(super) impostor_frames: AtomicU64,
    pub(super) tlog_dropped: AtomicU64,
    /// Frames refused by the signing: [GCS side, router side] × [`Rejection::ALL`].
    rejected: [[AtomicU64; 3]; 2],
}

impl LinkMetrics {
    /// Appends the Prometheus text of the link's counters, of `endpoints` (the first
    /// `gcs_endpoints` of them the GCS endpoints, then the router's) and of `vehicles`.
    pub fn render(
        &self,
        vehicles: &[VehicleSample],
        endpoints: &[EndpointHandle],
        gcs_endpoints: usize,
        out: &mut String,
    ) {
        self.render_frames(out);
        self.render_commands(out);
        let mut dropped = Family::counter(
            out,
            "harrier_mavlink_send_dropped_total",
            "Frames an endpoint could not send (slow TCP client, full socket, absent server).",
        );
        for e in endpoints {
            dropped.sample(
                &[("endpoint", &e.endpoint)],
                e.counters.send_dropped.load(Ordering::Relaxed),
            );
        }
        let mut filtered = Family::counter(
            out,
            "harrier_router_filtered_total",
            "Frames a router endpoint's filter ([[mavlink.router_filter]]) kept from its clients (direction out) or from the vehicles (direction in), by reason: blocked_msg, not_allowed_msg, blocked_comp, not_allowed_comp, blocked_sys, not_allowed_sys, rate.",
        );
        for e in endpoints.get(gcs_endpoints..).unwrap_or_default() {
            for (direction, counts) in Direction::ALL.iter().zip(&e.counters.filtered) {
                for (reason, n) in Filtered::ALL.iter().zip(counts) {
                    // Nothing is rate-limited on the way in.
                    if *direction == Direction::In && *reason == Filtered::Rate {
                        continue;
                    }
                    filtered.sample(
                        &[
                            ("endpoint", &e.endpoint),
                            ("direction", &direction.as_str()),
                            ("reason", &reason.as_str()),
                        ],
                        n.load(Ordering::Relaxed),
                    );
                }
            }
        }
        render_vehicles(vehicles, out);
    }

    /// Frames received, refused, sent and routed.
    fn render_frames(&self, out: &mut String) {
        let v = |a: &AtomicU64| a.load(Ordering::Relaxed);
        Family::counter(
            out,
            "harrier_mavlink_frames_received_total",
            "Valid MAVLink frames received on the GCS endpoints.",
        )
        .value(v(&self.frames_in));
        Family::counter(
            out,
            "harrier_mavlink_malformed_total",
            "Garbage datagrams, skipped byte stretches and undecodable frames, by side.",
        )
        .sample(&[("side", &"gcs")], v(&self.malformed_gcs))
        .sample(&[("side", &"router")], v(&self.malformed_router));
        let mut rejected = Family::counter(
            out,
            "harrier_mavlink_rejected_total",
            "Frames refused by MAVLink 2 signing, by side and reason (unsigned in signed_only mode, bad_signature, replay).",
        );
        for (side, counts) in ["gcs", "router"].iter().zip(&self.rejected) {
            for (reason, n) in Rejection::ALL.iter().zip(counts) {
                rejected.sample(&[("side", side), ("reason", &reason.as_str())], v(n));
            }
        }
        Family::counter(
            out,
            "harrier_mavlink_frames_sent_total",
            "Frames the ground station sent to vehicles (its own: heartbeats, commands, setpoints).",
        )
        .value(v(&self.frames_out));
        Family::counter(
            out,
            "harrier_mavlink_heartbeats_sent_total",
            "GCS HEARTBEATs sent.",
        )
        .value(v(&self.heartbeats));
        Family::counter(
            out,
            "harrier_router_track_messages_total",
            "Confirmed tracks sent to the router's clients as ADSB_VEHICLE (mavlink.tracks_hz).",
        )
        .value(v(&self.track_messages));
        Family::counter(
            out,
            "harrier_router_frames_total",
            "Frames routed: vehicle to clients, client to vehicles, from clients, unroutable (unknown target system).",
        )
        .sample(&[("direction", &"to_clients")], v(&self.routed_to_clients))
        .sample(&[("direction", &"to_vehicles")], v(&self.routed_to_vehicles))
        .sample(&[("direction", &"from_clients")], v(&self.frames_from_clients))
        .sample(&[("direction", &"unroutable")], v(&self.unroutable));
    }

    /// Commands, their retries and outcomes, lost vehicles and the `.tlog`'s drops.
    fn render_commands(&self, out: &mut String) {
        let v = |a: &AtomicU64| a.load(Ordering::Relaxed);
        Family::counter(
            out,
            "harrier_mavlink_commands_total",
            "Commands sent (first attempts).",
        )
        .value(v(&self.commands));
        Family::counter(
            out,
            "harrier_mavlink_command_retries_total",
            "Commands re-sent after an acknowledgement timeout.",
        )
        .value(v(&self.command_retries));
        let mut results = Family::counter(
            out,
            "harrier_mavlink_command_results_total",
            "Command outcomes by result (timeout: no final ACK).",
        );
        for (r, n) in self
            .acks
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .iter()
        {
            results.sample(&[("result", r)], n);
        }
        Family::counter(
            out,
            "harrier_mavlink_vehicle_lost_total",
            "Times a vehicle was marked lost.",
        )
        .value(v(&self.vehicles_lost));
        Family::counter(
            out,
            "harrier_mavlink_identity_conflicts_total",
            "Times a second source claimed the system id of a connected vehicle.",
        )
        .value(v(&self.identity_conflicts));
        Family::counter(
            out,
            "harrier_mavlink_impostor_frames_total",
            "Frames refused because they came from another address than their vehicle's.",
        )
        .value(v(&self.impostor_frames));
        Family::counter(
            out,
            "harrier_mavlink_tlog_dropped_total",
            "Frames not written to the .tlog (writer behind).",
        )
        .value(v(&self.tlog_dropped));
    }

    /// A frame refused by the signing on the GCS side (`gcs`) or the router's.
    pub(super) fn reject(&self, gcs: bool, reason: Rejection) {
        // `Rejection::ALL` lists the reasons in declaration order.
        self.rejected[usize::from(!gcs)][reason as usize].fetch_add(1, Ordering::Relaxed);
    }

    /// A command's outcome.
    pub(super) fn result(&self, result: super::messages::CommandResult) {
        *self
            .acks
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .entry(result.as_str())
            .or_default() += 1;
    }
}

/// Each vehicle's link: heard or lost, its message rate, its lost frames.
fn render_vehicles(vehicles: &[VehicleSample], out: &mut String) {
    let mut connected = Family::gauge(
        out,
        "harrier_vehicle_connected",
        "1 while the vehicle is heard, 0 when lost.",
    );
    for s in vehicles {
        let heard = s.view.state == LinkState::Connected;
        connected.sample(&[("vehicle", &s.view.id)], u8::from(heard));
    }
    let mut rate = Family::gauge(
        out,
        "harrier_vehicle_message_rate_hz",
        "Messages received from the vehicle over the last second.",
    );
    for s in vehicles {
        rate.sample(&[("vehicle", &s.view.id)], s.view.rate_hz);
    }
    // A gauge of that name since it was first published; its value only grows.
    let mut lost = Family::gauge(
        out,
        "harrier_vehicle_frames_lost_total",
        "Frames lost (MAVLink sequence gaps).",
    );
    for s in vehicles {
        lost.sample(&[("vehicle", &s.view.id)], s.view.lost_frames);
    }
}
