//! Uploading splat batches: a chunk missing from the cache is decoded by the method and
//! uploaded once; a stream is uploaded every frame. Also the per-draw uniform buffer's growth.

use super::*;

/// GPU buffers of one batch and their bind group.
pub(super) struct GpuBatch {
    pub(super) bind_group: wgpu::BindGroup,
    pub(super) len: u32,
    pub(super) attrs: Attributes,
    pub(super) lod: bool,
    pub(super) _buffers: Vec<wgpu::Buffer>,
}

impl Renderer<'_> {
    /// Uploads one batch's columns into storage buffers and binds them.
    pub(super) fn upload(&self, batch: &SplatBatch) -> anyhow::Result<GpuBatch> {
        batch.validate()?;
        let d = &self.gpu.device;
        let max = self.gpu.limits.max_storage_buffer_binding_size;
        let pos_bytes = batch.len() as u64 * 12;
        if pos_bytes > max {
            bail!(
                "a batch of {} splats needs {pos_bytes} bytes of positions, over the adapter's \
                 storage binding limit of {max} bytes: the method must split it",
                batch.len()
            );
        }
        let mut buffers = Vec::with_capacity(4);
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
        let pos = make("positions", bytemuck::cast_slice(&batch.positions));
        let nrm = batch
            .normals
            .as_ref()
            .map(|v| make("normals", bytemuck::cast_slice(v)));
        let col = batch
            .colors
            .as_ref()
            .map(|v| make("colors", bytemuck::cast_slice(v)));
        let rad = batch
            .radii
            .as_ref()
            .map(|v| make("radii", bytemuck::cast_slice(v)));
        let lod = batch
            .lod
            .as_ref()
            .map(|v| make("lod", bytemuck::cast_slice(v)));
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
        Ok(GpuBatch {
            bind_group,
            len: batch.len() as u32,
            attrs: batch.attributes(),
            lod: batch.lod.is_some(),
            _buffers: buffers,
        })
    }

    pub(super) fn ensure_draw_capacity(&mut self, n: u64) {
        if n > self.draw_capacity {
            self.draw_capacity = n.next_power_of_two();
            self.draw_ubo =
                Self::draw_buffer(&self.gpu.device, self.draw_stride * self.draw_capacity);
        }
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
