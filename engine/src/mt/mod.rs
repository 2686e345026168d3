//! Multi-Triangulations paged from disk (Holst & Schumann, *Memory-efficient
//! view-dependent level of detail of high-detailed meshes*): the second kind
//! of finest rep for large objects, beside El-Sana & Chiang's trees.
//!
//! - [`graph`]: the DAG of local simplifications whose arcs carry patches
//!   of triangles ([`Mt`]), its checks and cut extraction; built by
//!   `hlod_builder::mt`.
//! - [`partition`]: the greedy partitioning by connecting arcs (§4.2).
//! - [`file`]: the file layout (§4.1): each node followed by its outgoing
//!   arcs and their geometry, ingoing arcs as (father, position) tuples,
//!   nodes stored partition by partition, every record checksummed.
//! - [`cache`]: node caching with the layer tuples (§4.3) and the paper's
//!   three baselines; plain policy, told the frame.
//! - [`store`]: resident nodes under a byte budget, read through a
//!   [`crate::io::ByteSource`].
//! - [`cut`]: the per-frame cut by the screen-space error, top-down and
//!   bottom-up from the last cut.

pub mod cache;
pub mod cut;
pub mod file;
pub mod graph;
pub mod partition;
pub mod store;

pub use graph::{CutReport, DRAIN, Mt, MtArc, MtError, MtNode, Topology};
pub use partition::{Partitioning, partition};
