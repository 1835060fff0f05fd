//! The compute rasteriser, [`Raster::Compute`]: splats become pixels in a compute shader
//! instead of the fixed-function pipeline, the way Schütz, Kerbl and Wimmer (2021, "Rendering
//! Point Clouds with Compute Shaders and Vertex Order Optimization") draw points.
//!
//! Per phase of splat draws (`Renderer::encode_splats`):
//! 1. The visibility buffer (one 64-bit word per pixel) is cleared to 0 when the phase clears
//!    its targets (phase 3 of occlusion culling adds to phase 1's).
//! 2. `cs_raster` (`compute.wgsl`): one invocation per splat sent, 2-D dispatches past 65,535
//!    workgroups ([`dispatch_size`]). A splat behind the eye, failing the draw's interval
//!    test, or outside the near/far range writes nothing. Otherwise it covers the pixels
//!    whose centre lies in `[c − s/2, c + s/2)` on both axes (the quads' top-left rule; `s`
//!    the draw's or the splat's pixel size, capped at [`MAX_FOOTPRINT_PX`]; 1 px points are
//!    `s = 1`), and for each does a 64-bit atomic max of the complemented key
//!    `(depth bits << 32) | sRGB8 colour`: the nearest splat wins, equal depths resolve to the
//!    smaller colour value whatever the invocation order.
//! 3. A full-screen resolve pass (`resolve.wgsl`) writes each covered pixel's colour (alpha 1)
//!    and depth into the renderer's colour and depth targets (depth test off), so the
//!    metrics, the EDL pass and the occlusion queries read the same images as after quads.
//!
//! Shading is the quads' (`splat_linear` in `splat.wgsl`). Only the square kernel exists
//! here: circles, ellipses and gaussians are refused with an error naming `--raster quads`.
//! Needs the adapter features `SHADER_INT64` and `SHADER_INT64_ATOMIC_MIN_MAX` (Vulkan, DX12,
//! Metal; not wgpu's GL backend): without them [`Renderer::new`] fails naming the adapter and
//! the features. The CPU mirror is [`super::cpu`] with [`Raster::Compute`].
//!
//! GPU time: from the compute pass's beginning to the resolve pass's end.

use super::*;

/// Largest footprint side, pixels: a splat bigger than this is drawn this big, so that one
/// invocation writes at most 64² = 4,096 pixels (the quads path has no cap). At the
/// resolutions and tolerances of the papers' tables splats are a few pixels wide.
pub const MAX_FOOTPRINT_PX: f32 = 64.0;

/// The rasterising shader: `interval.wgsl` + `clod.wgsl` + `splat.wgsl` (bindings, tests, size, shading) +
/// `compute.wgsl`.
pub const COMPUTE_WGSL: &str = concat!(
    include_str!("interval.wgsl"),
    "\n",
    include_str!("clod.wgsl"),
    "\n",
    include_str!("splat.wgsl"),
    "\n",
    include_str!("compute.wgsl")
);

/// The resolve shader.
pub const RESOLVE_WGSL: &str = include_str!("resolve.wgsl");

/// What the compute rasteriser adds to a renderer.
pub(super) struct ComputeRaster {
    raster: wgpu::ComputePipeline,
    resolve: wgpu::RenderPipeline,
    visibility: wgpu::Buffer,
    /// Group 2 of `cs_raster`: the visibility buffer.
    raster_bg: wgpu::BindGroup,
    /// The resolve pass's uniform and visibility buffer.
    resolve_bg: wgpu::BindGroup,
    _resolve_ubo: wgpu::Buffer,
}

/// The features the compute rasteriser needs (defined with the device they are asked of).
pub const FEATURES: wgpu::Features = crate::gpu::INT64_ATOMICS;

/// Why a device with `features` and storage binding limit `max_binding` (bytes) on `adapter`
/// cannot run the compute rasteriser at `width` × `height`, if it cannot.
pub fn unsupported(
    features: wgpu::Features,
    max_binding: u64,
    adapter: &crate::gpu::AdapterDesc,
    width: u32,
    height: u32,
) -> Option<String> {
    if !features.contains(FEATURES) {
        return Some(format!(
            "--raster compute needs 64-bit integer atomics (wgpu features SHADER_INT64 and \
             SHADER_INT64_ATOMIC_MIN_MAX), which adapter '{}' ({}) does not offer; use \
             --raster quads",
            adapter.name, adapter.backend
        ));
    }
    let bytes = u64::from(width) * u64::from(height) * 8;
    (bytes > max_binding).then(|| {
        format!(
            "--raster compute at {width}x{height} needs a {bytes}-byte visibility buffer, over \
             adapter '{}''s storage binding limit of {max_binding} bytes; use a smaller \
             --width/--height or --raster quads",
            adapter.name
        )
    })
}

impl ComputeRaster {
    /// Pipelines and the visibility buffer for `settings`' size; `layout` is the renderer's
    /// frame+draw / splat columns / read-write buffer layout, `bgl2` its group 2.
    pub(super) fn new(
        gpu: &Gpu,
        settings: &RenderSettings,
        layout: &wgpu::PipelineLayout,
        bgl2: &wgpu::BindGroupLayout,
    ) -> anyhow::Result<Self> {
        let (features, max) = (
            gpu.device.features(),
            gpu.limits.max_storage_buffer_binding_size,
        );
        if let Some(why) = unsupported(features, max, &gpu.adapter, settings.width, settings.height)
        {
            bail!(why);
        }
        if settings.kernel != Kernel::Square {
            bail!(
                "--raster compute draws square splats (and 1 px points) only; kernel '{}' \
                 needs --raster quads",
                settings.kernel.name()
            );
        }
        let d = &gpu.device;
        let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("compute.wgsl"),
            source: wgpu::ShaderSource::Wgsl(COMPUTE_WGSL.into()),
        });
        let raster = d.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("compute raster"),
            layout: Some(layout),
            module: &module,
            entry_point: Some("cs_raster"),
            compilation_options: Default::default(),
            cache: None,
        });
        let pixels = u64::from(settings.width) * u64::from(settings.height);
        let visibility = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("visibility"),
            size: pixels * 8,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let raster_bg = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("visibility"),
            layout: bgl2,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: visibility.as_entire_binding(),
            }],
        });
        let resolve_ubo = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("resolve"),
            contents: bytemuck::cast_slice(&[settings.width, 0, 0, 0]),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty,
            count: None,
        };
        let resolve_bgl = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("resolve"),
            entries: &[
                entry(
                    0,
                    wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                ),
                entry(
                    1,
                    wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                ),
            ],
        });
        let resolve_bg = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("resolve"),
            layout: &resolve_bgl,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: resolve_ubo.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: visibility.as_entire_binding(),
                },
            ],
        });
        let resolve_module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("resolve.wgsl"),
            source: wgpu::ShaderSource::Wgsl(RESOLVE_WGSL.into()),
        });
        let resolve_layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("resolve"),
            bind_group_layouts: &[Some(&resolve_bgl)],
            immediate_size: 0,
        });
        let resolve = d.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("resolve"),
            layout: Some(&resolve_layout),
            vertex: wgpu::VertexState {
                module: &resolve_module,
                entry_point: Some("vs_fullscreen"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Always),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &resolve_module,
                entry_point: Some("fs_resolve"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: COLOR_FORMAT,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        Ok(Self {
            raster,
            resolve,
            visibility,
            raster_bg,
            resolve_bg,
            _resolve_ubo: resolve_ubo,
        })
    }
}

impl Renderer<'_> {
    /// Records one phase of splat draws with the compute rasteriser: the `resolved` draws
    /// ((splat columns bind group, first splat, splats sent), frame+draw bind group `bg0`), then the resolve pass into the
    /// colour and depth targets as `target` says.
    pub(super) fn encode_compute_raster(
        &self,
        enc: &mut wgpu::CommandEncoder,
        bg0: &wgpu::BindGroup,
        resolved: &[(&wgpu::BindGroup, u32, u32)],
        target: PhaseTarget,
    ) -> anyhow::Result<()> {
        let c = self
            .compute
            .as_ref()
            .context("the compute rasteriser was not set up")?;
        if target.clear {
            enc.clear_buffer(&c.visibility, 0, None);
        }
        let (b, e) = target.ts;
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("compute raster"),
            timestamp_writes: self
                .timestamps
                .as_ref()
                .map(|t| wgpu::ComputePassTimestampWrites {
                    query_set: &t.set,
                    beginning_of_pass_write_index: Some(b),
                    end_of_pass_write_index: None,
                }),
        });
        pass.set_pipeline(&c.raster);
        pass.set_bind_group(2, &c.raster_bg, &[]);
        let max = self.gpu.limits.max_compute_workgroups_per_dimension;
        for (i, (g, _, count)) in resolved.iter().enumerate() {
            if *count == 0 {
                continue;
            }
            pass.set_bind_group(0, bg0, &[(i as u64 * self.draw_stride) as u32]);
            pass.set_bind_group(1, *g, &[]);
            let (x, y) = dispatch_size(*count, max);
            pass.dispatch_workgroups(x, y, 1);
        }
        drop(pass);
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("resolve"),
            color_attachments: &[super::splats::color_attachment(
                &self.color_view,
                target.clear,
            )],
            depth_stencil_attachment: self.depth_attachment(target.clear, target.store_depth),
            timestamp_writes: self
                .timestamps
                .as_ref()
                .map(|t| wgpu::RenderPassTimestampWrites {
                    query_set: &t.set,
                    beginning_of_pass_write_index: None,
                    end_of_pass_write_index: Some(e),
                }),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&c.resolve);
        pass.set_bind_group(0, &c.resolve_bg, &[]);
        pass.draw(0..3, 0..1);
        Ok(())
    }
}
