//! The window's GPU side: surface, device (shared with the scene renderer)
//! and the egui painter.

use std::sync::Arc;

use engine_gpu::GpuContext;
use winit::window::Window;

use crate::overlay::{Overlay, color_pass};

/// Window, surface and egui state.
pub struct Gfx {
    pub window: Arc<Window>,
    pub ctx: GpuContext,
    surface: wgpu::Surface<'static>,
    pub config: wgpu::SurfaceConfiguration,
    /// The surface can be read back (screenshots include the overlay).
    pub copy_src: bool,
    /// The surface can be copied into: frames are drawn offscreen and copied
    /// (software presenters read slowly from their images, so the overlay's
    /// blending there costs more than the copy).
    pub copy_dst: bool,
    pub egui_ctx: egui::Context,
    pub egui_state: egui_winit::State,
    egui_renderer: egui_wgpu::Renderer,
    pub overlay: Overlay,
}

impl std::fmt::Debug for Gfx {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Gfx")
            .field("config", &self.config)
            .finish_non_exhaustive()
    }
}

/// A surface texture being drawn this frame.
pub struct Frame {
    pub texture: wgpu::SurfaceTexture,
    pub view: wgpu::TextureView,
}

impl Gfx {
    /// Creates the surface for `window` and an adapter that can present to it.
    pub fn new(window: Arc<Window>, vsync: bool) -> anyhow::Result<Self> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
        let surface = instance.create_surface(window.clone())?;
        let ctx = GpuContext::with_instance(&instance, Some(&surface))?;
        let size = window.inner_size();
        let caps = surface.get_capabilities(&ctx.adapter);
        use wgpu::TextureFormat as F;
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| matches!(f, F::Bgra8Unorm | F::Rgba8Unorm))
            .or_else(|| {
                caps.formats
                    .iter()
                    .copied()
                    .find(|f| matches!(f, F::Bgra8UnormSrgb | F::Rgba8UnormSrgb))
            })
            .ok_or_else(|| anyhow::anyhow!("no 8-bit RGBA/BGRA surface format"))?;
        let copy_src = caps.usages.contains(wgpu::TextureUsages::COPY_SRC);
        let copy_dst = caps.usages.contains(wgpu::TextureUsages::COPY_DST);
        let mut usage = wgpu::TextureUsages::RENDER_ATTACHMENT;
        if copy_src {
            usage |= wgpu::TextureUsages::COPY_SRC;
        }
        if copy_dst {
            usage |= wgpu::TextureUsages::COPY_DST;
        }
        let present_mode = if vsync {
            wgpu::PresentMode::AutoVsync
        } else {
            wgpu::PresentMode::AutoNoVsync
        };
        let config = wgpu::SurfaceConfiguration {
            usage,
            format,
            width: size.width.max(1),
            height: size.height.max(1),
            present_mode,
            desired_maximum_frame_latency: 2,
            alpha_mode: caps
                .alpha_modes
                .first()
                .copied()
                .unwrap_or(wgpu::CompositeAlphaMode::Auto),
            view_formats: vec![],
            color_space: Default::default(),
        };
        surface.configure(&ctx.device, &config);
        let egui_ctx = egui::Context::default();
        let max_side = ctx.device.limits().max_texture_dimension_2d as usize;
        let egui_state = egui_winit::State::new(
            egui_ctx.clone(),
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            None,
            Some(max_side),
        );
        let egui_renderer = egui_wgpu::Renderer::new(
            &ctx.device,
            format,
            egui_wgpu::RendererOptions {
                dithering: false,
                ..Default::default()
            },
        );
        let overlay = Overlay::new(&ctx.device, format, config.width, config.height);
        Ok(Self {
            overlay,
            window,
            ctx,
            surface,
            config,
            copy_src,
            copy_dst,
            egui_ctx,
            egui_state,
            egui_renderer,
        })
    }

    /// Reconfigures after a resize.
    pub fn resize(&mut self, width: u32, height: u32) {
        self.config.width = width.max(1);
        self.config.height = height.max(1);
        self.surface.configure(&self.ctx.device, &self.config);
        self.overlay
            .resize(&self.ctx.device, self.config.width, self.config.height);
    }

    /// The next surface texture, or `None` (after reconfiguring) when the
    /// surface must be skipped this frame.
    pub fn acquire(&mut self) -> Option<Frame> {
        use wgpu::CurrentSurfaceTexture as C;
        match self.surface.get_current_texture() {
            C::Success(t) | C::Suboptimal(t) => {
                let view = t.texture.create_view(&Default::default());
                Some(Frame { texture: t, view })
            }
            C::Outdated | C::Lost => {
                self.surface.configure(&self.ctx.device, &self.config);
                None
            }
            C::Timeout | C::Occluded | C::Validation => None,
        }
    }

    /// Copies a finished offscreen frame into the surface texture.
    pub fn blit(&self, from: &wgpu::Texture, to: &wgpu::Texture) {
        let mut enc = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("blit"),
            });
        enc.copy_texture_to_texture(
            from.as_image_copy(),
            to.as_image_copy(),
            wgpu::Extent3d {
                width: from.width().min(to.width()),
                height: from.height().min(to.height()),
                depth_or_array_layers: 1,
            },
        );
        self.ctx.queue.submit([enc.finish()]);
    }

    /// Blends the cached overlay over `view`.
    pub fn composite(&self, view: &wgpu::TextureView) {
        self.overlay
            .composite(&self.ctx.device, &self.ctx.queue, view);
    }

    /// Clears `view` (no scene open).
    pub fn clear(&self, view: &wgpu::TextureView) {
        let mut enc = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("clear"),
            });
        color_pass(
            &mut enc,
            "clear",
            view,
            wgpu::LoadOp::Clear(engine_gpu::BACKGROUND),
        );
        self.ctx.queue.submit([enc.finish()]);
    }

    /// Paints egui's output into the cached overlay (see [`Overlay`]).
    pub fn paint_egui(&mut self, mut output: egui::FullOutput) {
        self.egui_state
            .handle_platform_output(&self.window, std::mem::take(&mut output.platform_output));
        let shapes = std::mem::take(&mut output.shapes);
        let prims = self.egui_ctx.tessellate(shapes, output.pixels_per_point);
        let (device, queue) = (&self.ctx.device, &self.ctx.queue);
        for (id, deltas) in &output.textures_delta.set {
            for delta in deltas {
                self.egui_renderer.update_texture(device, queue, *id, delta);
            }
        }
        let sd = egui_wgpu::ScreenDescriptor {
            size_in_pixels: [self.config.width, self.config.height],
            pixels_per_point: output.pixels_per_point,
        };
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("egui"),
        });
        let extra = self
            .egui_renderer
            .update_buffers(device, queue, &mut enc, &prims, &sd);
        {
            let pass = color_pass(
                &mut enc,
                "egui",
                self.overlay.view(),
                wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
            );
            let mut pass = pass.forget_lifetime();
            self.egui_renderer.render(&mut pass, &prims, &sd);
        }
        queue.submit(extra.into_iter().chain([enc.finish()]));
        for id in &output.textures_delta.free {
            self.egui_renderer.free_texture(id);
        }
        output.textures_delta.clear();
        let used = self.egui_ctx.globally_used_rect();
        self.overlay.set_area(used, output.pixels_per_point);
    }
}
