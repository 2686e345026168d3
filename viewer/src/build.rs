//! Models opened directly (`hlod-view MODEL.glb`): built into the cache on
//! a background thread by the builder's own code
//! ([`hlod_builder::cache::cached_scene`]), with the stage and the nodes
//! done shown in the window, then opened as a scene.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

use hlod_builder::cache::{Cached, cache_dir, cached_scene};

/// Whether `path` is a model rather than a scene file: by its first bytes
/// (`glTF`, or JSON), else by its extension (`.glb`, `.gltf`, `.ply`,
/// `.obj`, `.stl`).
pub fn is_model(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 8];
    let n = engine::infile::open(path)
        .and_then(|mut f| f.read(&mut head))
        .unwrap_or(0);
    if n >= 8 && head == engine::format::MAGIC {
        return false;
    }
    let first = head[..n].iter().find(|b| !b.is_ascii_whitespace());
    if head[..n].starts_with(b"glTF")
        || first == Some(&b'{')
        || head[..n].starts_with(b"\xEF\xBB\xBF")
    {
        return true;
    }
    hlod_builder::import::Format::of_extension(path).is_some()
}

/// Stage, nodes done, nodes in all.
type Progress = Arc<Mutex<(String, u64, u64)>>;

/// A build in progress.
pub struct Building {
    pub input: PathBuf,
    progress: Progress,
    started: Instant,
    handle: JoinHandle<Result<(Cached, f64), String>>,
}

impl Building {
    /// Starts building `input` (with the default build parameters) into
    /// the cache in `dir` (or the default cache directory).
    pub fn start(input: &Path, dir: Option<&Path>) -> Self {
        let progress: Progress = Arc::new(Mutex::new(("starting".into(), 0, 0)));
        let (p, inp, dir) = (progress.clone(), input.to_path_buf(), cache_dir(dir));
        let handle = std::thread::spawn(move || {
            let t = Instant::now();
            // Said once the cache has no usable entry and the build starts,
            // not on a hit.
            let said = std::sync::atomic::AtomicBool::new(false);
            let (name, place) = (inp.display().to_string(), dir.display().to_string());
            let report = move |stage: &str, done: u64, total: u64| {
                let looking = matches!(stage, "hashing the model" | "checking the cached scene");
                if !looking && !said.swap(true, std::sync::atomic::Ordering::Relaxed) {
                    tracing::info!("building {name} into the cache at {place}");
                }
                if let Ok(mut g) = p.lock() {
                    *g = (stage.to_string(), done, total);
                }
            };
            cached_scene(&inp, &hlod_builder::BuildParams::default(), &dir, &report)
                .map(|c| (c, t.elapsed().as_secs_f64()))
                .map_err(|e| format!("{:#}", anyhow::Error::from(e)))
        });
        Self {
            input: input.to_path_buf(),
            progress,
            started: Instant::now(),
            handle,
        }
    }

    pub fn finished(&self) -> bool {
        self.handle.is_finished()
    }

    /// The build's result (a panic in it is an error, not the viewer's end).
    pub fn join(self) -> Result<(Cached, f64), String> {
        self.handle
            .join()
            .unwrap_or_else(|_| Err("the build stopped unexpectedly".into()))
    }

    /// What the overlay shows: "building NAME: stage (done/total), N s", and the fraction done.
    pub fn status(&self) -> (String, f32) {
        let (stage, done, total) = self
            .progress
            .lock()
            .map(|g| g.clone())
            .unwrap_or_else(|_| ("?".into(), 0, 0));
        let name = self
            .input
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        let counts = if total > 0 {
            format!(" ({done}/{total} nodes)")
        } else {
            String::new()
        };
        let frac = if total > 0 {
            done as f32 / total as f32
        } else {
            0.0
        };
        (
            format!(
                "building {name}: {stage}{counts}, {:.1} s",
                self.started.elapsed().as_secs_f64()
            ),
            frac,
        )
    }
}

/// What the viewer prints once a model's scene is ready: where it came from
/// (the cache, or built now) and, as `hlod-build` says it, what the build left
/// out.
pub fn opened_lines(input: &Path, cached: &Cached, secs: f64) -> Vec<String> {
    let how = if cached.hit {
        "cached scene"
    } else {
        "built into"
    };
    let mut lines = vec![format!(
        "{}: {how} {} in {secs:.2} s",
        input.display(),
        cached.scene.display()
    )];
    if cached.hidden_triangles > 0 {
        let objects = cached
            .hidden_objects
            .map_or_else(String::new, |n| format!("{n} objects, "));
        lines.push(format!(
            "{}: left out the IFC opening voids and spaces ({objects}{} triangles): they are not \
             drawn; `hlod-build build --ifc-voids` keeps them",
            input.display(),
            cached.hidden_triangles
        ));
    }
    lines
}
