//! The nodes of a QSplat build, below every file that makes or reads them: the stored node
//! ([`QNode`]), a node's true properties and its encoded sphere ([`TrueNode`], [`Encoded`]),
//! and the binary partition tree ([`Binary`], made in `build.rs`, read by `forest.rs`).

use glam::Vec3;

/// One quantised node, exactly the fields stored in the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct QNode {
    /// 13-bit child-sphere code (0 for the root, whose sphere is in the header).
    pub sphere: u16,
    /// 14-bit normal code (0 when the scene has no normals).
    pub normal: u16,
    /// 2-bit normal-cone class.
    pub cone: u8,
    /// Number of children: 0, 2, 3 or 4.
    pub children: u8,
    /// True if the node has children and none of them has children.
    pub all_leaves: bool,
    /// RGB565 colour (0 when the scene has no colours).
    pub color: u16,
}

/// True (unquantised) properties of a node.
#[derive(Debug, Clone, Copy)]
pub(super) struct TrueNode {
    pub(super) c: Vec3,
    pub(super) r: f32,
    /// Mean normal, unit (zero when the scene has none or the children cancel).
    pub(super) n: Vec3,
    /// Half-angle around `n` covering all normals below, radians (π = any).
    pub(super) cone: f64,
    pub(super) color: [f32; 3],
    pub(super) weight: u32,
}

/// A sphere code, the sphere it decodes to, and the absolute margin it was encoded with.
pub(super) type Encoded = (u16, (Vec3, f32), f64);

/// The binary partition tree, indexed by split position: the binary node covering
/// `[lo, hi)` splits at `m` (`lo < m < hi`) into `[lo, m)` and `[m, hi)`; every position
/// `1..n` is the split of exactly one binary node, so per-node data lives at index `m`.
pub(super) struct Binary {
    /// Split of the left child of the node splitting at `m` (0: the left child is a leaf).
    pub(super) left: Vec<u32>,
    /// Split of the right child (0: a leaf).
    pub(super) right: Vec<u32>,
    /// The node's children in the combined tree are its binary grandchildren.
    pub(super) grand: Vec<bool>,
    /// Split of the root (0 when `n = 1`).
    pub(super) root: u32,
}
