//! CPU mirror of `splat.wgsl`: the same splat size, coverage and shading in plain Rust.
//!
//! Used by tests to check the GPU path (coverage must agree but for pixels whose centre lies
//! within float rounding of a splat edge) and to reason about coverage with no GPU at all.
//! Rasterisation rule mirrored: a pixel is covered when its centre lies in the splat's quad
//! (top-left rule), and for circles, ellipses and gaussians also inside the inscribed disk of
//! the quad's unit coordinates; opaque kernels test depth `Less` with one depth per splat (the
//! first drawn wins ties). The gaussian mirrors the three passes: pushed-back depth, weighted
//! accumulation where the splat's depth ≤ that buffer, normalisation.
//!
//! Occlusion culling ([`render`]) mirrors the renderer's three phases on one CPU colour and
//! depth buffer; [`query_samples`] rasterises the same icosahedron triangles as the GPU
//! query and documents its rasterisation rule.

use glam::Vec3;
use methods::{ClodTest, DrawItem, DrawList, LodMethod, SplatBatch, SplatSize, SplatTest};

use scenes::View;

use super::occlusion::{Icosahedron, OcclusionStats, needs_query};
use super::{AMBIENT, BASE_COLOR, Kernel, Raster, Shade};
use crate::image::Image;

/// Pixel size of splat `i` of `batch` drawn with `size` at clip-space `w` (the view depth).
/// [`SplatSize::Clod`] depends on its test: [`clod_px`]; here (no test) it is 0.
#[inline]
pub fn splat_px(size: SplatSize, radius: Option<f32>, w: f32, proj_scale: f32) -> f32 {
    match size {
        SplatSize::Pixels(px) => px,
        SplatSize::Radius { scale, min_px } => {
            min_px.max(2.0 * radius.unwrap_or(0.0) * scale * proj_scale / w)
        }
        SplatSize::Clod { .. } => 0.0,
    }
}

/// Pixel size of a point of spacing `spacing` at `p` (`clip` = view_proj · p) drawn with
/// [`SplatSize::Clod`] under `test` (`splat_size_px`'s mode 2 in `splat.wgsl`).
#[inline]
pub fn clod_px(
    test: &ClodTest,
    point_size: f32,
    spacing: f32,
    p: Vec3,
    clip: glam::Vec4,
    eye: Vec3,
    proj_scale: f32,
) -> f32 {
    use methods::clod::select;
    let t = select::target_spacing(p, clip, eye, test.scale, test.fovea).unwrap_or(-1.0);
    select::size_px(spacing, t, clip.w, proj_scale, point_size)
}

/// sRGB-encoded (0–1) → linear, as `splat.wgsl`'s `srgb_to_linear`.
pub(crate) fn srgb_to_linear(c: f32) -> f32 {
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

/// The linear colour of splat `i` as the shader computes it with `shade` (base colour,
/// colour or elevation ramp × Lambert shade; [`super::shading`]).
pub fn shade_linear(batch: &SplatBatch, i: usize, eye: Vec3, shade: &Shade) -> Vec3 {
    let p = Vec3::from(batch.positions[i]);
    let code = shade.shading.shader_code();
    let base = match &batch.colors {
        _ if code == 2 => {
            let t = (p.z - shade.elevation[0]) * shade.elevation_scale();
            Vec3::from(super::shading::elevation_colour(t).map(srgb_to_linear))
        }
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
    let light = match &batch.normals {
        Some(n) if code == 0 => {
            let n = methods::octnormal::decode(n[i]);
            let l = (eye - p).normalize();
            AMBIENT + (1.0 - AMBIENT) * n.dot(l).abs()
        }
        _ => 1.0,
    };
    base * light
}

/// Encodes a linear colour to sRGB8 as the shaders do.
pub fn encode_srgb(c: Vec3) -> [u8; 3] {
    let q = |v: f32| (linear_to_srgb(v).clamp(0.0, 1.0) * 255.0).round() as u8;
    [q(c.x), q(c.y), q(c.z)]
}

/// The sRGB8 colour of splat `i` as the shader computes it.
pub fn shade(batch: &SplatBatch, i: usize, eye: Vec3, shade: &Shade) -> [u8; 3] {
    encode_srgb(shade_linear(batch, i, eye, shade))
}

/// One splat's footprint on screen.
#[derive(Clone)]
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
pub fn splat_passes(batch: &SplatBatch, i: usize, test: &SplatTest, eye: Vec3) -> bool {
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
    for y in pixel_span(f.cy, f.half, h) {
        for x in pixel_span(f.cx, f.half, w) {
            if let Some(uv) = f.uv(x, y) {
                visit(y * w + x, uv);
            }
        }
    }
}

/// The pixels `0..n` along one axis whose centre lies in `[c − r, c + r)` (the quads'
/// top-left rule, and the compute rasteriser's).
fn pixel_span(c: f32, r: f32, n: usize) -> std::ops::Range<usize> {
    let n = n as f32;
    let lo = (c - r - 0.5).ceil().clamp(0.0, n) as usize;
    let hi = (c + r - 0.5).ceil().clamp(0.0, n) as usize;
    lo..hi
}

/// What the CPU mirror drew.
#[derive(Debug, Clone)]
pub struct CpuFrame {
    /// The image.
    pub image: Image,
    /// Splats sent (phase 1 + phase 3 with occlusion culling), as [`super::FrameStats::points`].
    pub points: u64,
    /// Cached chunks drawn, as [`super::FrameStats::chunks`].
    pub chunks: u64,
    /// What the occlusion queries found (`query_gpu_ms` always `None`).
    pub occlusion: Option<OcclusionStats>,
    /// The depth buffer (NDC, 1 where nothing was drawn), row-major like the image.
    pub depth: Vec<f32>,
}

/// Rasterises `list` on the CPU, decoding chunks through `method`, with the default shading.
pub fn rasterize(
    view: &View,
    list: &DrawList,
    method: &dyn LodMethod,
    kernel: Kernel,
) -> anyhow::Result<Image> {
    render(view, list, method, kernel).map(|f| f.image)
}

/// [`rasterize`] with `shade` (EDL included).
pub fn rasterize_shaded(
    view: &View,
    list: &DrawList,
    method: &dyn LodMethod,
    kernel: Kernel,
    shade: &Shade,
) -> anyhow::Result<Image> {
    render_shaded(view, list, method, kernel, shade).map(|f| f.image)
}

/// The squares the mirror rasterises for `list` in `view`: each drawn splat's centre (x, y in
/// pixels, y down) and half side in pixels, in draw order (splats the LOD tests reject or
/// behind the eye left out). For tests that bound where the GPU's snapped quad edges may
/// cover pixels the mirror does not.
pub fn squares(
    view: &View,
    list: &DrawList,
    method: &dyn LodMethod,
) -> anyhow::Result<Vec<(f32, f32, f32)>> {
    let (splats, _, _) = footprints(view, &list.items, method, Kernel::Square, &Shade::default())?;
    Ok(splats.iter().map(|f| (f.cx, f.cy, f.half)).collect())
}

/// Footprints of the splats of `items` (those the interval tests pass, in front of the eye),
/// plus the splats sent and the cached chunks drawn.
fn footprints<'a>(
    view: &View,
    items: impl IntoIterator<Item = &'a DrawItem>,
    method: &dyn LodMethod,
    kernel: Kernel,
    shade: &Shade,
) -> anyhow::Result<(Vec<Footprint>, u64, u64)> {
    let vp = view.view_proj();
    let vm = view.view_matrix();
    let (w, h) = (view.width as usize, view.height as usize);
    let k = view.proj_scale();
    let eye = view.camera.position;
    let mut splats = Vec::new();
    let (mut points, mut chunks) = (0u64, 0u64);
    for item in items {
        let size = item.size();
        let chunk;
        let (batch, first, count, test) = match (item, item.cached()) {
            (_, Some(c)) => {
                chunk = method.chunk(c.id)?;
                let first = (c.first as usize).min(chunk.len());
                let n = (c.count as usize).min(chunk.len() - first);
                chunks += 1;
                (&*chunk, first, n, c.test)
            }
            (DrawItem::Stream { batch, .. }, None) => (batch, 0, batch.len(), None),
            (item, None) => anyhow::bail!("unexpected draw item {item:?}"),
        };
        if matches!(size, SplatSize::Clod { .. }) && !matches!(test, Some(SplatTest::Clod(_))) {
            anyhow::bail!("a draw item asks for CLOD's sizes without CLOD's test");
        }
        points += count as u64;
        for i in first..first + count {
            if let Some(t) = &test
                && !splat_passes(batch, i, t, eye)
            {
                continue;
            }
            let p = Vec3::from(batch.positions[i]);
            let clip = vp * p.extend(1.0);
            if clip.w <= 0.0 {
                continue;
            }
            let s = match (size, test) {
                (SplatSize::Clod { point_size }, Some(SplatTest::Clod(t))) => {
                    let spacing = batch.lod.as_ref().map_or(0.0, |l| l[i][0]);
                    clod_px(&t, point_size, spacing, p, clip, eye, k)
                }
                _ => splat_px(size, batch.radii.as_ref().map(|r| r[i]), clip.w, k),
            };
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
                    Some((
                        glam::Vec2::new(-d.y, d.x),
                        d,
                        n.dot(l).abs().max(shade.ellipse_min_ratio()),
                    ))
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
                linear: shade_linear(batch, i, eye, shade),
            });
        }
    }
    Ok((splats, points, chunks))
}

/// Opaque kernels: depth `Less`, one depth per splat, the first drawn wins ties.
fn draw_opaque(
    w: usize,
    h: usize,
    splats: &[Footprint],
    round: bool,
    rgba: &mut [u8],
    depth: &mut [f32],
) {
    for f in splats {
        let c = encode_srgb(f.linear);
        raster(w, h, f.z, f, |o, uv| {
            if (!round || uv.length_squared() <= 1.0) && f.z < depth[o] {
                depth[o] = f.z;
                rgba[o * 4..o * 4 + 4].copy_from_slice(&[c[0], c[1], c[2], 255]);
            }
        });
    }
}

/// The compute rasteriser ([`super::compute`]): every pixel whose centre lies in a splat's
/// square (half side capped at half of [`super::compute::MAX_FOOTPRINT_PX`]) keeps the
/// smallest key `(depth bits << 32) | packed sRGB8 colour` (`keys`, `u64::MAX` = none, kept
/// across phases), then the keys are resolved into `rgba` and `depth`.
fn draw_compute(
    w: usize,
    h: usize,
    splats: &[Footprint],
    keys: &mut [u64],
    rgba: &mut [u8],
    depth: &mut [f32],
) {
    let cap = super::compute::MAX_FOOTPRINT_PX * 0.5;
    for f in splats {
        if !(0.0..=1.0).contains(&f.z) {
            continue;
        }
        let c = encode_srgb(f.linear);
        let colour = u32::from_le_bytes([c[0], c[1], c[2], 255]);
        let key = (u64::from(f.z.to_bits()) << 32) | u64::from(colour);
        let r = f.half.min(cap);
        for y in pixel_span(f.cy, r, h) {
            for x in pixel_span(f.cx, r, w) {
                let k = &mut keys[y * w + x];
                *k = (*k).min(key);
            }
        }
    }
    for (o, &k) in keys.iter().enumerate() {
        if k != u64::MAX {
            rgba[o * 4..o * 4 + 4].copy_from_slice(&(k as u32).to_le_bytes());
            depth[o] = f32::from_bits((k >> 32) as u32);
        }
    }
}

/// Sub-pixel precision the query rasteriser snaps vertices to (lavapipe reports 8 bits).
pub const SUBPIXEL_BITS: u32 = 8;

/// Phase 2 of occlusion culling for one candidate: the pixels of the front faces of the
/// icosahedron `verts` ([`super::occlusion::Icosahedron::vertices`]) whose depth is below
/// `depth` (the buffer phase 1 left). Rasterisation rule: vertices projected to pixels (y
/// down) and snapped to 1/2^[`SUBPIXEL_BITS`] px; faces counter-clockwise in NDC (y up) are
/// front faces, the others culled; a pixel counts when its centre is inside the triangle by
/// the edge functions, a centre exactly on an edge counting only for top and left edges;
/// depth is the NDC `z` interpolated linearly in screen space at the centre, tested `Less`
/// (and `≥ 0`). The caller only queries candidates whose icosahedron lies beyond the near
/// plane ([`super::occlusion::needs_query`]), so no triangle needs clipping.
pub fn query_samples(view: &View, verts: &[Vec3; 12], depth: &[f32]) -> u64 {
    let (w, h) = (view.width as usize, view.height as usize);
    let vp = view.view_proj();
    let snap = (1u32 << SUBPIXEL_BITS) as f32;
    let screen = verts.map(|p| {
        let c = vp * p.extend(1.0);
        let x = (c.x / c.w * 0.5 + 0.5) * w as f32;
        let y = (0.5 - c.y / c.w * 0.5) * h as f32;
        Vec3::new(
            (x * snap).round() / snap,
            (y * snap).round() / snap,
            c.z / c.w,
        )
    });
    // Edge function: positive on the inside of a triangle wound clockwise on screen (y down).
    let edge =
        |a: Vec3, b: Vec3, px: f32, py: f32| (b.x - a.x) * (py - a.y) - (b.y - a.y) * (px - a.x);
    // For that winding, a top edge runs rightwards horizontally, a left edge upwards.
    let top_left = |a: Vec3, b: Vec3| (a.y == b.y && b.x > a.x) || b.y < a.y;
    let mut count = 0u64;
    for t in Icosahedron::INDICES {
        let (a, mut b, mut c) = (
            screen[t[0] as usize],
            screen[t[1] as usize],
            screen[t[2] as usize],
        );
        // Counter-clockwise in NDC (y up) is clockwise on screen (y down): negative area here.
        let area = edge(a, b, c.x, c.y);
        if area >= 0.0 {
            continue; // back face (or degenerate): culled
        }
        std::mem::swap(&mut b, &mut c);
        let area = -area;
        let x0 = a.x.min(b.x).min(c.x).floor().max(0.0) as usize;
        let y0 = a.y.min(b.y).min(c.y).floor().max(0.0) as usize;
        let x1 = (a.x.max(b.x).max(c.x).ceil().max(0.0) as usize).min(w);
        let y1 = (a.y.max(b.y).max(c.y).ceil().max(0.0) as usize).min(h);
        let (tl0, tl1, tl2) = (top_left(b, c), top_left(c, a), top_left(a, b));
        let inside = |e: f32, tl: bool| e > 0.0 || (e == 0.0 && tl);
        for y in y0..y1 {
            let py = y as f32 + 0.5;
            for x in x0..x1 {
                let px = x as f32 + 0.5;
                let (e0, e1, e2) = (edge(b, c, px, py), edge(c, a, px, py), edge(a, b, px, py));
                if !(inside(e0, tl0) && inside(e1, tl1) && inside(e2, tl2)) {
                    continue;
                }
                let z = (e0 * a.z + e1 * b.z + e2 * c.z) / area;
                if z >= 0.0 && z < depth[y * w + x] {
                    count += 1;
                }
            }
        }
    }
    count
}

/// Rasterises `list` on the CPU, decoding chunks through `method`, with the three phases of
/// occlusion culling when the list has an occlusion pass (as the GPU renderer: phase 1 =
/// `list.items`; every candidate that [`super::occlusion::needs_query`] counted by
/// [`query_samples`] against phase 1's depth; phase 3 = the visible candidates' items, drawn
/// over phase 1's colour and depth). The gaussian kernel refuses occlusion, as on the GPU.
pub fn render(
    view: &View,
    list: &DrawList,
    method: &dyn LodMethod,
    kernel: Kernel,
) -> anyhow::Result<CpuFrame> {
    render_shaded(view, list, method, kernel, &Shade::default())
}

/// [`render`] with `shade`; `edl` shading runs [`super::edl::apply_cpu`] on the result.
pub fn render_shaded(
    view: &View,
    list: &DrawList,
    method: &dyn LodMethod,
    kernel: Kernel,
    shade: &Shade,
) -> anyhow::Result<CpuFrame> {
    render_with(view, list, method, kernel, shade, Raster::Quads)
}

/// [`render_shaded`] as rasteriser `raster` draws: [`Raster::Compute`] mirrors
/// [`super::compute`] (square splats only, footprints capped at
/// [`super::compute::MAX_FOOTPRINT_PX`], the nearest splat per pixel and, at equal depths,
/// the smaller packed colour).
pub fn render_with(
    view: &View,
    list: &DrawList,
    method: &dyn LodMethod,
    kernel: Kernel,
    shade: &Shade,
    rasteriser: Raster,
) -> anyhow::Result<CpuFrame> {
    let kernel = list.shape.unwrap_or(kernel);
    if rasteriser == Raster::Compute && kernel != Kernel::Square {
        anyhow::bail!(
            "the compute rasteriser draws square splats only, not '{}'",
            kernel.name()
        );
    }
    let mut keys = (rasteriser == Raster::Compute)
        .then(|| vec![u64::MAX; view.width as usize * view.height as usize]);
    if list.occlusion.is_some() && kernel == Kernel::Gaussian {
        anyhow::bail!("occlusion culling needs an opaque kernel (square, circle or ellipse)");
    }
    let (w, h) = (view.width as usize, view.height as usize);
    let (splats, mut points, mut chunks) = footprints(view, &list.items, method, kernel, shade)?;
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
            // Pass 2's quad is GAUSS_SUPPORT × the splat's; `uv` back in nominal radii.
            let wide = Footprint {
                half: f.half * super::GAUSS_SUPPORT,
                ..f.clone()
            };
            raster(w, h, f.z, &wide, |o, uv| {
                let wgt = super::gauss_weight(uv.length() * super::GAUSS_SUPPORT);
                if wgt > 0.0 && f.z <= depth[o] {
                    acc[o] += (f.linear * wgt).extend(wgt);
                }
            });
        }
        for (o, a) in acc.iter().enumerate() {
            if a.w >= super::GAUSS_COVERED {
                let c = encode_srgb(a.truncate() / a.w.max(1.0));
                rgba[o * 4..o * 4 + 4].copy_from_slice(&[c[0], c[1], c[2], 255]);
            }
        }
    } else if let Some(keys) = keys.as_mut() {
        draw_compute(w, h, &splats, keys, &mut rgba, &mut depth);
    } else {
        draw_opaque(
            w,
            h,
            &splats,
            kernel != Kernel::Square,
            &mut rgba,
            &mut depth,
        );
    }
    let occlusion = match &list.occlusion {
        None => None,
        Some(occ) => {
            let samples = occ
                .candidates
                .iter()
                .map(|c| {
                    let v = Icosahedron::vertices(c.center, c.radius);
                    needs_query(view, c, &v).then(|| query_samples(view, &v, &depth))
                })
                .collect();
            let mut stats = OcclusionStats::classify(&occ.candidates, samples, occ.threshold);
            let items3 = occ
                .candidates
                .iter()
                .enumerate()
                .filter(|(i, _)| stats.is_visible(*i, occ.threshold))
                .filter_map(|(_, c)| c.item.as_ref());
            let (splats3, p3, c3) = footprints(view, items3, method, kernel, shade)?;
            match keys.as_mut() {
                Some(keys) => draw_compute(w, h, &splats3, keys, &mut rgba, &mut depth),
                None => draw_opaque(
                    w,
                    h,
                    &splats3,
                    kernel != Kernel::Square,
                    &mut rgba,
                    &mut depth,
                ),
            }
            stats.phase3_points = p3;
            points += p3;
            chunks += c3;
            Some(stats)
        }
    };
    let mut image = Image {
        width: view.width,
        height: view.height,
        rgba,
    };
    if shade.shading == super::Shading::Edl {
        super::edl::apply_cpu(&mut image, &depth, view.camera.near, view.camera.far);
    }
    Ok(CpuFrame {
        image,
        points,
        chunks,
        occlusion,
        depth,
    })
}
