//! Construction of view-dependence trees (El-Sana & Varshney; El-Sana &
//! Chiang §2.1.1, §3.3.5). The tree types, their checks and the meta-node
//! blocking live in [`engine::vdt`], which the run time shares; this module
//! builds the forest from a mesh ([`build_tree`]) and a large object's
//! tree rep for the scene file ([`tree_levels`], [`write_rep`]).

mod build;
pub(crate) mod rep;
#[cfg(test)]
mod tests;

pub use build::{Metric, VdtParams, build_tree};
pub use engine::vdt::{NONE, VdNode, VdTree, meta};
pub use rep::{TreeRep, tree_levels, write_rep};
