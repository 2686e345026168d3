//! The wgpu renderer: the only part of the engine that touches the GPU.
//!
//! - [`GpuContext`] opens an adapter by itself (a real GPU when there is one,
//!   else a software rasteriser such as Mesa's lavapipe) and a device.
//! - [`arena`] sub-allocates rep geometry from a few large buffers (plain
//!   Rust, tested without a GPU).
//! - [`GpuRenderer`] implements [`engine::render::Renderer`]: a rep's payload is
//!   uploaded into the arena when P_R first gets it (while P_I still loads the
//!   rest of the frame), freed when P_I evicts the rep, and the frame's reps
//!   are drawn in one depth-tested pass at the end of the frame, sorted by rep
//!   id so that equal fronts give identical images whatever the arrival order.
//!   It renders into its own texture (headless, read back on request) or into
//!   a caller's texture view (a window surface).

pub mod arena;
mod order;
mod parts;
mod renderer;
mod resources;

pub use parts::Colouring;
pub use renderer::{BACKGROUND, GpuRenderer, GpuStats, RendererConfig};
pub use resources::read_texture;

use std::sync::{Arc, Mutex};

/// Why the GPU cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error(
        "no usable GPU adapter (on a machine without a GPU install Mesa's software Vulkan driver: apt-get install mesa-vulkan-drivers libvulkan1): {0}"
    )]
    NoAdapter(String),
    #[error("the GPU device could not be opened: {0}")]
    Device(String),
    #[error("GPU error: {0}")]
    Wgpu(String),
    #[error("invalid renderer parameter: {0}")]
    Params(String),
}

/// An adapter, its device and queue, and the errors the device reported.
#[derive(Clone, Debug)]
pub struct GpuContext {
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    errors: Arc<Mutex<Vec<String>>>,
}

impl GpuContext {
    /// Opens the best adapter available, without a window.
    pub fn new() -> Result<Self, GpuError> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
        Self::with_instance(&instance, None)
    }

    /// Opens an adapter of `instance` that can present to `surface`, if given.
    pub fn with_instance(
        instance: &wgpu::Instance,
        surface: Option<&wgpu::Surface<'_>>,
    ) -> Result<Self, GpuError> {
        let mut last_err = String::new();
        let mut adapter = None;
        // A hardware adapter first; then whatever software one there is.
        for fallback in [false, true] {
            let opts = wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                force_fallback_adapter: fallback,
                compatible_surface: surface,
                apply_limit_buckets: false,
            };
            match pollster::block_on(instance.request_adapter(&opts)) {
                Ok(a) => {
                    adapter = Some(a);
                    break;
                }
                Err(e) => last_err = e.to_string(),
            }
        }
        let adapter = adapter.ok_or(GpuError::NoAdapter(last_err))?;
        let desc = wgpu::DeviceDescriptor {
            label: Some("engine"),
            required_features: wgpu::Features::empty(),
            required_limits: adapter.limits(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::MemoryUsage,
            trace: wgpu::Trace::Off,
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&desc))
            .map_err(|e| GpuError::Device(e.to_string()))?;
        let errors = Arc::new(Mutex::new(Vec::new()));
        let sink = errors.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            tracing::error!("wgpu: {e}");
            if let Ok(mut v) = sink.lock() {
                v.push(e.to_string());
            }
        }));
        Ok(Self {
            adapter,
            device,
            queue,
            errors,
        })
    }

    /// "name (backend, device type)".
    pub fn describe(&self) -> String {
        let i = self.adapter.get_info();
        format!("{} ({:?}, {:?})", i.name, i.backend, i.device_type)
    }

    /// The device errors reported since the last call.
    pub fn take_errors(&self) -> Vec<String> {
        self.errors
            .lock()
            .map(|mut v| std::mem::take(&mut *v))
            .unwrap_or_default()
    }
}

/// The WGSL source of the rep shader (`shaders/mesh.wgsl`).
pub const MESH_WGSL: &str = include_str!("../../../shaders/mesh.wgsl");
