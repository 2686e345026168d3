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
//! - [`format`](mod@format): the versioned on-disk scene format — `repr(C)` records with
//!   asserted sizes, the [`SceneWriter`] used by the builder, the validating
//!   [`SceneFile`] reader and the rep payload codec ([`RepMesh`]).
//! - [`skeleton`]: the in-core hierarchy, the paper's PAR/CHD/ASC/DSC relations
//!   over object-reps and [`Skeleton::validate`].
//! - [`io`] and [`disk`]: [`ByteSource`] (file, in-memory) and the disk models
//!   behind it (a modelled device on a [`clock::Clock`], fault injection).
//! - [`camera`]: poses, views, frustum, projected error and the camera path
//!   format; [`front`]: the per-frame front (frustum and
//!   simplification culling).
//! - [`evict`] (one eviction interface: StartTail InMemoryList, LRU, Belady), [`prefetch`] (bins, AngPr, Priority)
//!   and [`runtime`]: P_R ([`runtime::Walkthrough`]) and the P_I loader thread
//!   under a hard byte budget, in `incore`, `nopre` and `pre` modes.
//! - [`metrics`] (per-frame CSV, summaries) and [`render`] (the renderer trait
//!   and the `none` renderer).
//! - [`measure`]: point-to-point distances, picks snapped to a corner or edge.
//! - [`pick`]: the object under a pixel (leaf boxes, then the finest rep's
//!   triangles), resolved through the scene file's object section.
//! - [`section`]: section planes and boxes, culled with the frustum;
//!   [`hide`]: hidden elements, which nodes leave the front.
//! - [`limits`] (checked durations, allocations and reads bounded by the
//!   file and the machine) and [`infile`] (the input policy of every reader:
//!   regular files only, remembered so that no output overwrites them).
//! - [`vdt`]: view-dependence trees (El-Sana & Chiang) for large objects —
//!   the tree, meta-node blocking and file, per-frame refinement, the
//!   place-holder buffer manager with its I/O thread, and the
//!   virtual-memory baseline. A tree is a large object's finest rep in the
//!   scene file (`RepKind::Vdt`); P_R refines and draws it
//!   (`runtime::trees`) under the runtime's one footprint.
//!
//! This crate holds data and algorithms only: no GPU, no network, no sleeps
//! (time comes from a [`clock::Clock`]), no output files. The wgpu renderer
//! is the `engine-gpu` crate (`engine/gpu/`), behind [`render::Renderer`];
//! the programs' shared plumbing is `engine-cli` (`engine/cli/`): error
//! report, validated parameters, the output-file policy, PNG files, scene
//! files behind disk models, scenes on a server and their disk cache,
//! generated paths and report tables; `hlod-bench` / `vdt-bench` with their
//! plots live in `engine-tools` (`engine/tools/`).

pub mod camera;
pub mod clock;
pub mod disk;
pub mod evict;
pub mod fade;
pub mod format;
pub mod front;
pub mod governor;
pub mod hide;
pub mod image;
pub mod infile;
pub mod interior;
pub mod io;
pub mod limits;
pub mod measure;
pub mod metrics;
pub mod mt;
pub mod occlusion;
pub mod pick;
pub mod prefetch;
pub mod records;
pub mod render;
pub mod runtime;
pub mod section;
pub mod skeleton;
pub mod tree;
pub mod vdt;
pub mod walk;

#[cfg(test)]
mod testutil;

pub use format::{
    FileHeader, FormatError, NodeRecord, PackedVertex, RepHeader, RepKind, RepMesh, RepRecord,
    SceneFile, SceneMeta, SceneWriter,
};
pub use io::{AnswerLog, ByteSource, FileSource, MemSource, Response};
pub use skeleton::{RepId, Skeleton, ValidationError};
