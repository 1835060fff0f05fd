//! Puts a frame on the window: one full-screen pass (`present.wgsl`) that scales what the
//! session shows ([`Display`]: the renderer's own colour target, so nothing is read back, or
//! an image made on the CPU) to the surface and lays the HUD over it. No splat is drawn
//! here: the frame is the renderer's.

use bytemuck::{Pod, Zeroable};

use super::session::Display;
use crate::gpu::Gpu;
use crate::image::Image;
use crate::render::{COLOR_FORMAT, fragment_texture, fullscreen_pipeline};

/// The present shader.
pub const PRESENT_WGSL: &str = include_str!("present.wgsl");

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct PresentUniform {
    frame_size: [f32; 2],
    frame_origin: [f32; 2],
    frame_extent: [f32; 2],
    hud_size: [f32; 2],
    decode_srgb: f32,
    _pad: f32,
}

/// Where the frame goes on a surface of `surface` pixels whose top `band` rows hold the HUD:
/// `[x, y, width, height]`, the frame (`frame` pixels) scaled by the largest factor that fits
/// the rest (aspect kept), centred across and placed right under the band. The window opens
/// at the frame's size plus the band, where the factor is 1: the HUD covers nothing (before,
/// it lay over the frame's top at 85 %, a third of the default 512² frame once its lines
/// were broken to fit). A surface with no room left under the band gets the whole surface.
pub fn frame_rect(frame: (u32, u32), surface: (u32, u32), band: u32) -> [f32; 4] {
    let (fw, fh) = (frame.0.max(1) as f32, frame.1.max(1) as f32);
    let (sw, sh) = (surface.0.max(1) as f32, surface.1.max(1) as f32);
    let band = if band < surface.1 { band as f32 } else { 0.0 };
    let scale = (sw / fw).min((sh - band) / fh);
    let (w, h) = (fw * scale, fh * scale);
    [((sw - w) / 2.0).floor(), band, w, h]
}

/// An RGBA8 texture holding an [`Image`], remade when the size changes.
struct Uploaded {
    texture: wgpu::Texture,
    view: wgpu::TextureView,
    generation: u64,
}

impl Uploaded {
    fn write(gpu: &Gpu, slot: &mut Option<Uploaded>, img: &Image, generation: u64, label: &str) {
        let fits = slot
            .as_ref()
            .is_some_and(|u| u.texture.width() == img.width && u.texture.height() == img.height);
        if !fits {
            let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width: img.width.max(1),
                    height: img.height.max(1),
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: COLOR_FORMAT,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            });
            let view = texture.create_view(&Default::default());
            *slot = Some(Uploaded {
                texture,
                view,
                generation: u64::MAX,
            });
        }
        let Some(u) = slot.as_mut() else { return };
        if u.generation == generation || img.rgba.is_empty() {
            return;
        }
        gpu.queue.write_texture(
            u.texture.as_image_copy(),
            &img.rgba,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(img.width * 4),
                rows_per_image: None,
            },
            u.texture.size(),
        );
        u.generation = generation;
    }
}

/// The present pass for surfaces of one format.
pub struct Presenter {
    pipeline: wgpu::RenderPipeline,
    bgl: wgpu::BindGroupLayout,
    ubo: wgpu::Buffer,
    decode_srgb: bool,
    image: Option<Uploaded>,
    hud: Option<Uploaded>,
}

impl Presenter {
    /// A presenter drawing into `format` surfaces.
    pub fn new(gpu: &Gpu, format: wgpu::TextureFormat) -> Self {
        let d = &gpu.device;
        let texture = |binding| {
            fragment_texture(
                binding,
                wgpu::TextureSampleType::Float { filterable: false },
            )
        };
        let bgl = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("present"),
            entries: &[
                texture(0),
                texture(1),
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
            ],
        });
        let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("present.wgsl"),
            source: wgpu::ShaderSource::Wgsl(PRESENT_WGSL.into()),
        });
        let pipeline = fullscreen_pipeline(d, "present", &bgl, &module, "fs_present", format);
        let ubo = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("present"),
            size: std::mem::size_of::<PresentUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Presenter {
            pipeline,
            bgl,
            ubo,
            decode_srgb: format.is_srgb(),
            image: None,
            hud: None,
        }
    }

    /// Draws `shown` (frame size `frame`) under a HUD band of `band` rows ([`frame_rect`])
    /// and `hud` (an image and a generation number that changes with it: uploaded only then)
    /// into `target` (a surface texture of `surface` pixels) and submits.
    #[allow(clippy::too_many_arguments)]
    pub fn present(
        &mut self,
        gpu: &Gpu,
        shown: Display<'_>,
        frame: (u32, u32),
        (hud, hud_generation): (&Image, u64),
        band: u32,
        target: &wgpu::TextureView,
        surface: (u32, u32),
    ) {
        Uploaded::write(gpu, &mut self.hud, hud, hud_generation, "HUD");
        let frame_view = match shown {
            Display::Target(v) => v,
            Display::Image(img, generation) => {
                Uploaded::write(gpu, &mut self.image, img, generation, "shown image");
                match &self.image {
                    Some(u) => &u.view,
                    None => return,
                }
            }
        };
        let Some(hud_view) = self.hud.as_ref().map(|u| &u.view) else {
            return;
        };
        let [x, y, w, h] = frame_rect(frame, surface, band);
        let u = PresentUniform {
            frame_size: [frame.0 as f32, frame.1 as f32],
            frame_origin: [x, y],
            frame_extent: [w, h],
            hud_size: [hud.width as f32, hud.height as f32],
            decode_srgb: if self.decode_srgb { 1.0 } else { 0.0 },
            _pad: 0.0,
        };
        gpu.queue.write_buffer(&self.ubo, 0, bytemuck::bytes_of(&u));
        let bg = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("present"),
            layout: &self.bgl,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(frame_view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(hud_view),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: self.ubo.as_entire_binding(),
                },
            ],
        });
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("present"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: target,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
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
        gpu.queue.submit([enc.finish()]);
    }
}

/// The window's picture as an image: `shown` and `hud` presented (HUD band `band`), by the
/// same pass, into an offscreen RGBA8 target of the window's size `surface` and read back
/// (`--window-shot`).
pub fn window_image(
    gpu: &Gpu,
    shown: Display<'_>,
    frame: (u32, u32),
    (hud, band): (&Image, u32),
    surface: (u32, u32),
) -> anyhow::Result<Image> {
    let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("window shot"),
        size: wgpu::Extent3d {
            width: surface.0.max(1),
            height: surface.1.max(1),
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: COLOR_FORMAT,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let view = texture.create_view(&Default::default());
    Presenter::new(gpu, COLOR_FORMAT).present(gpu, shown, frame, (hud, 0), band, &view, surface);
    crate::render::read_texture(gpu, &texture)
}

/// The surface format the viewer asks for among `formats` (the surface's, best first): a
/// plain 8-bit one, so the frame's sRGB values go out unchanged; else the first (an sRGB
/// surface gets them decoded, [`Presenter`]).
pub fn surface_format(formats: &[wgpu::TextureFormat]) -> Option<wgpu::TextureFormat> {
    formats
        .iter()
        .copied()
        .find(|f| {
            matches!(
                f,
                wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Rgba8Unorm
            )
        })
        .or_else(|| formats.first().copied())
}

#[cfg(test)]
mod tests {
    use super::*;
    use wgpu::TextureFormat as F;

    #[test]
    fn the_frame_lies_under_the_band_one_to_one_at_the_opening_size() {
        // Opened at the frame's size plus the band: 1:1, right under it.
        assert_eq!(
            frame_rect((320, 240), (320, 440), 200),
            [0.0, 200.0, 320.0, 240.0]
        );
        // Twice as wide: the height limits, centred across.
        assert_eq!(
            frame_rect((320, 240), (640, 440), 200),
            [160.0, 200.0, 320.0, 240.0]
        );
        // Twice the room every way: scaled ×2.
        assert_eq!(
            frame_rect((320, 240), (640, 680), 200),
            [0.0, 200.0, 640.0, 480.0]
        );
        // Shorter than the band: the band is ignored, the frame fills what there is.
        assert_eq!(
            frame_rect((320, 240), (320, 150), 200),
            [60.0, 0.0, 200.0, 150.0]
        );
    }

    #[test]
    fn a_plain_format_is_preferred_to_srgb() {
        assert_eq!(
            surface_format(&[F::Bgra8UnormSrgb, F::Bgra8Unorm]),
            Some(F::Bgra8Unorm)
        );
        assert_eq!(surface_format(&[F::Rgba16Float]), Some(F::Rgba16Float));
        assert_eq!(surface_format(&[]), None);
    }
}
