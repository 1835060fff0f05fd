//! CPU mirror of `splat.wgsl`: the same splat size, coverage and shading in plain Rust.
//!
//! Used by tests to check the GPU path (coverage must agree but for pixels whose centre lies
//! within float rounding of a splat edge) and to reason about coverage with no GPU at all.
//! Rasterisation rule mirrored: a pixel is covered when its centre lies in the splat's quad
//! (top-left rule), and for circles, ellipses and gaussians also inside the inscribed disk of
//! the quad's unit coordinates; opaque kernels test depth `Less` with one depth per splat (the
//! first drawn wins ties). The gaussian mirrors the three passes: pushed-back depth, weighted
//! accumulation where the splat's depth ≤ that buffer, normalisation.

use glam::Vec3;
use methods::{DrawItem, DrawList, IntervalTest, LodMethod, SplatBatch, SplatSize};

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

/// The linear colour of splat `i` as the shader computes it (base colour × Lambert shade).
pub fn shade_linear(batch: &SplatBatch, i: usize, eye: Vec3) -> Vec3 {
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
    base * shade
}

/// Encodes a linear colour to sRGB8 as the shaders do.
pub fn encode_srgb(c: Vec3) -> [u8; 3] {
    let q = |v: f32| (linear_to_srgb(v).clamp(0.0, 1.0) * 255.0).round() as u8;
    [q(c.x), q(c.y), q(c.z)]
}

/// The sRGB8 colour of splat `i` as the shader computes it.
pub fn shade(batch: &SplatBatch, i: usize, eye: Vec3) -> [u8; 3] {
    encode_srgb(shade_linear(batch, i, eye))
}

/// One splat's footprint on screen.
struct Footprint {
    /// Centre in pixels (y down).
    cx: f32,
    cy: f32,
    /// Half the splat size in pixels.
    half: f32,
    /// NDC depth, and the gaussian pass-1 depth pushed back.
    z: f32,
    z_pushed: f32,
    /// Ellipse frame: major axis, minor axis (unit, y up), minor/major ratio.
    ellipse: Option<(glam::Vec2, glam::Vec2, f32)>,
    linear: Vec3,
}

impl Footprint {
    /// Unit-disk coordinates of the pixel centre (x, y), if inside the quad.
    fn uv(&self, x: usize, y: usize) -> Option<glam::Vec2> {
        // Offsets in pixels with y up, as the shader applies them in clip space.
        let d = glam::Vec2::new(x as f32 + 0.5 - self.cx, self.cy - (y as f32 + 0.5));
        let uv = match self.ellipse {
            None => d / self.half,
            Some((major, minor, ratio)) => {
                glam::Vec2::new(d.dot(major) / self.half, d.dot(minor) / (ratio * self.half))
            }
        };
        (uv.x.abs() <= 1.0 && uv.y.abs() <= 1.0).then_some(uv)
    }
}

/// The vertex stage's LOD test for splat `i` (`splat_passes` in `splat.wgsl`).
pub fn interval_passes(batch: &SplatBatch, i: usize, test: &IntervalTest, eye: Vec3) -> bool {
    let n = batch
        .normals
        .as_ref()
        .map_or(Vec3::Z, |n| methods::octnormal::decode(n[i]));
    let lod = batch.lod.as_ref().map_or([0.0; 4], |l| l[i]);
    test.passes(Vec3::from(batch.positions[i]), n, lod, eye)
}

/// Visits the pixels whose centre lies in the splat's quad (top-left rule), with their
/// unit-quad coordinates, when the depth `z` is inside the near/far range.
fn raster(w: usize, h: usize, z: f32, f: &Footprint, mut visit: impl FnMut(usize, glam::Vec2)) {
    if !(0.0..=1.0).contains(&z) {
        return;
    }
    let r = f.half;
    let x0 = ((f.cx - r - 0.5).ceil().max(0.0)) as usize;
    let y0 = ((f.cy - r - 0.5).ceil().max(0.0)) as usize;
    let x1 = ((f.cx + r - 0.5).ceil().min(w as f32)).max(0.0) as usize;
    let y1 = ((f.cy + r - 0.5).ceil().min(h as f32)).max(0.0) as usize;
    for y in y0..y1 {
        for x in x0..x1 {
            if let Some(uv) = f.uv(x, y) {
                visit(y * w + x, uv);
            }
        }
    }
}

/// Rasterises `list` on the CPU, decoding chunks through `method`.
pub fn rasterize(
    view: &View,
    list: &DrawList,
    method: &dyn LodMethod,
    kernel: Kernel,
) -> anyhow::Result<Image> {
    let kernel = list.shape.unwrap_or(kernel);
    let (w, h) = (view.width as usize, view.height as usize);
    let vp = view.view_proj();
    let vm = view.view_matrix();
    let k = view.proj_scale();
    let eye = view.camera.position;
    let mut splats = Vec::new();
    for item in &list.items {
        let size = item.size();
        let (batch, count, test) = match (item, item.cached()) {
            (_, Some((id, sent, test))) => {
                let b = method.chunk(id)?;
                let c = (sent as usize).min(b.len());
                (std::borrow::Cow::Owned(b), c, test)
            }
            (DrawItem::Stream { batch, .. }, None) => {
                (std::borrow::Cow::Borrowed(batch), batch.len(), None)
            }
            (item, None) => anyhow::bail!("unexpected draw item {item:?}"),
        };
        for i in 0..count {
            if let Some(t) = &test
                && !interval_passes(&batch, i, t, eye)
            {
                continue;
            }
            let p = Vec3::from(batch.positions[i]);
            let clip = vp * p.extend(1.0);
            if clip.w <= 0.0 {
                continue;
            }
            let s = splat_px(size, batch.radii.as_ref().map(|r| r[i]), clip.w, k);
            let l = (eye - p).normalize();
            let ellipse = match (&batch.normals, kernel) {
                (Some(n), Kernel::Ellipse) => {
                    let n = methods::octnormal::decode(n[i]);
                    let nv = (vm * n.extend(0.0)).truncate().truncate();
                    let d = if nv.length_squared() > 1e-12 {
                        nv.normalize()
                    } else {
                        glam::Vec2::X
                    };
                    Some((glam::Vec2::new(-d.y, d.x), d, n.dot(l).abs().max(0.1)))
                }
                _ => None,
            };
            let world = s * clip.w / k;
            let back = vp * (p - l * super::GAUSS_DEPTH_OFFSET * world).extend(1.0);
            splats.push(Footprint {
                cx: (clip.x / clip.w * 0.5 + 0.5) * w as f32,
                cy: (0.5 - clip.y / clip.w * 0.5) * h as f32,
                half: s * 0.5,
                z: clip.z / clip.w,
                z_pushed: back.z / back.w,
                ellipse,
                linear: shade_linear(&batch, i, eye),
            });
        }
    }
    let mut rgba = vec![0u8; w * h * 4];
    let mut depth = vec![1.0f32; w * h];
    if kernel == Kernel::Gaussian {
        for f in &splats {
            raster(w, h, f.z_pushed, f, |o, uv| {
                if uv.length_squared() <= 1.0 && f.z_pushed < depth[o] {
                    depth[o] = f.z_pushed;
                }
            });
        }
        let mut acc = vec![glam::Vec4::ZERO; w * h];
        for f in &splats {
            raster(w, h, f.z, f, |o, uv| {
                let r2 = uv.length_squared();
                if r2 <= 1.0 && f.z <= depth[o] {
                    let wgt = (-2.0 * r2).exp();
                    acc[o] += (f.linear * wgt).extend(wgt);
                }
            });
        }
        for (o, a) in acc.iter().enumerate() {
            if a.w > 0.0 {
                let c = encode_srgb(a.truncate() / a.w);
                rgba[o * 4..o * 4 + 4].copy_from_slice(&[c[0], c[1], c[2], 255]);
            }
        }
    } else {
        let round = kernel != Kernel::Square;
        for f in &splats {
            let c = encode_srgb(f.linear);
            raster(w, h, f.z, f, |o, uv| {
                if (!round || uv.length_squared() <= 1.0) && f.z < depth[o] {
                    depth[o] = f.z;
                    rgba[o * 4..o * 4 + 4].copy_from_slice(&[c[0], c[1], c[2], 255]);
                }
            });
        }
    }
    Ok(Image {
        width: view.width,
        height: view.height,
        rgba,
    })
}
