//! The octree as far as it is known: the nodes of the hierarchy chunks read so far, proxies
//! expanded on demand (as the Potree viewer loads a proxy's chunk before its points).
//!
//! Nodes are numbered in the order they become known (root 0); a node's number is its chunk
//! id for the loader and never changes. Every record is checked when its chunk is read:
//! type, child mask against the records that follow, byte range inside `octree.bin`, byte
//! size against the point count; errors name the file, the chunk and the node.

use std::path::{Path, PathBuf};
use std::sync::{Arc, RwLock};

use glam::{DVec3, Vec3};

use super::format::{self, MAX_LEVEL, Metadata, NodeKind, RECORD_BYTES, Record};
use crate::MethodError;

/// No node (a missing child or the root's parent).
pub const NONE: u32 = u32::MAX;

/// A node of the octree.
#[derive(Debug, Clone, PartialEq)]
pub struct Node {
    /// Depth (root 0).
    pub level: u32,
    /// Octant digits from the root, 3 bits per level, first digit highest.
    pub path: u64,
    /// Inner, leaf, or proxy (its chunk not read yet).
    pub kind: NodeKind,
    /// Bit `i`: child `i` exists.
    pub child_mask: u8,
    /// Points stored in the node.
    pub points: u32,
    /// Child node numbers ([`NONE`] where absent or not known yet).
    pub children: [u32; 8],
    /// Parent's number ([`NONE`] for the root).
    pub parent: u32,
    /// Box, world coordinates (children's boxes are split from it in `f64`).
    pub min: DVec3,
    /// Box, world coordinates.
    pub max: DVec3,
    /// Box, local coordinates (world minus the origin).
    pub lo: Vec3,
    /// Box, local coordinates.
    pub hi: Vec3,
}

impl Node {
    /// The converter's name of the node (`r`, `r0`, `r07`, …).
    pub fn name(&self) -> String {
        format::node_name(self.level, self.path)
    }
    /// Centre and radius of the box's bounding sphere.
    pub fn sphere(&self) -> (Vec3, f32) {
        (
            (self.lo + self.hi) * 0.5,
            (self.hi - self.lo).length() * 0.5,
        )
    }
}

/// Where a node's points are in `octree.bin`: what the loader reads and decodes.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Span {
    /// Byte offset.
    pub offset: u64,
    /// Byte size (`points × bytes_per_point`).
    pub size: u64,
    /// Points.
    pub points: u32,
    /// Level (the splat size follows from it).
    pub level: u32,
    /// Octant digits ([`Node::path`]), for messages.
    pub path: u64,
    /// The node's local box (its points are ordered by octant digits in it).
    pub lo: [f32; 3],
    /// The node's local box.
    pub hi: [f32; 3],
    /// True for a leaf (no children).
    pub leaf: bool,
}

impl Span {
    /// The node's name (`r07`).
    pub fn name(&self) -> String {
        format::node_name(self.level, self.path)
    }
}

/// Node spans shared with the loader's source and decoder; a proxy's span is empty until
/// its chunk is read.
pub type Spans = Arc<RwLock<Vec<Span>>>;

/// Reads byte ranges of a file (local now; the trait leaves room for HTTP range requests).
pub trait RangeRead: Send + Sync {
    /// `len` bytes at `offset`, or an error naming the file and `what` is read (a node).
    fn read(&self, offset: u64, len: u64, what: &str) -> Result<Vec<u8>, MethodError>;
    /// File size in bytes.
    fn len(&self) -> u64;
    /// True for an empty file.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// The file, for messages.
    fn path(&self) -> &Path;
}

/// A local file read with positioned reads (no mapping: Potree data sets run to terabytes
/// and are read a node at a time).
pub struct LocalFile {
    file: std::fs::File,
    len: u64,
    path: PathBuf,
}

impl LocalFile {
    /// Opens `path`.
    pub fn open(path: &Path) -> Result<Self, MethodError> {
        let file = std::fs::File::open(path).map_err(|e| MethodError::io(path, e))?;
        let len = file.metadata().map_err(|e| MethodError::io(path, e))?.len();
        Ok(Self {
            file,
            len,
            path: path.to_owned(),
        })
    }
}

impl RangeRead for LocalFile {
    fn read(&self, offset: u64, len: u64, what: &str) -> Result<Vec<u8>, MethodError> {
        let end = offset.checked_add(len).filter(|&e| e <= self.len);
        if end.is_none() {
            return Err(MethodError::corrupt(
                &self.path,
                format!(
                    "{what}: bytes {offset}..{offset}+{len} lie beyond the end of the file ({} \
                     bytes)",
                    self.len
                ),
            ));
        }
        let mut buf = vec![0u8; len as usize];
        scenes::os::read_exact_at(&self.file, &mut buf, offset).map_err(|e| {
            MethodError::io(
                &self.path,
                std::io::Error::new(e.kind(), format!("{what}: {e}")),
            )
        })?;
        Ok(buf)
    }
    fn len(&self) -> u64 {
        self.len
    }
    fn path(&self) -> &Path {
        &self.path
    }
}

/// The known octree.
pub struct Hierarchy {
    nodes: Vec<Node>,
    spans: Spans,
    /// Per unread proxy (by node number): its chunk in `hierarchy.bin`.
    proxy_chunks: std::collections::HashMap<u32, (u64, u64)>,
    file: Box<dyn RangeRead>,
    octree_len: u64,
    bytes_per_point: u64,
    origin: DVec3,
    chunks_read: u64,
}

impl Hierarchy {
    /// The root chunk of `file` (`hierarchy.bin`) read and checked against `meta`, for an
    /// `octree.bin` of `octree_len` bytes; local boxes relative to `origin`.
    pub fn open(
        meta: &Metadata,
        file: Box<dyn RangeRead>,
        octree_len: u64,
        bytes_per_point: u64,
        origin: DVec3,
    ) -> Result<Self, MethodError> {
        let (min, max) = meta.root_box();
        let mut h = Self {
            nodes: Vec::new(),
            spans: Arc::new(RwLock::new(Vec::new())),
            proxy_chunks: Default::default(),
            file,
            octree_len,
            bytes_per_point,
            origin,
            chunks_read: 0,
        };
        h.push(0, 0, NONE, min, max);
        h.proxy_chunks
            .insert(0, (0, meta.hierarchy.first_chunk_size));
        h.expand(0)?;
        Ok(h)
    }

    fn push(&mut self, level: u32, path: u64, parent: u32, min: DVec3, max: DVec3) -> u32 {
        let id = self.nodes.len() as u32;
        self.nodes.push(Node {
            level,
            path,
            kind: NodeKind::Proxy,
            child_mask: 0,
            points: 0,
            children: [NONE; 8],
            parent,
            min,
            max,
            lo: (min - self.origin).as_vec3(),
            hi: (max - self.origin).as_vec3(),
        });
        let (lo, hi) = (self.nodes[id as usize].lo, self.nodes[id as usize].hi);
        self.spans_mut().push(Span {
            level,
            path,
            lo: lo.to_array(),
            hi: hi.to_array(),
            ..Span::default()
        });
        id
    }

    fn spans_mut(&self) -> std::sync::RwLockWriteGuard<'_, Vec<Span>> {
        self.spans.write().unwrap_or_else(|e| e.into_inner())
    }

    /// The nodes known so far.
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }
    /// The spans shared with the loader.
    pub fn spans(&self) -> Spans {
        Arc::clone(&self.spans)
    }
    /// Hierarchy chunks read so far.
    pub fn chunks_read(&self) -> u64 {
        self.chunks_read
    }
    /// True if node `id` is a proxy whose chunk is not read yet.
    pub fn is_proxy(&self, id: u32) -> bool {
        self.proxy_chunks.contains_key(&id)
    }

    /// Reads the chunk of proxy `id` and adds the nodes it lists; a node that is no proxy is
    /// left alone. Errors name `hierarchy.bin`, the chunk and the node.
    pub fn expand(&mut self, id: u32) -> Result<(), MethodError> {
        let Some(&(offset, size)) = self.proxy_chunks.get(&id) else {
            return Ok(());
        };
        let name = self.nodes[id as usize].name();
        let path = self.file.path().to_owned();
        let bad = |msg: String| {
            MethodError::corrupt(
                &path,
                format!("hierarchy chunk of node {name} (bytes {offset}..+{size}): {msg}"),
            )
        };
        if size == 0 || !size.is_multiple_of(RECORD_BYTES as u64) {
            return Err(bad(format!(
                "{size} bytes is not a positive multiple of the {RECORD_BYTES}-byte record"
            )));
        }
        let bytes = self
            .file
            .read(offset, size, &format!("hierarchy chunk of node {name}"))?;
        self.chunks_read += 1;
        // Breadth first: record i describes queue[i]; a non-proxy record appends its
        // children in octant order.
        let mut queue = vec![id];
        for (i, raw) in bytes.chunks_exact(RECORD_BYTES).enumerate() {
            let Some(&node) = queue.get(i) else {
                return Err(bad(format!(
                    "{} records, but the child masks name only {} nodes",
                    bytes.len() / RECORD_BYTES,
                    queue.len()
                )));
            };
            let raw: &[u8; RECORD_BYTES] =
                raw.try_into().map_err(|_| bad("short record".into()))?;
            let node_name = self.nodes[node as usize].name();
            let rec = Record::parse(raw).map_err(|m| bad(format!("node {node_name}: {m}")))?;
            if i == 0 && rec.kind == NodeKind::Proxy {
                return Err(bad(format!(
                    "its first record (node {node_name} itself) is a proxy again"
                )));
            }
            let level = self.nodes[node as usize].level;
            self.check(&rec, level, &node_name).map_err(bad)?;
            let n = &mut self.nodes[node as usize];
            n.kind = rec.kind;
            n.child_mask = rec.child_mask;
            // A node with no bytes holds no points, whatever its count says (the Potree
            // viewer's rule, potree#1125).
            n.points = if rec.size == 0 { 0 } else { rec.points };
            let (level, path, min, max) = (n.level, n.path, n.min, n.max);
            if rec.kind == NodeKind::Proxy {
                self.proxy_chunks.insert(node, (rec.offset, rec.size));
                continue;
            }
            self.proxy_chunks.remove(&node);
            let mut spans = self.spans_mut();
            let s = &mut spans[node as usize];
            s.offset = rec.offset;
            s.size = rec.size;
            s.points = self.nodes[node as usize].points;
            s.leaf = rec.child_mask == 0;
            drop(spans);
            for c in 0..8u8 {
                if rec.child_mask & (1 << c) == 0 {
                    continue;
                }
                let (cmin, cmax) = format::child_box(min, max, c);
                let child = self.push(level + 1, (path << 3) | u64::from(c), node, cmin, cmax);
                self.nodes[node as usize].children[usize::from(c)] = child;
                queue.push(child);
            }
        }
        let records = bytes.len() / RECORD_BYTES;
        if records < queue.len() {
            return Err(bad(format!(
                "the child masks name {} nodes, but the chunk holds only {records} records",
                queue.len()
            )));
        }
        Ok(())
    }

    /// Checks one record of the node at `level` (the node's own, not its name's length):
    /// child mask against the deepest level, byte range and size. The type is not checked
    /// against the mask: PotreeConverter 2.0 writes nodes of type 1 ("leaf") that have
    /// children, and the viewer creates children from the mask for every
    /// type but proxy; so do we.
    fn check(&self, rec: &Record, level: u32, name: &str) -> Result<(), String> {
        if rec.child_mask != 0 && level >= MAX_LEVEL {
            return Err(format!(
                "node {name} has children below level {MAX_LEVEL}, the deepest splatbench reads"
            ));
        }
        match rec.kind {
            NodeKind::Proxy => {
                let fits = rec
                    .offset
                    .checked_add(rec.size)
                    .is_some_and(|e| e <= self.file.len());
                if !fits || rec.size == 0 || !rec.size.is_multiple_of(RECORD_BYTES as u64) {
                    return Err(format!(
                        "proxy {name} names hierarchy bytes {}..+{}, not whole records inside \
                         the file ({} bytes)",
                        rec.offset,
                        rec.size,
                        self.file.len()
                    ));
                }
                Ok(())
            }
            _ => {
                let fits = rec
                    .offset
                    .checked_add(rec.size)
                    .is_some_and(|e| e <= self.octree_len);
                if !fits {
                    return Err(format!(
                        "node {name}: octree.bin bytes {}..+{} lie beyond its end ({} bytes)",
                        rec.offset, rec.size, self.octree_len
                    ));
                }
                if rec.size != 0 && rec.size != u64::from(rec.points) * self.bytes_per_point {
                    return Err(format!(
                        "node {name}: {} bytes for {} points of {} bytes",
                        rec.size, rec.points, self.bytes_per_point
                    ));
                }
                Ok(())
            }
        }
    }
}
