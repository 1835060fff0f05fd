//! The per-splat tests on the GPU (SPT's interval test, METHODS.md; CLOD's filter): before a
//! phase's render pass, a compute pass (`interval.wgsl` and `clod.wgsl`, the same
//! `splat_passes` test as the vertex stage) counts, per tested draw, the splats that pass; the counts are copied to a readback buffer and
//! become `FrameStats::gpu_passed`. Outside the render-pass timestamps.

use super::*;

impl Renderer<'_> {
    /// Records the counting pass for the `tested` draws ((draw index, splats sent); counter
    /// slot = position in `tested`) of a phase whose draws are `resolved` and whose frame+draw
    /// bind group is `bg0`. Returns the counters' readback buffer and its size, or `None` when
    /// no draw is tested.
    pub(super) fn encode_interval_counts(
        &self,
        enc: &mut wgpu::CommandEncoder,
        bg0: &wgpu::BindGroup,
        tested: &[(usize, u32)],
        resolved: &[(&wgpu::BindGroup, u32, u32)],
    ) -> anyhow::Result<Option<(wgpu::Buffer, u64)>> {
        if tested.is_empty() {
            return Ok(None);
        }
        let d = &self.gpu.device;
        let bytes = tested.len() as u64 * 4;
        let counters = zeroed_counters(d, "interval counters", bytes);
        let readback = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("interval counters readback"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bg2 = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("counters"),
            layout: &self.bgl2,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: counters.as_entire_binding(),
            }],
        });
        let pipeline = self.count.as_ref().context("counting pipeline missing")?;
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("interval count"),
            timestamp_writes: None,
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(2, &bg2, &[]);
        for &(i, count) in tested {
            pass.set_bind_group(0, bg0, &[(i as u64 * self.draw_stride) as u32]);
            pass.set_bind_group(1, resolved[i].0, &[]);
            let (x, y) = dispatch_size(count, self.gpu.limits.max_compute_workgroups_per_dimension);
            pass.dispatch_workgroups(x, y, 1);
        }
        drop(pass);
        enc.copy_buffer_to_buffer(&counters, 0, &readback, 0, bytes);
        Ok(Some((readback, bytes)))
    }
}
