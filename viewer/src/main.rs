//! `hlod-view`: the interactive walkthrough viewer.
//!
//! The winit + egui viewer is built on the out-of-core runtime and the wgpu
//! renderer. Until those land, this binary opens a scene file, validates it and
//! prints its skeleton summary, so that the command and crate exist in the
//! workspace with their final names.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};

fn main() -> ExitCode {
    engine::cli::main_with(run)
}

fn run() -> Result<()> {
    let path: PathBuf = std::env::args_os()
        .nth(1)
        .map(PathBuf::from)
        .context("usage: hlod-view SCENE.hlod")?;
    let scene = engine::SceneFile::open(&path).with_context(|| path.display().to_string())?;
    let s = scene.skeleton();
    println!(
        "{}: {} nodes, {} object-reps, height {}, {} objects (interactive viewing is not implemented yet)",
        path.display(),
        s.nodes.len(),
        s.reps.len(),
        s.height(),
        scene.meta().object_count
    );
    Ok(())
}
