//! Headless pictures with wgpu (`lancet render`): triangle meshes drawn into a texture off
//! screen, read back and written as PNG. Works on any adapter wgpu opens, lavapipe (Vulkan on
//! the CPU) included; without one, [`Renderer::new`] fails with the adapter search's message
//! (there is no CPU rasteriser here: lavapipe is that).
//!
//! - [`camera`]: the perspective camera fitted to a bounding box.
//! - [`mesh_draw`]: meshes as the vertex buffer (flat-shaded triangles with colours).
//! - [`png_out`]: the picture read back, its colour bar, PNG files.
//! - [`frames`] (feature `scene`): the frame sink that draws each frame of a scene run.
//!
//! The pipeline (`shaders/render_mesh.wgsl`): depth-tested triangles, no culling (cut faces
//! and thin tools are seen from both sides), Lambert diffuse plus ambient lighting (weights
//! 0.65 and 0.35, so a colour is at most its own value and its hue survives the shading), 4x
//! multisampling resolved into an RGBA8 texture.

pub mod camera;
#[cfg(feature = "scene")]
pub mod frames;
pub mod mesh_draw;
pub mod png_out;

pub use camera::{Camera, View};
pub use mesh_draw::{DrawMesh, Paint};
pub use png_out::Image;

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use crate::engine::gpu::{buffers, GpuContext};
use crate::error::{Error, Result};

const SOURCE: &str = include_str!("../../shaders/render_mesh.wgsl");
/// Multisampling: four samples per pixel smooth the edges at little cost.
const SAMPLES: u32 = 4;
const COLOUR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Weight of the ambient light; the diffuse light has the rest.
pub const AMBIENT: f32 = 0.35;

/// Mirrors `struct Uniforms` in `shaders/render_mesh.wgsl` (112 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct Uniforms {
    view_projection: [[f32; 4]; 4],
    light: [f32; 4],
    eye: [f32; 4],
    shading: [f32; 4],
}

/// Draws meshes into pictures of one size.
pub struct Renderer {
    ctx: GpuContext,
    pipeline: wgpu::RenderPipeline,
    uniforms: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    colour: wgpu::Texture,
    resolved: wgpu::Texture,
    depth: wgpu::Texture,
    width: u32,
    height: u32,
    /// The background colour, RGBA in `[0, 1]`.
    pub background: [f64; 4],
}

/// The background of the pictures: a light grey no mesh colour equals (the colour map's
/// colours are saturated, the tools' grey is darker), so that coverage can be counted.
pub const BACKGROUND: [f64; 4] = [0.95, 0.95, 0.95, 1.0];

impl Renderer {
    /// A renderer of `width` by `height` pictures on `ctx`'s device.
    pub fn new(ctx: &GpuContext, width: u32, height: u32) -> Result<Self> {
        let max = ctx.limits.max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(Error::Unsupported(format!(
                "a picture of {width} x {height} pixels: each side must be from 1 to {max} on {}",
                ctx.describe()
            )));
        }
        let d = &ctx.device;
        let scope = d.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("render mesh"),
            source: wgpu::ShaderSource::Wgsl(SOURCE.into()),
        });
        let layout = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("render mesh"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let pipeline_layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("render mesh"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = d.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("render mesh"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: std::mem::size_of::<mesh_draw::DrawVertex>() as u64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &wgpu::vertex_attr_array![
                        0 => Float32x3, 1 => Float32x3, 2 => Float32x3
                    ],
                })],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                cull_mode: None,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: wgpu::MultisampleState {
                count: SAMPLES,
                ..Default::default()
            },
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: COLOUR_FORMAT,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        let uniforms = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("render mesh uniforms"),
            size: std::mem::size_of::<Uniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("render mesh"),
            layout: &layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: uniforms.as_entire_binding(),
            }],
        });
        let texture = |label, format, samples, usage| {
            d.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: samples,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let colour = texture(
            "render colour",
            COLOUR_FORMAT,
            SAMPLES,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let resolved = texture(
            "render resolved",
            COLOUR_FORMAT,
            1,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        );
        let depth = texture(
            "render depth",
            DEPTH_FORMAT,
            SAMPLES,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(Error::Gpu(format!("render pipeline: {e}")));
        }
        Ok(Renderer {
            ctx: ctx.clone(),
            pipeline,
            uniforms,
            bind_group,
            colour,
            resolved,
            depth,
            width,
            height,
            background: BACKGROUND,
        })
    }

    /// Width over height of the pictures.
    pub fn aspect(&self) -> f64 {
        self.width as f64 / self.height as f64
    }

    /// Draw `meshes` as `camera` sees them and read the picture back.
    pub fn render(&self, meshes: &[DrawMesh], camera: &Camera) -> Result<Image> {
        let origin = camera.target;
        let vertices = mesh_draw::vertices(meshes, origin);
        let to_f32 = |v: nalgebra::Vector3<f64>| [v.x as f32, v.y as f32, v.z as f32, 0.0];
        let m = camera.view_projection(origin);
        let mut view_projection = [[0.0f32; 4]; 4];
        for (c, column) in view_projection.iter_mut().enumerate() {
            for (r, x) in column.iter_mut().enumerate() {
                *x = m[(r, c)] as f32;
            }
        }
        let uniforms = Uniforms {
            view_projection,
            light: to_f32(camera.light_direction()),
            eye: to_f32(camera.eye - origin),
            shading: [AMBIENT, 1.0 - AMBIENT, 0.0, 0.0],
        };
        let ctx = &self.ctx;
        let scope = ctx.device.push_error_scope(wgpu::ErrorFilter::Validation);
        ctx.queue
            .write_buffer(&self.uniforms, 0, bytemuck::bytes_of(&uniforms));
        let bytes = (vertices.len() * std::mem::size_of::<mesh_draw::DrawVertex>()) as u64;
        if bytes > ctx.limits.max_buffer_size {
            return Err(Error::Gpu(format!(
                "{} triangles need a vertex buffer of {bytes} bytes; {} allows {}",
                vertices.len() / 3,
                ctx.describe(),
                ctx.limits.max_buffer_size
            )));
        }
        let vertex_buffer = (!vertices.is_empty()).then(|| {
            ctx.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("render vertices"),
                    contents: bytemuck::cast_slice(&vertices),
                    usage: wgpu::BufferUsages::VERTEX,
                })
        });
        let mut enc = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("render"),
            });
        {
            let colour_view = self.colour.create_view(&Default::default());
            let resolved_view = self.resolved.create_view(&Default::default());
            let depth_view = self.depth.create_view(&Default::default());
            let [r, g, b, a] = self.background;
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("render"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &colour_view,
                    depth_slice: None,
                    resolve_target: Some(&resolved_view),
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a }),
                        store: wgpu::StoreOp::Discard,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth_view,
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
            if let Some(buffer) = &vertex_buffer {
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &self.bind_group, &[]);
                pass.set_vertex_buffer(0, buffer.slice(..));
                pass.draw(0..vertices.len() as u32, 0..1);
            }
        }
        // Rows of a texture copy are padded to 256 bytes.
        let row = 4 * self.width;
        let padded =
            row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let size = padded as u64 * self.height as u64;
        let staging = buffers::staging_buffer(ctx, size);
        enc.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &self.resolved,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &staging,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded),
                    rows_per_image: Some(self.height),
                },
            },
            wgpu::Extent3d {
                width: self.width,
                height: self.height,
                depth_or_array_layers: 1,
            },
        );
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(Error::Gpu(format!("drawing the picture: {e}")));
        }
        let bytes = buffers::submit_and_read(ctx, enc, &staging, size)?;
        let rgba = bytes
            .chunks_exact(padded as usize)
            .flat_map(|r| &r[..row as usize])
            .copied()
            .collect();
        Ok(Image {
            width: self.width,
            height: self.height,
            rgba,
        })
    }
}
