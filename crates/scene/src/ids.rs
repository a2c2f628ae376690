//! Generational ids: [`ObjectId`], [`MeshId`] and [`LightId`].
//!
//! Each is a slot (the index into dense per-kind arrays) and a generation
//! (32 bits each, one `u64`). A living scene reuses a removed thing's slot
//! with the next generation, so memory stays bounded however long a host
//! streams things in and out, and a stale id is an error at its next use,
//! never another thing: a slot's generation would have to be reused 2³²
//! times to come round (such a slot is retired instead). Scenes flattened
//! from a graph have generation 0 everywhere: their ids are their slots.
//!
//! The ids are opaque: the library makes them (flattening, the host edit
//! calls); [`ObjectId::from_bits`] rebuilds one from [`ObjectId::to_bits`]
//! (for FFI and files), and whatever it names is checked at use.

use std::fmt;

macro_rules! generational_id {
    ($(#[$doc:meta])* $name:ident, $what:literal) => {
        $(#[$doc])*
        #[derive(
            Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
        )]
        #[serde(transparent)]
        pub struct $name(u64);

        impl $name {
            #[doc = concat!("The ", $what, " id of `slot` at `generation`.")]
            pub const fn new(slot: u32, generation: u32) -> Self {
                $name(slot as u64 | (generation as u64) << 32)
            }

            #[doc = concat!("The ", $what, " id of `slot` at generation 0: a slot of a scene ")]
            /// flattened from a graph, or of a slot never reused.
            pub const fn from_slot(slot: u32) -> Self {
                $name(slot as u64)
            }

            /// The slot: the index into dense per-kind arrays.
            pub const fn slot(self) -> u32 {
                self.0 as u32
            }

            /// The slot as an index.
            pub const fn index(self) -> usize {
                self.0 as u32 as usize
            }

            /// The generation: how many times the slot was reused before.
            pub const fn generation(self) -> u32 {
                (self.0 >> 32) as u32
            }

            /// The id as one number (slot in the low 32 bits, generation in
            /// the high 32), for FFI and files; [`Self::from_bits`] undoes it.
            pub const fn to_bits(self) -> u64 {
                self.0
            }

            /// The id whose [`Self::to_bits`] is `bits`. Any number gives an
            /// id; what it names is checked where it is used (an unknown,
            /// removed or stale id is an error there).
            pub const fn from_bits(bits: u64) -> Self {
                $name(bits)
            }
        }

        /// The slot, and the generation when it is not 0: `12`, `12 (generation 3)`.
        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                match self.generation() {
                    0 => write!(f, "{}", self.slot()),
                    g => write!(f, "{} (generation {g})", self.slot()),
                }
            }
        }

        impl fmt::Debug for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                match self.generation() {
                    0 => write!(f, "{}({})", stringify!($name), self.slot()),
                    g => write!(f, "{}({}, generation {g})", stringify!($name), self.slot()),
                }
            }
        }
    };
}

generational_id!(
    /// Identifies a scene object; every output names objects by it. Its slot
    /// indexes dense per-object arrays ([`crate::Scene::objects`]).
    ObjectId,
    "object"
);

generational_id!(
    /// Identifies a mesh of a scene; objects instance meshes by it. Its slot
    /// indexes [`crate::SceneGraph::meshes`].
    MeshId,
    "mesh"
);

generational_id!(
    /// Identifies a light of a pipeline (the facade's `Pipeline::add_light`);
    /// per-light state (silhouette cache, light views, culling history)
    /// follows the id.
    LightId,
    "light"
);

/// The next generation of a freed slot, or `None` when the slot must be
/// retired (its generation would wrap and bring old ids back).
pub(crate) fn next_generation(generation: u32) -> Option<u32> {
    generation.checked_add(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slot_and_generation_round_trip_through_bits() {
        let id = ObjectId::new(0x00ab_cdef, 0xffff_fffe);
        assert_eq!(id.slot(), 0x00ab_cdef);
        assert_eq!(id.generation(), 0xffff_fffe);
        assert_eq!(ObjectId::from_bits(id.to_bits()), id);
        assert_ne!(ObjectId::new(5, 1), ObjectId::from_slot(5));
        assert_eq!(ObjectId::from_slot(5).to_bits(), 5);
    }

    #[test]
    fn ids_read_as_their_slot_and_generation() {
        assert_eq!(MeshId::from_slot(7).to_string(), "7");
        assert_eq!(LightId::new(7, 2).to_string(), "7 (generation 2)");
        assert_eq!(
            format!("{:?}", ObjectId::new(3, 1)),
            "ObjectId(3, generation 1)"
        );
        assert_eq!(next_generation(u32::MAX), None);
        assert_eq!(next_generation(4), Some(5));
    }

    #[test]
    fn an_id_serializes_as_its_bits() {
        let id = ObjectId::new(9, 2);
        let json = serde_json::to_string(&id).unwrap();
        assert_eq!(json, id.to_bits().to_string());
    }
}
