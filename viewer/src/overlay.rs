//! The egui overlay as a cached texture: egui paints into it only when the
//! overlay changes (input, or `--overlay-hz` times a second for the live numbers), and
//! every frame composites it over the scene with a trivial blend restricted
//! to the overlay's area. On a software rasteriser egui's own pass costs
//! about half a frame; the composite costs a small fraction of that.

/// The composite pipeline and the cached overlay texture.
pub struct Overlay {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    texture: wgpu::Texture,
    view: wgpu::TextureView,
    bind_group: wgpu::BindGroup,
    /// Pixels covered by the overlay: x, y, width, height.
    pub rect: [u32; 4],
}

const WGSL: &str = include_str!("../../shaders/overlay.wgsl");

impl Overlay {
    pub fn new(device: &wgpu::Device, format: wgpu::TextureFormat, w: u32, h: u32) -> Self {
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("overlay"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            }],
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("overlay.wgsl"),
            source: wgpu::ShaderSource::Wgsl(WGSL.into()),
        });
        let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("overlay"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("overlay"),
            layout: Some(&pl),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: Default::default(),
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format,
                    blend: Some(wgpu::BlendState::PREMULTIPLIED_ALPHA_BLENDING),
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        let (texture, view, bind_group) = target(device, &layout, format, w, h);
        Self {
            pipeline,
            layout,
            texture,
            view,
            bind_group,
            rect: [0, 0, 0, 0],
        }
    }

    /// Follows a window resize.
    pub fn resize(&mut self, device: &wgpu::Device, w: u32, h: u32) {
        let (t, v, b) = target(device, &self.layout, self.texture.format(), w, h);
        self.texture = t;
        self.view = v;
        self.bind_group = b;
        self.rect = [0, 0, 0, 0];
    }

    /// Where egui paints (cleared to transparent first).
    pub fn view(&self) -> &wgpu::TextureView {
        &self.view
    }

    /// Sets the covered area from egui's used rectangle in points.
    pub fn set_area(&mut self, used: egui::Rect, pixels_per_point: f32) {
        let (w, h) = (self.texture.width(), self.texture.height());
        if !used.is_positive() {
            self.rect = [0, 0, 0, 0];
            return;
        }
        // Shadows reach a little beyond the windows.
        let pad = 24.0;
        let x0 = ((used.min.x * pixels_per_point - pad).max(0.0) as u32).min(w);
        let y0 = ((used.min.y * pixels_per_point - pad).max(0.0) as u32).min(h);
        let x1 = ((used.max.x * pixels_per_point + pad).max(0.0) as u32).min(w);
        let y1 = ((used.max.y * pixels_per_point + pad).max(0.0) as u32).min(h);
        self.rect = [x0, y0, x1.saturating_sub(x0), y1.saturating_sub(y0)];
    }

    /// Blends the cached overlay over `frame`.
    pub fn composite(&self, device: &wgpu::Device, queue: &wgpu::Queue, frame: &wgpu::TextureView) {
        let [x, y, w, h] = self.rect;
        if w == 0 || h == 0 {
            return;
        }
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("overlay composite"),
        });
        {
            let mut pass = color_pass(&mut enc, "overlay composite", frame, wgpu::LoadOp::Load);
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.set_scissor_rect(x, y, w, h);
            pass.draw(0..3, 0..1);
        }
        queue.submit([enc.finish()]);
    }
}

fn target(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    format: wgpu::TextureFormat,
    w: u32,
    h: u32,
) -> (wgpu::Texture, wgpu::TextureView, wgpu::BindGroup) {
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("overlay"),
        size: wgpu::Extent3d {
            width: w.max(1),
            height: h.max(1),
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
        view_formats: &[],
    });
    let view = texture.create_view(&Default::default());
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("overlay"),
        layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: wgpu::BindingResource::TextureView(&view),
        }],
    });
    (texture, view, bind_group)
}

/// A colour-only render pass over `view` (no depth), storing its result.
pub fn color_pass<'e>(
    enc: &'e mut wgpu::CommandEncoder,
    label: &str,
    view: &wgpu::TextureView,
    load: wgpu::LoadOp<wgpu::Color>,
) -> wgpu::RenderPass<'e> {
    enc.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load,
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}
