//! wgpu resources of the viewport and the per-frame egui_wgpu callback.

use super::{BLIT_SHADER, GpuVertex, MESH_SHADER, MeshData};
use bytemuck::{Pod, Zeroable};
use eframe::egui_wgpu::{self, CallbackResources, CallbackTrait, ScreenDescriptor};
use eframe::wgpu::{self, util::DeviceExt};
use std::collections::HashMap;
use std::sync::Arc;

const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Multisampling of the offscreen target on a GPU: smooth silhouettes and wire edges. A
/// software rasteriser (lavapipe, llvmpipe) renders without it: 4× MSAA there costs more than
/// the rest of the frame (the editor must stay interactive on machines without a GPU).
const GPU_SAMPLES: u32 = 4;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct CameraUniform {
    view_proj: [[f32; 4]; 4],
    eye: [f32; 4],
    viewport: [f32; 4],
    clip: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct DrawUniform {
    colour: [f32; 4],
    params: [f32; 4],
}

/// How one mesh is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DrawStyle {
    /// Draw the shaded surface.
    pub surface: bool,
    /// Uniform colour (linear RGB); `None` uses the per-vertex colours.
    pub colour: Option<[f32; 3]>,
    /// Flat (per-face) instead of smooth (per-vertex normal) shading.
    pub flat: bool,
    /// Opacity in [0, 1]; below 1 the surface is drawn after opaque ones, blended.
    pub opacity: f32,
    /// Draw polygon edges.
    pub wireframe: bool,
    /// Edge colour; `None` uses the per-vertex colours (line-only items such as arrows).
    pub wire_colour: Option<[f32; 4]>,
    /// Pushes the surface back in depth (clip units × w), so an underlay that coincides with
    /// another surface (the scan under the registered face) does not z-fight with it.
    pub depth_push: f32,
}

impl Default for DrawStyle {
    fn default() -> Self {
        DrawStyle {
            surface: true,
            colour: None,
            flat: false,
            opacity: 1.0,
            wireframe: false,
            wire_colour: Some([0.08, 0.1, 0.14, 0.55]),
            depth_push: 0.0,
        }
    }
}

/// One mesh of the scene. `id` names the GPU buffers; new `data` (another `Arc`) re-uploads them.
#[derive(Clone)]
pub struct SceneItem {
    pub id: u64,
    pub data: Arc<MeshData>,
    pub style: DrawStyle,
}

/// A feature-point marker (screen-sized disc).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct MarkerInstance {
    pub centre: [f32; 3],
    pub colour: [f32; 4],
}

/// Everything one frame draws; built by the app each frame (cheap: meshes are shared `Arc`s).
pub struct ViewportCallback {
    pub view_proj: glam::Mat4,
    pub eye_mm: glam::Vec3,
    /// Callback rectangle size in points (multiplied by pixels-per-point in `prepare`).
    pub size_points: [f32; 2],
    pub background: [f32; 4],
    pub items: Vec<SceneItem>,
    pub markers: Vec<MarkerInstance>,
    pub marker_radius_px: f32,
    /// Cut-away: points with `normal · p > offset` are not drawn (`None`: no cut).
    pub clip_plane: Option<(glam::Vec3, f32)>,
}

struct GpuMesh {
    /// The arrays uploaded last: the same `Arc` again is nothing to do (it is kept alive here,
    /// so a new one cannot reuse its address); new arrays with the same index arrays only
    /// rewrite the vertex buffer (a slider drag moves vertices, never topology).
    data: Arc<MeshData>,
    vertices: wgpu::Buffer,
    triangles: wgpu::Buffer,
    triangle_count: u32,
    edges: wgpu::Buffer,
    edge_count: u32,
    surface_uniform: wgpu::Buffer,
    surface_bind: wgpu::BindGroup,
    wire_uniform: wgpu::Buffer,
    wire_bind: wgpu::BindGroup,
}

struct Target {
    size: [u32; 2],
    msaa_view: Option<wgpu::TextureView>,
    depth_view: wgpu::TextureView,
    resolve_view: wgpu::TextureView,
    blit_bind: wgpu::BindGroup,
}

/// Pipelines and buffers, created once and stored in egui_wgpu's callback resources.
pub struct ViewportRenderer {
    format: wgpu::TextureFormat,
    samples: u32,
    opaque_pipeline: wgpu::RenderPipeline,
    blended_pipeline: wgpu::RenderPipeline,
    line_pipeline: wgpu::RenderPipeline,
    marker_pipeline: wgpu::RenderPipeline,
    blit_pipeline: wgpu::RenderPipeline,
    camera_buffer: wgpu::Buffer,
    camera_bind: wgpu::BindGroup,
    draw_layout: wgpu::BindGroupLayout,
    blit_layout: wgpu::BindGroupLayout,
    sampler: wgpu::Sampler,
    marker_uniform_bind: wgpu::BindGroup,
    marker_buffer: Option<(wgpu::Buffer, u32)>,
    meshes: HashMap<u64, GpuMesh>,
    target: Option<Target>,
    /// Draw order of the current frame (ids), opaque first.
    frame_order: Vec<(u64, DrawStyle)>,
}

fn uniform_layout(device: &wgpu::Device, label: &str, size: u64) -> wgpu::BindGroupLayout {
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &[wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: wgpu::BufferSize::new(size),
            },
            count: None,
        }],
    })
}

fn uniform_buffer<T: Pod>(device: &wgpu::Device, label: &str, value: &T) -> wgpu::Buffer {
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytemuck::bytes_of(value),
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
    })
}

fn bind_buffer(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    buffer: &wgpu::Buffer,
) -> wgpu::BindGroup {
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("facesynth uniform"),
        layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: buffer.as_entire_binding(),
        }],
    })
}

impl ViewportRenderer {
    /// Creates pipelines for egui's target format. Call once (app start-up).
    pub fn new(device: &wgpu::Device, format: wgpu::TextureFormat, samples: u32) -> Self {
        let mesh_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("facesynth mesh.wgsl"),
            source: wgpu::ShaderSource::Wgsl(MESH_SHADER.into()),
        });
        let blit_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("facesynth blit.wgsl"),
            source: wgpu::ShaderSource::Wgsl(BLIT_SHADER.into()),
        });
        let camera_layout = uniform_layout(
            device,
            "camera",
            std::mem::size_of::<CameraUniform>() as u64,
        );
        let draw_layout = uniform_layout(device, "draw", std::mem::size_of::<DrawUniform>() as u64);
        let scene_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("facesynth scene"),
            bind_group_layouts: &[Some(&camera_layout), Some(&draw_layout)],
            immediate_size: 0,
        });
        let vertex_layout = wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<GpuVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x4],
        };
        let marker_layout = wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<MarkerInstance>() as u64,
            step_mode: wgpu::VertexStepMode::Instance,
            attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x4],
        };
        let depth = |write: bool| {
            Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(write),
                depth_compare: Some(wgpu::CompareFunction::LessEqual),
                stencil: wgpu::StencilState::default(),
                bias: wgpu::DepthBiasState::default(),
            })
        };
        let blend = Some(wgpu::BlendState::ALPHA_BLENDING);
        let multisample = wgpu::MultisampleState {
            count: samples,
            ..Default::default()
        };
        let pipeline = |label: &str,
                        vs: &str,
                        fs: &str,
                        buffers: &[Option<wgpu::VertexBufferLayout>],
                        topology: wgpu::PrimitiveTopology,
                        depth_write: bool,
                        blend: Option<wgpu::BlendState>| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&scene_layout),
                vertex: wgpu::VertexState {
                    module: &mesh_module,
                    entry_point: Some(vs),
                    compilation_options: Default::default(),
                    buffers,
                },
                primitive: wgpu::PrimitiveState {
                    topology,
                    cull_mode: None,
                    ..Default::default()
                },
                depth_stencil: depth(depth_write),
                multisample,
                fragment: Some(wgpu::FragmentState {
                    module: &mesh_module,
                    entry_point: Some(fs),
                    compilation_options: Default::default(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format,
                        blend,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let tri = wgpu::PrimitiveTopology::TriangleList;
        let opaque_pipeline = pipeline(
            "facesynth opaque",
            "vs_mesh",
            "fs_mesh",
            &[Some(vertex_layout.clone())],
            tri,
            true,
            None,
        );
        let blended_pipeline = pipeline(
            "facesynth blended",
            "vs_mesh",
            "fs_mesh",
            &[Some(vertex_layout.clone())],
            tri,
            false,
            blend,
        );
        let line_pipeline = pipeline(
            "facesynth lines",
            "vs_line",
            "fs_line",
            &[Some(vertex_layout)],
            wgpu::PrimitiveTopology::LineList,
            false,
            blend,
        );
        let marker_pipeline = pipeline(
            "facesynth markers",
            "vs_marker",
            "fs_marker",
            &[Some(marker_layout)],
            tri,
            true,
            None,
        );

        let blit_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("facesynth blit"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
        });
        let blit_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("facesynth blit"),
            bind_group_layouts: &[Some(&blit_layout)],
            immediate_size: 0,
        });
        let blit_pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("facesynth blit"),
            layout: Some(&blit_pipeline_layout),
            vertex: wgpu::VertexState {
                module: &blit_module,
                entry_point: Some("vs_blit"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &blit_module,
                entry_point: Some("fs_blit"),
                compilation_options: Default::default(),
                targets: &[Some(format.into())],
            }),
            multiview_mask: None,
            cache: None,
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("facesynth blit"),
            mag_filter: wgpu::FilterMode::Nearest,
            min_filter: wgpu::FilterMode::Nearest,
            ..Default::default()
        });
        let camera_buffer = uniform_buffer(device, "camera", &CameraUniform::zeroed());
        let camera_bind = bind_buffer(device, &camera_layout, &camera_buffer);
        let marker_uniform = uniform_buffer(
            device,
            "markers",
            &DrawUniform {
                colour: [1.0; 4],
                params: [0.0, 1.0, 0.002, 0.0],
            },
        );
        let marker_uniform_bind = bind_buffer(device, &draw_layout, &marker_uniform);
        ViewportRenderer {
            format,
            samples,
            opaque_pipeline,
            blended_pipeline,
            line_pipeline,
            marker_pipeline,
            blit_pipeline,
            camera_buffer,
            camera_bind,
            draw_layout,
            blit_layout,
            sampler,
            marker_uniform_bind,
            marker_buffer: None,
            meshes: HashMap::new(),
            target: None,
            frame_order: Vec::new(),
        }
    }

    /// Registers the renderer in egui_wgpu's callback resources (once, at app start-up).
    pub fn install(render_state: &egui_wgpu::RenderState) {
        let software = render_state.adapter.get_info().device_type == wgpu::DeviceType::Cpu;
        let samples = if software { 1 } else { GPU_SAMPLES };
        let renderer =
            ViewportRenderer::new(&render_state.device, render_state.target_format, samples);
        render_state
            .renderer
            .write()
            .callback_resources
            .insert(renderer);
    }

    fn ensure_target(&mut self, device: &wgpu::Device, size: [u32; 2]) {
        if self.target.as_ref().is_some_and(|t| t.size == size) {
            return;
        }
        let extent = wgpu::Extent3d {
            width: size[0],
            height: size[1],
            depth_or_array_layers: 1,
        };
        let texture = |label: &str, format, samples, usage| {
            device
                .create_texture(&wgpu::TextureDescriptor {
                    label: Some(label),
                    size: extent,
                    mip_level_count: 1,
                    sample_count: samples,
                    dimension: wgpu::TextureDimension::D2,
                    format,
                    usage,
                    view_formats: &[],
                })
                .create_view(&wgpu::TextureViewDescriptor::default())
        };
        let attach = wgpu::TextureUsages::RENDER_ATTACHMENT;
        // Single-sampled: the pass draws straight into the resolve texture.
        let msaa_view =
            (self.samples > 1).then(|| texture("viewport msaa", self.format, self.samples, attach));
        let depth_view = texture("viewport depth", DEPTH_FORMAT, self.samples, attach);
        let resolve_view = texture(
            "viewport colour",
            self.format,
            1,
            attach | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let blit_bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("facesynth blit"),
            layout: &self.blit_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&resolve_view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Sampler(&self.sampler),
                },
            ],
        });
        self.target = Some(Target {
            size,
            msaa_view,
            depth_view,
            resolve_view,
            blit_bind,
        });
    }

    fn upload(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, item: &SceneItem) {
        let data = &item.data;
        if let Some(m) = self.meshes.get_mut(&item.id) {
            if Arc::ptr_eq(&m.data, data) {
                return;
            }
            let old = &m.data;
            if !data.vertices.is_empty()
                && old.vertices.len() == data.vertices.len()
                && old.triangles == data.triangles
                && old.edges == data.edges
            {
                queue.write_buffer(&m.vertices, 0, bytemuck::cast_slice(&data.vertices));
                m.data = data.clone();
                return;
            }
        }
        let buffer = |label: &str, contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                // wgpu rejects empty buffers: keep one dummy element.
                contents: if contents.is_empty() {
                    &[0u8; 64]
                } else {
                    contents
                },
                usage,
            })
        };
        let surface_uniform = uniform_buffer(device, "surface", &DrawUniform::zeroed());
        let wire_uniform = uniform_buffer(device, "wire", &DrawUniform::zeroed());
        let mesh = GpuMesh {
            data: data.clone(),
            vertices: buffer(
                "vertices",
                bytemuck::cast_slice(&data.vertices),
                wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            ),
            triangles: buffer(
                "triangles",
                bytemuck::cast_slice(&data.triangles),
                wgpu::BufferUsages::INDEX,
            ),
            triangle_count: data.triangles.len() as u32,
            edges: buffer(
                "edges",
                bytemuck::cast_slice(&data.edges),
                wgpu::BufferUsages::INDEX,
            ),
            edge_count: data.edges.len() as u32,
            surface_bind: bind_buffer(device, &self.draw_layout, &surface_uniform),
            surface_uniform,
            wire_bind: bind_buffer(device, &self.draw_layout, &wire_uniform),
            wire_uniform,
        };
        self.meshes.insert(item.id, mesh);
    }
}

impl CallbackTrait for ViewportCallback {
    fn prepare(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        screen: &ScreenDescriptor,
        encoder: &mut wgpu::CommandEncoder,
        resources: &mut CallbackResources,
    ) -> Vec<wgpu::CommandBuffer> {
        let Some(r) = resources.get_mut::<ViewportRenderer>() else {
            return Vec::new();
        };
        let ppp = screen.pixels_per_point;
        let size = [
            ((self.size_points[0] * ppp).round() as u32).clamp(1, 8192),
            ((self.size_points[1] * ppp).round() as u32).clamp(1, 8192),
        ];
        r.ensure_target(device, size);
        queue.write_buffer(
            &r.camera_buffer,
            0,
            bytemuck::bytes_of(&CameraUniform {
                view_proj: self.view_proj.to_cols_array_2d(),
                eye: self.eye_mm.extend(1.0).to_array(),
                viewport: [
                    size[0] as f32,
                    size[1] as f32,
                    self.marker_radius_px * ppp,
                    0.0,
                ],
                clip: self
                    .clip_plane
                    .map_or([0.0; 4], |(n, d)| [n.x, n.y, n.z, d]),
            }),
        );
        r.frame_order.clear();
        for item in &self.items {
            r.upload(device, queue, item);
            let mesh = &r.meshes[&item.id];
            let s = item.style;
            let colour = s
                .colour
                .map_or([0.0, 0.0, 0.0, -1.0], |c| [c[0], c[1], c[2], 1.0]);
            let flat = if s.flat { 1.0 } else { 0.0 };
            queue.write_buffer(
                &mesh.surface_uniform,
                0,
                bytemuck::bytes_of(&DrawUniform {
                    colour,
                    params: [flat, s.opacity.clamp(0.0, 1.0), -s.depth_push, 0.0],
                }),
            );
            queue.write_buffer(
                &mesh.wire_uniform,
                0,
                bytemuck::bytes_of(&DrawUniform {
                    colour: s.wire_colour.unwrap_or([0.0, 0.0, 0.0, -1.0]),
                    params: [0.0, 1.0, 0.0005, 0.0],
                }),
            );
            r.frame_order.push((item.id, s));
        }
        // Opaque surfaces first, blended ones after (depth test against the opaque ones).
        r.frame_order.sort_by_key(|(_, s)| s.opacity < 1.0);
        if !self.markers.is_empty() {
            let needed = self.markers.len() as u32;
            if r.marker_buffer
                .as_ref()
                .is_none_or(|(_, cap)| *cap < needed)
            {
                let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("markers"),
                    size: (needed.max(64) as u64) * std::mem::size_of::<MarkerInstance>() as u64,
                    usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                r.marker_buffer = Some((buffer, needed.max(64)));
            }
            if let Some((buffer, _)) = &r.marker_buffer {
                queue.write_buffer(buffer, 0, bytemuck::cast_slice(&self.markers));
            }
        }

        let Some(target) = r.target.as_ref() else {
            return Vec::new();
        };
        let bg = self.background;
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("facesynth viewport"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target.msaa_view.as_ref().unwrap_or(&target.resolve_view),
                depth_slice: None,
                resolve_target: target.msaa_view.as_ref().map(|_| &target.resolve_view),
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color {
                        r: bg[0] as f64,
                        g: bg[1] as f64,
                        b: bg[2] as f64,
                        a: bg[3] as f64,
                    }),
                    store: if target.msaa_view.is_some() {
                        wgpu::StoreOp::Discard
                    } else {
                        wgpu::StoreOp::Store
                    },
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &target.depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_bind_group(0, &r.camera_bind, &[]);
        for (id, style) in &r.frame_order {
            let mesh = &r.meshes[id];
            pass.set_vertex_buffer(0, mesh.vertices.slice(..));
            if style.surface && mesh.triangle_count > 0 {
                pass.set_pipeline(if style.opacity < 1.0 {
                    &r.blended_pipeline
                } else {
                    &r.opaque_pipeline
                });
                pass.set_bind_group(1, &mesh.surface_bind, &[]);
                pass.set_index_buffer(mesh.triangles.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..mesh.triangle_count, 0, 0..1);
            }
            if style.wireframe && mesh.edge_count > 0 {
                pass.set_pipeline(&r.line_pipeline);
                pass.set_bind_group(1, &mesh.wire_bind, &[]);
                pass.set_index_buffer(mesh.edges.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..mesh.edge_count, 0, 0..1);
            }
        }
        if let (false, Some((buffer, _))) = (self.markers.is_empty(), &r.marker_buffer) {
            pass.set_pipeline(&r.marker_pipeline);
            pass.set_bind_group(1, &r.marker_uniform_bind, &[]);
            pass.set_vertex_buffer(0, buffer.slice(..));
            pass.draw(0..6, 0..self.markers.len() as u32);
        }
        drop(pass);
        // Forget meshes the scene no longer shows.
        let live: std::collections::HashSet<u64> = self.items.iter().map(|i| i.id).collect();
        r.meshes.retain(|id, _| live.contains(id));
        Vec::new()
    }

    fn paint(
        &self,
        _info: eframe::egui::PaintCallbackInfo,
        render_pass: &mut wgpu::RenderPass<'static>,
        resources: &CallbackResources,
    ) {
        let Some(r) = resources.get::<ViewportRenderer>() else {
            return;
        };
        let Some(target) = &r.target else { return };
        render_pass.set_pipeline(&r.blit_pipeline);
        render_pass.set_bind_group(0, &target.blit_bind, &[]);
        render_pass.draw(0..3, 0..1);
    }
}
