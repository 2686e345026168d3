//! Scene generators: a procedural CAD plant and tiled real models, written as
//! GLB so that any glTF tool opens them.

pub mod glb;
pub mod lattice;
pub mod plant;
pub mod rock;
pub mod shapes;
pub mod tile;
