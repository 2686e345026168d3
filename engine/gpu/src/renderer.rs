//! [`GpuRenderer`]: resident reps in arena buffers, one pass per frame.

use std::collections::{HashMap, HashSet};
use std::mem::size_of;
use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use super::arena::{Alloc, Arena};
use super::order::back_to_front;
use super::parts::{Colouring, Parts, XRAY_DIRECTION};
use super::resources::{
    DrawData, Target, bind, create_pipeline, draw_buffer, layout_entry, make_target, read_texture,
    view_proj,
};
use super::{GpuContext, GpuError};
use engine::camera::View;
use engine::format::RepRecord;
use engine::format::{PackedVertex, REP_MAGIC, RepHeader};
use engine::image::RgbaImage;
use engine::render::{DrawStyle, Fade, Renderer};
use engine::skeleton::RepId;

/// The clear colour of every frame.
pub const BACKGROUND: wgpu::Color = wgpu::Color {
    r: 0.09,
    g: 0.10,
    b: 0.12,
    a: 1.0,
};

/// Renderer set-up.
#[derive(Clone, Copy, Debug)]
pub struct RendererConfig {
    pub width: u32,
    pub height: u32,
    /// GPU bytes for rep geometry: the runtime's budget in the out-of-core
    /// modes (a rep's geometry is its payload less the header, so whatever the
    /// runtime holds fits), the scene's data size in-core.
    pub capacity_bytes: u64,
    pub colouring: Colouring,
    /// Format of the colour target: `Rgba8Unorm` or `Bgra8Unorm` (and their
    /// sRGB forms) — a window surface's format, or the headless default.
    pub color_format: wgpu::TextureFormat,
}

impl RendererConfig {
    /// A headless RGBA8 target of `width × height` holding `capacity_bytes`.
    pub fn headless(width: u32, height: u32, capacity_bytes: u64) -> Self {
        Self {
            width,
            height,
            capacity_bytes,
            colouring: Colouring::Object,
            color_format: wgpu::TextureFormat::Rgba8Unorm,
        }
    }
}

/// Renderer counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GpuStats {
    pub uploads: u64,
    pub uploaded_bytes: u64,
    /// Geometry bytes on the GPU now, and the most ever.
    pub live_bytes: u64,
    pub max_live_bytes: u64,
    /// Times the arena was repacked because it was too fragmented.
    pub repacks: u32,
    /// Reps whose payload did not match its record (each logged once).
    pub bad_payloads: u64,
    pub draws: u64,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct Globals {
    view_proj: [[f32; 4]; 4],
    eye: [f32; 4],
    /// The view's section planes (`engine::section`), `section[0]` of them.
    planes: [[f32; 4]; engine::section::MAX_PLANES],
    section: [u32; 4],
}
const _: () = assert!(size_of::<Globals>() == 224);

#[derive(Clone, Copy, Debug)]
struct Slot {
    alloc: Alloc,
    vertex_count: u32,
    index_count: u32,
    index_u32: bool,
    quant_min: [f32; 3],
    quant_scale: [f32; 3],
    last_frame: u32,
    /// Some vertex colour is translucent: the rep is drawn by the
    /// translucent pass too.
    translucent: bool,
}

impl Slot {
    /// The size of the rep's quantisation box (its vertices' bounds).
    fn extent(&self) -> [f32; 3] {
        self.quant_scale.map(|x| x * 65535.0)
    }
}

#[derive(Debug)]
struct FrameDraw {
    rep: RepId,
    /// The id its payload's slot is held under (a shared payload's source).
    key: RepId,
    /// Rows of the affine placing the payload (identity when not shared).
    place: [[f32; 4]; 3],
    substitute: bool,
    fade: Fade,
    level: u16,
    kind: u16,
    payload: Arc<[u8]>,
}

/// The rows of the identity affine: a payload in scene coordinates.
const IDENTITY_ROWS: [[f32; 4]; 3] = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
];

/// Draws fronts with wgpu; see the module docs.
#[derive(Debug)]
pub struct GpuRenderer {
    ctx: GpuContext,
    cfg: RendererConfig,
    pipeline: wgpu::RenderPipeline,
    /// The translucent pass's pipeline (alpha blending, no depth write).
    blend_pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    globals: wgpu::Buffer,
    draw_buf: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    arena: Arena,
    chunks: Vec<wgpu::Buffer>,
    slots: HashMap<RepId, Slot>,
    frame_draws: Vec<FrameDraw>,
    frame_no: u32,
    view: Option<View>,
    target: Target,
    /// Where frames go instead of `target.color` (a surface texture).
    output: Option<wgpu::TextureView>,
    capture_next: bool,
    captured: Option<RgbaImage>,
    capture_every: u32,
    captures: Vec<(u32, RgbaImage)>,
    stats: GpuStats,
    warned: HashSet<RepId>,
    repacking: bool,
    /// Reps drawn in part or x-rayed ([`Renderer::set_parts`]).
    parts: Parts,
}

impl GpuRenderer {
    /// Creates the pipeline, the arena and a `width × height` target.
    pub fn new(ctx: GpuContext, cfg: RendererConfig) -> Result<Self, GpuError> {
        let limits = ctx.device.limits();
        let max_dim = limits.max_texture_dimension_2d;
        use wgpu::TextureFormat as F;
        if !matches!(
            cfg.color_format,
            F::Rgba8Unorm | F::Rgba8UnormSrgb | F::Bgra8Unorm | F::Bgra8UnormSrgb
        ) {
            return Err(GpuError::Params(format!(
                "colour format {:?} not supported",
                cfg.color_format
            )));
        }
        if cfg.width == 0 || cfg.height == 0 || cfg.width > max_dim || cfg.height > max_dim {
            return Err(GpuError::Params(format!(
                "target size {}x{} outside 1..={max_dim}",
                cfg.width, cfg.height
            )));
        }
        let chunk_size = limits.max_buffer_size.min(256 << 20);
        let arena = Arena::new(cfg.capacity_bytes, chunk_size);
        let device = &ctx.device;
        let chunks = arena
            .chunk_sizes()
            .enumerate()
            .map(|(i, size)| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(&format!("rep arena {i}")),
                    size,
                    usage: wgpu::BufferUsages::VERTEX
                        | wgpu::BufferUsages::INDEX
                        | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            })
            .collect();
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("mesh"),
            entries: &[
                layout_entry(0, wgpu::BufferBindingType::Uniform),
                layout_entry(1, wgpu::BufferBindingType::Storage { read_only: true }),
            ],
        });
        let pipeline = create_pipeline(device, &layout, cfg.color_format, false);
        let blend_pipeline = create_pipeline(device, &layout, cfg.color_format, true);
        let globals = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("globals"),
            size: size_of::<Globals>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let draw_buf = draw_buffer(device, 1024);
        let bind_group = bind(device, &layout, &globals, &draw_buf);
        let target = make_target(device, cfg.width, cfg.height, cfg.color_format);
        let errs = ctx.take_errors();
        if !errs.is_empty() {
            return Err(GpuError::Wgpu(errs.join("; ")));
        }
        Ok(Self {
            ctx,
            cfg,
            pipeline,
            blend_pipeline,
            layout,
            globals,
            draw_buf,
            bind_group,
            arena,
            chunks,
            slots: HashMap::new(),
            frame_draws: Vec::new(),
            frame_no: 0,
            view: None,
            target,
            output: None,
            capture_next: false,
            captured: None,
            capture_every: 0,
            captures: Vec::new(),
            stats: GpuStats::default(),
            warned: HashSet::new(),
            repacking: false,
            parts: Parts::default(),
        })
    }

    /// The device and queue in use.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// Counters so far.
    pub fn stats(&self) -> GpuStats {
        self.stats
    }

    /// Changes the debug colouring from the next frame on.
    pub fn set_colouring(&mut self, c: Colouring) {
        self.cfg.colouring = c;
    }

    /// Reads the next finished frame back (see [`take_capture`](Self::take_capture)).
    pub fn capture_next_frame(&mut self) {
        self.capture_next = true;
    }

    /// Reads back every `n`-th frame (frames 0, n, 2n, … counted from the
    /// first; 0 = none) and keeps the images for [`take_captures`](Self::take_captures).
    pub fn capture_every(&mut self, n: u32) {
        self.capture_every = n;
    }

    /// The periodic captures so far: (frame index, image).
    pub fn take_captures(&mut self) -> Vec<(u32, RgbaImage)> {
        std::mem::take(&mut self.captures)
    }

    /// The image read back from the last frame asked for.
    pub fn take_capture(&mut self) -> Option<RgbaImage> {
        self.captured.take()
    }

    /// The texture frames are drawn into when no output is set.
    pub fn target_texture(&self) -> &wgpu::Texture {
        &self.target.color
    }

    /// A view of the own target (to draw an overlay on before copying it out).
    pub fn target_view(&self) -> &wgpu::TextureView {
        &self.target.color_view
    }

    /// Draws the following frames into `view` (e.g. a window surface's
    /// texture, of the configured format and size) instead of the own
    /// target; `None` goes back to the own target.
    pub fn set_output(&mut self, view: Option<wgpu::TextureView>) {
        self.output = view;
    }

    /// Drops every GPU copy (the runtime restarted with a new resident set).
    pub fn clear(&mut self) {
        self.slots.clear();
        self.arena.reset();
        self.stats.live_bytes = 0;
    }

    /// The configuration in force.
    pub fn config(&self) -> &RendererConfig {
        &self.cfg
    }

    /// Changes the target size (a window resize).
    pub fn resize(&mut self, width: u32, height: u32) -> Result<(), GpuError> {
        let max_dim = self.ctx.device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max_dim || height > max_dim {
            return Err(GpuError::Params(format!(
                "target size {width}x{height} outside 1..={max_dim}"
            )));
        }
        self.cfg.width = width;
        self.cfg.height = height;
        self.target = make_target(&self.ctx.device, width, height, self.cfg.color_format);
        Ok(())
    }

    fn free_slot(&mut self, rep: RepId) {
        if let Some(s) = self.slots.remove(&rep) {
            self.arena.free(s.alloc);
            self.stats.live_bytes = self.arena.live_bytes();
        }
    }

    /// Makes `bytes` of arena space: first by dropping GPU copies not drawn
    /// this frame (oldest first), then by repacking this frame's reps.
    fn allocate(&mut self, bytes: u64) -> Option<Alloc> {
        if let Some(a) = self.arena.alloc(bytes) {
            return Some(a);
        }
        if bytes > self.arena.max_alloc() || self.repacking {
            return None;
        }
        let mut idle: Vec<(u32, RepId)> = self
            .slots
            .iter()
            .filter(|(_, s)| s.last_frame != self.frame_no)
            .map(|(&r, s)| (s.last_frame, r))
            .collect();
        idle.sort_unstable();
        for (_, r) in idle {
            self.free_slot(r);
            if let Some(a) = self.arena.alloc(bytes) {
                return Some(a);
            }
        }
        // Fragmented by this frame's own reps: repack them.
        self.stats.repacks += 1;
        self.arena.reset();
        self.slots.clear();
        let draws: Vec<(RepId, Arc<[u8]>)> = self
            .frame_draws
            .iter()
            .map(|d| (d.key, d.payload.clone()))
            .collect();
        self.repacking = true;
        for (rep, payload) in draws {
            if !self.slots.contains_key(&rep) {
                let _ = self.upload(rep, &payload);
            }
        }
        self.repacking = false;
        self.arena.alloc(bytes)
    }

    /// Uploads a payload's vertices and indices; `false` if it is malformed
    /// or cannot fit.
    fn upload(&mut self, rep: RepId, payload: &[u8]) -> bool {
        let hsize = size_of::<RepHeader>();
        let Some(h) = payload
            .get(..hsize)
            .map(bytemuck::pod_read_unaligned::<RepHeader>)
        else {
            return false;
        };
        let vbytes = h.vertex_count as usize * size_of::<PackedVertex>();
        let ibytes = (h.index_count as usize * h.index_size as usize).next_multiple_of(4);
        let ok = h.magic == REP_MAGIC
            && matches!(h.index_size, 2 | 4)
            && h.index_count % 3 == 0
            && payload.len() >= hsize + vbytes + ibytes;
        if !ok {
            return false;
        }
        let body = &payload[hsize..hsize + vbytes + ibytes];
        let Some(alloc) = self.allocate(body.len() as u64) else {
            return false;
        };
        let buf = &self.chunks[alloc.chunk as usize];
        self.ctx.queue.write_buffer(buf, alloc.offset, body);
        // The alpha byte ends each packed vertex.
        let vs = size_of::<PackedVertex>();
        let translucent = body[..vbytes].chunks_exact(vs).any(|v| v[vs - 1] < u8::MAX);
        self.slots.insert(
            rep,
            Slot {
                alloc,
                vertex_count: h.vertex_count,
                index_count: h.index_count,
                index_u32: h.index_size == 4,
                quant_min: h.quant_min,
                quant_scale: h.quant_scale,
                last_frame: self.frame_no,
                translucent,
            },
        );
        self.stats.uploads += 1;
        self.stats.uploaded_bytes += body.len() as u64;
        self.stats.live_bytes = self.arena.live_bytes();
        self.stats.max_live_bytes = self.stats.max_live_bytes.max(self.stats.live_bytes);
        true
    }

    /// Draws this frame's reps into `color` (with `depth`) and submits.
    fn encode_frame(&mut self, color: &wgpu::TextureView, depth: &wgpu::TextureView) {
        let device = &self.ctx.device;
        let mut draws: Vec<(usize, Slot)> = self
            .frame_draws
            .iter()
            .enumerate()
            .filter_map(|(i, d)| self.slots.get(&d.key).map(|s| (i, *s)))
            .collect();
        draws.sort_unstable_by_key(|(i, s)| (s.alloc.chunk, s.index_u32, self.frame_draws[*i].rep));
        let mut data: Vec<DrawData> = draws
            .iter()
            .map(|(i, s)| {
                let e = s.extent();
                // w: the fade's progress and direction (the shader's dither).
                let (t, dir) = match self.frame_draws[*i].fade {
                    Fade::Opaque => (1.0, 0.0),
                    Fade::In(t) => (t, 1.0),
                    Fade::Out(t) => (t, 2.0),
                };
                let d = &self.frame_draws[*i];
                DrawData {
                    quant_min: [s.quant_min[0], s.quant_min[1], s.quant_min[2], t],
                    quant_extent: [e[0], e[1], e[2], dir],
                    tint: self.cfg.colouring.tint(d.level, d.kind, d.substitute),
                    place: d.place,
                }
            })
            .collect();
        // X-rayed draws use a second record each, after the first ones.
        let n = data.len();
        if self.parts.any_xray() {
            data.extend_from_within(..);
            for d in &mut data[n..] {
                (d.quant_min[3], d.quant_extent[3]) = (1.0, XRAY_DIRECTION);
            }
        }
        if data.len() as u64 > self.draw_buf.size() / size_of::<DrawData>() as u64 {
            self.draw_buf = draw_buffer(device, data.len().next_power_of_two() as u64);
            self.bind_group = bind(device, &self.layout, &self.globals, &self.draw_buf);
        }
        if !data.is_empty() {
            self.ctx
                .queue
                .write_buffer(&self.draw_buf, 0, bytemuck::cast_slice(&data));
        }
        if let Some(v) = &self.view {
            let mut planes = [[0.0; 4]; engine::section::MAX_PLANES];
            for (d, p) in planes.iter_mut().zip(v.section.planes()) {
                *d = p.to_array();
            }
            let g = Globals {
                view_proj: view_proj(v).to_cols_array_2d(),
                eye: v.pose.position.extend(1.0).to_array(),
                planes,
                section: [v.section.planes().len() as u32, 0, 0, 0],
            };
            self.ctx
                .queue
                .write_buffer(&self.globals, 0, bytemuck::bytes_of(&g));
        }
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("frame"),
        });
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("front"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: color,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(BACKGROUND),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: depth,
                    // Reverse Z: 0 is infinitely far.
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(0.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            if self.view.is_some() && !draws.is_empty() {
                pass.set_bind_group(0, &self.bind_group, &[]);
                // The opaque pass, then the translucent pass over it: only
                // the reps with a translucent colour, back to front.
                // X-rayed elements go last, over everything, hiding nothing.
                pass.set_pipeline(&self.pipeline);
                self.stats.draws += self.issue(&mut pass, &draws, 0..draws.len(), false);
                let glass = self.translucent_order(&draws, false);
                let xray = self.translucent_order(&draws, true);
                if !glass.is_empty() || !xray.is_empty() {
                    pass.set_pipeline(&self.blend_pipeline);
                    self.stats.draws += self.issue(&mut pass, &draws, glass, false);
                    self.stats.draws += self.issue(&mut pass, &draws, xray, true);
                }
            }
        }
        self.ctx.queue.submit([enc.finish()]);
    }

    /// Issues the draws `order` picks from `draws`, in that order, into
    /// `pass`, whose pipeline is set: their opaque triangles, or their
    /// x-rayed ones with their x-ray records when `xray`; returns how many.
    fn issue(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        draws: &[(usize, Slot)],
        order: impl IntoIterator<Item = usize>,
        xray: bool,
    ) -> u64 {
        let mut issued = 0;
        let mut bound = None;
        for k in order {
            let s = &draws[k].1;
            issued += 1;
            let key = (s.alloc.chunk, s.index_u32);
            if bound != Some(key) {
                let buf = &self.chunks[s.alloc.chunk as usize];
                pass.set_vertex_buffer(0, buf.slice(..));
                let fmt = if s.index_u32 {
                    wgpu::IndexFormat::Uint32
                } else {
                    wgpu::IndexFormat::Uint16
                };
                pass.set_index_buffer(buf.slice(..), fmt);
                bound = Some(key);
            }
            let isize = if s.index_u32 { 4 } else { 2 };
            let first = ((s.alloc.offset + u64::from(s.vertex_count) * 16) / isize as u64) as u32;
            let base = (s.alloc.offset / 16) as i32;
            let rep = self.frame_draws[draws[k].0].rep;
            let (k32, ranges) = if xray {
                ((draws.len() + k) as u32, self.parts.xray(rep))
            } else {
                (k as u32, self.parts.opaque(rep))
            };
            match ranges {
                None => pass.draw_indexed(first..first + s.index_count, base, k32..k32 + 1),
                Some(ranges) => {
                    for r in ranges {
                        let (a, b) = (
                            (3 * r.start).min(s.index_count),
                            (3 * r.end).min(s.index_count),
                        );
                        pass.draw_indexed(first + a..first + b, base, k32..k32 + 1);
                    }
                }
            }
        }
        issued
    }

    /// The translucent pass's draws (indices into `draws`), back to front
    /// ([`back_to_front`]): the reps with a translucent colour, or the
    /// x-rayed ones when `xray`.
    fn translucent_order(&self, draws: &[(usize, Slot)], xray: bool) -> Vec<usize> {
        if xray && !self.parts.any_xray() {
            return Vec::new();
        }
        let eye = self.view.as_ref().map_or(Vec3::ZERO, |v| v.pose.position);
        back_to_front(
            eye,
            draws.iter().map(|(i, s)| {
                let half = Vec3::from(s.extent()) / 2.0;
                let rep = self.frame_draws[*i].rep;
                let take = if xray {
                    self.parts.xray(rep).is_some()
                } else {
                    s.translucent
                };
                let place = &self.frame_draws[*i].place;
                let c = (Vec3::from(s.quant_min) + half).extend(1.0);
                take.then(|| Vec3::from_array(place.map(|row| glam::Vec4::from(row).dot(c))))
            }),
        )
    }

    fn read_back(&mut self) -> Option<RgbaImage> {
        let tex = self.target.color.clone();
        self.read_texture(&tex)
    }

    /// Copies an 8-bit RGBA/BGRA texture (with `COPY_SRC` usage) to the CPU.
    pub fn read_texture(&self, texture: &wgpu::Texture) -> Option<RgbaImage> {
        read_texture(&self.ctx, texture)
    }
}

impl Renderer for GpuRenderer {
    fn set_parts(&mut self, parts: &engine::hide::DrawParts) {
        self.parts = Parts::new(parts);
    }

    fn begin_frame(&mut self, view: &View) {
        self.frame_no += 1;
        self.frame_draws.clear();
        self.view = Some(*view);
    }

    fn draw(&mut self, rep: RepId, record: &RepRecord, payload: &Arc<[u8]>, style: DrawStyle) {
        // A shared payload has one slot, under its source rep.
        let key = style.payload_rep(rep);
        let resident = match self.slots.get_mut(&key) {
            Some(s) => {
                s.last_frame = self.frame_no;
                true
            }
            None => false,
        };
        let consistent = payload.len() >= size_of::<RepHeader>() && {
            let h: RepHeader = bytemuck::pod_read_unaligned(&payload[..size_of::<RepHeader>()]);
            h.vertex_count == record.vertex_count && h.index_count == 3 * record.tri_count
        };
        if !consistent || (!resident && !self.upload(key, payload)) {
            self.stats.bad_payloads += 1;
            if self.warned.insert(key) {
                tracing::warn!("rep {rep}: payload cannot be drawn (malformed or too large)");
            }
            return;
        }
        self.frame_draws.push(FrameDraw {
            rep,
            key,
            place: style.placement.map_or(IDENTITY_ROWS, |p| p.transform),
            substitute: style.substitute,
            fade: style.fade,
            level: record.index,
            kind: record.kind,
            payload: payload.clone(),
        });
    }

    fn evict(&mut self, rep: RepId) {
        self.free_slot(rep);
    }

    fn end_frame(&mut self) {
        let color = self
            .output
            .clone()
            .unwrap_or_else(|| self.target.color_view.clone());
        let depth = self.target.depth_view.clone();
        self.encode_frame(&color, &depth);
        let index = self.frame_no - 1;
        let periodic = self.capture_every > 0 && index.is_multiple_of(self.capture_every);
        if std::mem::take(&mut self.capture_next) || periodic {
            let img = self.read_back();
            if periodic && let Some(i) = &img {
                self.captures.push((index, i.clone()));
            }
            self.captured = img;
        } else {
            let _ = self.ctx.device.poll(wgpu::PollType::wait_indefinitely());
        }
        self.frame_draws.clear();
    }

    fn gpu_bytes(&self) -> u64 {
        self.stats.live_bytes
    }

    fn name(&self) -> &'static str {
        "wgpu"
    }
}
