//! The GPU context: instance, adapter, device and queue (ARCHITECTURE.md "Backends": headless
//! wgpu, Mesa lavapipe on machines without a GPU).

use zwarp_core::{Error, Result};

/// What `zwarp info` prints about one adapter.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AdapterSummary {
    /// Adapter name, e.g. `llvmpipe (LLVM 15.0.6, 256 bits)`.
    pub name: String,
    /// Backend, e.g. `Vulkan`.
    pub backend: String,
    /// Device type, e.g. `Cpu`, `DiscreteGpu`.
    pub device_type: String,
    /// Driver name and version, e.g. `llvmpipe / Mesa 22.3.6`.
    pub driver: String,
}

impl AdapterSummary {
    fn from_info(info: &wgpu::AdapterInfo) -> Self {
        let driver = match (info.driver.is_empty(), info.driver_info.is_empty()) {
            (false, false) => format!("{} / {}", info.driver, info.driver_info),
            (false, true) => info.driver.clone(),
            (true, false) => info.driver_info.clone(),
            (true, true) => "unknown".to_string(),
        };
        AdapterSummary {
            name: info.name.clone(),
            backend: format!("{:?}", info.backend),
            device_type: format!("{:?}", info.device_type),
            driver,
        }
    }
}

impl std::fmt::Display for AdapterSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} ({}, {}, driver {})", self.name, self.backend, self.device_type, self.driver)
    }
}

/// An instance over `backends`; `WGPU_BACKEND` (wgpu's own variable) can override them.
fn instance(backends: wgpu::Backends) -> wgpu::Instance {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
    desc.backends = backends;
    wgpu::Instance::new(desc.with_env())
}

/// Backends tried in order: the native ones (Vulkan, which finds lavapipe on a Linux box
/// without GPU; Metal; DX12), then OpenGL as a last resort (it is only probed when nothing
/// native exists because EGL probing prints noise on headless machines).
const BACKEND_ORDER: [wgpu::Backends; 2] = [wgpu::Backends::PRIMARY, wgpu::Backends::GL];

/// Lists every adapter wgpu can see (for `zwarp info`). Empty when there is none.
pub fn list_adapters() -> Vec<AdapterSummary> {
    for backends in BACKEND_ORDER {
        let inst = instance(backends);
        let found: Vec<AdapterSummary> = pollster::block_on(inst.enumerate_adapters(backends))
            .iter()
            .map(|a| AdapterSummary::from_info(&a.get_info()))
            .collect();
        if !found.is_empty() {
            return found;
        }
    }
    Vec::new()
}

/// A wgpu device + queue with the optional features zwarp uses switched on where the adapter
/// has them. Cheap to clone (wgpu handles are reference counted).
#[derive(Clone, Debug)]
pub struct GpuContext {
    /// The logical device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// What the adapter is (from the device when built with [`GpuContext::from_device`]).
    pub adapter: AdapterSummary,
}

/// Optional features we enable when present: timestamps for [`crate::GpuTimer`], indirect
/// multi-draw (with count) for the batched draws of the culling pipeline (thesis, seed 002).
fn wanted_features() -> wgpu::Features {
    wgpu::Features::TIMESTAMP_QUERY
        | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS
        | wgpu::Features::MULTI_DRAW_INDIRECT_COUNT
        | wgpu::Features::INDIRECT_FIRST_INSTANCE
}

impl GpuContext {
    /// Opens the best adapter (a hardware GPU if present, else a fallback/software adapter such
    /// as lavapipe) and creates a device with the adapter's own limits and the optional
    /// features it supports. `Error::Unavailable` when no adapter exists.
    pub fn new() -> Result<Self> {
        let opts = |fallback| wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: fallback,
            compatible_surface: None,
            apply_limit_buckets: false,
        };
        // Hardware first; lavapipe is reported as a CPU device and may only be returned as a
        // fallback adapter, so ask again with `force_fallback_adapter` before giving up.
        let mut last_err = String::from("no backend enabled");
        let mut found = None;
        for backends in BACKEND_ORDER {
            let inst = instance(backends);
            match pollster::block_on(inst.request_adapter(&opts(false)))
                .or_else(|_| pollster::block_on(inst.request_adapter(&opts(true))))
            {
                Ok(a) => {
                    found = Some(a);
                    break;
                }
                Err(e) => last_err = e.to_string(),
            }
        }
        let adapter = found.ok_or_else(|| {
            Error::Unavailable(format!("no GPU adapter found ({last_err}); install mesa-vulkan-drivers for lavapipe"))
        })?;
        let features = adapter.features() & wanted_features();
        let desc = wgpu::DeviceDescriptor {
            label: Some("zwarp"),
            required_features: features,
            // The adapter's limits, not WebGPU's defaults: full-HD storage buffers of motion
            // samples exceed the default 128 MiB binding size on some adapters.
            required_limits: adapter.limits(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&desc))
            .map_err(|e| Error::Unavailable(format!("could not open GPU device: {e}")))?;
        Ok(GpuContext { device, queue, adapter: AdapterSummary::from_info(&adapter.get_info()) })
    }

    /// Wraps a device and queue the caller already has (an engine's own); zwarp uses whatever
    /// features that device has enabled.
    pub fn from_device(device: wgpu::Device, queue: wgpu::Queue) -> Self {
        let adapter = AdapterSummary::from_info(&device.adapter_info());
        GpuContext { device, queue, adapter }
    }

    /// `true` if pass timestamp queries are enabled (used by [`crate::GpuTimer`]).
    pub fn has_timestamps(&self) -> bool {
        self.device.features().contains(wgpu::Features::TIMESTAMP_QUERY)
    }

    /// Blocks until all submitted work is done.
    pub fn wait(&self) -> Result<()> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| Error::Unavailable(format!("GPU device poll failed: {e}")))
    }

    /// Runs `f` (resource or pipeline creation) inside validation and out-of-memory error
    /// scopes, turning a wgpu error into `Error::Unavailable` instead of wgpu's default panic
    /// (e.g. a format or feature the adapter lacks).
    pub fn catch<T>(&self, what: &str, f: impl FnOnce() -> T) -> Result<T> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let v = f();
        let e1 = pollster::block_on(validation.pop());
        let e2 = pollster::block_on(oom.pop());
        match e1.or(e2) {
            Some(e) => {
                let msg = e.to_string().split_whitespace().collect::<Vec<_>>().join(" ");
                Err(Error::Unavailable(format!("{what} failed on {}: {msg}", self.adapter.name)))
            }
            None => Ok(v),
        }
    }

    /// Compiles the WGSL `source` (named `name` in labels and errors) inside [`Self::catch`].
    pub fn shader(&self, name: &str, source: &str) -> Result<wgpu::ShaderModule> {
        self.catch(&format!("compiling {name}"), || {
            self.device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(name),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            })
        })
    }

    /// A buffer holding `bytes` (padded to at least 16: wgpu rejects empty bindings) with
    /// `usage`, after [`Self::check_storage_size`].
    pub fn buffer_with(&self, label: &str, bytes: &[u8], usage: wgpu::BufferUsages) -> Result<wgpu::Buffer> {
        use wgpu::util::DeviceExt;
        self.check_storage_size(bytes.len() as u64, label)?;
        let mut data = bytes.to_vec();
        data.resize(data.len().max(16), 0);
        Ok(self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: &data,
            usage,
        }))
    }

    /// Errors if a `width x height` 2-D texture exceeds the device limits.
    pub fn check_texture_size(&self, width: u32, height: u32, what: &str) -> Result<()> {
        let max = self.device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 {
            return Err(Error::invalid(format!("{what}: zero-size image {width}x{height}")));
        }
        if width > max || height > max {
            return Err(Error::invalid(format!("{what}: {width}x{height} exceeds the GPU texture limit {max}")));
        }
        Ok(())
    }

    /// Errors if a storage buffer of `bytes` cannot be bound on this device.
    pub fn check_storage_size(&self, bytes: u64, what: &str) -> Result<()> {
        let l = self.device.limits();
        let max = l.max_storage_buffer_binding_size.min(l.max_buffer_size);
        if bytes > max {
            return Err(Error::invalid(format!("{what}: {bytes} bytes exceed the GPU storage buffer limit {max}")));
        }
        Ok(())
    }
}

/// Test helper shared by this crate's tests (and usable by other crates' tests): a context, or
/// `None` to let the test pass-skip when no usable adapter exists. The GPU tests are written
/// against a native backend (Vulkan: lavapipe on CI); an OpenGL-only adapter lacks storage
/// features they use and would fail them with unrelated validation errors, so it counts as
/// missing. When the environment variable `ZWARP_REQUIRE_GPU` is set to anything but `0` (CI
/// sets `1`), a missing adapter is a test failure instead: this function panics with the reason.
pub fn test_context() -> Option<GpuContext> {
    let required = std::env::var("ZWARP_REQUIRE_GPU").is_ok_and(|v| !v.is_empty() && v != "0");
    let native = GpuContext::new().and_then(|ctx| {
        if ctx.adapter.backend == format!("{:?}", wgpu::Backend::Gl) {
            Err(Error::Unavailable(format!(
                "only an OpenGL adapter is available ({}); the GPU tests need Vulkan, install mesa-vulkan-drivers for lavapipe",
                ctx.adapter
            )))
        } else {
            Ok(ctx)
        }
    });
    match native {
        Ok(ctx) => Some(ctx),
        Err(e) if required => panic!("ZWARP_REQUIRE_GPU is set but no GPU is usable: {e}"),
        Err(e) => {
            eprintln!("skipping GPU test: {e} (set ZWARP_REQUIRE_GPU=1 to make this a failure)");
            None
        }
    }
}
