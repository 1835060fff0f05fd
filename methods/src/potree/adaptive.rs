//! Potree's adaptive point size, per point as the viewer computes it: a point is drawn
//! `1.7 · size · spacing / 2^lod` across, `lod` the level of the deepest *drawn* node whose
//! box holds it (the viewer's vertex shader walks a texture of the visible nodes; we do the
//! same walk on the CPU per range of points).
//!
//! At decode, a node's points are sorted by their octant digits below the node ([`sort`],
//! [`KEY_LEVELS`] levels, boxes halved in `f32` from the node's local box), so the points of
//! any descendant's box are one range. Per frame, [`ranges`] splits each drawn node's points
//! into ranges of equal `lod` by binary searches on the same digits.

use glam::Vec3;

use crate::SplatBatch;

/// Levels below a node its points are ordered by (30 bits of key); descendants deeper
/// than that share the deepest range (a node 10 levels finer than the one it is drawn over).
pub const KEY_LEVELS: u32 = 10;

/// The octant of the box `[lo, hi]` that `p` falls in (bit 2 x, bit 1 y, bit 0 z, upper
/// half on the middle plane), and that octant's box.
#[inline]
pub fn octant(lo: Vec3, hi: Vec3, p: Vec3) -> (u8, Vec3, Vec3) {
    let c = (lo + hi) * 0.5;
    let up = p.cmpge(c);
    let o = (u8::from(up.test(0)) << 2) | (u8::from(up.test(1)) << 1) | u8::from(up.test(2));
    (o, Vec3::select(up, c, lo), Vec3::select(up, hi, c))
}

/// The sort key of `p` in the box `[lo, hi]`: its octant digits for [`KEY_LEVELS`] levels,
/// the first highest.
pub fn key(mut lo: Vec3, mut hi: Vec3, p: Vec3) -> u32 {
    let mut k = 0u32;
    for _ in 0..KEY_LEVELS {
        let (o, l, h) = octant(lo, hi, p);
        k = (k << 3) | u32::from(o);
        (lo, hi) = (l, h);
    }
    k
}

/// Reorders `b`'s splats by [`key`] in the node box `[lo, hi]` (ties keep their order).
pub fn sort(b: &mut SplatBatch, lo: Vec3, hi: Vec3) {
    let keys: Vec<u32> = b
        .positions
        .iter()
        .map(|&p| key(lo, hi, Vec3::from(p)))
        .collect();
    let mut order: Vec<u32> = (0..b.len() as u32).collect();
    order.sort_by_key(|&i| keys[i as usize]);
    fn permute<T: Copy>(v: &mut Vec<T>, order: &[u32]) {
        *v = order.iter().map(|&i| v[i as usize]).collect();
    }
    permute(&mut b.positions, &order);
    if let Some(n) = b.normals.as_mut() {
        permute(n, &order);
    }
    if let Some(c) = b.colors.as_mut() {
        permute(c, &order);
    }
    if let Some(r) = b.radii.as_mut() {
        permute(r, &order);
    }
}

/// A range of a node's points and the level of the deepest drawn node holding them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Range {
    /// First point.
    pub first: u32,
    /// Points.
    pub len: u32,
    /// Level the points are sized by.
    pub lod: u32,
}

/// The ranges of equal `lod` of a node's `positions` (sorted by [`sort`] in `[lo, hi]`),
/// the node at `level`, in point order. `drawn(depth, path)` says whether the descendant
/// `depth` levels below, reached by the octant digits `path` (first digit highest), is drawn;
/// it is asked only for children of drawn cells.
pub fn ranges(
    positions: &[[f32; 3]],
    (lo, hi): (Vec3, Vec3),
    level: u32,
    drawn: &dyn Fn(u32, u64) -> bool,
) -> Vec<Range> {
    let mut out: Vec<Range> = Vec::new();
    let cell = Cell {
        lo,
        hi,
        depth: 0,
        path: 0,
    };
    walk(positions, cell, 0..positions.len(), level, drawn, &mut out);
    out
}

/// A cell below a node: its box, depth and octant digits.
#[derive(Clone, Copy)]
struct Cell {
    lo: Vec3,
    hi: Vec3,
    depth: u32,
    path: u64,
}

/// Emits the ranges of the points `span` of a drawn cell.
fn walk(
    positions: &[[f32; 3]],
    c: Cell,
    span: std::ops::Range<usize>,
    level: u32,
    drawn: &dyn Fn(u32, u64) -> bool,
    out: &mut Vec<Range>,
) {
    let lod = level + c.depth;
    let kids: [bool; 8] = std::array::from_fn(|o| {
        c.depth < KEY_LEVELS && drawn(c.depth + 1, (c.path << 3) | o as u64)
    });
    if !kids.contains(&true) {
        push(out, span, lod);
        return;
    }
    let mid = (c.lo + c.hi) * 0.5;
    let mut at = span.start;
    for o in 0..8u8 {
        let slice = &positions[at..span.end];
        let end = at + slice.partition_point(|&p| octant(c.lo, c.hi, Vec3::from(p)).0 <= o);
        if kids[usize::from(o)] {
            let up = glam::BVec3::new(o & 4 != 0, o & 2 != 0, o & 1 != 0);
            let child = Cell {
                lo: Vec3::select(up, mid, c.lo),
                hi: Vec3::select(up, c.hi, mid),
                depth: c.depth + 1,
                path: (c.path << 3) | u64::from(o),
            };
            walk(positions, child, at..end, level, drawn, out);
        } else {
            push(out, at..end, lod);
        }
        at = end;
    }
}

/// Appends `span` at `lod`, merged with the last range if it continues it at the same lod.
fn push(out: &mut Vec<Range>, span: std::ops::Range<usize>, lod: u32) {
    if span.is_empty() {
        return;
    }
    match out.last_mut() {
        Some(r) if r.lod == lod && (r.first + r.len) as usize == span.start => {
            r.len += span.len() as u32;
        }
        _ => out.push(Range {
            first: span.start as u32,
            len: span.len() as u32,
            lod,
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_follow_the_drawn_descendants() {
        // Points on a 4³ lattice in the unit cube: 64 points, one per cell of level 2.
        let mut b = SplatBatch::default();
        for i in 0..64u32 {
            let c = [i % 4, (i / 4) % 4, i / 16].map(|v| (v as f32 + 0.5) / 4.0);
            b.positions.push(c);
        }
        b.radii = Some((0..64).map(|i| i as f32).collect());
        let (lo, hi) = (Vec3::ZERO, Vec3::ONE);
        sort(&mut b, lo, hi);
        // Sorted: the first 8 points lie in octant 0 (x, y, z < 0.5), in its octant order.
        assert!(b.positions[..8].iter().all(|p| p.iter().all(|&v| v < 0.5)));
        let r0 = b.radii.as_ref().unwrap()[0];
        assert_eq!(b.positions[0], [0.125; 3]);
        assert_eq!(r0, 0.0, "columns move together");
        // Nothing below drawn: one range at the node's level.
        let none = ranges(&b.positions, (lo, hi), 3, &|_, _| false);
        assert_eq!(
            none,
            [Range {
                first: 0,
                len: 64,
                lod: 3
            }]
        );
        // Child 0 drawn, and its child 7 (the cell at 0.375³): 7 points at level 4, one at 5,
        // then the other 56 at 3.
        let some = ranges(&b.positions, (lo, hi), 3, &|d, p| {
            (d, p) == (1, 0) || (d, p) == (2, 7)
        });
        assert_eq!(
            some,
            [
                Range {
                    first: 0,
                    len: 7,
                    lod: 4
                },
                Range {
                    first: 7,
                    len: 1,
                    lod: 5
                },
                Range {
                    first: 8,
                    len: 56,
                    lod: 3
                },
            ]
        );
        // Every child drawn: all points at level 4, merged into one range.
        let all = ranges(&b.positions, (lo, hi), 3, &|d, _| d == 1);
        assert_eq!(
            all,
            [Range {
                first: 0,
                len: 64,
                lod: 4
            }]
        );
    }
}
