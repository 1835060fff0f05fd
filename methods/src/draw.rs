//! Draw lists: what a method asks the renderer to draw this frame, as plain data.
//!
//! A [`DrawList`] holds items of two kinds: cached *chunks* (decoded once through
//! [`crate::LodMethod::chunk`], then kept in the renderer's LRU GPU cache) and *streams* of
//! splats generated this frame (QSplat's per-frame traversal output, uploaded every frame).
//! Splat size is either a pixel size for the whole item or per splat from its object-space
//! radius, projected in the vertex stage: `px = max(min_px, 2·radius·scale·k / z)`.

use std::collections::HashSet;

use scenes::Attributes;

use crate::MethodError;

/// Identifies a chunk within one opened method instance.
pub type ChunkId = u64;

/// How large each splat of an item is drawn.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum SplatSize {
    /// Every splat of the item is this many pixels across.
    Pixels(f32),
    /// Per splat: diameter `2·radius·scale` in object units, projected; never below `min_px`.
    Radius {
        /// Multiplier on the stored radius.
        scale: f32,
        /// Smallest size drawn, in pixels.
        min_px: f32,
    },
    /// Per splat, from a [`SplatTest::Clod`] test's target spacing and the splat's own
    /// spacing (`lod[0]`), fading in near its cut-off ([`crate::clod::select::size_px`]);
    /// only with that test.
    Clod {
        /// Multiplier (CLOD's `pointSize`).
        point_size: f32,
    },
}

/// The splats a chunk decodes to, or a stream generated this frame. Columns mirror the
/// cloud's [`Attributes`]: an attribute the scene lacks is `None` and is never uploaded.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SplatBatch {
    /// Local positions.
    pub positions: Vec<[f32; 3]>,
    /// Octahedral-encoded normals ([`crate::octnormal`]).
    pub normals: Option<Vec<u32>>,
    /// sRGB colours packed as `r | g<<8 | b<<16 | 255<<24`.
    pub colors: Option<Vec<u32>>,
    /// Object-space splat radii.
    pub radii: Option<Vec<f32>>,
    /// Per-splat data of a vertex-stage LOD test (SPT: see `methods::spt`); uploaded only
    /// by methods that use [`DrawItem::Sequential`].
    pub lod: Option<Vec<[f32; 4]>>,
}

impl SplatBatch {
    /// An empty batch carrying the given attributes.
    pub fn with_attributes(attrs: Attributes, capacity: usize) -> Self {
        Self {
            positions: Vec::with_capacity(capacity),
            normals: attrs.normals.then(|| Vec::with_capacity(capacity)),
            colors: attrs.colors.then(|| Vec::with_capacity(capacity)),
            radii: attrs.radii.then(|| Vec::with_capacity(capacity)),
            lod: None,
        }
    }
    /// The samples `range` of `cloud` with the given radii (one per sample of the cloud),
    /// converted to the upload format. Only the columns the cloud has are filled.
    pub fn from_cloud_range(
        cloud: &scenes::PointCloud,
        range: std::ops::Range<usize>,
        radii: Option<&[f32]>,
    ) -> Self {
        Self {
            positions: cloud.positions()[range.clone()].to_vec(),
            normals: cloud.normals().map(|n| {
                n[range.clone()]
                    .iter()
                    .map(|v| crate::octnormal::encode(glam::Vec3::from(*v)))
                    .collect()
            }),
            colors: cloud
                .colors()
                .map(|c| c[range.clone()].iter().map(|c| pack_color(*c)).collect()),
            radii: radii.map(|r| r[range].to_vec()),
            lod: None,
        }
    }
    /// Number of splats.
    pub fn len(&self) -> usize {
        self.positions.len()
    }
    /// True if there are no splats.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }
    /// Which attribute columns are present.
    pub fn attributes(&self) -> Attributes {
        Attributes {
            normals: self.normals.is_some(),
            colors: self.colors.is_some(),
            radii: self.radii.is_some(),
        }
    }
    /// Bytes of the columns as uploaded.
    pub fn byte_size(&self) -> u64 {
        let n = self.len() as u64;
        let a = self.attributes();
        n * (12 + 4 * (a.normals as u64 + a.colors as u64 + a.radii as u64))
            + self.lod.as_ref().map_or(0, |l| l.len() as u64 * 16)
    }
    /// Checks that every present column has one value per position.
    pub fn validate(&self) -> Result<(), MethodError> {
        let n = self.len();
        let bad = [
            ("normals", self.normals.as_ref().map(Vec::len)),
            ("colors", self.colors.as_ref().map(Vec::len)),
            ("radii", self.radii.as_ref().map(Vec::len)),
            ("lod", self.lod.as_ref().map(Vec::len)),
        ]
        .into_iter()
        .find(|(_, l)| l.is_some_and(|l| l != n));
        match bad {
            Some((name, l)) => Err(MethodError::Limit(format!(
                "splat batch column {name} has {} values for {n} positions",
                l.unwrap_or(0)
            ))),
            None => Ok(()),
        }
    }
}

/// Packs an sRGB colour for [`SplatBatch::colors`].
#[inline]
pub fn pack_color(c: [u8; 3]) -> u32 {
    c[0] as u32 | (c[1] as u32) << 8 | (c[2] as u32) << 16 | 0xff00_0000
}

/// One thing to draw.
#[derive(Debug, Clone, PartialEq)]
pub enum DrawItem {
    /// Splats `first .. first + points` of cached chunk `id`.
    Chunk {
        /// The chunk.
        id: ChunkId,
        /// The first splat drawn (0 for a prefix; Potree draws a node in ranges, each sized
        /// by the deepest node drawn over it).
        first: u32,
        /// How many splats of it to draw (with `first = 0`, the chunk's length draws it all).
        points: u32,
        /// Splat size.
        size: SplatSize,
    },
    /// The first `prefix` splats of cached chunk `id`, each kept or culled by a per-splat
    /// test in the vertex stage (Sequential Point Trees' interval test, CLOD's filter).
    Sequential {
        /// The chunk (uploaded once, kept in the GPU cache).
        id: ChunkId,
        /// How many splats of it are sent.
        prefix: u32,
        /// The per-splat test.
        test: SplatTest,
        /// Splat size of the splats that pass.
        size: SplatSize,
    },
    /// Splats generated this frame, uploaded every frame.
    Stream {
        /// The splats.
        batch: SplatBatch,
        /// Splat size.
        size: SplatSize,
    },
}

/// What an item drawn from a cached chunk sends ([`DrawItem::cached`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cached {
    /// The chunk.
    pub id: ChunkId,
    /// First splat sent.
    pub first: u32,
    /// Splats sent from `first` on.
    pub count: u32,
    /// The vertex-stage test, if any.
    pub test: Option<SplatTest>,
}

/// SPT's per-splat interval test, evaluated in the vertex stage and mirrored on the CPU by
/// [`IntervalTest::passes`]. What `SplatBatch::lod` holds and how `mode`, `scale` and
/// `overlap` combine is defined in `methods::spt::select` (there `scale = ε/k`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct IntervalTest {
    /// Error mode: 0 = unified geometric error, 1 = split (perpendicular + tangential).
    pub mode: u32,
    /// `ε / k`: pixel tolerance over the projection scale.
    pub scale: f32,
    /// Overlap factor on the distance to the parent (1 = provably no holes, 0 = bare intervals).
    pub overlap: f32,
}

impl IntervalTest {
    /// The CPU mirror of the vertex-stage test (`harness/src/render/interval.wgsl` is a
    /// line-for-line port; the renderer's tests compare GPU pass counts with this). Defined
    /// by [`crate::spt::select::interval_pass`], where `lod`, `scale` and `overlap` are
    /// documented.
    #[inline]
    pub fn passes(&self, p: glam::Vec3, n: glam::Vec3, lod: [f32; 4], eye: glam::Vec3) -> bool {
        crate::spt::select::interval_pass(p, n, lod, eye, self)
    }
}

/// CLOD's per-point filter ([`crate::clod::select`]): a point is kept when its spacing
/// (`lod[0]`) is at least the target spacing at its distance.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ClodTest {
    /// `ε / k`: the target spacing per unit of distance at the screen's centre.
    pub scale: f32,
    /// Foveation: the target spacing is divided by `max(1 − fovea·|ndc|, 0.3)`.
    pub fovea: f32,
    /// The view's `view_proj` (column-major), the one the renderer draws with: `|ndc|` and
    /// the extended frustum come from it.
    pub view_proj: [[f32; 4]; 4],
}

impl ClodTest {
    /// The CPU mirror of the GPU's filter ([`crate::clod::select::keeps`]).
    #[inline]
    pub fn passes(&self, p: glam::Vec3, lod: [f32; 4], eye: glam::Vec3) -> bool {
        let vp = glam::Mat4::from_cols_array_2d(&self.view_proj);
        crate::clod::select::keeps(p, lod[0], &vp, eye, self.scale, self.fovea)
    }
}

/// A per-splat test of [`DrawItem::Sequential`] items, evaluated on the GPU (vertex stage,
/// compute rasteriser, counting pass) and mirrored on the CPU by [`SplatTest::passes`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum SplatTest {
    /// Sequential Point Trees' interval test.
    Interval(IntervalTest),
    /// CLOD's filter.
    Clod(ClodTest),
}

impl SplatTest {
    /// The CPU mirror: true if the splat at `p` with normal `n` and LOD data `lod` passes
    /// for an eye at `eye`.
    #[inline]
    pub fn passes(&self, p: glam::Vec3, n: glam::Vec3, lod: [f32; 4], eye: glam::Vec3) -> bool {
        match self {
            SplatTest::Interval(t) => t.passes(p, n, lod, eye),
            SplatTest::Clod(t) => t.passes(p, lod, eye),
        }
    }
}

impl From<IntervalTest> for SplatTest {
    fn from(t: IntervalTest) -> Self {
        SplatTest::Interval(t)
    }
}

impl DrawItem {
    /// For items drawn from a cached chunk (`Chunk` and `Sequential`): the chunk, the first
    /// splat sent, how many are sent, and the interval test if any. `None` for streams.
    pub fn cached(&self) -> Option<Cached> {
        match self {
            DrawItem::Chunk {
                id, first, points, ..
            } => Some(Cached {
                id: *id,
                first: *first,
                count: *points,
                test: None,
            }),
            DrawItem::Sequential {
                id, prefix, test, ..
            } => Some(Cached {
                id: *id,
                first: 0,
                count: *prefix,
                test: Some(*test),
            }),
            DrawItem::Stream { .. } => None,
        }
    }
    /// The item's splat size.
    pub fn size(&self) -> SplatSize {
        match self {
            DrawItem::Chunk { size, .. }
            | DrawItem::Sequential { size, .. }
            | DrawItem::Stream { size, .. } => *size,
        }
    }
    /// Splats this item draws (for [`DrawItem::Sequential`], the prefix sent: an upper bound
    /// of what passes the interval test).
    pub fn points(&self) -> u64 {
        match self {
            DrawItem::Chunk { points, .. } => *points as u64,
            DrawItem::Sequential { prefix, .. } => *prefix as u64,
            DrawItem::Stream { batch, .. } => batch.len() as u64,
        }
    }
}

/// Splat shape (the renderer's kernel). QSplat's paper offers all four.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum SplatShape {
    /// Screen-aligned square (fastest).
    #[default]
    Square,
    /// Opaque disk.
    Circle,
    /// Elliptical disk from the splat normal: minor/major = |n̂·v̂|, major/minor ≤ 10.
    Ellipse,
    /// Gaussian blob, two passes: depth offset by z₀, then additive weighted colour, normalised.
    Gaussian,
}

impl SplatShape {
    /// All shapes.
    pub const ALL: &'static [SplatShape] = &[
        SplatShape::Square,
        SplatShape::Circle,
        SplatShape::Ellipse,
        SplatShape::Gaussian,
    ];
    /// Name (`--kernel`, `--param kernel=`).
    pub fn name(self) -> &'static str {
        match self {
            SplatShape::Square => "square",
            SplatShape::Circle => "circle",
            SplatShape::Ellipse => "ellipse",
            SplatShape::Gaussian => "gaussian",
        }
    }

    /// One line describing the shape (`--help`, `splatbench list`).
    pub fn describe(self) -> &'static str {
        match self {
            SplatShape::Square => "screen-aligned square (fastest)",
            SplatShape::Circle => "opaque disk",
            SplatShape::Ellipse => {
                "elliptical disk from the splat normal: minor/major = |n̂·v̂|, major/minor ≤ 10"
            }
            SplatShape::Gaussian => {
                "Gaussian blob, two passes: depth offset by z₀, then additive weighted colour, normalised"
            }
        }
    }
}

impl std::str::FromStr for SplatShape {
    type Err = crate::error::UnknownName;

    /// The shape of a name (exact, lower case).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        crate::error::UnknownName::lookup("kernel", Self::ALL, Self::name, s)
    }
}

/// Everything a method asks for in one frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DrawList {
    /// Shape the method asks for (e.g. QSplat's `--param kernel=`); `None` = the run's
    /// `--kernel`.
    pub shape: Option<SplatShape>,
    /// What to draw.
    pub items: Vec<DrawItem>,
    /// Chunks the method wanted this frame but could not use yet (out-of-core methods: data
    /// still loading). The method issues its own requests; the renderer ignores this list.
    pub fetch: Vec<ChunkId>,
    /// Values of the method's extra CSV columns ([`crate::LodMethod::extra_columns`]), same order.
    pub counters: Vec<f64>,
    /// Three-phase occlusion culling (LPC §4), when the method asks for it: `items` are then
    /// phase 1 (the clouds visible last frame); the renderer queries every candidate's
    /// bounding sphere against the depth phase 1 left and draws, in phase 3, the candidates
    /// that turn out visible and were not drawn in phase 1.
    pub occlusion: Option<OcclusionPass>,
}

/// Phases 2 and 3 of occlusion culling: what to query and what to draw if visible.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OcclusionPass {
    /// Every potentially visible cloud of this frame (those drawn in phase 1 included).
    pub candidates: Vec<OcclusionCandidate>,
    /// A candidate is visible when more than this many fragments of its sphere pass the
    /// depth test (0 = any fragment).
    pub threshold: u64,
}

/// One potentially visible cloud.
#[derive(Debug, Clone, PartialEq)]
pub struct OcclusionCandidate {
    /// Identifies the cloud in [`Feedback::visible`] / [`Feedback::occluded`].
    pub id: ChunkId,
    /// Bounding sphere centre (local coordinates); the query draws an icosahedron that
    /// circumscribes it. A sphere that contains the eye (or reaches the near plane) is
    /// visible without a query.
    pub center: [f32; 3],
    /// Bounding sphere radius.
    pub radius: f32,
    /// What to draw in phase 3 if visible; `None` if already drawn in phase 1.
    pub item: Option<DrawItem>,
}

impl DrawList {
    /// Total splats drawn.
    pub fn points(&self) -> u64 {
        self.items.iter().map(DrawItem::points).sum()
    }
    /// Number of cached chunks drawn.
    pub fn chunks(&self) -> u64 {
        self.items
            .iter()
            .filter(|i| matches!(i, DrawItem::Chunk { .. }))
            .count() as u64
    }
}

/// What the frame asks of the method: a pixel tolerance or a point budget.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum Target {
    /// Largest acceptable screen-space error / splat size in pixels (≥ 0, finite).
    Tolerance(f32),
    /// Largest number of splats to draw (≥ 1).
    Budget(u64),
}

impl Target {
    /// A validated tolerance: NaN, ±∞ and negative values are errors.
    pub fn tolerance(px: f32) -> Result<Self, MethodError> {
        if !px.is_finite() || px < 0.0 {
            return Err(MethodError::Target(format!(
                "a tolerance must be a finite number of pixels ≥ 0, got {px}"
            )));
        }
        Ok(Target::Tolerance(px))
    }
    /// A validated budget: 0 is an error.
    pub fn budget(points: u64) -> Result<Self, MethodError> {
        if points == 0 {
            return Err(MethodError::Target(
                "a budget must be at least 1 point".into(),
            ));
        }
        Ok(Target::Budget(points))
    }
    /// Re-validates (for targets built directly from the enum).
    pub fn validate(self) -> Result<Self, MethodError> {
        match self {
            Target::Tolerance(px) => Self::tolerance(px),
            Target::Budget(b) => Self::budget(b),
        }
    }
    /// The tolerance in pixels, if this is a tolerance target.
    pub fn eps_px(self) -> Option<f32> {
        match self {
            Target::Tolerance(e) => Some(e),
            Target::Budget(_) => None,
        }
    }
    /// The budget, if this is a budget target.
    pub fn budget_points(self) -> Option<u64> {
        match self {
            Target::Budget(b) => Some(b),
            Target::Tolerance(_) => None,
        }
    }
}

/// What the renderer tells the method about the previous frame.
#[derive(Debug, Clone, Default)]
pub struct Feedback {
    /// Index of the frame about to be drawn.
    pub frame: u64,
    /// Chunks resident in the GPU cache now.
    pub cached: HashSet<ChunkId>,
    /// Candidates found occluded last frame (when occlusion queries ran).
    pub occluded: HashSet<ChunkId>,
    /// Candidates found visible last frame (when occlusion queries ran): the occluders of
    /// this frame's phase 1.
    pub visible: HashSet<ChunkId>,
    /// GPU time of the previous frame, ms.
    pub last_gpu_ms: Option<f64>,
    /// Wall time of the previous frame, ms.
    pub last_wall_ms: Option<f64>,
    /// True when the camera did not move since the previous frame.
    pub camera_still: bool,
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn targets_reject_bad_values() {
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -1.0] {
            assert!(Target::tolerance(bad).is_err(), "{bad}");
        }
        assert!(Target::tolerance(0.0).is_ok());
        assert!(Target::budget(0).is_err());
        assert_eq!(Target::budget(5).unwrap().budget_points(), Some(5));
    }
    #[test]
    fn batch_validation_and_sizes() {
        let mut b = SplatBatch::with_attributes(
            Attributes {
                normals: true,
                colors: false,
                radii: true,
            },
            2,
        );
        b.positions.push([0.0; 3]);
        b.normals.as_mut().unwrap().push(0);
        b.radii.as_mut().unwrap().push(1.0);
        assert!(b.validate().is_ok());
        assert_eq!(b.byte_size(), 12 + 4 + 4);
        b.positions.push([0.0; 3]);
        assert!(b.validate().unwrap_err().to_string().contains("normals"));
    }
}
