//! The occlusion tests' scene: a test double [`Walls`] that behaves like LPC with
//! `occlusion=true` (a big near "wall" chunk, clouds behind and beside it), its view and
//! renderer settings. Shared by `tests/occlusion.rs` and `benches/occlusion.rs` (a module
//! directory, so cargo does not take it for a test of its own).
#![allow(dead_code)]

use harness::render::{Kernel, RenderSettings};
use methods::{
    ChunkId, DrawItem, DrawList, Feedback, LodMethod, MethodError, MethodStats, OcclusionCandidate,
    OcclusionPass, SplatBatch, SplatSize, Target,
};
use scenes::{Attributes, Camera, View};

pub const W: u32 = 160;
pub const H: u32 = 120;

/// The wall chunk, and the other clouds' chunk ids.
pub const WALL: ChunkId = 0;
pub const BEHIND: ChunkId = 1;
pub const BESIDE: ChunkId = 2;

/// One cloud of the test scene: its splats and bounding sphere.
pub struct Cloud {
    pub batch: SplatBatch,
    pub center: [f32; 3],
    pub radius: f32,
}

/// A test double that behaves like LPC with `occlusion=true`: every cloud is a candidate;
/// those `Feedback::visible` names are drawn in phase 1, the others wait for their query.
pub struct Walls {
    pub clouds: Vec<Cloud>,
    pub threshold: u64,
    pub occlusion: bool,
}

pub fn color(c: [u8; 3]) -> u32 {
    methods::draw::pack_color(c)
}

/// A square grid of `n × n` splats in the plane z = `z`, centred at (`cx`, `cy`), side `side`.
pub fn grid(cx: f32, cy: f32, z: f32, side: f32, n: usize, rgb: [u8; 3]) -> Cloud {
    let mut positions = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let t = |k: usize| (k as f32 / (n - 1) as f32 - 0.5) * side;
            positions.push([cx + t(i), cy + t(j), z]);
        }
    }
    let len = positions.len();
    Cloud {
        batch: SplatBatch {
            positions,
            colors: Some(vec![color(rgb); len]),
            ..Default::default()
        },
        center: [cx, cy, z],
        radius: side * std::f32::consts::FRAC_1_SQRT_2,
    }
}

/// A ball of splats (Fibonacci sphere of radius 0.8 · `radius`) with bounding sphere `radius`.
pub fn ball(c: [f32; 3], radius: f32, n: usize, rgb: [u8; 3]) -> Cloud {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let positions = (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - y * y).sqrt();
            let a = golden * i as f32;
            let s = 0.8 * radius;
            [c[0] + s * r * a.cos(), c[1] + s * y, c[2] + s * r * a.sin()]
        })
        .collect();
    Cloud {
        batch: SplatBatch {
            positions,
            colors: Some(vec![color(rgb); n]),
            ..Default::default()
        },
        center: c,
        radius,
    }
}

impl Walls {
    /// Wall at z = 0 (side 3, in front), a ball straight behind it, a ball beside it.
    pub fn scene() -> Self {
        Self {
            clouds: vec![
                grid(0.0, 0.0, 0.0, 3.0, 31, [200, 40, 40]),
                ball([0.0, 0.0, -3.0], 0.5, 400, [40, 200, 40]),
                ball([3.5, 0.0, -3.0], 0.5, 400, [40, 40, 200]),
            ],
            threshold: 0,
            occlusion: true,
        }
    }
    pub fn item(&self, id: ChunkId) -> DrawItem {
        DrawItem::Chunk {
            id,
            first: 0,
            points: self.clouds[id as usize].batch.len() as u32,
            size: SplatSize::Pixels(4.0),
        }
    }
    pub fn bytes(&self, id: ChunkId) -> u64 {
        self.clouds[id as usize].batch.byte_size()
    }
    pub fn points(&self, ids: &[ChunkId]) -> u64 {
        ids.iter()
            .map(|&i| self.clouds[i as usize].batch.len() as u64)
            .sum()
    }
}

impl LodMethod for Walls {
    fn attributes(&self) -> Attributes {
        Attributes {
            normals: false,
            colors: true,
            radii: false,
        }
    }
    fn input_points(&self) -> u64 {
        self.clouds.iter().map(|c| c.batch.len() as u64).sum()
    }
    fn frame(&mut self, _: &View, _: Target, fb: &Feedback) -> Result<DrawList, MethodError> {
        let mut list = DrawList {
            counters: vec![self.clouds.len() as f64],
            ..Default::default()
        };
        let ids = 0..self.clouds.len() as ChunkId;
        if !self.occlusion {
            list.items = ids.map(|id| self.item(id)).collect();
            return Ok(list);
        }
        let mut candidates = Vec::new();
        for id in ids {
            let c = &self.clouds[id as usize];
            let item = if fb.visible.contains(&id) {
                list.items.push(self.item(id));
                None
            } else {
                Some(self.item(id))
            };
            candidates.push(OcclusionCandidate {
                id,
                center: c.center,
                radius: c.radius,
                item,
            });
        }
        list.occlusion = Some(OcclusionPass {
            candidates,
            threshold: self.threshold,
        });
        Ok(list)
    }
    fn chunk(&self, id: ChunkId) -> Result<std::sync::Arc<SplatBatch>, MethodError> {
        self.clouds
            .get(id as usize)
            .map(|c| std::sync::Arc::new(c.batch.clone()))
            .ok_or(MethodError::NoChunk(id))
    }
    fn stats(&self) -> MethodStats {
        MethodStats::default()
    }
    fn extra_columns(&self) -> &'static [&'static str] {
        &["clouds"]
    }
    fn occlusion_culled(&self) -> bool {
        self.occlusion
    }
}

/// Camera at z = 5 looking down −z at the origin.
pub fn view() -> View {
    View {
        camera: Camera {
            position: glam::Vec3::new(0.0, 0.0, 5.0),
            target: glam::Vec3::ZERO,
            up: glam::Vec3::Y,
            fov_y: 60f32.to_radians(),
            near: 0.1,
            far: 50.0,
        },
        width: W,
        height: H,
    }
}

pub fn settings(kernel: Kernel) -> RenderSettings {
    RenderSettings {
        width: W,
        height: H,
        kernel,
        cache_bytes: 64 << 20,
        shade: Default::default(),
        raster: Default::default(),
    }
}

pub fn feedback(visible: &[ChunkId]) -> Feedback {
    Feedback {
        visible: visible.iter().copied().collect(),
        ..Default::default()
    }
}
