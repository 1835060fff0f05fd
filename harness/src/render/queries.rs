//! The occlusion-query draw path (LPC §4, phase 2; see the module docs of [`super`]): the
//! query passes over the candidates' icosahedra and their pipeline.

use super::*;

/// Phase 2 recorded, its counts not yet read.
pub(super) struct PendingQueries {
    /// Candidate index of each query, in query order.
    pub(super) queried: Vec<usize>,
    /// Readback of the hardware query results (u64 each) followed, at `counters_at`, by the
    /// fragment counters (u32 each), and its size; `None` when nothing was queried.
    pub(super) readback: Option<(wgpu::Buffer, u64)>,
    pub(super) counters_at: u64,
    pub(super) _keep: Vec<wgpu::Buffer>,
}

/// The occlusion-query pipeline (made on first use).
pub(super) struct QueryPipeline {
    pub(super) pipeline: wgpu::RenderPipeline,
    pub(super) bgl: wgpu::BindGroupLayout,
    pub(super) indices: wgpu::Buffer,
    pub(super) sampler: wgpu::Sampler,
}

/// The buffers of one frame's queries.
struct QueryBuffers {
    /// The queried candidates' icosahedra, 12 vertices each.
    vertices: wgpu::Buffer,
    /// The hardware query results (u64 each), `bytes` long.
    resolve: wgpu::Buffer,
    /// The fragment counters (u32 each), `counter_bytes` long.
    counters: wgpu::Buffer,
    /// The results followed by the counters, mapped for reading.
    readback: wgpu::Buffer,
    bytes: u64,
    counter_bytes: u64,
    /// Queries, one per candidate queried.
    queries: usize,
}

impl QueryBuffers {
    /// The buffers for `n` queries of the icosahedra `verts`.
    fn new(d: &wgpu::Device, verts: &[[f32; 3]], n: usize) -> Self {
        let vertices = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("query icosahedra"),
            contents: bytemuck::cast_slice(verts),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let bytes = n as u64 * wgpu::QUERY_SIZE as u64;
        let resolve = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("occlusion resolve"),
            size: bytes,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let counter_bytes = n as u64 * 4;
        let counters = zeroed_counters(d, "occlusion fragment counters", counter_bytes);
        let readback = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("occlusion readback"),
            size: bytes + counter_bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Self {
            vertices,
            resolve,
            counters,
            readback,
            bytes,
            counter_bytes,
            queries: n,
        }
    }
}

/// The candidates that need a query ([`occlusion::needs_query`]), by index, and their
/// icosahedra's vertices, in query order.
fn query_candidates(view: &View, occ: &OcclusionPass) -> (Vec<usize>, Vec<[f32; 3]>) {
    let mut queried = Vec::new();
    let mut verts: Vec<[f32; 3]> = Vec::new();
    for (i, c) in occ.candidates.iter().enumerate() {
        let v = Icosahedron::vertices(c.center, c.radius);
        if occlusion::needs_query(view, c, &v) {
            queried.push(i);
            verts.extend(v.map(Into::<[f32; 3]>::into));
        }
    }
    (queried, verts)
}

impl Renderer<'_> {
    /// Phase 2: records one occlusion query per candidate that needs one (in as many render
    /// passes as [`wgpu::QUERY_SET_MAX_QUERIES`] requires), timestamps `ts` around them, and
    /// the resolve + copy of the counts.
    pub(super) fn encode_queries(
        &mut self,
        view: &View,
        occ: &OcclusionPass,
        enc: &mut wgpu::CommandEncoder,
        ts: (u32, u32),
    ) -> anyhow::Result<PendingQueries> {
        let (queried, verts) = query_candidates(view, occ);
        if queried.is_empty() {
            return Ok(PendingQueries {
                queried,
                readback: None,
                counters_at: 0,
                _keep: Vec::new(),
            });
        }
        let shared_depth = self.prepare_queries(queried.len());
        let bufs = QueryBuffers::new(&self.gpu.device, &verts, queried.len());
        let q = self.query.as_ref().context("query pipeline missing")?;
        let bind_group = self.query_bind_group(q, shared_depth, &bufs.counters);
        self.encode_query_passes(enc, q, &bind_group, &bufs, shared_depth, ts);
        let QueryBuffers {
            vertices,
            resolve,
            counters,
            readback,
            bytes,
            counter_bytes,
            ..
        } = bufs;
        enc.copy_buffer_to_buffer(&resolve, 0, &readback, 0, bytes);
        enc.copy_buffer_to_buffer(&counters, 0, &readback, bytes, counter_bytes);
        Ok(PendingQueries {
            queried,
            readback: Some((readback, bytes + counter_bytes)),
            counters_at: bytes,
            _keep: vec![vertices, counters, resolve],
        })
    }

    /// Makes what `n` queries need on first use: the query pipeline, enough query sets and,
    /// on backends without exact counts, the depth stand-in. Returns whether the queries share
    /// phase 1's depth buffer (attached read-only and bound as a texture).
    fn prepare_queries(&mut self, n: usize) -> bool {
        if self.query.is_none() {
            self.query = Some(self.make_query_pipeline());
        }
        let sets = n.div_ceil(wgpu::QUERY_SET_MAX_QUERIES as usize);
        while self.query_sets.len() < sets {
            let set = self.gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("occlusion queries"),
                ty: wgpu::QueryType::Occlusion,
                count: wgpu::QUERY_SET_MAX_QUERIES,
            });
            self.query_sets.push(set);
        }
        // The queries' fragment stage reads phase 1's depth to count exactly: the depth buffer
        // is attached read-only and bound as a texture at once (every backend but GL, which
        // lacks wgpu's READ_ONLY_DEPTH_STENCIL downlevel flag). On GL an unwritten stand-in
        // is bound (copying depth textures did not work on llvmpipe's GL), the counters stay
        // unused and the hardware queries (boolean there) decide.
        let shared_depth = exact_counts(self.gpu);
        if !shared_depth && self.depth_copy.is_none() {
            let t = self.gpu.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("occlusion depth stand-in"),
                size: self.depth.size(),
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: DEPTH_FORMAT,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            });
            self.depth_copy = Some(t.create_view(&Default::default()));
        }
        shared_depth
    }

    /// The queries' bind group: the frame's `view_proj`, the depth they sample (phase 1's,
    /// or the stand-in unless `shared_depth`), the fragment `counters` and the sampler.
    fn query_bind_group(
        &self,
        q: &QueryPipeline,
        shared_depth: bool,
        counters: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        let sampled_depth = match (&self.depth_copy, shared_depth) {
            (Some(copy), false) => copy,
            _ => &self.depth_view,
        };
        self.gpu
            .device
            .create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("occlusion queries"),
                layout: &q.bgl,
                entries: &[
                    // `QueryFrame` is the leading `view_proj` of the frame uniform.
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: &self.frame_ubo,
                            offset: 0,
                            size: wgpu::BufferSize::new(64),
                        }),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::TextureView(sampled_depth),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: counters.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 3,
                        resource: wgpu::BindingResource::Sampler(&q.sampler),
                    },
                ],
            })
    }

    /// Records the query passes, one per query set of [`wgpu::QUERY_SET_MAX_QUERIES`]
    /// queries (of `bufs.queries` in all), each followed by the resolve of its results into
    /// `bufs.resolve`; timestamps `ts` at the beginning of the first and the end of the last.
    fn encode_query_passes(
        &self,
        enc: &mut wgpu::CommandEncoder,
        q: &QueryPipeline,
        bind_group: &wgpu::BindGroup,
        bufs: &QueryBuffers,
        shared_depth: bool,
        ts: (u32, u32),
    ) {
        let per_set = wgpu::QUERY_SET_MAX_QUERIES as usize;
        let n = bufs.queries;
        let sets = n.div_ceil(per_set);
        for k in 0..sets {
            let len = per_set.min(n - k * per_set);
            let (first, last) = (k == 0, k + 1 == sets);
            let timestamp_writes = self.timestamps.as_ref().filter(|_| first || last).map(|t| {
                wgpu::RenderPassTimestampWrites {
                    query_set: &t.set,
                    beginning_of_pass_write_index: first.then_some(ts.0),
                    end_of_pass_write_index: last.then_some(ts.1),
                }
            });
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("occlusion queries"),
                color_attachments: &[],
                // Read-only where the same pass binds it as a texture (no writes either way).
                depth_stencil_attachment: if shared_depth {
                    Some(wgpu::RenderPassDepthStencilAttachment {
                        view: &self.depth_view,
                        depth_ops: None,
                        stencil_ops: None,
                    })
                } else {
                    self.depth_attachment(false, true)
                },
                timestamp_writes,
                occlusion_query_set: Some(&self.query_sets[k]),
                multiview_mask: None,
            });
            pass.set_pipeline(&q.pipeline);
            pass.set_bind_group(0, bind_group, &[]);
            pass.set_vertex_buffer(0, bufs.vertices.slice(..));
            pass.set_index_buffer(q.indices.slice(..), wgpu::IndexFormat::Uint16);
            for j in 0..len {
                let n = (k * per_set + j) as u32;
                pass.begin_occlusion_query(j as u32);
                pass.draw_indexed(0..60, (n * 12) as i32, n..n + 1);
                pass.end_occlusion_query();
            }
            drop(pass);
            enc.resolve_query_set(
                &self.query_sets[k],
                0..len as u32,
                &bufs.resolve,
                (k * per_set) as u64 * wgpu::QUERY_SIZE as u64,
            );
        }
    }

    /// Makes the occlusion-query pipeline: `occlusion.wgsl`, its bind-group layout, the
    /// icosahedron's index buffer and the depth-compare sampler.
    pub(super) fn make_query_pipeline(&self) -> QueryPipeline {
        let d = &self.gpu.device;
        let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("occlusion.wgsl"),
            source: wgpu::ShaderSource::Wgsl(OCCLUSION_WGSL.into()),
        });
        let bgl = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("occlusion queries"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: wgpu::BufferSize::new(64),
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Depth,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: false },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 3,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Comparison),
                    count: None,
                },
            ],
        });
        let layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("occlusion queries"),
            bind_group_layouts: &[Some(&bgl)],
            immediate_size: 0,
        });
        let pipeline = d.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("occlusion queries"),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_query"),
                compilation_options: Default::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: 12,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &wgpu::vertex_attr_array![0 => Float32x3],
                })],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                front_face: wgpu::FrontFace::Ccw,
                cull_mode: Some(wgpu::Face::Back),
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(false),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_query"),
                compilation_options: Default::default(),
                targets: &[],
            }),
            multiview_mask: None,
            cache: None,
        });
        let flat: Vec<u16> = Icosahedron::INDICES.iter().flatten().copied().collect();
        let indices = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("icosahedron indices"),
            contents: bytemuck::cast_slice(&flat),
            usage: wgpu::BufferUsages::INDEX,
        });
        let sampler = d.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("phase 1 depth, compare Less"),
            mag_filter: wgpu::FilterMode::Nearest,
            min_filter: wgpu::FilterMode::Nearest,
            compare: Some(wgpu::CompareFunction::Less),
            ..Default::default()
        });
        QueryPipeline {
            pipeline,
            bgl,
            indices,
            sampler,
        }
    }
}
