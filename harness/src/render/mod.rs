//! The headless splat renderer.
//!
//! Draws a [`DrawList`] into an offscreen RGBA8 colour target (sRGB-encoded values, alpha = 1
//! where a splat landed, 0 = background) with a Depth32Float depth test. With
//! [`Raster::Compute`] square splats are rasterised by a compute shader instead and resolved
//! into the same targets ([`compute`]); otherwise splats are instanced
//! screen-aligned quads sized per draw in pixels or per splat from the object-space radius
//! (`splat.wgsl`), in one of four shapes ([`Kernel`] = [`methods::SplatShape`]):
//! - square; circle (discard outside the unit disk);
//! - ellipse: the quad's minor axis along the projected normal, minor/major = |n̂·v̂| clamped
//!   at 1/10 (QSplat §4.3); a circle for splats without normals;
//! - gaussian, QSplat's two-pass blend: (1) circles into depth only, pushed back by
//!   [`GAUSS_DEPTH_OFFSET`] × the splat diameter; (2) weighted linear colour added into an
//!   Rgba16Float target with depth test and no depth write, over a quad [`GAUSS_SUPPORT`] ×
//!   the splat's: the weight is QSplat's "spline in opacity that falls to 1/2 at the nominal
//!   radius" (§3.3), [`gauss_weight`]` = 1 − smoothstep(0, 2, r)` (r in nominal radii: 1 at
//!   the centre, 1/2 at the radius, 0 at twice it); (3) a full-screen pass composites the
//!   weighted colour over the black background at the summed weight's opacity,
//!   `Σwc / max(Σw, 1)`, covered from [`GAUSS_COVERED`] on, and encodes sRGB.
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
//!
//! ## Files
//! One room per responsibility, all behind [`Renderer::draw`] (this file: settings, the
//! renderer's resources and the frame's phases): `setup.rs` (the fixed resources
//! [`Renderer::new`] makes: targets, layouts, uniform buffers, timestamp queries), `splats.rs` (one phase of splat draws: the render
//! passes per kernel, or the compute rasteriser's passes), `interval.rs` (the counting compute pass of the per-splat tests: SPT's `interval.wgsl`, CLOD's `clod.wgsl`),
//! `pipelines.rs` (pipelines and targets; WGSL in `splat.wgsl` and `normalize.wgsl`),
//! `queries.rs` and `occlusion.rs` (the occlusion-query pass, `occlusion.wgsl`, and its
//! icosahedra), `upload.rs` (chunk cache and stream uploads), `uniforms.rs` (frame/draw
//! uniforms), `readback.rs` (timestamps, counters, colour readback), `edl.rs` and
//! `shading.rs` (shading modes), `compute.rs` (the compute rasteriser, `compute.wgsl` and
//! `resolve.wgsl`), `cpu.rs` (the CPU mirror the tests compare against).

pub mod compute;
pub mod cpu;
pub mod edl;
mod interval;
pub mod occlusion;
mod pipelines;
mod queries;
mod readback;
mod setup;
pub mod shading;
mod splats;
mod uniforms;
mod upload;

use std::collections::{HashMap, HashSet};
use std::ops::Range;
use std::time::Instant;

use anyhow::{Context as _, bail};
use methods::{
    ChunkId, DrawItem, DrawList, LodMethod, OcclusionPass, SplatBatch, SplatSize, SplatTest,
};
use scenes::{Attributes, View};
use wgpu::util::DeviceExt as _;

use crate::cache::LruCache;
use crate::gpu::Gpu;
use crate::image::Image;
use occlusion::Icosahedron;
pub use occlusion::OcclusionStats;
use queries::{PendingQueries, QueryPipeline};
pub(crate) use readback::read_texture;
use readback::{TIMESTAMP_READBACK_BYTES, Timestamps, read_buffer, zeroed_counters};
use setup::{FrameBuffers, SplatLayouts};
pub use shading::{ELLIPSE_CLAMP, Shade, Shading};
use splats::{PhaseItems, PhaseTarget};
use upload::GpuBatch;
pub use upload::splats_per_part;

pub use methods::SplatShape as Kernel;
pub(crate) use pipelines::{fragment_texture, fullscreen_pipeline};
pub use uniforms::{
    AMBIENT, BASE_COLOR, DrawUniform, FrameUniform, GAUSS_COVERED, GAUSS_DEPTH_OFFSET,
    GAUSS_SUPPORT, LEVEL_PALETTE, frame_uniform, gauss_weight, level_tint,
};

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
    /// How splats become pixels: instanced quads (the default) or the compute rasteriser.
    pub raster: Raster,
}

/// The GPU chunk cache's budget when none is given (`--gpu-cache-mb`, a suite's or a spec's
/// `gpu_cache_mb`), MiB.
pub const DEFAULT_GPU_CACHE_MB: u64 = 512;

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            width: 512,
            height: 512,
            kernel: Kernel::Square,
            cache_bytes: DEFAULT_GPU_CACHE_MB << 20,
            shade: Shade::default(),
            raster: Raster::Quads,
        }
    }
}

/// How splats become pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Raster {
    /// Instanced screen-aligned quads through the fixed-function rasteriser and depth test
    /// (every kernel).
    #[default]
    Quads,
    /// A compute shader per splat: 64-bit atomic depth|colour into a visibility buffer,
    /// resolved into the colour and depth targets (square splats and 1 px points;
    /// see the `compute` module). Needs 64-bit integer atomics.
    Compute,
}

impl Raster {
    /// Every rasteriser.
    pub const ALL: [Raster; 2] = [Raster::Quads, Raster::Compute];

    /// The name as the CLI and result files spell it.
    pub fn name(self) -> &'static str {
        match self {
            Raster::Quads => "quads",
            Raster::Compute => "compute",
        }
    }
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
    /// The compute rasteriser, for [`Raster::Compute`].
    compute: Option<compute::ComputeRaster>,
    /// Tint chunks by their level ([`LodMethod::chunk_level`]): the viewer's `L`.
    level_colours: bool,
    /// Store the depth target at the end of every frame, for [`Renderer::read_depth`].
    keep_depth: bool,
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

/// The splat shader: the per-splat tests (SPT's `interval.wgsl`, CLOD's `clod.wgsl`) followed by
/// `splat.wgsl`.
pub const SPLAT_WGSL: &str = concat!(
    include_str!("interval.wgsl"),
    "\n",
    include_str!("clod.wgsl"),
    "\n",
    include_str!("splat.wgsl")
);

/// Every shader module the renderer compiles, as (name, source): the naga test validates
/// each (and the viewer's `PRESENT_WGSL`), and checks that every `.wgsl` file of the crate is
/// part of one. All of them draw images: their sources key the cached references
/// ([`image_shaders_hash`]).
pub const SHADER_MODULES: &[(&str, &str)] = &[
    ("interval.wgsl + clod.wgsl + splat.wgsl", SPLAT_WGSL),
    (
        "interval.wgsl + clod.wgsl + splat.wgsl + compute.wgsl",
        compute::COMPUTE_WGSL,
    ),
    ("resolve.wgsl", compute::RESOLVE_WGSL),
    ("normalize.wgsl", include_str!("normalize.wgsl")),
    ("occlusion.wgsl", OCCLUSION_WGSL),
    ("edl.wgsl", edl::EDL_WGSL),
];

/// A hash of the source of every shader that draws an image ([`SHADER_MODULES`]; the
/// viewer's presentation pass draws none): part of a cached reference image's key, so that a change
/// to a kernel's shader can never leave images drawn by the old one in a cache (the gaussian
/// spline of 8def070 did: references cached before it kept being compared with runs after).
pub fn image_shaders_hash() -> u64 {
    // The sources are compiled in: hashed once per process (every reference lookup asks).
    static HASH: std::sync::OnceLock<u64> = std::sync::OnceLock::new();
    *HASH.get_or_init(|| {
        let mut h = scenes::hash::Fnv64::default();
        for (name, src) in SHADER_MODULES {
            h.write_str(name).write_str(src);
        }
        h.finish()
    })
}

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
        setup::check_settings(gpu, &settings)?;
        let d = &gpu.device;
        let (color, depth) = setup::make_targets(d, &settings);
        let SplatLayouts {
            bgl0,
            bgl1,
            layout,
            module,
            bgl2,
            count_layout,
        } = SplatLayouts::new(d);
        let FrameBuffers {
            frame_ubo,
            draw_stride,
            draw_capacity,
            draw_ubo,
            dummy,
            quad_indices,
        } = FrameBuffers::new(gpu);
        let compute = match settings.raster {
            Raster::Quads => None,
            Raster::Compute => Some(compute::ComputeRaster::new(
                gpu,
                &settings,
                &count_layout,
                &bgl2,
            )?),
        };
        let timestamps = setup::make_timestamps(gpu);
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
            compute,
            level_colours: false,
            keep_depth: false,
        })
    }

    /// Draws every chunk of a method that knows its chunks' levels
    /// ([`LodMethod::chunk_level`]) in its level's colour ([`uniforms::LEVEL_PALETTE`],
    /// shaded as usual) when `on`; the viewer's `L`. Runs never set it.
    pub fn set_level_colours(&mut self, on: bool) {
        self.level_colours = on;
    }

    /// Keep the depth target of every frame for [`Renderer::read_depth`] (the reference's,
    /// for the warped popping metric): every pass then stores its depth instead of
    /// discarding it.
    pub fn keep_depth(&mut self, on: bool) {
        self.keep_depth = on;
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

    /// The colour target the frames are drawn into (the viewer presents it).
    pub fn color_view(&self) -> &wgpu::TextureView {
        &self.color_view
    }

    /// Chunks resident in the GPU cache.
    pub fn cached(&self) -> HashSet<ChunkId> {
        self.cache.keys().copied().collect()
    }

    /// Drops every cached chunk (e.g. between methods).
    pub fn clear_cache(&mut self) {
        self.cache.clear();
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
        self.check_view(view)?;
        let t0 = Instant::now();
        let shape = list.shape.unwrap_or(self.settings.kernel);
        self.check_list(list, shape)?;
        self.ensure_pipelines(shape);
        self.ensure_count_pipeline(list);
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
        let phase1 = PhaseTarget {
            clear: true,
            store_depth: list.occlusion.is_some() || self.edl.is_some() || self.keep_depth,
            ts: (0, 1),
        };
        let (mut enc, counters1, streams) =
            self.encode_phase(shape, method, &items, &mut stats, phase1)?;
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
        let mut occlusion = self.read_occlusion(occ, &pending)?;

        // Phase 3: upload (only now) and draw the visible candidates not drawn in phase 1.
        if let Some((counters3, streams3)) =
            self.draw_phase3(shape, method, occ, &mut occlusion, &mut stats)?
        {
            counters.push(counters3);
            ts_pairs.push(4);
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

    /// Refuses a view whose size is not the renderer's.
    fn check_view(&self, view: &View) -> anyhow::Result<()> {
        if view.width != self.settings.width || view.height != self.settings.height {
            bail!(
                "view is {}x{} but the renderer was made for {}x{}",
                view.width,
                view.height,
                self.settings.width,
                self.settings.height
            );
        }
        Ok(())
    }

    /// Refuses a draw list this renderer cannot draw with kernel `shape`: an occlusion
    /// threshold without exact sample counts, a kernel the compute rasteriser lacks, or
    /// occlusion culling with the gaussian kernel.
    fn check_list(&self, list: &DrawList, shape: Kernel) -> anyhow::Result<()> {
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
        if self.settings.raster == Raster::Compute && shape != Kernel::Square {
            bail!(
                "--raster compute draws square splats (and 1 px points) only, but this draw \
                 list asks for kernel '{}'; use --raster quads",
                shape.name()
            );
        }
        if list.occlusion.is_some() && shape == Kernel::Gaussian {
            bail!(
                "occlusion culling needs an opaque kernel (square, circle or ellipse): the \
                 gaussian kernel's blended passes are not split into occlusion phases; choose \
                 another --kernel or turn the method's occlusion culling off"
            );
        }
        Ok(())
    }

    /// Makes the interval-counting pipeline on first use: when an item of phase 1 or a
    /// candidate's item (phase 3) is sequential (SPT).
    fn ensure_count_pipeline(&mut self, list: &DrawList) {
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
    }

    /// Uploads one phase's `items` ([`Self::upload_items`]), grows the draw buffer for them
    /// and records their splat draws ([`Self::encode_splats`]) into a new command encoder.
    /// Returns the encoder (not yet submitted), the interval counters' readback, if any, and
    /// the stream buffers, which must live until the encoder's submission is done.
    fn encode_phase(
        &mut self,
        shape: Kernel,
        method: &dyn LodMethod,
        items: &[&DrawItem],
        stats: &mut FrameStats,
        target: PhaseTarget,
    ) -> anyhow::Result<PhaseEncoded> {
        let streams = self.upload_items(items, method, stats)?;
        self.ensure_draw_capacity(items, &streams)?;
        let mut enc = self.gpu.device.create_command_encoder(&Default::default());
        let counters = self.encode_splats(
            shape,
            PhaseItems {
                method,
                items,
                streams: &streams,
            },
            stats,
            &mut enc,
            target,
        )?;
        Ok((enc, counters, streams))
    }

    /// Phase 2's results, once its submission is done: reads the query counts back (exact
    /// fragment counts where the adapter has them, else the hardware results) and classifies
    /// the candidates against the pass's threshold.
    fn read_occlusion(
        &self,
        occ: &OcclusionPass,
        pending: &PendingQueries,
    ) -> anyhow::Result<OcclusionStats> {
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
        Ok(occlusion)
    }

    /// Phase 3, its own submission: uploads and draws the visible candidates that carry an
    /// item, waits for it and records the splats drawn in `occlusion.phase3_points`. Returns
    /// the interval counters' readback and the stream buffers, or `None` when no candidate
    /// was drawn.
    fn draw_phase3(
        &mut self,
        shape: Kernel,
        method: &dyn LodMethod,
        occ: &OcclusionPass,
        occlusion: &mut OcclusionStats,
        stats: &mut FrameStats,
    ) -> anyhow::Result<Option<(IntervalCounters, Vec<GpuBatch>)>> {
        let items3: Vec<&DrawItem> = occ
            .candidates
            .iter()
            .enumerate()
            .filter(|(i, _)| occlusion.is_visible(*i, occ.threshold))
            .filter_map(|(_, c)| c.item.as_ref())
            .collect();
        if items3.is_empty() {
            return Ok(None);
        }
        let points_before = stats.points;
        let phase3 = PhaseTarget {
            clear: false,
            store_depth: self.edl.is_some() || self.keep_depth,
            ts: (4, 5),
        };
        let (mut enc, counters, streams3) =
            self.encode_phase(shape, method, &items3, stats, phase3)?;
        self.resolve_timestamps(&mut enc, 4..6, wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT);
        self.gpu.queue.submit([enc.finish()]);
        self.gpu.wait()?;
        occlusion.phase3_points = stats.points - points_before;
        Ok(Some((counters, streams3)))
    }
}

/// The interval counters' readback of one phase (buffer and size), when a draw had a test.
type IntervalCounters = Option<(wgpu::Buffer, u64)>;

/// One phase recorded by [`Renderer::encode_phase`]: its command encoder, the interval
/// counters' readback, if any, and the stream buffers uploaded for it.
type PhaseEncoded = (wgpu::CommandEncoder, IntervalCounters, Vec<GpuBatch>);

/// Workgroups `(x, y)` of 64 invocations covering `count` splats when one dimension holds at
/// most `max_per_dimension` workgroups (65,535 on most adapters, so 4,194,240 splats): rows of
/// `x` workgroups, `y` rows; the shaders' `dispatch_index` numbers the splats row after row
/// and skips those past `count`. `(0, 1)` for no splats.
pub fn dispatch_size(count: u32, max_per_dimension: u32) -> (u32, u32) {
    let groups = count.div_ceil(64);
    let x = groups.min(max_per_dimension.max(1));
    (x, if x == 0 { 1 } else { groups.div_ceil(x) })
}

/// True when the renderer counts occlusion samples exactly (in the queries' fragment stage):
/// every backend but GL. On GL, `OcclusionStats::samples` are the hardware query results,
/// which wgpu's GL backend makes boolean (`ANY_SAMPLES_PASSED_CONSERVATIVE`).
pub fn exact_counts(gpu: &Gpu) -> bool {
    gpu.device.adapter_info().backend != wgpu::Backend::Gl
}
