//! Choosing a GPU adapter and opening a device on it.

use crate::error::{Error, Result};

/// An open wgpu device with what lancet needs to know about it.
pub struct GpuContext {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// The adapter it runs on.
    pub info: wgpu::AdapterInfo,
    /// The limits requested (the adapter's own, which are larger than wgpu's defaults).
    pub limits: wgpu::Limits,
}

/// Preference among adapters: discrete GPUs first, a CPU device (lavapipe) last but one.
fn rank(info: &wgpu::AdapterInfo) -> (u8, u8) {
    let kind = match info.device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Cpu => 3,
        wgpu::DeviceType::Other => 4,
    };
    // Native APIs before OpenGL, which wgpu supports with fewer compute features.
    let backend = u8::from(info.backend == wgpu::Backend::Gl);
    (kind, backend)
}

impl GpuContext {
    /// Open the preferred adapter. Without any adapter this is an error that says what to
    /// install, never a panic.
    ///
    /// The environment variable `WGPU_BACKEND` (wgpu's own, a comma-separated list such as
    /// `vulkan` or `vulkan,gl`) restricts the backends searched; without it, native APIs are
    /// searched first and OpenGL only when they have no adapter. Restricting to `vulkan` is how
    /// to make sure no OpenGL fallback is picked up, e.g. to test the no-GPU path with the
    /// Vulkan driver hidden (`VK_ICD_FILENAMES=/nonexistent`).
    pub fn new() -> Result<Self> {
        Self::with_limits(|_| {})
    }

    /// Like [`GpuContext::new`], with the device's limits lowered by `lower` (which may only
    /// lower them): to check that a mesh too big for a smaller device gets a clear error.
    pub fn with_limits(lower: impl FnOnce(&mut wgpu::Limits)) -> Result<Self> {
        let from_env = std::env::var("WGPU_BACKEND").ok();
        let searches = match wgpu::Backends::from_env() {
            Some(b) if b.is_empty() => {
                return Err(Error::Unsupported(format!(
                    "WGPU_BACKEND={:?} names no backend; use a comma-separated list of vulkan, \
                     metal, dx12, gl, or unset it",
                    from_env.unwrap_or_default()
                )))
            }
            Some(b) => vec![b],
            // Native APIs first; OpenGL (which also runs compute on llvmpipe) only when none
            // has an adapter, since probing it costs time and prints EGL warnings.
            None => vec![wgpu::Backends::PRIMARY, wgpu::Backends::GL],
        };
        let adapter = searches
            .into_iter()
            .find_map(|backends| {
                let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
                    backends,
                    ..wgpu::InstanceDescriptor::new_without_display_handle()
                });
                pollster::block_on(instance.enumerate_adapters(backends))
                    .into_iter()
                    .min_by_key(|a| rank(&a.get_info()))
            })
            .ok_or_else(|| {
                let restricted = from_env.map_or(String::new(), |v| {
                    format!(" on the backends WGPU_BACKEND={v:?} allows (unset it to search all)")
                });
                Error::Unsupported(format!(
                    "no GPU adapter found{restricted}; install a Vulkan driver (on Debian: \
                     apt-get install mesa-vulkan-drivers libvulkan1 gives a CPU Vulkan device) \
                     or run with --engine cpu"
                ))
            })?;
        let info = adapter.get_info();
        let mut limits = adapter.limits();
        lower(&mut limits);
        // Float atomics serve only the edge layout's AtomicFloat variant, timestamps only the
        // device timing in `lancet bench`; ask for them where the adapter has them, never
        // require them.
        let features = adapter.features()
            & (wgpu::Features::SHADER_FLOAT32_ATOMIC | wgpu::Features::TIMESTAMP_QUERY);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("lancet"),
            required_features: features,
            required_limits: limits.clone(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| Error::Gpu(format!("cannot open {}: {e}", info.name)))?;
        Ok(GpuContext {
            device,
            queue,
            info,
            limits,
        })
    }

    /// "name (backend, device type)".
    pub fn describe(&self) -> String {
        format!(
            "{} ({:?}, {:?})",
            self.info.name, self.info.backend, self.info.device_type
        )
    }
}
