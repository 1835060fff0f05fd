//! The renderer's fixed resources, made once by [`Renderer::new`]: the size check, the
//! colour and depth targets, the splat and counting layouts and shader module, the uniform
//! and index buffers, and the timestamp queries. Each helper makes its resources in the order
//! `new` always made them.

use super::*;

/// The bind-group and pipeline layouts and the shader module of the splat passes and the
/// interval-counting pass.
pub(super) struct SplatLayouts {
    /// Group 0: the frame uniform and the per-draw uniform (dynamic offset).
    pub(super) bgl0: wgpu::BindGroupLayout,
    /// Group 1: the splat columns (five read-only storage buffers).
    pub(super) bgl1: wgpu::BindGroupLayout,
    /// Groups 0 and 1: the splat pipelines' layout.
    pub(super) layout: wgpu::PipelineLayout,
    /// `interval.wgsl` + `clod.wgsl` + `splat.wgsl` ([`SPLAT_WGSL`]).
    pub(super) module: wgpu::ShaderModule,
    /// Group 2 of the counting pass: its counters (read-write storage).
    pub(super) bgl2: wgpu::BindGroupLayout,
    /// Groups 0, 1 and 2: the counting pipeline's layout.
    pub(super) count_layout: wgpu::PipelineLayout,
}

/// The uniform, placeholder and index buffers every frame uses.
pub(super) struct FrameBuffers {
    /// The frame uniform.
    pub(super) frame_ubo: wgpu::Buffer,
    /// Bytes between two draws' uniforms (the struct rounded up to the offset alignment).
    pub(super) draw_stride: u64,
    /// Draw uniforms the draw buffer holds.
    pub(super) draw_capacity: u64,
    /// The per-draw uniforms.
    pub(super) draw_ubo: wgpu::Buffer,
    /// Bound in place of an absent attribute column.
    pub(super) dummy: wgpu::Buffer,
    /// The two triangles of a splat's quad.
    pub(super) quad_indices: wgpu::Buffer,
}

/// Refuses a target size the adapter cannot hold and an out-of-range ellipse clamp.
pub(super) fn check_settings(gpu: &Gpu, settings: &RenderSettings) -> anyhow::Result<()> {
    let max = gpu.limits.max_texture_dimension_2d;
    if settings.width == 0 || settings.height == 0 || settings.width > max || settings.height > max
    {
        bail!(
            "--width/--height {}x{} must be between 1 and {max} on adapter '{}'",
            settings.width,
            settings.height,
            gpu.adapter.name
        );
    }
    Shade::check_ellipse_clamp(settings.shade.ellipse_clamp).map_err(anyhow::Error::msg)?;
    Ok(())
}

/// The colour and depth targets, `settings.width` × `settings.height`.
pub(super) fn make_targets(
    d: &wgpu::Device,
    settings: &RenderSettings,
) -> (wgpu::Texture, wgpu::Texture) {
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
        // Bound as a texture by the occlusion queries (with a read-only depth attachment);
        // copied out for the reference's depth (`Renderer::read_depth`).
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    (color, depth)
}

impl SplatLayouts {
    /// Makes the layouts and compiles the splat shader module.
    pub(super) fn new(d: &wgpu::Device) -> Self {
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
        Self {
            bgl0,
            bgl1,
            layout,
            module,
            bgl2,
            count_layout,
        }
    }
}

impl FrameBuffers {
    /// Makes the frame uniform, a draw buffer for 256 draws, the placeholder column and the
    /// quad's index buffer.
    pub(super) fn new(gpu: &Gpu) -> Self {
        let d = &gpu.device;
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
        let draw_ubo = Renderer::draw_buffer(d, draw_stride * draw_capacity);
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
        Self {
            frame_ubo,
            draw_stride,
            draw_capacity,
            draw_ubo,
            dummy,
            quad_indices,
        }
    }
}

/// The frame's timestamp queries and their resolve and readback buffers, when the adapter
/// has timestamps.
pub(super) fn make_timestamps(gpu: &Gpu) -> Option<Timestamps> {
    let d = &gpu.device;
    gpu.timestamps.then(|| Timestamps {
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
    })
}
