//! The handles of meshes, objects and lights: a pipeline's generational id
//! (`to_bits`: slot in the low 32 bits, generation in the high 32) with the
//! kind in bits 28–31 of the slot word, plus 1 so that 0 is the null handle.
//! Handles of different kinds never coincide: a mesh's handle given where an
//! object's is expected is `SC_INVALID_ARGUMENT` naming both kinds, never
//! another object (slots stay below 2²⁸: objects below 2²⁴ by
//! `scene::MAX_OBJECTS`, meshes and lights far below by memory).

use crate::error::{Failure, Result};
use shadowcull::scene::{LightId, MeshId, ObjectId};

/// What a handle names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    Object = 1,
    Mesh = 2,
    Light = 3,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Object => "an object's",
            Kind::Mesh => "a mesh's",
            Kind::Light => "a light's",
        }
    }
}

const KIND_SHIFT: u32 = 28;
const KIND_MASK: u64 = 0xf << KIND_SHIFT;

fn encode(kind: Kind, bits: u64) -> u64 {
    debug_assert_eq!(bits & KIND_MASK, 0, "slot beyond 2^28");
    (bits & !KIND_MASK | (kind as u64) << KIND_SHIFT) + 1
}

/// The id bits inside handle `h`, which must be of `kind`; `what` names the
/// argument in the error.
fn decode(kind: Kind, h: u64, what: &str) -> Result<u64> {
    let Some(b) = h.checked_sub(1) else {
        return Err(Failure::invalid(format!("{what}: the null handle")));
    };
    let tag = (b & KIND_MASK) >> KIND_SHIFT;
    if tag != kind as u64 {
        let got = [Kind::Object, Kind::Mesh, Kind::Light]
            .into_iter()
            .find(|k| *k as u64 == tag);
        return Err(Failure::invalid(match got {
            Some(got) => format!(
                "{what}: {h:#x} is {} handle, not {}",
                got.name(),
                kind.name()
            ),
            None => format!("{what}: {h:#x} is not a handle"),
        }));
    }
    Ok(b & !KIND_MASK)
}

/// The handle (`sc_object`) of object `id`.
pub(crate) fn object_handle(id: ObjectId) -> u64 {
    encode(Kind::Object, id.to_bits())
}

/// The handle (`sc_mesh`) of mesh `id`.
pub(crate) fn mesh_handle(id: MeshId) -> u64 {
    encode(Kind::Mesh, id.to_bits())
}

/// The handle (`sc_light`) of light `id`.
pub(crate) fn light_handle(id: LightId) -> u64 {
    encode(Kind::Light, id.to_bits())
}

/// The object an `sc_object` names (checked at use like any id).
pub(crate) fn object_of(h: u64, what: &str) -> Result<ObjectId> {
    decode(Kind::Object, h, what).map(ObjectId::from_bits)
}

/// The mesh an `sc_mesh` names.
pub(crate) fn mesh_of(h: u64, what: &str) -> Result<MeshId> {
    decode(Kind::Mesh, h, what).map(MeshId::from_bits)
}

/// The light an `sc_light` names.
pub(crate) fn light_of(h: u64, what: &str) -> Result<LightId> {
    decode(Kind::Light, h, what).map(LightId::from_bits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn handles_round_trip_and_kinds_never_mix() {
        let id = ObjectId::new(0x00ff_ffff, 7);
        let h = object_handle(id);
        assert_eq!(object_of(h, "object").unwrap(), id);
        assert_ne!(h, mesh_handle(MeshId::new(0x00ff_ffff, 7)));
        let m = mesh_handle(MeshId::from_slot(0));
        let e = mesh_of(object_handle(ObjectId::from_slot(0)), "mesh").unwrap_err();
        assert!(
            e.message.contains("is an object's handle, not a mesh's"),
            "{}",
            e.message
        );
        assert!(object_of(m, "object").is_err());
        assert!(light_of(m, "light").is_err());
        assert!(light_of(0, "light").unwrap_err().message.contains("null"));
        assert!(object_of(5, "object")
            .unwrap_err()
            .message
            .contains("not a handle"));
        assert_eq!(
            light_of(light_handle(LightId::new(3, 1)), "l").unwrap(),
            LightId::new(3, 1)
        );
    }
}
