//! A simulation on a device the host opened: it steps there, and the host copies and draws
//! the node positions and the boundary's index buffer with its own device, without readback
//! through lancet; the buffers follow a patch; a device with too low limits is refused.

use lancet::collide::broad::Surface;
use lancet::engine::gpu::GpuContext;
use lancet::engine::{GpuOptions, SimConfig};
use lancet::mesh::generate::BoxGrid;
use lancet::mesh::TetMesh;
use lancet::model::{FixedSelector, Material, ModelConfig, PackedModel, SpringModel};
use lancet::Simulation;

use super::common;
use super::models::{random_diff, random_model};

/// A device, queue and adapter info opened by "the host" (not through `GpuContext`), on the
/// adapter the tests' shared context runs on, with `limits`.
fn host_device(
    limits: impl FnOnce(&wgpu::Adapter) -> wgpu::Limits,
) -> Option<(wgpu::Device, wgpu::Queue, wgpu::AdapterInfo)> {
    let shared = common::gpu()?;
    let backends = wgpu::Backends::from(shared.info.backend);
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends,
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapter = pollster::block_on(instance.enumerate_adapters(backends))
        .into_iter()
        .find(|a| {
            let info = a.get_info();
            info.name == shared.info.name && info.backend == shared.info.backend
        })
        .expect("the shared context's adapter is listed");
    let info = adapter.get_info();
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("host"),
        required_limits: limits(&adapter),
        ..Default::default()
    }))
    .expect("the host opens its device");
    Some((device, queue, info))
}

/// A 3 x 3 x 3 cm block clamped at its base, settling under gravity along -z (the drawing looks
/// down z: the settling barely changes the x-y outline), and its mesh.
fn block() -> (TetMesh, PackedModel) {
    let mesh = BoxGrid::cube_cells([3, 3, 3], 0.01).build().unwrap();
    let mut config = ModelConfig::new(Material::elastic(5e4, 0.3, 1000.0));
    config.gravity = [0.0, 0.0, -9.81];
    config.fixed.push(FixedSelector::Plane {
        point: [0.0, 0.0, 0.0],
        normal: [0.0, 0.0, 1.0],
        tolerance: 1e-9,
    });
    let model = SpringModel::build(&mesh, &config)
        .unwrap()
        .pack(&mesh)
        .unwrap();
    (mesh, model)
}

/// Copy `buffer`'s first `bytes` into a mapped buffer with the host's own device and read them.
fn host_copy(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    buffer: &wgpu::Buffer,
    bytes: u64,
) -> Vec<u8> {
    let read = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("host readback"),
        size: bytes,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = device.create_command_encoder(&Default::default());
    enc.copy_buffer_to_buffer(buffer, 0, &read, 0, bytes);
    queue.submit([enc.finish()]);
    read.slice(..)
        .map_async(wgpu::MapMode::Read, |r| r.unwrap());
    device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
    let out = read.slice(..).get_mapped_range().expect("mapped").to_vec();
    read.unmap();
    out
}

/// The host's copy of the node positions equals what lancet reads back (float32 rounding of
/// the coordinates), and has moved away from rest.
fn assert_positions_match(sim: &mut Simulation, device: &wgpu::Device, queue: &wgpu::Queue) {
    let expected = sim.positions();
    let rest = sim.model().rest.clone();
    let v = sim.gpu_node_positions().unwrap().expect("a GPU engine");
    assert_eq!(v.count as usize, expected.len());
    let bytes = host_copy(device, queue, v.buffer, u64::from(v.count) * 16);
    let got: &[[f32; 4]] = bytemuck::cast_slice(&bytes);
    let mut moved = 0.0f64;
    for (i, (g, e)) in got.iter().zip(&expected).enumerate() {
        assert_eq!(g[3], 1.0, "w = 1 at node {i}");
        for c in 0..3 {
            // A float32 sum of rest and displacement: a few ulps of the coordinate.
            assert!(
                (f64::from(g[c]) - e[c]).abs() <= 5e-7 * e[c].abs() + 1e-9,
                "node {i} axis {c}: host reads {} where lancet reads {}",
                g[c],
                e[c]
            );
            moved = moved.max((e[c] - rest[i][c]).abs());
        }
    }
    assert!(
        moved > 1e-6,
        "the block sagged ({moved:e} m): not a rest-state comparison"
    );
}

#[test]
fn a_simulation_on_the_hosts_device_serves_positions_and_indices_the_host_draws() {
    let Some((device, queue, info)) = host_device(|a| a.limits()) else {
        return;
    };
    let ctx = GpuContext::from_device(device.clone(), queue.clone(), info).unwrap();
    let (mesh, model) = block();
    let dt = 0.5 * lancet::model::stable_time_step(&model).dt;
    let mut sim = Simulation::with_gpu_context(
        model,
        ctx.clone(),
        SimConfig::new(dt),
        GpuOptions::default(),
    )
    .unwrap();
    assert!(
        sim.gpu_context().unwrap().same_device(&ctx),
        "the engine runs on the host's device"
    );
    sim.set_surface(Surface::of(&mesh).triangles).unwrap();
    sim.run(200).unwrap();
    assert_positions_match(&mut sim, &device, &queue);

    // The host draws the boundary with its own pipeline: an orthographic view down z of the
    // block's x-y extent mapped to [-0.8, 0.8], so the block covers 0.8^2 = 64% of the
    // picture (less what the sag moved, which is far under a pixel here).
    let size = 64u32;
    let target = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("host target"),
        size: wgpu::Extent3d {
            width: size,
            height: size,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("host draw"),
        source: wgpu::ShaderSource::Wgsl(
            "@vertex fn vs(@location(0) p: vec3<f32>) -> @builtin(position) vec4<f32> {
                 let q = (p.xy / 0.03) * 1.6 - vec2<f32>(0.8, 0.8);
                 return vec4<f32>(q, 0.5, 1.0);
             }
             @fragment fn fs() -> @location(0) vec4<f32> { return vec4<f32>(1.0, 1.0, 1.0, 1.0); }"
                .into(),
        ),
    });
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("host draw"),
        layout: None,
        vertex: wgpu::VertexState {
            module: &shader,
            entry_point: Some("vs"),
            compilation_options: Default::default(),
            buffers: &[Some(wgpu::VertexBufferLayout {
                array_stride: 16,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &wgpu::vertex_attr_array![0 => Float32x3],
            })],
        },
        fragment: Some(wgpu::FragmentState {
            module: &shader,
            entry_point: Some("fs"),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::TextureFormat::Rgba8Unorm.into())],
        }),
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: None,
        multisample: Default::default(),
        multiview_mask: None,
        cache: None,
    });
    let positions = sim.gpu_node_positions().unwrap().unwrap().buffer.clone();
    let indices = sim
        .gpu_surface_indices()
        .unwrap()
        .expect("a surface was set");
    let (index_buffer, index_count) = (indices.buffer.clone(), indices.count);
    assert_eq!(index_count as usize, 3 * Surface::of(&mesh).triangles.len());
    let view = target.create_view(&Default::default());
    let mut enc = device.create_command_encoder(&Default::default());
    {
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("host draw"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            ..Default::default()
        });
        pass.set_pipeline(&pipeline);
        pass.set_vertex_buffer(0, positions.slice(..));
        pass.set_index_buffer(index_buffer.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..index_count, 0, 0..1);
    }
    let read = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("picture"),
        size: u64::from(size * size * 4),
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    enc.copy_texture_to_buffer(
        target.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &read,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(size * 4),
                rows_per_image: None,
            },
        },
        wgpu::Extent3d {
            width: size,
            height: size,
            depth_or_array_layers: 1,
        },
    );
    queue.submit([enc.finish()]);
    read.slice(..)
        .map_async(wgpu::MapMode::Read, |r| r.unwrap());
    device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
    let covered = read
        .slice(..)
        .get_mapped_range()
        .expect("mapped")
        .chunks(4)
        .filter(|p| p[0] > 128)
        .count();
    let share = covered as f64 / f64::from(size * size);
    assert!(
        (0.58..0.70).contains(&share),
        "the drawn block covers {share:.3} of the picture, expected about 0.64"
    );
}

#[test]
fn the_hosts_buffers_follow_a_patch() {
    let Some((device, queue, info)) = host_device(|a| a.limits()) else {
        return;
    };
    let ctx = GpuContext::from_device(device.clone(), queue.clone(), info).unwrap();
    let model = random_model(7, true);
    let mut config = SimConfig::new(2e-5);
    config.allow_unstable = true;
    let mut sim = Simulation::with_gpu_context(model, ctx, config, GpuOptions::default()).unwrap();
    // Gravity-free random model: give it a state that is not rest.
    let (x, v) = super::models::random_state(sim.model(), 7);
    sim.set_state(&x, &v).unwrap();
    sim.run(5).unwrap();
    let before = sim.model().node_count();
    for round in 0..3 {
        let diff = random_diff(sim.model(), 300 + round);
        sim.apply_with(&diff, true).unwrap();
        sim.run(3).unwrap();
        assert_positions_match(&mut sim, &device, &queue);
    }
    assert!(sim.model().node_count() > before, "the patches added nodes");
}

#[test]
fn a_host_device_below_the_needed_limits_is_refused_by_name() {
    let Some((device, queue, info)) = host_device(|_| wgpu::Limits::downlevel_defaults()) else {
        return;
    };
    let err = GpuContext::from_device(device, queue, info)
        .err()
        .expect("refused");
    assert!(
        err.to_string()
            .contains("max_storage_buffers_per_shader_stage"),
        "{err}"
    );
}
