//! The vehicle's parameters (PARAM_REQUEST_LIST / _READ / PARAM_SET → PARAM_VALUE).
//!
//! PX4's are REAL32 or INT32, sent bytewise (an INT32's bits in the float field, as PX4
//! declares MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE). ArduPilot's have their own types, sent "C-cast": the value as a float
//! whatever the type (ArduPilot declares MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST); a
//! PARAM_SET of an integer parameter is rounded to it.

use mavlink::dialects::common::{MavMessage, MavParamType, PARAM_SET_DATA, PARAM_VALUE_DATA};

use harrier_link::autopilot::Autopilot;

use super::Vehicle;

impl Vehicle {
    pub(super) fn param_value(&self, index: usize) -> MavMessage {
        let p = self.params[index];
        MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
            param_value: if self.bytewise(p.kind) {
                f32::from_bits(p.value as i32 as u32)
            } else {
                p.value
            },
            param_count: self.params.len() as u16,
            param_index: index as u16,
            param_id: p.name.into(),
            param_type: p.kind,
        })
    }

    /// Whether a parameter of `kind` travels bytewise: a PX4 integer.
    fn bytewise(&self, kind: MavParamType) -> bool {
        self.personality.autopilot == Autopilot::Px4 && kind != MavParamType::MAV_PARAM_TYPE_REAL32
    }

    pub(super) fn param_set(&mut self, p: &PARAM_SET_DATA) -> Vec<MavMessage> {
        let name = p.param_id.to_str().unwrap_or("");
        let Some(i) = self.params.iter().position(|q| q.name == name) else {
            self.counters.rejected_params += 1;
            return Vec::new();
        };
        let bytewise = self.bytewise(self.params[i].kind);
        let q = &mut self.params[i];
        let value = if bytewise {
            p.param_value.to_bits() as i32 as f32
        } else if q.kind == MavParamType::MAV_PARAM_TYPE_REAL32 {
            p.param_value
        } else {
            p.param_value.round()
        };
        if value.is_finite() && (q.min..=q.max).contains(&value) {
            q.value = value;
        } else {
            self.counters.rejected_params += 1;
        }
        // PX4 and ArduPilot answer with the value in force, changed or not.
        vec![self.param_value(i)]
    }
}
