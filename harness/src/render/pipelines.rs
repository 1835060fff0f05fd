//! Building the renderer's pipelines and offscreen targets: the splat pipelines per kernel,
//! the gaussian kernel's accumulation targets, and the per-draw uniform buffer.

use super::*;

impl Renderer<'_> {
    /// Makes the pipelines `shape` needs, once.
    pub(super) fn ensure_pipelines(&mut self, shape: Kernel) {
        let kinds: &[PassKind] = match shape {
            Kernel::Gaussian => &[PassKind::GaussDepth, PassKind::GaussAccum],
            k => &[PassKind::Opaque(k)],
        };
        for &kind in kinds {
            if !self.pipelines.contains_key(&kind) {
                let p = self.make_pipeline(kind);
                self.pipelines.insert(kind, p);
            }
        }
        if shape == Kernel::Gaussian && self.gauss.is_none() {
            self.gauss = Some(self.make_gauss_targets());
        }
    }

    pub(super) fn make_pipeline(&self, kind: PassKind) -> wgpu::RenderPipeline {
        let (vs, fs, target, depth_write, compare) = match kind {
            PassKind::Opaque(k) => (
                if k == Kernel::Ellipse {
                    "vs_ellipse"
                } else {
                    "vs_main"
                },
                if k == Kernel::Square {
                    "fs_square"
                } else {
                    "fs_circle"
                },
                Some((COLOR_FORMAT, None)),
                true,
                wgpu::CompareFunction::Less,
            ),
            PassKind::GaussDepth => (
                "vs_gauss_depth",
                "fs_gauss_depth",
                None,
                true,
                wgpu::CompareFunction::Less,
            ),
            PassKind::GaussAccum => {
                let add = wgpu::BlendComponent {
                    src_factor: wgpu::BlendFactor::One,
                    dst_factor: wgpu::BlendFactor::One,
                    operation: wgpu::BlendOperation::Add,
                };
                (
                    "vs_gauss_accum",
                    "fs_gauss_accum",
                    Some((
                        ACCUM_FORMAT,
                        Some(wgpu::BlendState {
                            color: add,
                            alpha: add,
                        }),
                    )),
                    false,
                    wgpu::CompareFunction::LessEqual,
                )
            }
        };
        let targets: Vec<Option<wgpu::ColorTargetState>> = target
            .map(|(format, blend)| wgpu::ColorTargetState {
                format,
                blend,
                write_mask: wgpu::ColorWrites::ALL,
            })
            .into_iter()
            .map(Some)
            .collect();
        self.gpu
            .device
            .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(fs),
                layout: Some(&self.layout),
                vertex: wgpu::VertexState {
                    module: &self.module,
                    entry_point: Some(vs),
                    compilation_options: Default::default(),
                    buffers: &[],
                },
                primitive: wgpu::PrimitiveState::default(),
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(depth_write),
                    depth_compare: Some(compare),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &self.module,
                    entry_point: Some(fs),
                    compilation_options: Default::default(),
                    targets: &targets,
                }),
                multiview_mask: None,
                cache: None,
            })
    }

    pub(super) fn make_gauss_targets(&self) -> GaussTargets {
        let d = &self.gpu.device;
        let accum = d.create_texture(&wgpu::TextureDescriptor {
            label: Some("gaussian accumulation"),
            size: wgpu::Extent3d {
                width: self.settings.width,
                height: self.settings.height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: ACCUM_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let accum_view = accum.create_view(&Default::default());
        let bgl = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("normalize"),
            entries: &[fragment_texture(
                0,
                wgpu::TextureSampleType::Float { filterable: false },
            )],
        });
        let normalize_bg = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("normalize"),
            layout: &bgl,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&accum_view),
            }],
        });
        let module = d.create_shader_module(wgpu::include_wgsl!("normalize.wgsl"));
        let normalize =
            fullscreen_pipeline(d, "normalize", &bgl, &module, "fs_normalize", COLOR_FORMAT);
        GaussTargets {
            accum_view,
            normalize,
            normalize_bg,
        }
    }

    pub(super) fn draw_buffer(d: &wgpu::Device, size: u64) -> wgpu::Buffer {
        d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("draws"),
            size,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }
}

/// A 2-D, single-sampled texture binding of the fragment stage (the full-screen passes'
/// inputs: the gaussian accumulation, EDL's colour and depth, the viewer's frame and HUD).
pub(crate) fn fragment_texture(
    binding: u32,
    sample_type: wgpu::TextureSampleType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture {
            sample_type,
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
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
