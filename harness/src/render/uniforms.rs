//! The uniforms of `splat.wgsl` (per frame and per draw) and the constants they carry.

use super::*;

/// Ambient term of the Lambert shading.
pub const AMBIENT: f32 = 0.25;
/// Linear RGB of splats in scenes without colour.
pub const BASE_COLOR: [f32; 3] = [0.8, 0.8, 0.8];
/// Gaussian kernel, pass 1: depth pushed back by this × the splat's object-space diameter,
/// so splats within that distance of the front surface blend in pass 2.
pub const GAUSS_DEPTH_OFFSET: f32 = 0.5;

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
    /// offset 92
    pub _pad0: f32,
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
    /// offset 20: 0 = none, 1 = SPT interval test
    pub test_kind: u32,
    /// offset 24
    pub test_mode: u32,
    /// offset 28
    pub test_scale: f32,
    /// offset 32
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
    /// The uniform for a splat size, the attributes present and an optional interval test.
    pub fn new(size: SplatSize, attrs: Attributes, lod: bool, test: Option<IntervalTest>) -> Self {
        let flags = attrs.normals as u32
            | (attrs.colors as u32) << 1
            | (attrs.radii as u32) << 2
            | (lod as u32) << 3;
        let (size_px, radius_scale, min_px, mode) = match size {
            SplatSize::Pixels(px) => (px, 0.0, 0.0, 0),
            SplatSize::Radius { scale, min_px } => (0.0, scale, min_px, 1),
        };
        Self {
            size_px,
            radius_scale,
            min_px,
            mode,
            flags,
            test_kind: test.is_some() as u32,
            test_mode: test.map_or(0, |t| t.mode),
            test_scale: test.map_or(0.0, |t| t.scale),
            test_overlap: test.map_or(0.0, |t| t.overlap),
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
        _pad0: 0.0,
        base_color: [BASE_COLOR[0], BASE_COLOR[1], BASE_COLOR[2], 1.0],
        view: view.view_matrix().to_cols_array_2d(),
        depth_offset: GAUSS_DEPTH_OFFSET,
        shading: shade.shading.shader_code(),
        elevation_lo: shade.elevation[0],
        elevation_scale: shade.elevation_scale(),
    }
}
