//! Uploading splat batches: a chunk missing from the cache is decoded by the method and
//! uploaded once; a stream is uploaded every frame. A batch whose widest column is over the
//! adapter's storage binding limit (`max_storage_buffer_binding_size`: 128 MiB on lavapipe,
//! so ≥ 8 M splats with SPT's LOD column) is uploaded in parts of [`splats_per_part`] splats,
//! each drawn as its own draw with the batch's settings (and, under an interval test, the
//! part's share of the splats sent); before, such a batch was an error. Also the per-draw
//! uniform buffer's growth (one slot per part).

use super::*;

/// GPU buffers of one batch and their bind groups: one part, or several when a column is
/// larger than the adapter's storage binding limit.
pub(super) struct GpuBatch {
    pub(super) parts: Vec<BatchPart>,
    pub(super) len: u32,
    pub(super) attrs: Attributes,
    pub(super) lod: bool,
    pub(super) _buffers: Vec<wgpu::Buffer>,
}

/// Splats `start .. start + len` of a batch, bound as their own columns.
pub(super) struct BatchPart {
    pub(super) bind_group: wgpu::BindGroup,
    pub(super) start: u32,
    pub(super) len: u32,
}

/// Bytes per splat of the widest column (`lod`: four `f32`).
const WIDEST_COLUMN_BYTES: u64 = 16;

/// Splats per part for a storage binding limit of `max_binding` bytes: every column of a
/// part fits one binding.
pub fn splats_per_part(max_binding: u64) -> u64 {
    (max_binding / WIDEST_COLUMN_BYTES).max(1)
}

impl Renderer<'_> {
    /// Uploads one batch's columns into storage buffers and binds them: in parts of
    /// [`splats_per_part`] splats when its widest column is over the storage binding limit
    /// (each part its own buffers, drawn as its own draw with the same settings).
    pub(super) fn upload(&self, batch: &SplatBatch) -> anyhow::Result<GpuBatch> {
        batch.validate()?;
        let len = u32::try_from(batch.len())
            .map_err(|_| anyhow::anyhow!("a batch of {} splats is over 2³² − 1", batch.len()))?;
        let max = self.gpu.limits.max_storage_buffer_binding_size;
        let widest = if batch.lod.is_some() {
            WIDEST_COLUMN_BYTES
        } else {
            12
        };
        let per = if u64::from(len) * widest > max {
            splats_per_part(max) as usize
        } else {
            batch.len().max(1)
        };
        let mut buffers = Vec::new();
        let mut parts = Vec::new();
        let mut start = 0usize;
        loop {
            let r = start..(start + per).min(batch.len());
            parts.push(self.upload_part(batch, r.clone(), &mut buffers));
            start = r.end;
            if start >= batch.len() {
                break;
            }
        }
        Ok(GpuBatch {
            parts,
            len,
            attrs: batch.attributes(),
            lod: batch.lod.is_some(),
            _buffers: buffers,
        })
    }

    /// Uploads splats `r` of `batch` into new buffers (appended to `buffers`) and binds them.
    fn upload_part(
        &self,
        batch: &SplatBatch,
        r: Range<usize>,
        buffers: &mut Vec<wgpu::Buffer>,
    ) -> BatchPart {
        let d = &self.gpu.device;
        let mut make = |label: &str, bytes: &[u8]| -> usize {
            // Empty batches still need a non-empty buffer to bind.
            let contents: &[u8] = if bytes.is_empty() { &[0u8; 16] } else { bytes };
            buffers.push(d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE,
            }));
            buffers.len() - 1
        };
        let pos = make(
            "positions",
            bytemuck::cast_slice(&batch.positions[r.clone()]),
        );
        let nrm = batch
            .normals
            .as_ref()
            .map(|v| make("normals", bytemuck::cast_slice(&v[r.clone()])));
        let col = batch
            .colors
            .as_ref()
            .map(|v| make("colors", bytemuck::cast_slice(&v[r.clone()])));
        let rad = batch
            .radii
            .as_ref()
            .map(|v| make("radii", bytemuck::cast_slice(&v[r.clone()])));
        let lod = batch
            .lod
            .as_ref()
            .map(|v| make("lod", bytemuck::cast_slice(&v[r.clone()])));
        let buf = |i: Option<usize>| i.map(|i| &buffers[i]).unwrap_or(&self.dummy);
        let entries: Vec<_> = [Some(pos), nrm, col, rad, lod]
            .into_iter()
            .enumerate()
            .map(|(b, i)| wgpu::BindGroupEntry {
                binding: b as u32,
                resource: buf(i).as_entire_binding(),
            })
            .collect();
        let bind_group = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("splat columns"),
            layout: &self.bgl1,
            entries: &entries,
        });
        BatchPart {
            bind_group,
            start: r.start as u32,
            len: r.len() as u32,
        }
    }

    /// Draws (uniform slots) one phase of `items` needs: one per part of each item's batch.
    /// The items' chunks must be cached and `streams` uploaded ([`Self::upload_items`]).
    fn draw_slots(&self, items: &[&DrawItem], streams: &[GpuBatch]) -> anyhow::Result<u64> {
        let mut n = streams.iter().map(|g| g.parts.len() as u64).sum::<u64>();
        for item in items {
            if let Some(methods::Cached { id, .. }) = item.cached() {
                let g = self
                    .cache
                    .peek(&id)
                    .with_context(|| format!("chunk {id} vanished from the cache"))?;
                n += g.parts.len() as u64;
            }
        }
        Ok(n)
    }

    /// Grows the per-draw uniform buffer to hold the draws of `items` and `streams`.
    pub(super) fn ensure_draw_capacity(
        &mut self,
        items: &[&DrawItem],
        streams: &[GpuBatch],
    ) -> anyhow::Result<()> {
        let n = self.draw_slots(items, streams)?;
        if n > self.draw_capacity {
            self.draw_capacity = n.next_power_of_two();
            self.draw_ubo =
                Self::draw_buffer(&self.gpu.device, self.draw_stride * self.draw_capacity);
        }
        Ok(())
    }

    /// Uploads the chunks of `items` missing from the cache (marking the others used) and
    /// the streams, which get their own buffers this frame (returned, in item order).
    pub(super) fn upload_items(
        &mut self,
        items: &[&DrawItem],
        method: &dyn LodMethod,
        stats: &mut FrameStats,
    ) -> anyhow::Result<Vec<GpuBatch>> {
        let mut streams = Vec::new();
        for item in items {
            match item {
                DrawItem::Chunk { id, .. } | DrawItem::Sequential { id, .. } => {
                    if self.cache.get(id).is_none() {
                        let batch = method
                            .chunk(*id)
                            .with_context(|| format!("decoding chunk {id}"))?;
                        let bytes = batch.byte_size();
                        let g = self.upload(&batch)?;
                        stats.upload_bytes += bytes;
                        self.cache.insert(*id, g, bytes);
                    }
                }
                DrawItem::Stream { batch, .. } => {
                    stats.upload_bytes += batch.byte_size();
                    streams.push(self.upload(batch)?);
                }
            }
        }
        Ok(streams)
    }
}
