//! CPU mirror of `splat.wgsl`: the same splat size, coverage and shading in plain Rust.
//!
//! Used by tests to check the GPU path (coverage must agree but for pixels whose centre lies
//! within float rounding of a splat edge) and to reason about coverage with no GPU at all.
//! Rasterisation rule mirrored: a pixel is covered when its centre lies in the splat's square
//! `[cx − s/2, cx + s/2) × [cy − s/2, cy + s/2)` (top-left rule), and for circles also inside
//! the inscribed disk; the depth test is `Less` with one depth per splat, so among splats at
//! equal depth the first drawn wins.

use glam::Vec3;
use methods::{DrawItem, DrawList, LodMethod, SplatBatch, SplatSize};
use scenes::View;

use super::{AMBIENT, BASE_COLOR, Kernel};
use crate::image::Image;

/// Pixel size of splat `i` of `batch` drawn with `size` at clip-space `w` (the view depth).
#[inline]
pub fn splat_px(size: SplatSize, radius: Option<f32>, w: f32, proj_scale: f32) -> f32 {
    match size {
        SplatSize::Pixels(px) => px,
        SplatSize::Radius { scale, min_px } => {
            min_px.max(2.0 * radius.unwrap_or(0.0) * scale * proj_scale / w)
        }
    }
}

fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// The sRGB8 colour of splat `i` as the shader computes it.
pub fn shade(batch: &SplatBatch, i: usize, eye: Vec3) -> [u8; 3] {
    let p = Vec3::from(batch.positions[i]);
    let base = match &batch.colors {
        Some(c) => {
            let c = c[i];
            Vec3::new(
                srgb_to_linear((c & 0xff) as f32 / 255.0),
                srgb_to_linear(((c >> 8) & 0xff) as f32 / 255.0),
                srgb_to_linear(((c >> 16) & 0xff) as f32 / 255.0),
            )
        }
        None => Vec3::from(BASE_COLOR),
    };
    let shade = match &batch.normals {
        Some(n) => {
            let n = methods::octnormal::decode(n[i]);
            let l = (eye - p).normalize();
            AMBIENT + (1.0 - AMBIENT) * n.dot(l).abs()
        }
        None => 1.0,
    };
    let c = base * shade;
    let q = |v: f32| (linear_to_srgb(v).clamp(0.0, 1.0) * 255.0).round() as u8;
    [q(c.x), q(c.y), q(c.z)]
}

/// Rasterises `list` on the CPU, decoding chunks through `method`.
pub fn rasterize(
    view: &View,
    list: &DrawList,
    method: &dyn LodMethod,
    kernel: Kernel,
) -> anyhow::Result<Image> {
    let (w, h) = (view.width as usize, view.height as usize);
    let mut rgba = vec![0u8; w * h * 4];
    let mut depth = vec![1.0f32; w * h];
    let vp = view.view_proj();
    let k = view.proj_scale();
    let eye = view.camera.position;
    for item in &list.items {
        let (batch, count, size) = match item {
            DrawItem::Chunk { id, points, size } => {
                let b = method.chunk(*id)?;
                let c = (*points as usize).min(b.len());
                (std::borrow::Cow::Owned(b), c, *size)
            }
            DrawItem::Stream { batch, size } => {
                (std::borrow::Cow::Borrowed(batch), batch.len(), *size)
            }
        };
        for i in 0..count {
            let p = Vec3::from(batch.positions[i]);
            let clip = vp * p.extend(1.0);
            if clip.w <= 0.0 {
                continue;
            }
            let ndc = clip.truncate() / clip.w;
            if !(0.0..=1.0).contains(&ndc.z) {
                continue;
            }
            let s = splat_px(size, batch.radii.as_ref().map(|r| r[i]), clip.w, k);
            let cx = (ndc.x * 0.5 + 0.5) * w as f32;
            let cy = (0.5 - ndc.y * 0.5) * h as f32;
            let half = s * 0.5;
            let x0 = ((cx - half - 0.5).ceil().max(0.0)) as usize;
            let y0 = ((cy - half - 0.5).ceil().max(0.0)) as usize;
            let x1 = ((cx + half - 0.5).ceil().min(w as f32)).max(0.0) as usize;
            let y1 = ((cy + half - 0.5).ceil().min(h as f32)).max(0.0) as usize;
            let color = shade(&batch, i, eye);
            for y in y0..y1 {
                for x in x0..x1 {
                    if kernel == Kernel::Circle {
                        let u = (x as f32 + 0.5 - cx) / half;
                        let v = (y as f32 + 0.5 - cy) / half;
                        if u * u + v * v > 1.0 {
                            continue;
                        }
                    }
                    let o = y * w + x;
                    if ndc.z < depth[o] {
                        depth[o] = ndc.z;
                        rgba[o * 4..o * 4 + 4]
                            .copy_from_slice(&[color[0], color[1], color[2], 255]);
                    }
                }
            }
        }
    }
    Ok(Image {
        width: view.width,
        height: view.height,
        rgba,
    })
}
