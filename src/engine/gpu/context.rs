//! Choosing a GPU adapter and opening a device on it.

use crate::error::{Error, Result};

/// An open wgpu device with what lancet needs to know about it. Clones share the device.
#[derive(Clone)]
pub struct GpuContext {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// The adapter it runs on.
    pub info: wgpu::AdapterInfo,
    /// The limits requested (the adapter's own, which are larger than wgpu's defaults).
    pub limits: wgpu::Limits,
    /// Set by the device's lost callback.
    lost: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

/// Storage buffers the largest pass binds in one shader stage (`gather_edges.wgsl`,
/// `implicit_solve.wgsl`, `self_pairs.wgsl`): wgpu's default limit, which every adapter
/// lancet runs on has.
const MIN_STORAGE_BUFFERS: u32 = 8;

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
    ///
    /// The device is opened once per process and shared by every engine and context made with
    /// `new` (they submit to its one queue; error scopes are per thread): opening a device costs
    /// a tenth of a second or more and driver resources, and NVIDIA's Linux Vulkan driver
    /// crashes or runs out of devices when many are opened and closed, on several threads at
    /// once (wgpu issues 5930 and 10234; seen here as heap corruption and "device lost" in the
    /// GPU tests, which made an engine per test in parallel). A device that is lost is opened
    /// again at the next call. A failure to open is not kept: the next call tries again.
    pub fn new() -> Result<Self> {
        static SHARED: std::sync::Mutex<Option<GpuContext>> = std::sync::Mutex::new(None);
        let mut shared = SHARED.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(ctx) = shared.as_ref().filter(|c| !c.is_lost()) {
            return Ok(ctx.clone());
        }
        let ctx = Self::open(|_| {})?;
        *shared = Some(ctx.clone());
        Ok(ctx)
    }

    /// A context on a device the host opened (its renderer's), so that lancet's passes and
    /// the host's drawing share buffers with no copy between devices: give it the host's
    /// device, queue and the adapter's info. The device's own limits are used; a device whose
    /// limits are below what lancet's passes need is refused with the limit named.
    ///
    /// Requested features decide what runs: the edge layout's `AtomicFloat` accumulation needs
    /// `SHADER_FLOAT32_ATOMIC`, device timings `TIMESTAMP_QUERY`; without them those are
    /// refused or left out as on any adapter. lancet does not set the device's lost callback
    /// (the host owns it): [`GpuContext::is_lost`] stays false on such a context.
    pub fn from_device(
        device: wgpu::Device,
        queue: wgpu::Queue,
        info: wgpu::AdapterInfo,
    ) -> Result<Self> {
        let limits = device.limits();
        let needs = [
            (
                "max_storage_buffers_per_shader_stage",
                limits.max_storage_buffers_per_shader_stage,
                MIN_STORAGE_BUFFERS,
            ),
            (
                "max_compute_workgroup_size_x",
                limits.max_compute_workgroup_size_x,
                super::WORKGROUP,
            ),
            (
                "max_compute_invocations_per_workgroup",
                limits.max_compute_invocations_per_workgroup,
                super::WORKGROUP,
            ),
            (
                "max_compute_workgroups_per_dimension",
                limits.max_compute_workgroups_per_dimension,
                1,
            ),
        ];
        if let Some((name, has, need)) = needs.into_iter().find(|(_, has, need)| has < need) {
            return Err(Error::Unsupported(format!(
                "the host's device {} has {name} = {has}, below the {need} lancet's passes \
                 need: request the adapter's limits (adapter.limits()) or at least \
                 wgpu::Limits::default() when opening it",
                info.name
            )));
        }
        Ok(GpuContext {
            device,
            queue,
            info,
            limits,
            lost: std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false)),
        })
    }

    /// A device of its own, with its limits lowered by `lower` (which may only lower them): to
    /// check that a mesh too big for a smaller device gets a clear error.
    pub fn with_limits(lower: impl FnOnce(&mut wgpu::Limits)) -> Result<Self> {
        Self::open(lower)
    }

    /// Whether the device was lost (a driver reset, the GPU removed): nothing more runs on it.
    pub fn is_lost(&self) -> bool {
        self.lost.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Whether `self` and `other` are the same device (wgpu compares devices by an id that is
    /// unique only within one instance, and each opening makes its own instance).
    pub fn same_device(&self, other: &GpuContext) -> bool {
        std::sync::Arc::ptr_eq(&self.lost, &other.lost)
    }

    /// Open a new device on the preferred adapter.
    fn open(lower: impl FnOnce(&mut wgpu::Limits)) -> Result<Self> {
        // One opening at a time in a process, for the same driver's sake.
        static OPENING: std::sync::Mutex<()> = std::sync::Mutex::new(());
        let _one_at_a_time = OPENING.lock().unwrap_or_else(|e| e.into_inner());
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
        let lost = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let flag = lost.clone();
        device.set_device_lost_callback(move |_, _| {
            flag.store(true, std::sync::atomic::Ordering::Relaxed);
        });
        Ok(GpuContext {
            device,
            queue,
            info,
            limits,
            lost,
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
