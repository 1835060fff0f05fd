//! The uniforms of `splat.wgsl` (per frame and per draw) and the constants they carry.

use super::*;

/// Ambient term of the Lambert shading.
pub const AMBIENT: f32 = 0.25;
/// Linear RGB of splats in scenes without colour.
pub const BASE_COLOR: [f32; 3] = [0.8, 0.8, 0.8];
/// Gaussian kernel, pass 1: depth pushed back by this × the splat's object-space diameter,
/// so splats within that distance of the front surface blend in pass 2.
pub const GAUSS_DEPTH_OFFSET: f32 = 0.5;
/// Gaussian kernel, pass 2: the footprint's half-size in nominal splat radii (`GAUSS_SUPPORT`
/// in `splat.wgsl`, which a test holds equal): where [`gauss_weight`] reaches 0.
pub const GAUSS_SUPPORT: f32 = 2.0;

/// Gaussian kernel, pass 3: a pixel whose summed weight (its opacity) is at least this is
/// covered (`GAUSS_COVERED` in `normalize.wgsl`): the spline's value at the nominal radius,
/// so a lone splat covers its nominal disc. Its colour is the weighted colour over the
/// black background, `Σwc / max(Σw, 1)`: full opacity from Σw = 1 on.
pub const GAUSS_COVERED: f32 = 0.5;

/// The gaussian kernel's weight at `r` nominal radii from the splat's centre (`gauss_weight`
/// in `splat.wgsl`): QSplat's "spline in opacity that falls to 1/2 at the nominal radius of
/// the splat" (§3.3), which the paper does not give further. Ours is the cubic Hermite spline
/// `1 − smoothstep(0, GAUSS_SUPPORT, r)` = `1 − 3t² + 2t³`, `t = r / 2`: 1 at the centre,
/// exactly 1/2 at the nominal radius, 0 with zero slope at twice it — a gaussian's shape
/// (C¹, bell-like) with compact support. The quad of pass 2 is [`GAUSS_SUPPORT`] × the
/// splat's, four times the area, which matches the paper's "Gaussians take approximately
/// four times as long" as squares (Fig. 3).
pub fn gauss_weight(r: f32) -> f32 {
    let t = r / GAUSS_SUPPORT;
    if t >= 1.0 {
        0.0
    } else {
        1.0 - t * t * (3.0 - 2.0 * t)
    }
}

/// `Frame` uniform of `splat.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FrameUniform {
    /// offset 0
    pub view_proj: [[f32; 4]; 4],
    /// offset 64
    pub eye: [f32; 3],
    /// offset 76
    pub proj_scale: f32,
    /// offset 80
    pub viewport: [f32; 2],
    /// offset 88
    pub ambient: f32,
    /// offset 92: the smallest minor ÷ major ratio of an ellipse ([`Shade::ellipse_min_ratio`])
    pub ellipse_min_ratio: f32,
    /// offset 96
    pub base_color: [f32; 4],
    /// offset 112
    pub view: [[f32; 4]; 4],
    /// offset 176
    pub depth_offset: f32,
    /// offset 180: [`Shading::shader_code`]
    pub shading: u32,
    /// offset 184: local Z at the bottom of the elevation ramp
    pub elevation_lo: f32,
    /// offset 188: 1 / the ramp's height range
    pub elevation_scale: f32,
}
const _: () = assert!(std::mem::size_of::<FrameUniform>() == 192);

/// `Draw` uniform of `splat.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub struct DrawUniform {
    /// offset 0
    pub size_px: f32,
    /// offset 4
    pub radius_scale: f32,
    /// offset 8
    pub min_px: f32,
    /// offset 12
    pub mode: u32,
    /// offset 16
    pub flags: u32,
    /// offset 20: 0 = none, 1 = SPT interval test, 2 = CLOD's filter
    pub test_kind: u32,
    /// offset 24: SPT's error mode
    pub test_mode: u32,
    /// offset 28: SPT's and CLOD's `ε / k`
    pub test_scale: f32,
    /// offset 32: SPT's overlap; CLOD's fovea
    pub test_overlap: f32,
    /// offset 36: splats sent (counting pass)
    pub count: u32,
    /// offset 40: counter slot (counting pass)
    pub slot: u32,
    /// offset 44: first splat of the part sent (compute and counting passes; the quads
    /// pass starts its instance range there)
    pub first: u32,
    /// offset 48: when `tint[3] > 0`, linear RGB that replaces the splats' base colour
    /// (shading still applies): the viewer's level colours ([`level_tint`]); zero otherwise
    pub tint: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<DrawUniform>() == 64);

/// Linear RGB of the viewer's level colours, level 0 first, repeating after 8 levels:
/// a qualitative palette (Okabe–Ito, distinguishable with the common colour-vision
/// deficiencies), sRGB values decoded.
pub const LEVEL_PALETTE: [[u8; 3]; 8] = [
    [230, 159, 0],
    [86, 180, 233],
    [0, 158, 115],
    [240, 228, 66],
    [0, 114, 178],
    [213, 94, 0],
    [204, 121, 167],
    [255, 255, 255],
];

/// The tint of level `level` ([`LEVEL_PALETTE`], linear, alpha 1).
pub fn level_tint(level: u32) -> [f32; 4] {
    let c = LEVEL_PALETTE[level as usize % LEVEL_PALETTE.len()];
    let lin = |v: u8| super::cpu::srgb_to_linear(f32::from(v) / 255.0);
    [lin(c[0]), lin(c[1]), lin(c[2]), 1.0]
}

impl DrawUniform {
    /// The uniform for a splat size, the attributes present and an optional per-splat test.
    pub fn new(size: SplatSize, attrs: Attributes, lod: bool, test: Option<SplatTest>) -> Self {
        let flags = attrs.normals as u32
            | (attrs.colors as u32) << 1
            | (attrs.radii as u32) << 2
            | (lod as u32) << 3;
        let (size_px, radius_scale, min_px, mode) = match size {
            SplatSize::Pixels(px) => (px, 0.0, 0.0, 0),
            SplatSize::Radius { scale, min_px } => (0.0, scale, min_px, 1),
            SplatSize::Clod { point_size } => (0.0, point_size, 0.0, 2),
        };
        let (test_kind, test_mode, test_scale, test_overlap) = match test {
            None => (0, 0, 0.0, 0.0),
            Some(SplatTest::Interval(t)) => (1, t.mode, t.scale, t.overlap),
            Some(SplatTest::Clod(t)) => (2, 0, t.scale, t.fovea),
        };
        Self {
            size_px,
            radius_scale,
            min_px,
            mode,
            flags,
            test_kind,
            test_mode,
            test_scale,
            test_overlap,
            count: 0,
            slot: 0,
            first: 0,
            tint: [0.0; 4],
        }
    }
}

/// The `Frame` uniform for a view drawn with `shade`.
pub fn frame_uniform(view: &View, shade: &Shade) -> FrameUniform {
    FrameUniform {
        view_proj: view.view_proj().to_cols_array_2d(),
        eye: view.camera.position.into(),
        proj_scale: view.proj_scale(),
        viewport: [view.width as f32, view.height as f32],
        ambient: AMBIENT,
        ellipse_min_ratio: shade.ellipse_min_ratio(),
        base_color: [BASE_COLOR[0], BASE_COLOR[1], BASE_COLOR[2], 1.0],
        view: view.view_matrix().to_cols_array_2d(),
        depth_offset: GAUSS_DEPTH_OFFSET,
        shading: shade.shading.shader_code(),
        elevation_lo: shade.elevation[0],
        elevation_scale: shade.elevation_scale(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// QSplat §3.3: the spline falls to 1/2 at the nominal radius; ours is 1 at the centre,
    /// 0 from GAUSS_SUPPORT on, decreasing in between, and the shader has the same support.
    #[test]
    fn the_gaussian_spline_is_one_half_at_the_nominal_radius() {
        assert_eq!(gauss_weight(0.0), 1.0);
        assert_eq!(gauss_weight(1.0), 0.5);
        assert_eq!(gauss_weight(GAUSS_SUPPORT), 0.0);
        assert_eq!(gauss_weight(3.0), 0.0);
        let samples: Vec<f32> = (0..=200).map(|i| gauss_weight(i as f32 / 100.0)).collect();
        assert!(
            samples.windows(2).all(|w| w[1] < w[0]),
            "strictly decreasing on [0, 2)"
        );
        // C¹ at the support's edge: the slope tends to 0 (1 − 3t² + 2t³ has 6t² − 6t = 0 at 1).
        let eps = 1e-3;
        assert!(gauss_weight(GAUSS_SUPPORT - eps) / eps < 1e-2);
        assert!(
            SPLAT_WGSL.contains(&format!("const GAUSS_SUPPORT: f32 = {GAUSS_SUPPORT:?};")),
            "splat.wgsl's GAUSS_SUPPORT is this one"
        );
        assert_eq!(
            gauss_weight(1.0),
            GAUSS_COVERED,
            "a lone splat covers its nominal disc"
        );
        assert!(
            include_str!("normalize.wgsl")
                .contains(&format!("const GAUSS_COVERED: f32 = {GAUSS_COVERED:?};")),
            "normalize.wgsl's GAUSS_COVERED is this one"
        );
    }
}
