//! A headless wgpu device: prefers a real GPU, falls back to a software adapter (Mesa's
//! lavapipe), and says which one it got.

use crate::gpu::Setting;
use crate::gpu::pieces::Uploader;

/// Which adapter to ask for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AdapterChoice {
    /// A real GPU if there is one, else a software adapter.
    #[default]
    Auto,
    /// Only a software (CPU) adapter, e.g. for reproducible tests.
    Software,
}

impl AdapterChoice {
    /// `TETVR_ADAPTER=software` (or `cpu`) forces the software adapter; anything else is auto.
    pub fn from_env() -> Self {
        match std::env::var("TETVR_ADAPTER").as_deref() {
            Ok("software") | Ok("cpu") => Self::Software,
            _ => Self::Auto,
        }
    }
}

/// Why the GPU could not be opened or could not do what a renderer asked of it.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter (or no software adapter, when one was asked for) was found: no Vulkan, Metal
    /// or DX12 driver is installed.
    #[error(
        "no GPU adapter found{detail}. tetvr needs Vulkan (or Metal/DX12). Without a GPU, install \
         Mesa's software Vulkan driver: `apt-get install mesa-vulkan-drivers libvulkan1` \
         (Debian/Ubuntu), or render on the CPU with --mode raycast-cpu (or the exact \
         --mode reference)"
    )]
    NoAdapter {
        /// Empty, or why the search was narrowed (`TETVR_ADAPTER=software`).
        detail: String,
    },
    /// The adapter was found but refused a device with its own limits and the optional
    /// features tetvr asks for (a driver problem: update or change the driver).
    #[error("the adapter '{adapter}' refused a device: {source}")]
    Device {
        /// The adapter's name.
        adapter: String,
        /// wgpu's reason.
        source: wgpu::RequestDeviceError,
    },
    /// A setting needs a feature or limit the adapter lacks (32-bit float slices without
    /// `FLOAT32_BLENDABLE`, or not one colour target of the slice format): change that setting
    /// or the adapter.
    #[error("the adapter '{adapter}' lacks {what}, which {needed_by} needs")]
    Missing {
        /// The adapter's name.
        adapter: String,
        /// The missing feature or limit, with the adapter's value.
        what: String,
        /// The setting that needs it.
        needed_by: &'static str,
    },
    /// The adapter offers less of a limit than a setting's shaders need
    /// ([`crate::gpu::limits::ShaderNeeds`]): the nearest settings that the adapter runs
    /// ([`crate::gpu::limits::Ask::nearest`]), another adapter, or the CPU must render.
    #[error(
        "the adapter '{adapter}' offers {limit} = {has}, but {needed_by} needs {needs}: {}render \
         on an adapter that offers at least {needs} (another GPU or driver), or on the CPU with \
         --mode raycast-cpu",
        use_instead(.instead, *.no_setting_of)
    )]
    Limit {
        /// The adapter's name (a boxed `str`: this error is in every renderer's `Result`,
        /// which clippy keeps under 128 bytes).
        adapter: Box<str>,
        /// The limit's name in [`wgpu::Limits`], e.g. `max_storage_buffers_per_shader_stage`.
        limit: &'static str,
        /// The adapter's value.
        has: u32,
        /// The value the setting's shaders need.
        needs: u32,
        /// The setting, e.g. `the shells mode's compute sampler`.
        needed_by: &'static str,
        /// The changes to make instead that the adapter's limits run, each every flag to
        /// change together as the CLI spells them (e.g. `--sampler raster --binning cpu`),
        /// best first; empty where there is none.
        instead: Vec<crate::gpu::limits::Change>,
        /// The request where no setting of its mode ([`crate::gpu::Ask::mode`]) runs on
        /// these limits: `instead` then names other modes; `None` where `instead` keeps the
        /// mode.
        no_setting_of: Option<crate::gpu::Ask>,
    },
    /// The adapter ran out of memory for work that tetvr gave it: a mesh's GPU buffers, a
    /// renderer's build, or a frame's per-frame buffers and image targets. Its per-buffer
    /// limits are not the cause (arrays over them are split into several buffers, and a
    /// frame's image is checked against them first): the work needs more memory than the
    /// adapter has free. Caught by wgpu's error scopes (uncaught, wgpu panics).
    #[error(
        "the adapter '{adapter}' ran out of memory for {during}; {smaller}, use an adapter \
         with more memory, or render on the CPU with --mode raycast-cpu"
    )]
    OutOfMemory {
        /// The adapter's name.
        adapter: String,
        /// The work that did not fit, e.g. `a shells frame` or `4096 bytes of raycast links`.
        during: String,
        /// What makes that work smaller, e.g. `render a smaller image (--size) or a smaller
        /// mesh`.
        smaller: &'static str,
    },
    /// wgpu refused work a renderer gave the device, a frame or the renderer's build (a
    /// validation or internal error, which wgpu's default handler turns into a panic): the
    /// device was lost or destroyed (a driver reset, [`wgpu::Device::destroy`]; or its
    /// readback fails: [`GpuError::Readback`]), [`GpuContext::limits`] were declared above
    /// what the device was opened with, or tetvr has a bug.
    #[error(
        "the GPU refused {during}: {reason}. If the device was lost or destroyed, open a new \
         GPU context and build the renderer again; if the GpuContext's limits were raised above \
         the device's, keep them at most the device's; otherwise this is a bug in tetvr, please \
         report it (render on the CPU with --mode raycast-cpu meanwhile)"
    )]
    Failed {
        /// The work that failed, e.g. `a shells frame` or `building the shells renderer`.
        during: &'static str,
        /// wgpu's error.
        reason: String,
    },
    /// Waiting for submitted GPU work failed (device lost or a timeout).
    #[error("GPU work failed: {0}")]
    Poll(#[from] wgpu::PollError),
    /// Mapping a result buffer for reading failed: the device was lost (a driver reset, or
    /// GPU memory ran out).
    #[error(
        "reading {what} back from the GPU failed ({reason}); the device was probably lost: \
         update or restart the GPU driver, or render a smaller mesh or image if GPU memory ran \
         out"
    )]
    Readback {
        /// The buffer, e.g. `the tile flags`.
        what: &'static str,
        /// wgpu's reason.
        reason: String,
    },
}

/// The first remedy of [`GpuError::Limit`]: the changes to make `instead`, or nothing; said to
/// be other modes where no setting of `no_setting_of`'s mode runs.
fn use_instead(
    instead: &[crate::gpu::limits::Change],
    no_setting_of: Option<crate::gpu::Ask>,
) -> String {
    let none = no_setting_of.map_or_else(String::new, |ask| {
        let sep = if instead.is_empty() { ":" } else { ";" };
        format!("no setting of {} runs on these limits{sep} ", ask.mode())
    });
    let changes: Vec<String> = instead.iter().map(|c| c.join(" ")).collect();
    let remedy = match changes.as_slice() {
        [] => String::new(),
        [one] => format!("use {one} instead, which these limits run; or "),
        more => format!(
            "use {} instead (these limits run each); or ",
            more.join(" or ")
        ),
    };
    none + &remedy
}

/// The optional features tetvr uses where the adapter has them: blendable 32-bit float targets
/// (shells) and timestamps (stage timings).
const WANTED_FEATURES: wgpu::Features = wgpu::Features::FLOAT32_BLENDABLE
    .union(wgpu::Features::TIMESTAMP_QUERY)
    .union(wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS);

/// A device and queue with the adapter's full limits, plus what tetvr needs to know of it.
///
/// The fields are public so that a caller can share its own device with tetvr, or declare
/// lower limits than the adapter's (the tests lower `limits.max_storage_buffer_binding_size`
/// and `limits.max_buffer_size` to exercise chunked buffers on small meshes): the renderers
/// size everything from `limits` and `features`, never from the adapter directly. A clone
/// shares the device (wgpu's handles are reference counted).
#[derive(Clone)]
pub struct GpuContext {
    /// The adapter the device was opened on.
    pub adapter: wgpu::Adapter,
    /// The device every renderer records on.
    pub device: wgpu::Device,
    /// The device's queue.
    pub queue: wgpu::Queue,
    /// The adapter's name, type, backend and driver (see [`GpuContext::summary`]).
    pub info: wgpu::AdapterInfo,
    /// The limits renderers plan for: binding and buffer sizes, colour targets. Must not exceed
    /// what the device was opened with.
    pub limits: wgpu::Limits,
    /// The optional features the device has: `FLOAT32_BLENDABLE` (32-bit float slices in the
    /// shells mode) and `TIMESTAMP_QUERY` (GPU stage timings); others are unused.
    pub features: wgpu::Features,
}

impl GpuContext {
    /// Uploads to this device, in pieces ([`Uploader`]).
    pub(crate) fn uploader(&self) -> Uploader<'_> {
        Uploader::new(&self.device, &self.queue)
    }

    /// Opens a headless device on [`Self::pick_adapter`]'s adapter, as
    /// [`Self::device_descriptor`] asks.
    pub fn new(choice: AdapterChoice) -> Result<Self, GpuError> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        if std::env::var_os("WGPU_BACKEND").is_none() {
            desc.backends = wgpu::Backends::PRIMARY;
        }
        let instance = wgpu::Instance::new(desc);
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
        let adapter = Self::pick_adapter(adapters, choice)?;
        let info = adapter.get_info();
        let (device, queue) =
            pollster::block_on(adapter.request_device(&Self::device_descriptor(&adapter)))
                .map_err(|source| GpuError::Device {
                    adapter: info.name.clone(),
                    source,
                })?;
        Ok(Self::from_device(adapter, device, queue))
    }

    /// The adapter tetvr prefers among `adapters`: discrete, then integrated, then virtual or
    /// other GPUs, then software ones; only software ones for [`AdapterChoice::Software`].
    pub fn pick_adapter(
        adapters: impl IntoIterator<Item = wgpu::Adapter>,
        choice: AdapterChoice,
    ) -> Result<wgpu::Adapter, GpuError> {
        let is_software = |a: &wgpu::Adapter| a.get_info().device_type == wgpu::DeviceType::Cpu;
        let rank = |a: &wgpu::Adapter| match a.get_info().device_type {
            wgpu::DeviceType::DiscreteGpu => 0,
            wgpu::DeviceType::IntegratedGpu => 1,
            wgpu::DeviceType::VirtualGpu | wgpu::DeviceType::Other => 2,
            wgpu::DeviceType::Cpu => 3,
        };
        adapters
            .into_iter()
            .filter(|a| choice == AdapterChoice::Auto || is_software(a))
            .min_by_key(rank)
            .ok_or_else(|| GpuError::NoAdapter {
                detail: match choice {
                    AdapterChoice::Auto => String::new(),
                    AdapterChoice::Software => {
                        " (a software adapter was asked for: TETVR_ADAPTER=software)".into()
                    }
                },
            })
    }

    /// The device tetvr asks `adapter` for: its own limits (software adapters offer 8 colour
    /// targets and 128 bytes per sample, more than the WebGPU defaults) and the optional
    /// features tetvr uses where present. A front end that opens the device itself (the
    /// viewer, whose window surface shares it) asks with this, then calls [`Self::from_device`].
    pub fn device_descriptor(adapter: &wgpu::Adapter) -> wgpu::DeviceDescriptor<'static> {
        wgpu::DeviceDescriptor {
            label: Some("tetvr"),
            required_features: adapter.features() & WANTED_FEATURES,
            required_limits: adapter.limits(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }
    }

    /// Wraps a device opened elsewhere (e.g. by a window's surface setup), planning for the
    /// limits and the tetvr features it was opened with.
    pub fn from_device(adapter: wgpu::Adapter, device: wgpu::Device, queue: wgpu::Queue) -> Self {
        Self {
            info: adapter.get_info(),
            limits: device.limits(),
            features: device.features() & WANTED_FEATURES,
            adapter,
            device,
            queue,
        }
    }

    /// Whether this is a software rasterizer (lavapipe and the like).
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// A one-line description: name, type, backend, driver.
    pub fn summary(&self) -> String {
        let i = &self.info;
        format!(
            "{} ({:?}, {:?}, driver {} {})",
            i.name, i.device_type, i.backend, i.driver, i.driver_info
        )
    }

    /// Every setting ([`Setting::ALL`]) with what this adapter's limits say of it: `Ok` where
    /// they run its stages, else the error that refuses it (for `tetvr gpu-info`).
    pub fn settings(&self) -> Vec<(Setting, Result<(), GpuError>)> {
        (Setting::ALL.into_iter())
            .map(|s| (s, self.check_setting(s)))
            .collect()
    }

    /// A multi-line report for `tetvr gpu-info`: the adapter, the limits and features the
    /// renderers depend on, and a table of every GPU setting ([`Self::settings`]): `yes` where
    /// its limits run it, else `no` and why.
    pub fn report(&self) -> String {
        let l = &self.limits;
        let yes = |f| {
            if self.features.contains(f) {
                "yes"
            } else {
                "no"
            }
        };
        let timestamps = match (
            self.features.contains(wgpu::Features::TIMESTAMP_QUERY),
            self.is_software(),
        ) {
            (true, true) => {
                "yes, not used for stage timings (they mis-time compute passes on \
                             this software adapter)"
            }
            (true, false) => "yes",
            (false, _) => "no",
        };
        let settings: String = (self.settings().into_iter())
            .map(|(s, runs)| match runs {
                Ok(()) => format!("\n  {}: yes", s.name()),
                Err(e) => format!("\n  {}: no: {e}", s.name()),
            })
            .collect();
        format!(
            "adapter: {}\n\
             software adapter: {}\n\
             max colour attachments: {}\n\
             max colour attachment bytes per sample: {}\n\
             max storage buffer binding: {} bytes\n\
             max buffer size: {} bytes\n\
             max texture size 2D: {}\n\
             max compute workgroups per dimension: {}\n\
             max storage buffers per shader stage: {}\n\
             blendable 32-bit float targets (FLOAT32_BLENDABLE): {}\n\
             GPU timestamps (TIMESTAMP_QUERY): {}\n\
             settings these limits run:{}",
            self.summary(),
            if self.is_software() { "yes" } else { "no" },
            l.max_color_attachments,
            l.max_color_attachment_bytes_per_sample,
            l.max_storage_buffer_binding_size,
            l.max_buffer_size,
            l.max_texture_dimension_2d,
            l.max_compute_workgroups_per_dimension,
            l.max_storage_buffers_per_shader_stage,
            yes(wgpu::Features::FLOAT32_BLENDABLE),
            timestamps,
            settings,
        )
    }
}
