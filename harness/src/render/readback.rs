//! Reading results back from the GPU: timestamps (resolved per phase), interval counters,
//! and the colour target.

use super::*;
use crate::metrics::warp::DepthImage;

/// Bytes of the timestamp resolve/readback buffers: queries 0..4 at offset 0, 4..6 at the
/// second [`wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT`] slot (phase 3 resolves in its own
/// submission).
pub(super) const TIMESTAMP_READBACK_BYTES: u64 = 2 * wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT;

/// The frame's timestamp query set and its resolve and readback buffers.
pub(super) struct Timestamps {
    pub(super) set: wgpu::QuerySet,
    pub(super) resolve: wgpu::Buffer,
    pub(super) readback: wgpu::Buffer,
    pub(super) period_ns: f64,
}

impl Renderer<'_> {
    /// After the last submission: wall time, interval counters, timestamps, the image (with
    /// the EDL pass first, when the shading has one: outside the timings, see [`edl`]).
    pub(super) fn finish_frame(
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
    pub(super) fn resolve_timestamps(
        &self,
        enc: &mut wgpu::CommandEncoder,
        range: Range<u32>,
        offset: u64,
    ) {
        if let Some(t) = &self.timestamps {
            let bytes = range.len() as u64 * 8;
            enc.resolve_query_set(&t.set, range, &t.resolve, offset);
            enc.copy_buffer_to_buffer(&t.resolve, offset, &t.readback, offset, bytes);
        }
    }

    /// Reads the colour target back.
    pub fn read_color(&self) -> anyhow::Result<Image> {
        read_texture(self.gpu, &self.color)
    }

    /// Reads the depth target of the last frame drawn of `view` back as view depths
    /// ([`DepthImage::from_ndc`]). The depth is kept only by a renderer made to keep it
    /// ([`Renderer::keep_depth`]): an error otherwise.
    pub fn read_depth(&self, view: &View) -> anyhow::Result<DepthImage> {
        anyhow::ensure!(
            self.keep_depth,
            "the renderer does not keep its depth (Renderer::keep_depth)"
        );
        let raw = read_rows(self.gpu, &self.depth, wgpu::TextureAspect::DepthOnly, 4)?;
        let ndc: Vec<f32> = bytemuck::pod_collect_to_vec(&raw);
        Ok(DepthImage::from_ndc(view, &ndc))
    }
}

/// Reads an RGBA8 `texture` back (its whole first mip level).
pub(crate) fn read_texture(gpu: &Gpu, texture: &wgpu::Texture) -> anyhow::Result<Image> {
    let rgba = read_rows(gpu, texture, wgpu::TextureAspect::All, 4)?;
    Ok(Image {
        width: texture.width(),
        height: texture.height(),
        rgba,
    })
}

/// The first mip level of `aspect` of `texture` (`texel` bytes per texel), its rows packed
/// without the copy's row padding.
fn read_rows(
    gpu: &Gpu,
    texture: &wgpu::Texture,
    aspect: wgpu::TextureAspect,
    texel: u32,
) -> anyhow::Result<Vec<u8>> {
    let (w, h) = (texture.width(), texture.height());
    let row = w * texel;
    let padded =
        row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let size = padded as u64 * h as u64;
    let buf = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("texture readback"),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    enc.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            aspect,
            ..texture.as_image_copy()
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buf,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: Some(h),
            },
        },
        texture.size(),
    );
    gpu.queue.submit([enc.finish()]);
    let bytes = read_buffer(gpu, &buf, size)?;
    let mut out = Vec::with_capacity((row * h) as usize);
    for y in 0..h as usize {
        let start = y * padded as usize;
        out.extend_from_slice(&bytes[start..start + row as usize]);
    }
    Ok(out)
}

/// Maps `buf`, waits for the device, and copies its first `size` bytes out.
pub(super) fn read_buffer(gpu: &Gpu, buf: &wgpu::Buffer, size: u64) -> anyhow::Result<Vec<u8>> {
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

/// A zero-filled storage buffer of `bytes` that the GPU counts into and that is copied to a
/// readback buffer afterwards (interval counters, occlusion fragment counters).
pub(super) fn zeroed_counters(d: &wgpu::Device, label: &str, bytes: u64) -> wgpu::Buffer {
    d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: &vec![0u8; bytes as usize],
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
    })
}
