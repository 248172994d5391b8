//! `[[mavlink.router_filter]]`: what the router sends to one client endpoint (message ids, source
//! components and source systems allowed or blocked, a rate limit per message id) and what that
//! endpoint's clients may send to the vehicles (the same lists, `…_in`), named after
//! mavlink-router's filters, checked and resolved into the link's
//! [`FilterSpec`](crate::gcs::filter::FilterSpec)s (`MavlinkConfig::router_filters`).

use std::collections::BTreeMap;

use harrier_link::frame::Endpoint;
use harrier_link::mavlink::Message;
use harrier_link::mavlink::dialects::common::MavMessage;
use serde::{Deserialize, Serialize};

use super::error::ConfigError;
use crate::gcs::filter::{FilterSpec, Lists};

/// Largest MAVLink message id (24 bits in MAVLink 2).
const MAX_MESSAGE_ID: u32 = 0xFF_FFFF;

/// A message: its id, or its name in MAVLink's common dialect (`"ATTITUDE"`).
#[derive(Debug, Clone, PartialEq, Eq, Deserialize, Serialize)]
#[serde(untagged)]
pub enum MessageRef {
    /// A message id.
    Id(u32),
    /// A message name, as the MAVLink XML spells it.
    Name(String),
}

impl MessageRef {
    /// The message id (`what` names the key in an error).
    fn resolve(&self, what: &str) -> Result<u32, ConfigError> {
        match self {
            Self::Id(id) if *id <= MAX_MESSAGE_ID => Ok(*id),
            Self::Id(id) => Err(ConfigError::Invalid(format!(
                "{what}: message id {id} is above {MAX_MESSAGE_ID} (24 bits)"
            ))),
            Self::Name(name) => message_id(name).ok_or_else(|| {
                ConfigError::Invalid(format!(
                    "{what}: {name:?} is not a message of MAVLink's common dialect (a message id, \
                     or its name as the MAVLink XML spells it, e.g. \"ATTITUDE\")"
                ))
            }),
        }
    }
}

/// The id of the common dialect's message `name`, or of a message id written as a string.
fn message_id(name: &str) -> Option<u32> {
    match name.parse::<u32>() {
        Ok(id) => (id <= MAX_MESSAGE_ID).then_some(id),
        Err(_) => MavMessage::message_id_from_name(name),
    }
}

/// One `[[mavlink.router_filter]]` table.
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RouterFilterConfig {
    /// The router endpoint it applies to, as written in `mavlink.router`.
    pub endpoint: String,
    /// Only these messages go to the endpoint (ids or names; mavlink-router's `AllowMsgIdOut`).
    pub allow_msg: Vec<MessageRef>,
    /// These messages never go to the endpoint (`BlockMsgIdOut`).
    pub block_msg: Vec<MessageRef>,
    /// Only frames of these source components go to the endpoint (`AllowSrcCompOut`).
    pub allow_src_comp: Vec<u8>,
    /// Frames of these source components never go to the endpoint (`BlockSrcCompOut`).
    pub block_src_comp: Vec<u8>,
    /// Only frames of these source systems go to the endpoint (`AllowSrcSysOut`).
    pub allow_src_sys: Vec<u8>,
    /// Frames of these source systems never go to the endpoint (`BlockSrcSysOut`).
    pub block_src_sys: Vec<u8>,
    /// Most frames per second of a message (by name or id) from each source system and
    /// component: `{ ATTITUDE = 2.0 }`.
    pub max_rate_hz: BTreeMap<String, f64>,
    /// Only these messages go from the endpoint's clients to the vehicles (`AllowMsgIdIn`).
    pub allow_msg_in: Vec<MessageRef>,
    /// These messages from the endpoint's clients never reach a vehicle (`BlockMsgIdIn`).
    pub block_msg_in: Vec<MessageRef>,
    /// Only the clients' frames of these source components reach the vehicles
    /// (`AllowSrcCompIn`).
    pub allow_src_comp_in: Vec<u8>,
    /// The clients' frames of these source components never reach a vehicle (`BlockSrcCompIn`).
    pub block_src_comp_in: Vec<u8>,
    /// Only the clients' frames of these source systems reach the vehicles (`AllowSrcSysIn`).
    pub allow_src_sys_in: Vec<u8>,
    /// The clients' frames of these source systems never reach a vehicle (`BlockSrcSysIn`).
    pub block_src_sys_in: Vec<u8>,
}

impl RouterFilterConfig {
    /// The checked filter (`what` names it in errors).
    fn resolve(&self, what: &str) -> Result<FilterSpec, ConfigError> {
        let bad = |m: String| Err(ConfigError::Invalid(format!("{what}: {m}")));
        let out = lists(
            what,
            "",
            [&self.allow_msg, &self.block_msg],
            [&self.allow_src_comp, &self.block_src_comp],
            [&self.allow_src_sys, &self.block_src_sys],
        )?;
        let incoming = lists(
            what,
            "_in",
            [&self.allow_msg_in, &self.block_msg_in],
            [&self.allow_src_comp_in, &self.block_src_comp_in],
            [&self.allow_src_sys_in, &self.block_src_sys_in],
        )?;
        let mut max_rate_hz = Vec::new();
        for (name, &hz) in &self.max_rate_hz {
            let Some(id) = message_id(name) else {
                return bad(format!(
                    "max_rate_hz: {name:?} is not a message of MAVLink's common dialect (a \
                     message id, or its name as the MAVLink XML spells it, e.g. ATTITUDE)"
                ));
            };
            if !(hz.is_finite() && hz > 0.0) {
                return bad(format!("max_rate_hz.{name} must be > 0 (Hz), got {hz}"));
            }
            if out.block_msg.contains(&id)
                || (!out.allow_msg.is_empty() && !out.allow_msg.contains(&id))
            {
                return bad(format!(
                    "max_rate_hz.{name}: the message never goes to this endpoint (allow_msg, \
                     block_msg)"
                ));
            }
            if max_rate_hz.iter().any(|&(other, _)| other == id) {
                return bad(format!("max_rate_hz: message {id} is given twice"));
            }
            max_rate_hz.push((id, hz));
        }
        Ok(FilterSpec {
            out,
            max_rate_hz,
            incoming,
        })
    }
}

/// The checked lists of one direction (`suffix`: `""` out, `"_in"` in): each pair an allow and
/// a block list, which cannot both be set.
fn lists(
    what: &str,
    suffix: &str,
    [allow_msg, block_msg]: [&[MessageRef]; 2],
    [allow_src_comp, block_src_comp]: [&[u8]; 2],
    [allow_src_sys, block_src_sys]: [&[u8]; 2],
) -> Result<Lists, ConfigError> {
    for (kind, allow, block) in [
        ("msg", allow_msg.is_empty(), block_msg.is_empty()),
        (
            "src_comp",
            allow_src_comp.is_empty(),
            block_src_comp.is_empty(),
        ),
        (
            "src_sys",
            allow_src_sys.is_empty(),
            block_src_sys.is_empty(),
        ),
    ] {
        if !allow && !block {
            return Err(ConfigError::Invalid(format!(
                "{what}: allow_{kind}{suffix} and block_{kind}{suffix} are both set: an allow \
                 list lets only its members through, leave the blocked ones out of it"
            )));
        }
    }
    let ids = |list: &[MessageRef], key: &str| {
        list.iter()
            .map(|m| m.resolve(&format!("{what}.{key}{suffix}")))
            .collect::<Result<Vec<u32>, _>>()
    };
    Ok(Lists {
        allow_msg: ids(allow_msg, "allow_msg")?,
        block_msg: ids(block_msg, "block_msg")?,
        allow_src_comp: allow_src_comp.to_vec(),
        block_src_comp: block_src_comp.to_vec(),
        allow_src_sys: allow_src_sys.to_vec(),
        block_src_sys: block_src_sys.to_vec(),
    })
}

/// Each endpoint of `router`'s filter among `filters`, in the order of `router` (open where
/// none is configured); refuses a filter that names no router endpoint, one of two equal
/// endpoints, or an endpoint already filtered, and the values [`RouterFilterConfig`] cannot
/// take.
pub(super) fn resolve_all(
    router: &[String],
    filters: &[RouterFilterConfig],
) -> Result<Vec<FilterSpec>, ConfigError> {
    let parse = |e: &str, what: &str| {
        Endpoint::parse(e).map_err(|e| ConfigError::Invalid(format!("{what}: {e}")))
    };
    let endpoints = router
        .iter()
        .map(|e| parse(e, "mavlink.router"))
        .collect::<Result<Vec<_>, _>>()?;
    let mut specs = vec![FilterSpec::default(); endpoints.len()];
    let mut filtered = vec![false; endpoints.len()];
    for f in filters {
        let what = format!("mavlink.router_filter {:?}", f.endpoint);
        let endpoint = parse(&f.endpoint, &format!("{what}: endpoint"))?;
        let mut at = endpoints
            .iter()
            .enumerate()
            .filter(|(_, r)| **r == endpoint);
        let (i, _) = at.next().ok_or_else(|| {
            ConfigError::Invalid(format!(
                "{what}: endpoint is not one of mavlink.router {router:?}"
            ))
        })?;
        if at.next().is_some() {
            return Err(ConfigError::Invalid(format!(
                "{what}: mavlink.router lists this endpoint twice; which one is meant?"
            )));
        }
        if std::mem::replace(&mut filtered[i], true) {
            return Err(ConfigError::Invalid(format!(
                "{what}: a second [[mavlink.router_filter]] for the same endpoint"
            )));
        }
        specs[i] = f.resolve(&what)?;
    }
    Ok(specs)
}

#[cfg(test)]
mod tests {
    use crate::config::Config;

    const ROUTER: &str = "[mavlink]\nrouter = [\"udpin:0.0.0.0:14551\", \"tcpin:0.0.0.0:5760\"]\n";

    fn filters(toml: &str) -> Result<Vec<crate::gcs::filter::FilterSpec>, String> {
        let c = Config::parse(&format!("{ROUTER}{toml}"), "f").map_err(|e| e.to_string())?;
        let specs = c.mavlink.router_filters().map_err(|e| e.to_string())?;
        c.check().map_err(|e| e.to_string())?;
        Ok(specs)
    }

    #[test]
    fn the_example_filter_uncommented_is_valid() {
        let text = include_str!("../../../harrier.example.toml");
        let mut on = false;
        let lines: Vec<&str> = text
            .lines()
            .map(|l| {
                on = (on || l == "# [[mavlink.router_filter]]") && !l.is_empty();
                if on { &l[2..] } else { l }
            })
            .collect();
        let c = Config::parse(&lines.join("\n"), "example").expect("uncommented example");
        let specs = c.mavlink.router_filters().expect("example filter");
        assert_eq!(specs[0].out.block_msg, vec![24, 245]);
        assert_eq!(specs[0].incoming.allow_msg, vec![0]);
        assert_eq!(specs[0].max_rate_hz, vec![(30, 2.0), (33, 1.0)]);
        c.check().expect("example");
    }

    #[test]
    fn router_as_a_list_of_strings_keeps_working() {
        let specs = filters("").unwrap();
        assert_eq!(specs.len(), 2);
        assert!(specs.iter().all(crate::gcs::filter::FilterSpec::is_open));
    }

    #[test]
    fn names_and_ids_resolve() {
        let specs = filters(
            "[[mavlink.router_filter]]\nendpoint = \"udpin:0.0.0.0:14551\"\n\
             block_msg = [\"SYS_STATUS\", 24]\nallow_src_sys = [1, 2]\n\
             max_rate_hz = { ATTITUDE = 2.0, \"33\" = 0.5 }\n",
        )
        .unwrap();
        assert_eq!(specs[0].out.block_msg, vec![1, 24]);
        assert_eq!(specs[0].out.allow_src_sys, vec![1, 2]);
        assert_eq!(specs[0].max_rate_hz, vec![(33, 0.5), (30, 2.0)]);
        assert!(specs[1].is_open());
        let specs = filters(
            "[[mavlink.router_filter]]\nendpoint = \"tcpin:0.0.0.0:5760\"\n\
             block_src_comp = [100]\nallow_msg_in = [\"HEARTBEAT\", \"COMMAND_LONG\", 11]\n\
             allow_src_comp_in = [190]\nblock_src_sys_in = [3]\n",
        )
        .unwrap();
        assert!(specs[0].is_open());
        assert_eq!(specs[1].out.block_src_comp, vec![100]);
        assert_eq!(specs[1].incoming.allow_msg, vec![0, 76, 11]);
        assert_eq!(specs[1].incoming.allow_src_comp, vec![190]);
        assert_eq!(specs[1].incoming.block_src_sys, vec![3]);
        assert!(specs[1].out.block_msg.is_empty() && specs[1].max_rate_hz.is_empty());
    }

    #[test]
    fn bad_filters_are_refused_with_the_reason() {
        let ep = "[[mavlink.router_filter]]\nendpoint = \"tcpin:0.0.0.0:5760\"\n";
        for (toml, want) in [
            (
                "[[mavlink.router_filter]]\nendpoint = \"udpin:0.0.0.0:9\"\n".to_owned(),
                "is not one of mavlink.router",
            ),
            (
                "[[mavlink.router_filter]]\nblock_msg = [0]\n".to_owned(),
                "router_filter \"\": endpoint",
            ),
            (format!("{ep}{ep}"), "a second [[mavlink.router_filter]]"),
            (
                format!("{ep}block_msg = [\"ATTITUDES\"]\n"),
                "\"ATTITUDES\" is not a message",
            ),
            (format!("{ep}allow_msg = [16777216]\n"), "above 16777215"),
            (
                format!("{ep}allow_msg = [0]\nblock_msg = [1]\n"),
                "allow_msg and block_msg are both set",
            ),
            (
                format!("{ep}allow_src_sys = [1]\nblock_src_sys = [2]\n"),
                "allow_src_sys and block_src_sys are both set",
            ),
            (
                format!("{ep}allow_src_comp = [1]\nblock_src_comp = [2]\n"),
                "allow_src_comp and block_src_comp are both set",
            ),
            (
                format!("{ep}allow_msg_in = [0]\nblock_msg_in = [1]\n"),
                "allow_msg_in and block_msg_in are both set",
            ),
            (
                format!("{ep}allow_src_sys_in = [1]\nblock_src_sys_in = [2]\n"),
                "allow_src_sys_in and block_src_sys_in are both set",
            ),
            (
                format!("{ep}block_msg_in = [\"COMMAND_LONGER\"]\n"),
                "block_msg_in: \"COMMAND_LONGER\" is not a message",
            ),
            (format!("{ep}block_src_comp_in = [256]\n"), "256"),
            (
                format!("{ep}max_rate_hz = {{ ATTITUDE = 0.0 }}\n"),
                "must be > 0",
            ),
            (
                format!("{ep}max_rate_hz = {{ ATTITUDE = -1.0 }}\n"),
                "must be > 0",
            ),
            (
                format!("{ep}max_rate_hz = {{ ATTITUDE = nan }}\n"),
                "must be > 0",
            ),
            (
                format!("{ep}max_rate_hz = {{ ATTITUDE = inf }}\n"),
                "must be > 0",
            ),
            (
                format!("{ep}max_rate_hz = {{ NOPE = 1.0 }}\n"),
                "\"NOPE\" is not a message",
            ),
            (
                format!("{ep}max_rate_hz = {{ ATTITUDE = 1.0, \"30\" = 2.0 }}\n"),
                "given twice",
            ),
            (
                format!("{ep}block_msg = [\"ATTITUDE\"]\nmax_rate_hz = {{ ATTITUDE = 1.0 }}\n"),
                "never goes to this endpoint",
            ),
            (format!("{ep}allow_src_sys = [256]\n"), "256"),
            (format!("{ep}block = [1]\n"), "unknown field"),
        ] {
            let e = filters(&toml).expect_err(&toml);
            assert!(e.contains(want), "{toml}: {e}");
        }
    }

    #[test]
    fn an_endpoint_listed_twice_cannot_be_filtered() {
        let e = Config::parse(
            "[mavlink]\nrouter = [\"udpin:127.0.0.1:0\", \"udpin:127.0.0.1:0\"]\n\
             [[mavlink.router_filter]]\nendpoint = \"udpin:127.0.0.1:0\"\nblock_msg = [0]\n",
            "f",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("lists this endpoint twice"), "{e}");
    }
}
