//! The end-to-end tests, one module per area, linked into one test binary
//! (each binary links the builder and wgpu; one link instead of eleven).

mod bad_input;
mod conformance;
mod corrupt_gltf;
mod draco;
mod fade;
mod formats;
mod gpu_shot;
mod ifc;
mod instances;
mod layout;
mod mt_scene;
mod objects;
mod occlusion;
mod reencode;
mod remote;
mod render;
mod scenes;
mod section;
mod tiles3d;
mod tree;
mod vdt;
mod vdt_runtime;
mod vdt_scene;
mod walkthrough;
