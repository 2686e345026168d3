//! `hlod-builder`: turns glTF scenes into the engine's out-of-core scene format.
//!
//! # Architecture
//!
//! - [`import`]: glTF 2.0 reader with bounds-checked accessors (each mesh
//!   instance is an *object*; primitives merged with per-vertex base colours).
//! - [`mesh`]: float meshes and their operations (transform, merge, chunking).
//! - [`cluster`]: scene-graph topology from a BVH over object boxes (obvhs).
//! - [`lod`]: static LOD chains and HLODs with meshopt.
//! - [`build`]: the pipeline writing the scene file through
//!   [`engine::SceneWriter`], atomically and deterministically.
//! - [`scenegen`]: scene generators (procedural plant, tiling of real models) and the
//!   GLB writer they share.
//! - [`layout`]: the order of the reps on disk (selection band, then Morton
//!   order), so that the reps one frame misses are read without seeks.
//! - [`heap`]: the counted heap a build is sized and checked by.
//! - [`summary`]: the Table-1-style summary printed by `build` and `info`.
//! - [`tiles3d`]: export of a scene file as an OGC 3D Tiles 1.1 tileset.
//! - [`walkmap`]: the walk section (solid space by columns, for walk mode).

pub mod build;
pub mod cache;
pub mod cluster;
pub mod deviation;
pub mod heap;
pub mod import;
pub mod layout;
pub mod lod;
pub mod mesh;
pub mod mt;
pub mod scenegen;
pub mod summary;
pub mod tiles3d;
pub mod vdt;
pub mod walkmap;

pub use build::{BuildError, BuildParams, BuildStats, build_file};
