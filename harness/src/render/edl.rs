//! Eye-dome lighting (`--shading edl`): a screen-space pass from depth only, for scenes with
//! neither normals nor colours (Boucheny 2009, as Potree's viewer draws it).
//!
//! For a covered pixel `p` with view distance `d(p)` (linearised from the depth buffer):
//! `s = Σ_q max(0, log₂ d(p) − log₂ d(q))` over its 8 neighbours `q` (the pixels at offsets
//! ±1 in x and y and the diagonals) that lie inside the image and are covered;
//! `shade = exp(−300 · strength · s / 8)`; the pixel's sRGB-encoded colour is multiplied by
//! `shade`, its coverage unchanged. Uncovered pixels stay background: the pass draws no
//! outline into them, so coverage — and with it the hole ratio — is the same with and
//! without EDL.
//!
//! Constants are Potree's viewer defaults: strength [`EDL_STRENGTH`] = 1, radius 1.4 px with
//! 8 samples on the circle, which nearest-texel sampling turns into exactly the 8-neighbourhood
//! used here (±1.4 px from a texel centre lands in the next texel; the diagonals at
//! (0.99, 0.99) likewise), and the factor 300 of its shader.
//!
//! The pass runs when a frame is read back, after wall time and GPU timestamps are taken:
//! it costs the same for every method (one full-screen pass), so splat rates stay comparable
//! with and without it. With the gaussian kernel it reads the depth of its first pass (pushed
//! back by [`super::GAUSS_DEPTH_OFFSET`] × the splat size, the same for all splats), which
//! shifts every log-depth alike to first order.
//!
//! [`apply_cpu`] is the CPU mirror, used by the tests.

use crate::gpu::Gpu;
use crate::image::Image;

/// EDL strength (Potree's default).
pub const EDL_STRENGTH: f32 = 1.0;

/// The 8 neighbour offsets, (dx, dy).
pub const NEIGHBOURS: [(i32, i32); 8] = [
    (1, 0),
    (1, 1),
    (0, 1),
    (-1, 1),
    (-1, 0),
    (-1, -1),
    (0, -1),
    (1, -1),
];

/// `Edl` uniform of `edl.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct EdlUniform {
    near: f32,
    far: f32,
    strength: f32,
    _pad: f32,
}

/// The shader.
pub const EDL_WGSL: &str = include_str!("edl.wgsl");

/// `log₂` of the view distance at NDC depth `z` (0 at `near`, 1 at `far`).
fn log_depth(z: f32, near: f32, far: f32) -> f32 {
    (near * far / (far - z * (far - near))).log2()
}

/// EDL on the CPU: `image` shaded in place from `depth` (NDC, one per pixel, row-major like
/// the image), as the GPU pass computes it.
pub fn apply_cpu(image: &mut Image, depth: &[f32], near: f32, far: f32) {
    let (w, h) = (image.width as i32, image.height as i32);
    let src = image.rgba.clone();
    let covered = |x: i32, y: i32| src[(y * w + x) as usize * 4 + 3] > 0;
    for y in 0..h {
        for x in 0..w {
            if !covered(x, y) {
                continue;
            }
            let here = log_depth(depth[(y * w + x) as usize], near, far);
            let mut sum = 0.0f32;
            for (dx, dy) in NEIGHBOURS {
                let (qx, qy) = (x + dx, y + dy);
                if qx < 0 || qy < 0 || qx >= w || qy >= h || !covered(qx, qy) {
                    continue;
                }
                sum += (here - log_depth(depth[(qy * w + qx) as usize], near, far)).max(0.0);
            }
            let shade = (-300.0 * EDL_STRENGTH * sum / 8.0).exp();
            let o = (y * w + x) as usize * 4;
            for c in 0..3 {
                image.rgba[o + c] = (src[o + c] as f32 / 255.0 * shade * 255.0).round() as u8;
            }
        }
    }
}

/// The GPU pass: a pipeline and a target of the renderer's size.
pub struct EdlPass {
    pipeline: wgpu::RenderPipeline,
    bgl: wgpu::BindGroupLayout,
    uniform: wgpu::Buffer,
    target: wgpu::Texture,
    target_view: wgpu::TextureView,
}

impl EdlPass {
    /// Makes the pipeline and a `width × height` target of `format`.
    pub fn new(gpu: &Gpu, width: u32, height: u32, format: wgpu::TextureFormat) -> Self {
        let d = &gpu.device;
        let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("edl.wgsl"),
            source: wgpu::ShaderSource::Wgsl(EDL_WGSL.into()),
        });
        let texture = super::pipelines::fragment_texture;
        let bgl = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("edl"),
            entries: &[
                texture(0, wgpu::TextureSampleType::Float { filterable: false }),
                texture(1, wgpu::TextureSampleType::Float { filterable: false }),
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: wgpu::BufferSize::new(
                            std::mem::size_of::<EdlUniform>() as u64
                        ),
                    },
                    count: None,
                },
            ],
        });
        let pipeline = super::fullscreen_pipeline(d, "edl", &bgl, &module, "fs_edl", format);
        let uniform = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("edl"),
            size: std::mem::size_of::<EdlUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let target = d.create_texture(&wgpu::TextureDescriptor {
            label: Some("edl target"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let target_view = target.create_view(&Default::default());
        Self {
            pipeline,
            bgl,
            uniform,
            target,
            target_view,
        }
    }

    /// Shades `color` (bound as `color_view`) from `depth_view` and copies the result back
    /// into `color`; submits, does not wait.
    pub fn apply(
        &self,
        gpu: &Gpu,
        color: &wgpu::Texture,
        color_view: &wgpu::TextureView,
        depth_view: &wgpu::TextureView,
        near: f32,
        far: f32,
    ) {
        let u = EdlUniform {
            near,
            far,
            strength: EDL_STRENGTH,
            _pad: 0.0,
        };
        gpu.queue
            .write_buffer(&self.uniform, 0, bytemuck::bytes_of(&u));
        let bg = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("edl"),
            layout: &self.bgl,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(color_view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(depth_view),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: self.uniform.as_entire_binding(),
                },
            ],
        });
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("edl"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &self.target_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bg, &[]);
            pass.draw(0..3, 0..1);
        }
        enc.copy_texture_to_texture(
            self.target.as_image_copy(),
            color.as_image_copy(),
            self.target.size(),
        );
        gpu.queue.submit([enc.finish()]);
    }
}
