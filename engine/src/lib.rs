//! `engine`: the out-of-core walkthrough engine's core library.
//!
//! # Architecture
//!
//! The engine follows Varadhan & Manocha, *Out-of-Core Rendering of Massive
//! Geometric Environments* (IEEE Vis 2002). A scene is a scene graph whose leaves
//! carry each object's static LODs and whose interior nodes carry HLODs; every
//! approximation is an *object-rep* with an object-space error and a bounding box.
//!
//! Only the **skeleton** ([`Skeleton`]: nodes, boxes, errors, rep byte ranges) is
//! held in core. Object-rep payloads stay in the scene file and are read one at a
//! time through a [`ByteSource`], the I/O trait with a file and an in-memory
//! implementation.
//!
//! Modules:
//! - [`format`]: the versioned on-disk scene format — `repr(C)` records with
//!   asserted sizes, the [`SceneWriter`] used by the builder, the validating
//!   [`SceneFile`] reader and the rep payload codec ([`RepMesh`]).
//! - [`skeleton`]: the in-core hierarchy, the paper's PAR/CHD/ASC/DSC relations
//!   over object-reps and [`Skeleton::validate`].
//! - [`io`]: [`ByteSource`] and its implementations.
//!
//! Nothing on the format path depends on a GPU API: the renderer, when present,
//! is the only module that touches wgpu.

pub mod cache;
pub mod camera;
pub mod disk;
pub mod format;
pub mod front;
pub mod io;
pub mod metrics;
pub mod prefetch;
pub mod render;
pub mod runtime;
pub mod skeleton;

#[cfg(test)]
mod testutil;

pub use format::{
    FileHeader, FormatError, NodeRecord, PackedVertex, RepHeader, RepKind, RepMesh, RepRecord,
    SceneFile, SceneMeta, SceneWriter,
};
pub use io::{ByteSource, FileSource, MemSource};
pub use skeleton::{RepId, Skeleton, ValidationError};
