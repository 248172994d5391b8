//! The running link as the API and the guidance hold it ([`GcsLink`]).

use std::sync::Arc;
use std::time::Instant;

use harrier_link::frame::Endpoint;
use harrier_link::mavlink::dialects::common::MavMessage;
use tokio::sync::{broadcast, mpsc, oneshot, watch};

use super::messages::{CommandError, CommandOutcome, LinkEvent, Request, VehicleSample};
use super::metrics::LinkMetrics;
use super::transport::EndpointHandle;

/// The running link, as the API and the guidance use it.
#[derive(Debug, Clone)]
pub struct GcsLink {
    /// Requests (commands, messages) to the link actor.
    pub requests: mpsc::Sender<Request>,
    /// Every vehicle, updated at [`PUBLISH_HZ`](super::messages::PUBLISH_HZ).
    pub vehicles: watch::Receiver<Arc<Vec<VehicleSample>>>,
    /// Link events.
    pub events: broadcast::Sender<LinkEvent>,
    /// COMMAND_ACKs from the vehicles: (system id, the ACK).
    pub acks: broadcast::Sender<(u8, MavMessage)>,
    /// The endpoints as bound: the GCS endpoints first, then the router's.
    pub endpoints: Vec<EndpointHandle>,
    /// How many of `endpoints` are GCS endpoints.
    pub gcs_endpoints: usize,
    /// Counters.
    pub metrics: Arc<LinkMetrics>,
    /// Zero of the link's clock (the `at` of [`VehicleStatus`](harrier_link::autopilot::VehicleStatus)).
    pub epoch: Instant,
}

impl GcsLink {
    /// Sends a command and waits for its outcome (never longer than the attempts take).
    pub async fn command(
        &self,
        vehicle: u8,
        message: MavMessage,
    ) -> Result<CommandOutcome, CommandError> {
        let (reply, rx) = oneshot::channel();
        self.requests
            .send(Request::Command {
                vehicle,
                message,
                reply,
            })
            .await
            .map_err(|_| CommandError::Stopped)?;
        rx.await.map_err(|_| CommandError::Stopped)?
    }

    /// Accepts vehicle `vehicle`'s new address (gcs::identity): `Ok(true)` when it was
    /// unconfirmed, `Ok(false)` when there was nothing to accept.
    pub async fn accept(&self, vehicle: u8) -> Result<bool, CommandError> {
        let (reply, rx) = oneshot::channel();
        self.requests
            .send(Request::Accept { vehicle, reply })
            .await
            .map_err(|_| CommandError::Stopped)?;
        rx.await.map_err(|_| CommandError::Stopped)?
    }

    /// The bound GCS endpoints.
    pub fn gcs(&self) -> impl Iterator<Item = &Endpoint> {
        self.endpoints[..self.gcs_endpoints]
            .iter()
            .map(|e| &e.endpoint)
    }

    /// The bound router endpoints.
    pub fn router(&self) -> impl Iterator<Item = &Endpoint> {
        self.endpoints[self.gcs_endpoints..]
            .iter()
            .map(|e| &e.endpoint)
    }

    /// The bound GCS and router endpoints as connection strings, comma-separated (for the
    /// operator).
    pub fn describe(&self) -> (String, String) {
        let list = |it: &mut dyn Iterator<Item = &Endpoint>| {
            it.map(ToString::to_string).collect::<Vec<_>>().join(", ")
        };
        (list(&mut self.gcs()), list(&mut self.router()))
    }

    /// Appends the link's counters to a Prometheus text.
    pub fn render_metrics(&self, out: &mut String) {
        let vehicles = self.vehicles.borrow().clone();
        self.metrics
            .render(&vehicles, &self.endpoints, self.gcs_endpoints, out);
    }
}
