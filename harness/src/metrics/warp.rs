//! Exact-motion warping: frame `j` of a camera path moved into frame `i`'s view by
//! reprojection with the two cameras and the full-resolution reference's depth, so that two
//! frames can be compared pixel by pixel without the motion between them (issue 38).
//!
//! For each pixel `p` of frame `i` (its centre), the reference's depth there gives the surface
//! point `X` it shows ([`unproject`]); `X` projected into frame `j` lands at `p'` with view
//! depth `d'`. The pixel is **valid** when
//!
//! 1. the reference covers `p` in frame `i` (a finite depth),
//! 2. `X` lies in front of camera `j` and `p'` inside its viewport,
//! 3. `X` is what frame `j` shows at `p'`: the pixel whose square holds `p'` has a reference
//!    depth within [`same_surface_tolerance`] of `d'`. It has not where `X` was hidden in
//!    frame `j` (disoccluded: something nearer covered it) or frame `j` showed nothing there
//!    (no reference coverage).
//!
//! A valid pixel takes the value of that pixel (nearest-neighbour: colours and coverage are
//! moved, never blended, a motion of whole pixels is reproduced exactly, and a pixel is never
//! fetched across an occluding edge, which a bilinear footprint would straddle). [`Warp::apply`] fills invalid pixels with frame
//! `i`'s own, so they carry no error into FLIP's spatial filters, and measures average over
//! valid pixels only ([`masked_mean`]).
//!
//! The warp runs on the CPU beside the metrics, which are CPU code too; the GPU contributes
//! the reference's depth (`Renderer::read_depth`), whose CPU mirror is the CPU renderer's
//! depth buffer (`render::cpu`).

use glam::{DVec3, DVec4};
use scenes::View;

use super::MetricsError;
use crate::image::Image;

/// View depths of one frame: distance along the camera's view direction of the surface each
/// pixel shows, [`f32::INFINITY`] where nothing was drawn. Rows top to bottom.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width · height` depths.
    pub depth: Vec<f32>,
}

impl DepthImage {
    /// A depth image from the renderer's depth buffer: `ndc` in 0..1 as wgpu stores it with
    /// `view`'s projection (`scenes::View::proj_matrix`), 1 where it was cleared.
    /// The inverse of `ndc = f (d − n) / ((f − n) d)`: `d = f n / (f − ndc (f − n))`.
    pub fn from_ndc(view: &View, ndc: &[f32]) -> Self {
        let (n, f) = (f64::from(view.camera.near), f64::from(view.camera.far));
        let depth = ndc
            .iter()
            .map(|&z| {
                if z >= 1.0 {
                    f32::INFINITY
                } else {
                    (f * n / (f - f64::from(z) * (f - n))) as f32
                }
            })
            .collect();
        Self {
            width: view.width,
            height: view.height,
            depth,
        }
    }

    /// Writes the depths to `path`: [`DEPTH_MAGIC`], width and height (u32 LE), the
    /// depths' byte count (u64 LE), then the little-endian `f32` depths compressed with
    /// LZO1X-1 (the background's runs of infinity shrink to nothing). Written to a temporary
    /// file renamed into place, so a reader sees a whole file or none.
    pub fn save(&self, path: &std::path::Path) -> std::io::Result<()> {
        let raw: Vec<u8> = self.depth.iter().flat_map(|d| d.to_le_bytes()).collect();
        let mut out = Vec::with_capacity(24 + raw.len() / 2);
        out.extend_from_slice(DEPTH_MAGIC);
        out.extend_from_slice(&self.width.to_le_bytes());
        out.extend_from_slice(&self.height.to_le_bytes());
        out.extend_from_slice(&(raw.len() as u64).to_le_bytes());
        out.extend_from_slice(&methods::store::compress(&raw));
        let mut tmp = path.as_os_str().to_owned();
        tmp.push(format!(".tmp.{}", std::process::id()));
        std::fs::write(&tmp, &out)?;
        std::fs::rename(&tmp, path)
    }

    /// Reads a file [`DepthImage::save`] wrote; an error (naming the file) for anything else,
    /// a truncated file included.
    pub fn load(path: &std::path::Path) -> Result<Self, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let bad = |m: &str| format!("{}: not a depth image ({m})", path.display());
        if bytes.len() < 24 || &bytes[..8] != DEPTH_MAGIC {
            return Err(bad("no header"));
        }
        let word = |at: usize| {
            u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
        };
        let (width, height) = (word(8), word(12));
        let mut len = [0u8; 8];
        len.copy_from_slice(&bytes[16..24]);
        let raw_len = u64::from_le_bytes(len);
        let pixels = u64::from(width) * u64::from(height);
        if raw_len != pixels * 4 {
            return Err(bad(&format!("{raw_len} bytes for {width}x{height}")));
        }
        let raw = methods::store::decompress(&bytes[24..], raw_len as usize, "depth")
            .map_err(|m| bad(&m))?;
        Ok(Self {
            width,
            height,
            depth: bytemuck::pod_collect_to_vec(&raw),
        })
    }

    fn at(&self, x: i64, y: i64) -> Option<f32> {
        (x >= 0 && y >= 0 && x < i64::from(self.width) && y < i64::from(self.height))
            .then(|| self.depth[y as usize * self.width as usize + x as usize])
    }
}

/// The first bytes of a depth file ([`DepthImage::save`]).
pub const DEPTH_MAGIC: &[u8; 8] = b"SBDEPTH1";

/// How many pixel footprints (world size of a pixel at the point's depth in frame `j`) two
/// depths may differ by and still show one surface: 8. A splat's depth is its centre's over
/// the whole quad (screen-aligned kernels) or follows its plane (ellipses), the gaussian's
/// depth pass pushes splats back by `GAUSS_DEPTH_OFFSET` of their size, and the reference's
/// splats are 1–3 px across, so one surface's depth varies by a few footprints on a tilted
/// surface (≈ 3.7 per pixel of radius at 75°); a surface that hides another lies further in
/// front than that on every path of the suite (`tests/popping.rs`'s occluder: 60 footprints).
pub const SAME_SURFACE_PX: f64 = 8.0;

/// The largest difference between a depth `d` seen in `view` and another depth of the same
/// surface: [`SAME_SURFACE_PX`] pixel footprints at `d`.
pub fn same_surface_tolerance(view: &View, d: f64) -> f64 {
    SAME_SURFACE_PX * d / f64::from(view.proj_scale())
}

/// Pixel centres of one view back to the points they show.
struct Unprojector {
    inverse_view: glam::DMat4,
    /// `tan(fov_y / 2)`.
    t: f64,
    size: (f64, f64),
}

impl Unprojector {
    fn new(view: &View) -> Self {
        Self {
            inverse_view: view.view_matrix().as_dmat4().inverse(),
            t: (f64::from(view.camera.fov_y) * 0.5).tan(),
            size: (f64::from(view.width), f64::from(view.height)),
        }
    }

    fn at(&self, x: f64, y: f64, d: f64) -> DVec3 {
        let (w, h) = self.size;
        let ndc_x = (x + 0.5) / w * 2.0 - 1.0;
        let ndc_y = 1.0 - (y + 0.5) / h * 2.0;
        let v = DVec4::new(ndc_x * d * self.t * (w / h), ndc_y * d * self.t, -d, 1.0);
        (self.inverse_view * v).truncate()
    }
}

/// The point (local frame) that pixel centre `(x + ½, y + ½)` of `view` shows at view depth
/// `d`.
pub fn unproject(view: &View, x: f64, y: f64, d: f64) -> DVec3 {
    Unprojector::new(view).at(x, y, d)
}

/// Marks a pixel of frame `i` that nothing in frame `j` maps to.
const INVALID: u32 = u32::MAX;

/// Where each pixel of frame `i` comes from in frame `j` (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Warp {
    width: u32,
    height: u32,
    /// Per pixel of frame `i`, the index of its source pixel in frame `j`, or [`INVALID`].
    source: Vec<u32>,
}

impl Warp {
    /// The warp from frame `j` (`from`, with the reference's depth `from_depth`) into frame
    /// `i` (`to`, `to_depth`). The two frames must have one size.
    pub fn new(
        to: &View,
        to_depth: &DepthImage,
        from: &View,
        from_depth: &DepthImage,
    ) -> Result<Self, MetricsError> {
        let size = |v: &View, d: &DepthImage| {
            if (v.width, v.height) != (d.width, d.height)
                || d.depth.len() != v.width as usize * v.height as usize
            {
                Err(MetricsError::SizeMismatch {
                    reference: (v.width, v.height),
                    test: (d.width, d.height),
                })
            } else {
                Ok(())
            }
        };
        size(to, to_depth)?;
        size(from, from_depth)?;
        size(to, from_depth)?;
        let w = to.width as usize;
        let unproject = Unprojector::new(to);
        let from_vp = from.view_proj().as_dmat4();
        let eye = from.camera.position.as_dvec3();
        let forward = from.camera.forward().as_dvec3();
        let (fw, fh) = (f64::from(from.width), f64::from(from.height));
        use rayon::prelude::*;
        let source = (0..to_depth.depth.len())
            .into_par_iter()
            .map(|k| {
                let d = f64::from(to_depth.depth[k]);
                if !d.is_finite() {
                    return INVALID;
                }
                let p = unproject.at((k % w) as f64, (k / w) as f64, d);
                let d_from = (p - eye).dot(forward);
                let clip = from_vp * p.extend(1.0);
                if clip.w <= 0.0 || d_from <= 0.0 {
                    return INVALID;
                }
                // Pixel coordinates of `p` in frame j, origin top-left, pixel centres at +½.
                let px = (clip.x / clip.w * 0.5 + 0.5) * fw;
                let py = (0.5 - clip.y / clip.w * 0.5) * fh;
                if !(0.0..fw).contains(&px) || !(0.0..fh).contains(&py) {
                    return INVALID;
                }
                // The pixel of frame j whose square holds p' shows X, or X was hidden there.
                let (sx, sy) = (px.floor() as i64, py.floor() as i64);
                let agrees = from_depth.at(sx, sy).is_some_and(|s| {
                    (f64::from(s) - d_from).abs() <= same_surface_tolerance(from, d_from)
                });
                if agrees {
                    (sy as usize * fw as usize + sx as usize) as u32
                } else {
                    INVALID
                }
            })
            .collect();
        Ok(Self {
            width: to.width,
            height: to.height,
            source,
        })
    }

    /// Valid pixels.
    pub fn valid(&self) -> usize {
        self.source.iter().filter(|&&s| s != INVALID).count()
    }

    /// Pixels of frame `i`.
    pub fn pixels(&self) -> usize {
        self.source.len()
    }

    /// Whether pixel `k` (row-major) of frame `i` is valid.
    pub fn is_valid(&self, k: usize) -> bool {
        self.source[k] != INVALID
    }

    /// Frame `j`'s image `from` moved into frame `i`: each valid pixel takes its source pixel
    /// (all four channels), each invalid one `fill`'s pixel (frame `i`'s own image, so that
    /// masked pixels compare as equal).
    pub fn apply(&self, from: &Image, fill: &Image) -> Result<Image, MetricsError> {
        for img in [from, fill] {
            if (img.width, img.height) != (self.width, self.height) {
                return Err(MetricsError::SizeMismatch {
                    reference: (self.width, self.height),
                    test: (img.width, img.height),
                });
            }
        }
        let mut out = fill.clone();
        for (k, &s) in self.source.iter().enumerate() {
            if s != INVALID {
                let s = s as usize * 4;
                out.rgba[k * 4..k * 4 + 4].copy_from_slice(&from.rgba[s..s + 4]);
            }
        }
        Ok(out)
    }
}

/// The mean of `map` over the valid pixels of `warp` (0 when none is valid).
pub fn masked_mean(warp: &Warp, map: &[f32]) -> f64 {
    let (sum, n) = map
        .iter()
        .enumerate()
        .filter(|(k, _)| warp.is_valid(*k))
        .fold((0.0f64, 0usize), |(s, n), (_, &v)| {
            (s + f64::from(v), n + 1)
        });
    if n == 0 { 0.0 } else { sum / n as f64 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use scenes::Camera;

    /// A 64 × 48 view from `eye` looking down −y (a wall at y = 0 faces it).
    fn view(eye: Vec3) -> View {
        View {
            camera: Camera {
                position: eye,
                target: eye + Vec3::new(0.0, -1.0, 0.0),
                up: Vec3::Z,
                fov_y: 0.8,
                near: 0.1,
                far: 100.0,
            },
            width: 64,
            height: 48,
        }
    }

    /// The depth image of the wall y = 0 seen from `v` (its plane faces the camera: every
    /// pixel's view depth is the eye's y), with a square [lo, hi]² in x, z at y = `near_y`
    /// in front of it when given.
    fn wall(v: &View, square: Option<(f32, f32, f32)>) -> DepthImage {
        let mut depth = vec![v.camera.position.y; (v.width * v.height) as usize];
        if let Some((lo, hi, y)) = square {
            for (k, d) in depth.iter_mut().enumerate() {
                let (x, z) = ((k % 64) as f64, (k / 64) as f64);
                let p = unproject(v, x, z, f64::from(v.camera.position.y - y));
                if (f64::from(lo)..f64::from(hi)).contains(&p.x)
                    && (f64::from(lo)..f64::from(hi)).contains(&p.z)
                {
                    *d = v.camera.position.y - y;
                }
            }
        }
        DepthImage {
            width: v.width,
            height: v.height,
            depth,
        }
    }

    fn image(f: impl Fn(u32, u32) -> [u8; 4]) -> Image {
        let mut img = Image::new(64, 48);
        for y in 0..48 {
            for x in 0..64 {
                let k = (y * 64 + x) as usize * 4;
                img.rgba[k..k + 4].copy_from_slice(&f(x, y));
            }
        }
        img
    }

    #[test]
    fn unproject_inverts_project() {
        let v = view(Vec3::new(0.3, 5.0, -0.2));
        for (x, y) in [(0.0, 0.0), (31.0, 17.0), (63.0, 47.0)] {
            let p = unproject(&v, x, y, 5.0);
            let q = v.project(p.as_vec3()).unwrap();
            assert!((f64::from(q.x) - (x + 0.5)).abs() < 1e-3, "{q}");
            assert!((f64::from(q.y) - (y + 0.5)).abs() < 1e-3, "{q}");
            assert!((f64::from(v.view_depth(p.as_vec3())) - 5.0).abs() < 1e-5);
        }
    }

    #[test]
    fn ndc_depth_linearises_to_view_depth() {
        let v = view(Vec3::new(0.0, 5.0, 0.0));
        let ndc: Vec<f32> = [0.1f32, 5.0, 99.0]
            .iter()
            .map(|&d| v.project(Vec3::new(0.0, 5.0 - d, 0.0)).unwrap().z)
            .chain([1.0])
            .collect();
        let lin = DepthImage::from_ndc(&v, &ndc).depth;
        // One f32 step of ndc (2⁻²⁴ near 1) is a relative depth step of d (f − n) / (f n)
        // times it: 6·10⁻⁵ at d = 99 with n = 0.1, f = 100.
        for (got, want) in lin.iter().zip([0.1f32, 5.0, 99.0]) {
            let relative = want * (100.0 - 0.1) / (100.0 * 0.1) * 2f32.powi(-24);
            assert!((got - want).abs() <= want * relative, "{got} vs {want}");
        }
        assert_eq!(lin[3], f32::INFINITY);
    }

    #[test]
    fn a_still_camera_maps_every_covered_pixel_to_itself() {
        let v = view(Vec3::new(0.0, 5.0, 0.0));
        let mut d = wall(&v, None);
        d.depth[100] = f32::INFINITY; // one pixel with no reference coverage
        let warp = Warp::new(&v, &d, &v, &d).unwrap();
        assert_eq!(warp.valid(), 64 * 48 - 1);
        assert!(!warp.is_valid(100));
        let img = image(|x, y| [x as u8 * 3, y as u8 * 5, 7, 255]);
        assert_eq!(
            warp.apply(&img, &Image::new(64, 48)).unwrap().rgba[..400],
            img.rgba[..400]
        );
        assert_eq!(warp.apply(&img, &img).unwrap(), img);
    }

    #[test]
    fn a_sideways_step_of_whole_pixels_is_reproduced_exactly_and_the_rest_masked() {
        // Wall at depth 5: a step of s along the screen's right (world −x for a camera
        // looking down −y with z up) moves the image by s · k / 5 pixels to the left, with
        // k = 48 / (2 tan 0.4) = 56.94; s = 3 · 5 / k moves it by exactly 3 pixels.
        let a = view(Vec3::new(0.0, 5.0, 0.0));
        let s = 3.0 * 5.0 / a.proj_scale();
        let b = view(Vec3::new(-s, 5.0, 0.0));
        let frame_a = image(|x, y| [x as u8 * 3, y as u8 * 5, 7, 255]);
        // What b sees: a's content 3 pixels further left; its last 3 columns are new.
        let frame_b = image(|x, y| [(x as u8 + 3) * 3, y as u8 * 5, 7, 255]);
        let warp = Warp::new(&b, &wall(&b, None), &a, &wall(&a, None)).unwrap();
        // The last 3 columns of b were outside a's viewport.
        assert_eq!(warp.valid(), 61 * 48);
        for y in 0..48 {
            for x in 0..64 {
                assert_eq!(warp.is_valid(y * 64 + x), x < 61, "({x}, {y})");
            }
        }
        let moved = warp.apply(&frame_a, &frame_b).unwrap();
        assert_eq!(moved, frame_b);
    }

    #[test]
    fn what_an_occluder_hid_is_masked_as_disoccluded() {
        // A square 1 unit in front of the wall (60 footprints at depth 4: far beyond the
        // tolerance of 8), seen from a then from b, 6 pixels to the right at the wall's
        // depth: the wall strip the square hid from a is disoccluded in b.
        let a = view(Vec3::new(0.0, 5.0, 0.0));
        let s = 6.0 * 5.0 / a.proj_scale();
        let b = view(Vec3::new(-s, 5.0, 0.0));
        let sq = Some((-0.5, 0.5, 1.0));
        let (da, db) = (wall(&a, sq), wall(&b, sq));
        let warp = Warp::new(&b, &db, &a, &da).unwrap();
        // Masked: the 6 columns at b's right edge (the wall outside a) and, on the rows the
        // square spans, the wall the square hid from a. The square moves 6 · 5/4 = 7.5 px, the
        // wall 6 px: a strip 1.5 px wide on the square's right side; the wall on its left
        // side was in view in both frames. A square pixel at its edge may be masked too
        // (its source's pixel centre falls half a pixel off a's square).
        let square = |y: usize| -> Option<(usize, usize)> {
            let xs: Vec<usize> = (0..64).filter(|&x| db.depth[y * 64 + x] < 4.5).collect();
            Some((*xs.first()?, *xs.last()?))
        };
        let mut rows = 0;
        for y in 0..48 {
            let Some((left, right)) = square(y) else {
                // A row without the square: only the edge columns are masked.
                for x in 0..64 {
                    assert_eq!(warp.is_valid(y * 64 + x), x < 58, "({x}, {y})");
                }
                continue;
            };
            rows += 1;
            assert!(
                !warp.is_valid(y * 64 + right + 1),
                "row {y}: the wall right of the square"
            );
            assert!(
                warp.is_valid(y * 64 + left - 1),
                "row {y}: the wall left of the square"
            );
            for x in 0..58 {
                let near = (left..=right + 2).contains(&x);
                assert!(warp.is_valid(y * 64 + x) || near, "({x}, {y}) masked");
            }
        }
        assert!(rows >= 10, "{rows} rows hold the square");
        // Every valid pixel's source shows the same surface (its depth agrees).
        let tol = same_surface_tolerance(&a, 5.0);
        for k in (0..64 * 48).filter(|&k| warp.is_valid(k)) {
            let src = warp.source[k] as usize;
            let d_b = f64::from(db.depth[k]);
            let d_a = f64::from(da.depth[src]);
            assert!((d_a - d_b).abs() <= tol, "pixel {k}: {d_a} vs {d_b}");
        }
    }

    #[test]
    fn masked_mean_averages_valid_pixels_only() {
        let v = view(Vec3::new(0.0, 5.0, 0.0));
        let mut d = wall(&v, None);
        for k in 0..64 {
            d.depth[k] = f32::INFINITY;
        }
        let warp = Warp::new(&v, &d, &v, &d).unwrap();
        let map: Vec<f32> = (0..64 * 48)
            .map(|k| if k < 64 { 1.0 } else { 0.25 })
            .collect();
        assert_eq!(masked_mean(&warp, &map), 0.25);
        let nothing = DepthImage {
            depth: vec![f32::INFINITY; 64 * 48],
            ..d
        };
        let none = Warp::new(&v, &nothing, &v, &nothing).unwrap();
        assert_eq!((none.valid(), masked_mean(&none, &map)), (0, 0.0));
    }

    #[test]
    fn a_depth_file_round_trips_and_a_damaged_one_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let v = view(Vec3::new(0.0, 5.0, 0.0));
        let mut d = wall(&v, Some((-0.5, 0.5, 1.0)));
        d.depth[7] = f32::INFINITY;
        let path = dir.path().join("a.depth");
        d.save(&path).unwrap();
        assert_eq!(DepthImage::load(&path).unwrap(), d);
        let bytes = std::fs::read(&path).unwrap();
        for cut in [0, 10, 24, bytes.len() - 1] {
            std::fs::write(&path, &bytes[..cut]).unwrap();
            let e = DepthImage::load(&path).unwrap_err();
            assert!(e.contains("a.depth"), "{e}");
        }
        let mut wrong = bytes.clone();
        wrong[8] = 63; // width 63: the byte count no longer matches
        std::fs::write(&path, &wrong).unwrap();
        assert!(
            DepthImage::load(&path)
                .unwrap_err()
                .contains("bytes for 63x48")
        );
    }

    #[test]
    fn sizes_that_differ_are_errors() {
        let v = view(Vec3::new(0.0, 5.0, 0.0));
        let d = wall(&v, None);
        let small = DepthImage {
            width: 2,
            height: 2,
            depth: vec![1.0; 4],
        };
        assert!(Warp::new(&v, &small, &v, &d).is_err());
        let warp = Warp::new(&v, &d, &v, &d).unwrap();
        assert!(warp.apply(&Image::new(2, 2), &Image::new(64, 48)).is_err());
    }
}
