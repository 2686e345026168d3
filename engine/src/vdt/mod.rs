//! View-dependence trees (El-Sana & Chiang, *External Memory
//! View-Dependent Simplification*, §2.1.1, §3.2, §3.3): the finest
//! object-rep of large objects, refined per frame and paged from disk.
//!
//! - [`tree`]: the vertex hierarchy ([`VdTree`], [`VdNode`]) with its
//!   implicit-dependency data and `validate()`; built by
//!   `hlod_builder::vdt`.
//! - [`meta`]: meta-node blocking (every `L` levels top-down into a block),
//!   the DATA/MNT encoding and its checked decode.
//! - [`file`]: the `.vdt` file (header, MNT, DATA, and the flat layout the
//!   virtual-memory baseline pages).
//! - [`refine`]: per-frame refinement (active nodes, active triangles,
//!   split/collapse under the screen-space metric and the implicit
//!   dependency tests), generic over a [`refine::NodeStore`].
//! - [`buffer`]: the place-holder buffer manager (hash table, FIFO free list
//!   with second chance, usage and reference counts, urgent prefetch).
//! - [`ext`]: the external-memory store (buffer manager on the navigating
//!   thread, an I/O thread reading meta-nodes); [`virt`]: the
//!   virtual-memory baseline (4 KiB pages, LRU, synchronous faults).
//! - [`raster`]: a small CPU rasteriser used to measure image quality.
//!
//! Leaves are numbered depth-first, so a node's subtree holds exactly the
//! leaves `leaf..leaf_end` and the active nodes partition the leaf range:
//! a split hands each triangle corner to the child whose interval holds the
//! corner's leaf, without touching anything below the split node.

pub mod buffer;
pub mod ext;
pub mod file;
pub mod meta;
pub mod raster;
pub mod refine;
pub mod tree;
pub mod virt;

pub use tree::{NONE, VdNode, VdTree};
