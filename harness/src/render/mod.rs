//! The headless splat renderer.
//!
//! Draws a [`DrawList`] into an offscreen RGBA8 colour target (sRGB-encoded values, alpha = 1
//! where a splat landed, 0 = background) with a Depth32Float depth test. Splats are instanced
//! screen-aligned quads sized per draw in pixels or per splat from the object-space radius
//! (`splat.wgsl`), in one of four shapes ([`Kernel`] = [`methods::SplatShape`]):
//! - square; circle (discard outside the unit disk);
//! - ellipse: the quad's minor axis along the projected normal, minor/major = |n̂·v̂| clamped
//!   at 1/10 (QSplat §4.3); a circle for splats without normals;
//! - gaussian, QSplat's two-pass blend: (1) circles into depth only, pushed back by
//!   [`GAUSS_DEPTH_OFFSET`] × the splat diameter; (2) weighted linear colour `w = exp(−2r²)`
//!   added into an Rgba16Float target with depth test and no depth write; (3) a full-screen
//!   pass divides by the summed weight and encodes sRGB.
//!
//! Chunks live in an [`LruCache`] of GPU buffers with a byte budget: a chunk missing from the
//! cache is decoded by the method and uploaded (counted in `upload_bytes`); streams are
//! uploaded every frame. GPU time comes from timestamp queries around the render pass (when
//! the adapter has them); wall time spans upload + encode + submit + wait, excluding the
//! readback that only metrics need.
//!
//! ## Occlusion culling (LPC §4)
//! A draw list with an [`methods::OcclusionPass`] is drawn in three phases, two submissions:
//! 1. *Phase 1* — `list.items` (the clouds visible last frame) in the ordinary splat pass,
//!    which then **stores** depth (without occlusion culling depth is discarded).
//! 2. *Phase 2* — same submission: a depth-only render pass (depth loaded and stored,
//!    `occlusion_query_set` set) draws, per candidate, the icosahedron circumscribing its
//!    bounding sphere ([`occlusion::Icosahedron`]) inside `begin_occlusion_query(i)` /
//!    `end_occlusion_query()`: depth test `Less`, no depth or colour writes, back faces
//!    culled. More than [`wgpu::QUERY_SET_MAX_QUERIES`] queries take several such passes.
//!    The counts are resolved and copied to a readback buffer; the submission is waited
//!    for and the counts read. A candidate is visible when its count is above the pass's
//!    threshold; one whose icosahedron reaches the near plane (sphere containing the eye
//!    included) is visible without a query ([`occlusion::needs_query`]).
//! 3. *Phase 3* — second submission: the visible candidates that carry an item are uploaded
//!    (only now: an occluded candidate's chunk is never decoded or uploaded) and drawn in a
//!    splat pass that loads phase 1's colour and depth.
//!
//! `FrameStats::points`/`chunks` count phase 1 + phase 3; `FrameStats::occlusion` has the
//! per-candidate counts and the visible/occluded ids (next frame's [`methods::Feedback`]).
//! GPU time is the sum of the three passes' timestamp intervals (`phase_gpu_ms`); the CPU
//! round trip between phases 2 and 3 shows in wall time only. The gaussian kernel refuses
//! occlusion culling with an error: its depth, accumulation and normalisation passes would
//! all have to be split around the queries, and LPC draws opaque splats.

pub mod cpu;
pub mod edl;
pub mod occlusion;
mod pipelines;
mod queries;
pub mod shading;
mod splats;

use std::collections::{HashMap, HashSet};
use std::ops::Range;
use std::time::Instant;

use anyhow::{Context as _, bail};
use methods::{
    ChunkId, DrawItem, DrawList, IntervalTest, LodMethod, OcclusionPass, SplatBatch, SplatSize,
};
use scenes::{Attributes, View};
use wgpu::util::DeviceExt as _;

use crate::cache::LruCache;
use crate::gpu::Gpu;
use crate::image::Image;
use occlusion::Icosahedron;
pub use occlusion::OcclusionStats;
pub use shading::{Shade, Shading};

pub use methods::SplatShape as Kernel;

/// Fixed settings of a renderer.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RenderSettings {
    /// Target width, pixels.
    pub width: u32,
    /// Target height, pixels.
    pub height: u32,
    /// Splat shape.
    pub kernel: Kernel,
    /// GPU chunk cache budget, bytes.
    pub cache_bytes: u64,
    /// Shading ([`shading`]; resolve `auto` first for `edl`).
    pub shade: Shade,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            width: 512,
            height: 512,
            kernel: Kernel::Square,
            cache_bytes: 512 << 20,
            shade: Shade::default(),
        }
    }
}

/// Ambient term of the Lambert shading.
pub const AMBIENT: f32 = 0.25;
/// Linear RGB of splats in scenes without colour.
pub const BASE_COLOR: [f32; 3] = [0.8, 0.8, 0.8];
/// Gaussian kernel, pass 1: depth pushed back by this × the splat's object-space diameter,
/// so splats within that distance of the front surface blend in pass 2.
pub const GAUSS_DEPTH_OFFSET: f32 = 0.5;

/// `Frame` uniform of `splat.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FrameUniform {
    /// offset 0
    pub view_proj: [[f32; 4]; 4],
    /// offset 64
    pub eye: [f32; 3],
    /// offset 76
    pub proj_scale: f32,
    /// offset 80
    pub viewport: [f32; 2],
    /// offset 88
    pub ambient: f32,
    /// offset 92
    pub _pad0: f32,
    /// offset 96
    pub base_color: [f32; 4],
    /// offset 112
    pub view: [[f32; 4]; 4],
    /// offset 176
    pub depth_offset: f32,
    /// offset 180: [`Shading::shader_code`]
    pub shading: u32,
    /// offset 184: local Z at the bottom of the elevation ramp
    pub elevation_lo: f32,
    /// offset 188: 1 / the ramp's height range
    pub elevation_scale: f32,
}
const _: () = assert!(std::mem::size_of::<FrameUniform>() == 192);

/// `Draw` uniform of `splat.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub struct DrawUniform {
    /// offset 0
    pub size_px: f32,
    /// offset 4
    pub radius_scale: f32,
    /// offset 8
    pub min_px: f32,
    /// offset 12
    pub mode: u32,
    /// offset 16
    pub flags: u32,
    /// offset 20: 0 = none, 1 = SPT interval test
    pub test_kind: u32,
    /// offset 24
    pub test_mode: u32,
    /// offset 28
    pub test_scale: f32,
    /// offset 32
    pub test_overlap: f32,
    /// offset 36: splats sent (counting pass)
    pub count: u32,
    /// offset 40: counter slot (counting pass)
    pub slot: u32,
    /// offset 44
    pub _pad: u32,
}
const _: () = assert!(std::mem::size_of::<DrawUniform>() == 48);

impl DrawUniform {
    /// The uniform for a splat size, the attributes present and an optional interval test.
    pub fn new(size: SplatSize, attrs: Attributes, lod: bool, test: Option<IntervalTest>) -> Self {
        let flags = attrs.normals as u32
            | (attrs.colors as u32) << 1
            | (attrs.radii as u32) << 2
            | (lod as u32) << 3;
        let (size_px, radius_scale, min_px, mode) = match size {
            SplatSize::Pixels(px) => (px, 0.0, 0.0, 0),
            SplatSize::Radius { scale, min_px } => (0.0, scale, min_px, 1),
        };
        Self {
            size_px,
            radius_scale,
            min_px,
            mode,
            flags,
            test_kind: test.is_some() as u32,
            test_mode: test.map_or(0, |t| t.mode),
            test_scale: test.map_or(0.0, |t| t.scale),
            test_overlap: test.map_or(0.0, |t| t.overlap),
            count: 0,
            slot: 0,
            _pad: 0,
        }
    }
}

/// GPU buffers of one batch and their bind group.
struct GpuBatch {
    bind_group: wgpu::BindGroup,
    len: u32,
    attrs: Attributes,
    lod: bool,
    _buffers: Vec<wgpu::Buffer>,
}

/// What one frame cost.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct FrameStats {
    /// Splats sent to the GPU (with occlusion culling: phase 1 + phase 3, i.e. what was drawn).
    pub points: u64,
    /// Of those, splats that passed a vertex-stage LOD test (SPT), counted on the GPU; `None`
    /// when no draw had a test (then every splat sent is drawn).
    pub gpu_passed: Option<u64>,
    /// Cached chunks drawn (with occlusion culling: phase 1 + phase 3).
    pub chunks: u64,
    /// GPU time of the frame's passes (timestamps), if available: with occlusion culling the
    /// sum of the three phases' intervals ([`FrameStats::phase_gpu_ms`]), which leaves out the
    /// CPU round trip between phase 2 and phase 3 (that is in `wall_ms`).
    pub gpu_ms: Option<f64>,
    /// GPU time per phase (timestamps), ms: `[phase 1 or the only pass, occlusion queries,
    /// phase 3]`, `None` for a phase that did not run; empty without timestamps.
    pub phase_gpu_ms: Vec<Option<f64>>,
    /// Upload + encode + submit + wait.
    pub wall_ms: f64,
    /// Bytes uploaded this frame (missing chunks + streams).
    pub upload_bytes: u64,
    /// Bytes in the chunk cache after the frame.
    pub cache_bytes: u64,
    /// What the occlusion queries found; `None` when the list had no occlusion pass.
    pub occlusion: Option<OcclusionStats>,
}

/// Bytes of the timestamp resolve/readback buffers: queries 0..4 at offset 0, 4..6 at the
/// second [`wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT`] slot (phase 3 resolves in its own
/// submission).
const TIMESTAMP_READBACK_BYTES: u64 = 2 * wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT;

/// How one phase of splat draws treats the targets.
#[derive(Debug, Clone, Copy)]
struct PhaseTarget {
    /// Clear colour and depth (else load them).
    clear: bool,
    /// Keep the depth for a later pass (else discard it).
    store_depth: bool,
    /// Timestamp indices written at the beginning and end of the phase.
    ts: (u32, u32),
}

/// Phase 2 recorded, its counts not yet read.
struct PendingQueries {
    /// Candidate index of each query, in query order.
    queried: Vec<usize>,
    /// Readback of the hardware query results (u64 each) followed, at `counters_at`, by the
    /// fragment counters (u32 each), and its size; `None` when nothing was queried.
    readback: Option<(wgpu::Buffer, u64)>,
    counters_at: u64,
    _keep: Vec<wgpu::Buffer>,
}

/// The occlusion-query pipeline (made on first use).
struct QueryPipeline {
    pipeline: wgpu::RenderPipeline,
    bgl: wgpu::BindGroupLayout,
    indices: wgpu::Buffer,
    sampler: wgpu::Sampler,
}

struct Timestamps {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    readback: wgpu::Buffer,
    period_ns: f64,
}

/// The renderer.
pub struct Renderer<'g> {
    gpu: &'g Gpu,
    settings: RenderSettings,
    color: wgpu::Texture,
    color_view: wgpu::TextureView,
    depth: wgpu::Texture,
    depth_view: wgpu::TextureView,
    /// Stand-in depth texture bound by the occlusion queries on backends without read-only
    /// depth attachments (made on first use; never written).
    depth_copy: Option<wgpu::TextureView>,
    module: wgpu::ShaderModule,
    layout: wgpu::PipelineLayout,
    pipelines: HashMap<PassKind, wgpu::RenderPipeline>,
    gauss: Option<GaussTargets>,
    count: Option<wgpu::ComputePipeline>,
    count_layout: wgpu::PipelineLayout,
    bgl2: wgpu::BindGroupLayout,
    frame_ubo: wgpu::Buffer,
    draw_ubo: wgpu::Buffer,
    draw_capacity: u64,
    bgl0: wgpu::BindGroupLayout,
    bgl1: wgpu::BindGroupLayout,
    dummy: wgpu::Buffer,
    quad_indices: wgpu::Buffer,
    cache: LruCache<ChunkId, GpuBatch>,
    timestamps: Option<Timestamps>,
    draw_stride: u64,
    query: Option<QueryPipeline>,
    query_sets: Vec<wgpu::QuerySet>,
    /// The eye-dome lighting pass, for `edl` shading.
    edl: Option<edl::EdlPass>,
}

/// Which pipeline: an opaque kernel, or one of the gaussian passes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum PassKind {
    Opaque(Kernel),
    GaussDepth,
    GaussAccum,
}

/// What the gaussian kernel needs beyond the opaque ones (made on first use).
struct GaussTargets {
    accum_view: wgpu::TextureView,
    normalize: wgpu::RenderPipeline,
    normalize_bg: wgpu::BindGroup,
}

/// The splat shader: the interval test (`interval.wgsl`) followed by `splat.wgsl`.
pub const SPLAT_WGSL: &str = concat!(
    include_str!("interval.wgsl"),
    "\n",
    include_str!("splat.wgsl")
);

/// Every shader module the renderer compiles, as (name, source): the naga test validates
/// each, and checks that every `.wgsl` file of the crate is part of one.
pub const SHADER_MODULES: &[(&str, &str)] = &[
    ("interval.wgsl + splat.wgsl", SPLAT_WGSL),
    ("normalize.wgsl", include_str!("normalize.wgsl")),
    ("occlusion.wgsl", OCCLUSION_WGSL),
    ("edl.wgsl", edl::EDL_WGSL),
];

/// The occlusion-query shader (phase 2 of occlusion culling).
pub const OCCLUSION_WGSL: &str = include_str!("occlusion.wgsl");

/// Accumulation format of the gaussian kernel's pass 2.
const ACCUM_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

/// Colour target format.
pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

impl<'g> Renderer<'g> {
    /// Creates targets and pipelines.
    pub fn new(gpu: &'g Gpu, settings: RenderSettings) -> anyhow::Result<Self> {
        let d = &gpu.device;
        let max = gpu.limits.max_texture_dimension_2d;
        if settings.width == 0
            || settings.height == 0
            || settings.width > max
            || settings.height > max
        {
            bail!(
                "--width/--height {}x{} must be between 1 and {max} on adapter '{}'",
                settings.width,
                settings.height,
                gpu.adapter.name
            );
        }
        let size = wgpu::Extent3d {
            width: settings.width,
            height: settings.height,
            depth_or_array_layers: 1,
        };
        let color = d.create_texture(&wgpu::TextureDescriptor {
            label: Some("color"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: COLOR_FORMAT,
            // Read by the EDL pass, which writes its result back by a copy.
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::COPY_SRC
                | wgpu::TextureUsages::COPY_DST
                | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let depth = d.create_texture(&wgpu::TextureDescriptor {
            label: Some("depth"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH_FORMAT,
            // Bound as a texture by the occlusion queries (with a read-only depth attachment).
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let stages = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::COMPUTE;
        let uniform = |binding, dynamic, size: u64| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: stages,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: dynamic,
                min_binding_size: wgpu::BufferSize::new(size),
            },
            count: None,
        };
        let bgl0 = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("frame+draw"),
            entries: &[
                uniform(0, false, std::mem::size_of::<FrameUniform>() as u64),
                uniform(1, true, std::mem::size_of::<DrawUniform>() as u64),
            ],
        });
        let storage = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: stages,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: true },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let bgl1 = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("splat columns"),
            entries: &[storage(0), storage(1), storage(2), storage(3), storage(4)],
        });
        let layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("splat"),
            bind_group_layouts: &[Some(&bgl0), Some(&bgl1)],
            immediate_size: 0,
        });
        let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("splat.wgsl"),
            source: wgpu::ShaderSource::Wgsl(SPLAT_WGSL.into()),
        });
        let bgl2 = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("counters"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Storage { read_only: false },
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let count_layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("count"),
            bind_group_layouts: &[Some(&bgl0), Some(&bgl1), Some(&bgl2)],
            immediate_size: 0,
        });
        let frame_ubo = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame"),
            size: std::mem::size_of::<FrameUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        // Dynamic offsets must be multiples of the alignment: round the struct size up to it.
        let draw_stride = (std::mem::size_of::<DrawUniform>() as u64)
            .next_multiple_of(gpu.limits.min_uniform_buffer_offset_alignment as u64);
        let draw_capacity = 256;
        let draw_ubo = Self::draw_buffer(d, draw_stride * draw_capacity);
        let dummy = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("absent attribute"),
            size: 16,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let quad_indices = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("quad indices"),
            contents: bytemuck::cast_slice(&[0u16, 1, 2, 0, 2, 3]),
            usage: wgpu::BufferUsages::INDEX,
        });
        let timestamps = gpu.timestamps.then(|| Timestamps {
            set: d.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("frame timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 6,
            }),
            resolve: d.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamp resolve"),
                size: TIMESTAMP_READBACK_BYTES,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            readback: d.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamp readback"),
                size: TIMESTAMP_READBACK_BYTES,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            period_ns: gpu.queue.get_timestamp_period() as f64,
        });
        Ok(Self {
            gpu,
            settings,
            color_view: color.create_view(&Default::default()),
            color,
            depth_view: depth.create_view(&Default::default()),
            depth,
            depth_copy: None,
            module,
            layout,
            pipelines: HashMap::new(),
            gauss: None,
            count: None,
            count_layout,
            bgl2,
            frame_ubo,
            draw_ubo,
            draw_capacity,
            bgl0,
            bgl1,
            dummy,
            quad_indices,
            cache: LruCache::new(settings.cache_bytes),
            timestamps,
            draw_stride,
            query: None,
            query_sets: Vec::new(),
            edl: (settings.shade.shading == Shading::Edl)
                .then(|| edl::EdlPass::new(gpu, settings.width, settings.height, COLOR_FORMAT)),
        })
    }

    /// True when occlusion sample counts are exact on this renderer's adapter
    /// ([`exact_counts`]).
    pub fn exact_counts(&self) -> bool {
        exact_counts(self.gpu)
    }

    /// The settings.
    pub fn settings(&self) -> RenderSettings {
        self.settings
    }

    /// Chunks resident in the GPU cache.
    pub fn cached(&self) -> HashSet<ChunkId> {
        self.cache.keys().copied().collect()
    }

    /// Drops every cached chunk (e.g. between methods).
    pub fn clear_cache(&mut self) {
        self.cache.clear();
    }

    fn upload(&self, batch: &SplatBatch) -> anyhow::Result<GpuBatch> {
        batch.validate()?;
        let d = &self.gpu.device;
        let max = self.gpu.limits.max_storage_buffer_binding_size;
        let pos_bytes = batch.len() as u64 * 12;
        if pos_bytes > max {
            bail!(
                "a batch of {} splats needs {pos_bytes} bytes of positions, over the adapter's \
                 storage binding limit of {max} bytes: the method must split it",
                batch.len()
            );
        }
        let mut buffers = Vec::with_capacity(4);
        let mut make = |label: &str, bytes: &[u8]| -> usize {
            // Empty batches still need a non-empty buffer to bind.
            let contents: &[u8] = if bytes.is_empty() { &[0u8; 16] } else { bytes };
            buffers.push(d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE,
            }));
            buffers.len() - 1
        };
        let pos = make("positions", bytemuck::cast_slice(&batch.positions));
        let nrm = batch
            .normals
            .as_ref()
            .map(|v| make("normals", bytemuck::cast_slice(v)));
        let col = batch
            .colors
            .as_ref()
            .map(|v| make("colors", bytemuck::cast_slice(v)));
        let rad = batch
            .radii
            .as_ref()
            .map(|v| make("radii", bytemuck::cast_slice(v)));
        let lod = batch
            .lod
            .as_ref()
            .map(|v| make("lod", bytemuck::cast_slice(v)));
        let buf = |i: Option<usize>| i.map(|i| &buffers[i]).unwrap_or(&self.dummy);
        let entries: Vec<_> = [Some(pos), nrm, col, rad, lod]
            .into_iter()
            .enumerate()
            .map(|(b, i)| wgpu::BindGroupEntry {
                binding: b as u32,
                resource: buf(i).as_entire_binding(),
            })
            .collect();
        let bind_group = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("splat columns"),
            layout: &self.bgl1,
            entries: &entries,
        });
        Ok(GpuBatch {
            bind_group,
            len: batch.len() as u32,
            attrs: batch.attributes(),
            lod: batch.lod.is_some(),
            _buffers: buffers,
        })
    }
    /// Draws `list` for `view`, decoding missing chunks through `method`. Returns the frame's
    /// costs and, when `readback` is set, the image.
    ///
    /// With an [`methods::OcclusionPass`] the frame runs the three phases of occlusion culling
    /// (module documentation); the gaussian kernel refuses it with an error.
    pub fn draw(
        &mut self,
        view: &View,
        list: &DrawList,
        method: &dyn LodMethod,
        readback: bool,
    ) -> anyhow::Result<(FrameStats, Option<Image>)> {
        if view.width != self.settings.width || view.height != self.settings.height {
            bail!(
                "view is {}x{} but the renderer was made for {}x{}",
                view.width,
                view.height,
                self.settings.width,
                self.settings.height
            );
        }
        let t0 = Instant::now();
        let shape = list.shape.unwrap_or(self.settings.kernel);
        if let Some(o) = &list.occlusion
            && o.threshold > 0
            && !exact_counts(self.gpu)
        {
            bail!(
                "occlusion threshold {} needs exact sample counts, but on adapter '{}' ({}) \
                 wgpu's occlusion queries only say whether any sample passed: use threshold 0 \
                 or the Vulkan backend",
                o.threshold,
                self.gpu.adapter.name,
                self.gpu.adapter.backend
            );
        }
        if list.occlusion.is_some() && shape == Kernel::Gaussian {
            bail!(
                "occlusion culling needs an opaque kernel (square, circle or ellipse): the \
                 gaussian kernel's blended passes are not split into occlusion phases; choose \
                 another --kernel or turn the method's occlusion culling off"
            );
        }
        self.ensure_pipelines(shape);
        let phase3_items = list
            .occlusion
            .iter()
            .flat_map(|o| o.candidates.iter().filter_map(|c| c.item.as_ref()));
        if self.count.is_none()
            && list
                .items
                .iter()
                .chain(phase3_items)
                .any(|i| matches!(i, DrawItem::Sequential { .. }))
        {
            self.count = Some(self.gpu.device.create_compute_pipeline(
                &wgpu::ComputePipelineDescriptor {
                    label: Some("interval count"),
                    layout: Some(&self.count_layout),
                    module: &self.module,
                    entry_point: Some("cs_count"),
                    compilation_options: Default::default(),
                    cache: None,
                },
            ));
        }
        self.cache.begin_frame();
        let mut stats = FrameStats::default();
        self.gpu.queue.write_buffer(
            &self.frame_ubo,
            0,
            bytemuck::bytes_of(&frame_uniform(view, &self.settings.shade)),
        );
        // Timestamp pairs written, by first index: 0 = phase 1 (or the only pass), 2 = the
        // occlusion queries, 4 = phase 3.
        let mut ts_pairs: Vec<u32> = vec![0];

        // Phase 1 (or the whole frame without occlusion culling).
        let items: Vec<&DrawItem> = list.items.iter().collect();
        let streams = self.upload_items(&items, method, &mut stats)?;
        self.ensure_draw_capacity(items.len() as u64);
        let mut enc = self.gpu.device.create_command_encoder(&Default::default());
        let counters1 = self.encode_splats(
            shape,
            &items,
            &streams,
            &mut stats,
            &mut enc,
            PhaseTarget {
                clear: true,
                store_depth: list.occlusion.is_some() || self.edl.is_some(),
                ts: (0, 1),
            },
        )?;
        let mut counters = vec![counters1];
        let mut keep_alive = vec![streams];
        let Some(occ) = &list.occlusion else {
            self.resolve_timestamps(&mut enc, 0..2, 0);
            self.gpu.queue.submit([enc.finish()]);
            self.gpu.wait()?;
            return self.finish_frame(view, t0, stats, counters, &ts_pairs, readback);
        };

        // Phase 2: one occlusion query per candidate against phase 1's depth.
        let pending = self.encode_queries(view, occ, &mut enc, (2, 3))?;
        let queried_any = pending.readback.is_some();
        if queried_any {
            ts_pairs.push(2);
        }
        self.resolve_timestamps(&mut enc, 0..if queried_any { 4 } else { 2 }, 0);
        self.gpu.queue.submit([enc.finish()]);
        self.gpu.wait()?;
        let mut samples = vec![None; occ.candidates.len()];
        let mut query_results = vec![None; occ.candidates.len()];
        if let Some((buf, bytes)) = &pending.readback {
            let raw = read_buffer(self.gpu, buf, *bytes)?;
            let at = pending.counters_at as usize;
            let hw: Vec<u64> = bytemuck::pod_collect_to_vec(&raw[..at]);
            let exact: Vec<u32> = bytemuck::pod_collect_to_vec(&raw[at..]);
            let counted = exact_counts(self.gpu);
            for ((&i, &h), &n) in pending.queried.iter().zip(&hw).zip(&exact) {
                samples[i] = Some(if counted { n as u64 } else { h });
                query_results[i] = Some(h);
            }
        }
        let mut occlusion = OcclusionStats::classify(&occ.candidates, samples, occ.threshold);
        occlusion.query_results = query_results;

        // Phase 3: upload (only now) and draw the visible candidates not drawn in phase 1.
        let items3: Vec<&DrawItem> = occ
            .candidates
            .iter()
            .enumerate()
            .filter(|(i, _)| occlusion.is_visible(*i, occ.threshold))
            .filter_map(|(_, c)| c.item.as_ref())
            .collect();
        if !items3.is_empty() {
            let points_before = stats.points;
            let streams3 = self.upload_items(&items3, method, &mut stats)?;
            self.ensure_draw_capacity(items3.len() as u64);
            let mut enc = self.gpu.device.create_command_encoder(&Default::default());
            counters.push(self.encode_splats(
                shape,
                &items3,
                &streams3,
                &mut stats,
                &mut enc,
                PhaseTarget {
                    clear: false,
                    store_depth: self.edl.is_some(),
                    ts: (4, 5),
                },
            )?);
            ts_pairs.push(4);
            self.resolve_timestamps(&mut enc, 4..6, wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT);
            self.gpu.queue.submit([enc.finish()]);
            self.gpu.wait()?;
            occlusion.phase3_points = stats.points - points_before;
            keep_alive.push(streams3);
        }
        drop(keep_alive);
        drop(pending);
        let (mut stats, image) =
            self.finish_frame(view, t0, stats, counters, &ts_pairs, readback)?;
        if queried_any {
            occlusion.query_gpu_ms = stats.phase_gpu_ms.get(1).copied().flatten();
        }
        stats.occlusion = Some(occlusion);
        Ok((stats, image))
    }

    /// After the last submission: wall time, interval counters, timestamps, the image (with
    /// the EDL pass first, when the shading has one: outside the timings, see [`edl`]).
    fn finish_frame(
        &self,
        view: &View,
        t0: Instant,
        mut stats: FrameStats,
        counters: Vec<Option<(wgpu::Buffer, u64)>>,
        ts_pairs: &[u32],
        readback: bool,
    ) -> anyhow::Result<(FrameStats, Option<Image>)> {
        stats.wall_ms = t0.elapsed().as_secs_f64() * 1e3;
        for (buf, bytes) in counters.iter().flatten() {
            let raw = read_buffer(self.gpu, buf, *bytes)?;
            let counts: Vec<u32> = bytemuck::pod_collect_to_vec(&raw);
            *stats.gpu_passed.get_or_insert(0) += counts.iter().map(|&c| c as u64).sum::<u64>();
        }
        if let Some(t) = &self.timestamps {
            let raw = read_buffer(self.gpu, &t.readback, TIMESTAMP_READBACK_BYTES)?;
            let at = |index: u32| {
                // Indices 0..4 resolve at offset 0, 4..6 at the second aligned slot.
                let off = if index < 4 {
                    index as usize * 8
                } else {
                    wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT as usize + (index as usize - 4) * 8
                };
                bytemuck::pod_read_unaligned::<u64>(&raw[off..off + 8])
            };
            let mut phases = vec![None; 3];
            for &b in ts_pairs {
                let ms = at(b + 1).saturating_sub(at(b)) as f64 * t.period_ns / 1e6;
                phases[b as usize / 2] = Some(ms);
            }
            stats.gpu_ms = Some(phases.iter().flatten().sum());
            stats.phase_gpu_ms = phases;
        }
        stats.cache_bytes = self.cache.bytes();
        let image = if readback {
            if let Some(e) = &self.edl {
                e.apply(
                    self.gpu,
                    &self.color,
                    &self.color_view,
                    &self.depth_view,
                    view.camera.near,
                    view.camera.far,
                );
            }
            Some(self.read_color()?)
        } else {
            None
        };
        Ok((stats, image))
    }

    /// Resolves timestamp queries `range` into the resolve buffer at `offset` and copies them
    /// to the same offset of the readback buffer.
    fn resolve_timestamps(&self, enc: &mut wgpu::CommandEncoder, range: Range<u32>, offset: u64) {
        if let Some(t) = &self.timestamps {
            let bytes = range.len() as u64 * 8;
            enc.resolve_query_set(&t.set, range, &t.resolve, offset);
            enc.copy_buffer_to_buffer(&t.resolve, offset, &t.readback, offset, bytes);
        }
    }

    fn ensure_draw_capacity(&mut self, n: u64) {
        if n > self.draw_capacity {
            self.draw_capacity = n.next_power_of_two();
            self.draw_ubo =
                Self::draw_buffer(&self.gpu.device, self.draw_stride * self.draw_capacity);
        }
    }

    /// Uploads the chunks of `items` missing from the cache (marking the others used) and
    /// the streams, which get their own buffers this frame (returned, in item order).
    fn upload_items(
        &mut self,
        items: &[&DrawItem],
        method: &dyn LodMethod,
        stats: &mut FrameStats,
    ) -> anyhow::Result<Vec<GpuBatch>> {
        let mut streams = Vec::new();
        for item in items {
            match item {
                DrawItem::Chunk { id, .. } | DrawItem::Sequential { id, .. } => {
                    if self.cache.get(id).is_none() {
                        let batch = method
                            .chunk(*id)
                            .with_context(|| format!("decoding chunk {id}"))?;
                        let bytes = batch.byte_size();
                        let g = self.upload(&batch)?;
                        stats.upload_bytes += bytes;
                        self.cache.insert(*id, g, bytes);
                    }
                }
                DrawItem::Stream { batch, .. } => {
                    stats.upload_bytes += batch.byte_size();
                    streams.push(self.upload(batch)?);
                }
            }
        }
        Ok(streams)
    }

    /// Reads the colour target back.
    pub fn read_color(&self) -> anyhow::Result<Image> {
        let (w, h) = (self.settings.width, self.settings.height);
        let row = w * 4;
        let padded =
            row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let size = padded as u64 * h as u64;
        let buf = self.gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("color readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = self.gpu.device.create_command_encoder(&Default::default());
        enc.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &self.color,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &buf,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded),
                    rows_per_image: Some(h),
                },
            },
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
        self.gpu.queue.submit([enc.finish()]);
        let bytes = read_buffer(self.gpu, &buf, size)?;
        let mut rgba = Vec::with_capacity((row * h) as usize);
        for y in 0..h as usize {
            let start = y * padded as usize;
            rgba.extend_from_slice(&bytes[start..start + row as usize]);
        }
        Ok(Image {
            width: w,
            height: h,
            rgba,
        })
    }
}

/// A pipeline that draws one full-screen triangle (`vs_fullscreen` of `module`) with the
/// fragment entry `fs` into one `format` target: no depth, no blending. The gaussian
/// normalisation and the EDL pass are such passes.
pub(crate) fn fullscreen_pipeline(
    d: &wgpu::Device,
    label: &str,
    bgl: &wgpu::BindGroupLayout,
    module: &wgpu::ShaderModule,
    fs: &str,
    format: wgpu::TextureFormat,
) -> wgpu::RenderPipeline {
    let layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(bgl)],
        immediate_size: 0,
    });
    d.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(&layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs_fullscreen"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: None,
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some(fs),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// True when the renderer counts occlusion samples exactly (in the queries' fragment stage):
/// every backend but GL. On GL, `OcclusionStats::samples` are the hardware query results,
/// which wgpu's GL backend makes boolean (`ANY_SAMPLES_PASSED_CONSERVATIVE`).
pub fn exact_counts(gpu: &Gpu) -> bool {
    gpu.device.adapter_info().backend != wgpu::Backend::Gl
}

/// The `Frame` uniform for a view drawn with `shade`.
pub fn frame_uniform(view: &View, shade: &Shade) -> FrameUniform {
    FrameUniform {
        view_proj: view.view_proj().to_cols_array_2d(),
        eye: view.camera.position.into(),
        proj_scale: view.proj_scale(),
        viewport: [view.width as f32, view.height as f32],
        ambient: AMBIENT,
        _pad0: 0.0,
        base_color: [BASE_COLOR[0], BASE_COLOR[1], BASE_COLOR[2], 1.0],
        view: view.view_matrix().to_cols_array_2d(),
        depth_offset: GAUSS_DEPTH_OFFSET,
        shading: shade.shading.shader_code(),
        elevation_lo: shade.elevation[0],
        elevation_scale: shade.elevation_scale(),
    }
}

fn read_buffer(gpu: &Gpu, buf: &wgpu::Buffer, size: u64) -> anyhow::Result<Vec<u8>> {
    let (tx, rx) = std::sync::mpsc::channel();
    buf.map_async(wgpu::MapMode::Read, 0..size, move |r| {
        let _ = tx.send(r);
    });
    gpu.wait()?;
    rx.recv()
        .context("buffer map callback dropped")?
        .context("mapping a readback buffer")?;
    let bytes = buf
        .get_mapped_range(0..size)
        .context("reading a mapped buffer")?
        .to_vec();
    buf.unmap();
    Ok(bytes)
}
