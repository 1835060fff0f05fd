//! The GPU context: one adapter, device and queue, found the way wgpu's examples do
//! (`WGPU_BACKEND`, `WGPU_ADAPTER_NAME` honoured). On a machine without a GPU, Mesa's
//! lavapipe (software Vulkan) is the adapter; with none at all, [`Gpu::new`] returns `None`
//! and callers say so (tests print "skipped: no adapter").

use anyhow::Context as _;

/// 64-bit integer atomics (`atomicMin`/`atomicMax` on `u64`): requested where the adapter has
/// them, for the compute rasteriser (`render::compute::FEATURES`).
pub const INT64_ATOMICS: wgpu::Features =
    wgpu::Features::SHADER_INT64.union(wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX);

/// What results files record about the adapter.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AdapterDesc {
    /// Adapter name, e.g. `llvmpipe (LLVM 15.0.6, 256 bits)`.
    pub name: String,
    /// Backend (Vulkan, Gl, …).
    pub backend: String,
    /// Device type (Cpu, DiscreteGpu, …).
    pub device_type: String,
    /// Driver name.
    pub driver: String,
    /// Driver version string.
    pub driver_info: String,
}

/// An opened device.
pub struct Gpu {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// What it is.
    pub adapter: AdapterDesc,
    /// Whether timestamp queries are available (GPU time per frame).
    pub timestamps: bool,
    /// The device's limits (the adapter's best).
    pub limits: wgpu::Limits,
    /// The instance it came from (a window's surface is made from it).
    pub instance: wgpu::Instance,
    /// The adapter (a surface's capabilities are asked of it).
    pub handle: wgpu::Adapter,
}

impl Gpu {
    /// Opens the default adapter, or `Ok(None)` when the machine has none.
    pub fn new() -> anyhow::Result<Option<Gpu>> {
        Self::with_limits(|_| {})
    }

    /// [`Gpu::new`] with the device's limits changed by `adjust` from the adapter's best
    /// (lowered, e.g. a small storage binding limit, to test how the renderer copes with a
    /// smaller GPU; raising one past the adapter's fails).
    pub fn with_limits(adjust: impl FnOnce(&mut wgpu::Limits)) -> anyhow::Result<Option<Gpu>> {
        Self::from_instance(
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env()),
            adjust,
        )
    }

    /// The default adapter of `instance` (the viewer's has the window system's display
    /// handle), or `Ok(None)` when it has none.
    pub fn from_instance(
        instance: wgpu::Instance,
        adjust: impl FnOnce(&mut wgpu::Limits),
    ) -> anyhow::Result<Option<Gpu>> {
        let Ok(adapter) = pollster::block_on(wgpu::util::initialize_adapter_from_env_or_default(
            &instance, None,
        )) else {
            return Ok(None);
        };
        let info = adapter.get_info();
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let mut features = wgpu::Features::empty();
        if timestamps {
            features |= wgpu::Features::TIMESTAMP_QUERY;
        }
        // 64-bit atomics for the compute rasteriser, where the adapter has them.
        let int64 = INT64_ATOMICS;
        if adapter.features().contains(int64) {
            features |= int64;
        }
        let mut limits = adapter.limits();
        adjust(&mut limits);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("splatbench"),
            required_features: features,
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .with_context(|| format!("opening a device on adapter '{}'", info.name))?;
        Ok(Some(Gpu {
            device,
            queue,
            adapter: AdapterDesc {
                name: info.name,
                backend: format!("{:?}", info.backend),
                device_type: format!("{:?}", info.device_type),
                driver: info.driver,
                driver_info: info.driver_info,
            },
            timestamps,
            limits,
            instance,
            handle: adapter,
        }))
    }

    /// Waits until all submitted work is done.
    pub fn wait(&self) -> anyhow::Result<()> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .context("waiting for the GPU")?;
        Ok(())
    }
}

/// Environment variable that turns "no adapter" in tests from a loud skip into a failure.
/// CI sets it: lavapipe is installed there, so a missing adapter is a broken machine.
pub const REQUIRE_GPU_ENV: &str = "SPLATBENCH_REQUIRE_GPU";

/// For tests: the GPU, or `None` after printing a loud "skipped: no adapter" line — unless
/// [`REQUIRE_GPU_ENV`] is `1`, in which case a missing adapter fails the test.
pub fn gpu_for_test(test: &str) -> Option<Gpu> {
    gpu_for_test_with_limits(test, |_| {})
}

/// [`gpu_for_test`] on a device whose limits `adjust` lowers ([`Gpu::with_limits`]).
pub fn gpu_for_test_with_limits(test: &str, adjust: impl FnOnce(&mut wgpu::Limits)) -> Option<Gpu> {
    match Gpu::with_limits(adjust) {
        Ok(Some(g)) => Some(g),
        other => {
            let why = match other {
                Err(e) => format!("{e:#}"),
                _ => "no adapter".into(),
            };
            if std::env::var(REQUIRE_GPU_ENV).as_deref() == Ok("1") {
                panic!("{test}: {why}, and {REQUIRE_GPU_ENV}=1 requires one");
            }
            eprintln!("\n*** {test}: skipped: no adapter ({why}) ***\n");
            None
        }
    }
}
