//! The splat draw path: recording one phase of splat draws (the interval-counting compute
//! pass through `interval.rs`, then the render passes, per kernel) and the depth attachment
//! the passes share.

use super::*;

/// What one phase draws: its items, the stream buffers uploaded for them (in order), and the
/// method they came from (it decodes chunks and knows their levels).
pub(super) struct PhaseItems<'a> {
    pub(super) method: &'a dyn LodMethod,
    pub(super) items: &'a [&'a DrawItem],
    pub(super) streams: &'a [GpuBatch],
}

/// How one phase of splat draws treats the targets.
#[derive(Debug, Clone, Copy)]
pub(super) struct PhaseTarget {
    /// Clear colour and depth (else load them).
    pub(super) clear: bool,
    /// Keep the depth for a later pass (else discard it).
    pub(super) store_depth: bool,
    /// Timestamp indices written at the beginning and end of the phase.
    pub(super) ts: (u32, u32),
}

/// A phase's draws: the draw uniforms (one per `stride` bytes), each draw's (splat columns
/// of the part, first splat sent in the part, splats sent), and the draws whose splats pass
/// an interval test, as (draw index, splats sent); counter slot = position in `tested` (the
/// counts are summed into `gpu_passed`).
struct PhaseDraws<'a> {
    draws: Vec<u8>,
    resolved: Vec<(&'a wgpu::BindGroup, u32, u32)>,
    tested: Vec<(usize, u32)>,
}

/// A draw item's batch, first splat, splats sent, interval test and level tint
/// ([`Renderer::item_batch`]).
type ItemBatch<'a> = (&'a GpuBatch, u32, u32, Option<SplatTest>, [f32; 4]);

impl Renderer<'_> {
    /// Records one phase of splat draws into `enc`: the interval-counting compute pass (if any
    /// draw has a test) and the render pass(es). Adds the splats sent and chunks drawn to
    /// `stats`; returns the interval counters' readback buffer, if any. The items' chunks must
    /// be cached ([`Self::upload_items`]) and the draw buffer large enough.
    pub(super) fn encode_splats(
        &self,
        shape: Kernel,
        phase: PhaseItems<'_>,
        stats: &mut FrameStats,
        enc: &mut wgpu::CommandEncoder,
        target: PhaseTarget,
    ) -> anyhow::Result<Option<(wgpu::Buffer, u64)>> {
        let PhaseDraws {
            draws,
            resolved,
            tested,
        } = self.resolve_draws(phase, stats)?;
        if !draws.is_empty() {
            self.gpu.queue.write_buffer(&self.draw_ubo, 0, &draws);
        }
        let bg0 = self.frame_draw_bind_group();
        // Interval-tested draws: count the splats that pass (interval.rs).
        let counters = self.encode_interval_counts(enc, &bg0, &tested, &resolved)?;
        if self.settings.raster == Raster::Compute {
            self.encode_compute_raster(enc, &bg0, &resolved, target)?;
            return Ok(counters);
        }
        let splats = Splats {
            bg0: &bg0,
            stride: self.draw_stride,
            indices: &self.quad_indices,
            batches: &resolved,
        };
        self.encode_render_passes(shape, &splats, enc, target)?;
        Ok(counters)
    }

    /// One draw per part of each item's batch (a batch over the storage binding limit is
    /// uploaded in parts, upload.rs), with its own uniform: the splats of the part sent.
    /// The draw buffer holds them all ([`Self::ensure_draw_capacity`]). Adds the splats sent
    /// and chunks drawn to `stats`.
    fn resolve_draws<'a>(
        &'a self,
        phase: PhaseItems<'a>,
        stats: &mut FrameStats,
    ) -> anyhow::Result<PhaseDraws<'a>> {
        let PhaseItems {
            method,
            items,
            streams,
        } = phase;
        let stride = self.draw_stride as usize;
        let mut out = PhaseDraws {
            draws: Vec::with_capacity(stride * items.len().max(1)),
            resolved: Vec::with_capacity(items.len()),
            tested: Vec::new(),
        };
        let mut s = streams.iter();
        for (i, item) in items.iter().enumerate() {
            let (g, first, count, test, tint) = self.item_batch(method, i, item, &mut s, stats)?;
            let size = item.size();
            if matches!(size, SplatSize::Radius { .. }) && !g.attrs.radii {
                bail!("draw item {i} asks for per-splat radii but its splats carry none");
            }
            stats.points += count as u64;
            for part in &g.parts {
                // Splats `first .. first + count` of the batch: this part's share of them,
                // in the part's own numbering.
                let lo = first.max(part.start) - part.start;
                let hi = (first + count).min(part.start + part.len).max(part.start) - part.start;
                let sent = hi.saturating_sub(lo);
                let mut u = DrawUniform::new(size, g.attrs, g.lod, test);
                u.tint = tint;
                // Splats sent: the compute passes (interval count, compute raster) start at
                // `first` and stop after `count`; the quads pass draws instances lo..lo+sent.
                u.first = lo;
                u.count = sent;
                let draw = out.resolved.len();
                if test.is_some() {
                    u.slot = out.tested.len() as u32;
                    out.tested.push((draw, sent));
                }
                out.draws.extend_from_slice(bytemuck::bytes_of(&u));
                out.draws.resize((draw + 1) * stride, 0);
                out.resolved.push((&part.bind_group, lo, sent));
            }
        }
        Ok(out)
    }

    /// The batch draw item `i` draws, with its first splat, splats sent, interval test and
    /// level tint: a cached chunk's (counted in `stats.chunks`; its range clamped to the
    /// batch) or the next of the phase's `streams`.
    fn item_batch<'a>(
        &'a self,
        method: &dyn LodMethod,
        i: usize,
        item: &DrawItem,
        streams: &mut std::slice::Iter<'a, GpuBatch>,
        stats: &mut FrameStats,
    ) -> anyhow::Result<ItemBatch<'a>> {
        let mut tint = [0.0; 4];
        let (g, first, count, test) = match item.cached() {
            Some(c) => {
                if self.level_colours
                    && let Some(level) = method.chunk_level(c.id)
                {
                    tint = level_tint(level);
                }
                let g = self
                    .cache
                    .peek(&c.id)
                    .with_context(|| format!("chunk {} vanished from the cache", c.id))?;
                if c.test.is_some() && !g.lod {
                    bail!(
                        "draw item {i} has an interval test but chunk {} carries no lod column",
                        c.id
                    );
                }
                stats.chunks += 1;
                let first = c.first.min(g.len);
                (g, first, c.count.min(g.len - first), c.test)
            }
            None => {
                let g = streams.next().context("stream buffers out of step")?;
                (g, 0, g.len, None)
            }
        };
        Ok((g, first, count, test, tint))
    }

    /// The phase's group 0: the frame uniform and the draw uniforms (one draw's worth, at a
    /// dynamic offset).
    fn frame_draw_bind_group(&self) -> wgpu::BindGroup {
        self.gpu
            .device
            .create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("frame+draw"),
                layout: &self.bgl0,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: self.frame_ubo.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: &self.draw_ubo,
                            offset: 0,
                            size: wgpu::BufferSize::new(std::mem::size_of::<DrawUniform>() as u64),
                        }),
                    },
                ],
            })
    }

    /// Records the phase's render pass(es) for kernel `shape`: the gaussian kernel's depth,
    /// accumulate and normalize passes, or one splat pass.
    fn encode_render_passes(
        &self,
        shape: Kernel,
        splats: &Splats<'_>,
        enc: &mut wgpu::CommandEncoder,
        target: PhaseTarget,
    ) -> anyhow::Result<()> {
        match (shape, &self.gauss) {
            (Kernel::Gaussian, Some(g)) => self.encode_gaussian_passes(g, splats, enc, target)?,
            _ => {
                let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("splats"),
                    color_attachments: &[color_attachment(&self.color_view, target.clear)],
                    depth_stencil_attachment: self
                        .depth_attachment(target.clear, target.store_depth),
                    timestamp_writes: self.pass_timestamps(target, true, true),
                    occlusion_query_set: None,
                    multiview_mask: None,
                });
                splats.record(&mut pass, self.pipeline(PassKind::Opaque(shape))?);
            }
        }
        Ok(())
    }

    /// The gaussian kernel's three passes: circles into depth, weighted colour accumulated
    /// into `g`'s target, and the full-screen normalisation into the colour target.
    fn encode_gaussian_passes(
        &self,
        g: &GaussTargets,
        splats: &Splats<'_>,
        enc: &mut wgpu::CommandEncoder,
        target: PhaseTarget,
    ) -> anyhow::Result<()> {
        let mut p1 = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("gaussian depth"),
            color_attachments: &[],
            depth_stencil_attachment: self.depth_attachment(target.clear, true),
            timestamp_writes: self.pass_timestamps(target, true, false),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        splats.record(&mut p1, self.pipeline(PassKind::GaussDepth)?);
        drop(p1);
        let mut p2 = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("gaussian accumulate"),
            color_attachments: &[color_attachment(&g.accum_view, target.clear)],
            depth_stencil_attachment: self.depth_attachment(false, target.store_depth),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        splats.record(&mut p2, self.pipeline(PassKind::GaussAccum)?);
        drop(p2);
        let mut p3 = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("gaussian normalize"),
            color_attachments: &[color_attachment(&self.color_view, true)],
            depth_stencil_attachment: None,
            timestamp_writes: self.pass_timestamps(target, false, true),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        p3.set_pipeline(&g.normalize);
        p3.set_bind_group(0, &g.normalize_bg, &[]);
        p3.draw(0..3, 0..1);
        Ok(())
    }

    /// The timestamp writes of a pass of the phase: the phase's first index at its beginning
    /// when `begin`, its second at its end when `end`; none without timestamps or either.
    fn pass_timestamps(
        &self,
        target: PhaseTarget,
        begin: bool,
        end: bool,
    ) -> Option<wgpu::RenderPassTimestampWrites<'_>> {
        let (b, e) = target.ts;
        self.timestamps
            .as_ref()
            .filter(|_| begin || end)
            .map(|t| wgpu::RenderPassTimestampWrites {
                query_set: &t.set,
                beginning_of_pass_write_index: begin.then_some(b),
                end_of_pass_write_index: end.then_some(e),
            })
    }

    /// The render pipeline of `kind` (made by [`Self::ensure_pipelines`]).
    fn pipeline(&self, kind: PassKind) -> anyhow::Result<&wgpu::RenderPipeline> {
        self.pipelines
            .get(&kind)
            .with_context(|| format!("pipeline {kind:?} missing"))
    }

    /// The depth attachment of a splat pass: cleared to 1 or loaded, stored or discarded.
    pub(super) fn depth_attachment(
        &self,
        clear: bool,
        store: bool,
    ) -> Option<wgpu::RenderPassDepthStencilAttachment<'_>> {
        Some(wgpu::RenderPassDepthStencilAttachment {
            view: &self.depth_view,
            depth_ops: Some(wgpu::Operations {
                load: if clear {
                    wgpu::LoadOp::Clear(1.0)
                } else {
                    wgpu::LoadOp::Load
                },
                store: if store {
                    wgpu::StoreOp::Store
                } else {
                    wgpu::StoreOp::Discard
                },
            }),
            stencil_ops: None,
        })
    }
}

/// A colour attachment of a splat pass: cleared to transparent (uncovered) or loaded; stored.
pub(super) fn color_attachment(
    view: &wgpu::TextureView,
    clear: bool,
) -> Option<wgpu::RenderPassColorAttachment<'_>> {
    Some(wgpu::RenderPassColorAttachment {
        view,
        depth_slice: None,
        resolve_target: None,
        ops: wgpu::Operations {
            load: if clear {
                wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT)
            } else {
                wgpu::LoadOp::Load
            },
            store: wgpu::StoreOp::Store,
        },
    })
}

/// One frame's splat draws, recorded identically into every pass that needs them.
struct Splats<'a> {
    bg0: &'a wgpu::BindGroup,
    stride: u64,
    indices: &'a wgpu::Buffer,
    batches: &'a [(&'a wgpu::BindGroup, u32, u32)],
}

impl Splats<'_> {
    fn record(&self, pass: &mut wgpu::RenderPass<'_>, pipeline: &wgpu::RenderPipeline) {
        pass.set_pipeline(pipeline);
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint16);
        for (i, (g, first, count)) in self.batches.iter().enumerate() {
            if *count == 0 {
                continue;
            }
            pass.set_bind_group(0, self.bg0, &[(i as u64 * self.stride) as u32]);
            pass.set_bind_group(1, *g, &[]);
            pass.draw_indexed(0..6, 0, *first..*first + *count);
        }
    }
}
