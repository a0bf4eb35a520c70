//! Instance, physical-device choice, logical device and the validation messenger.

mod caps;

use std::ffi::{c_void, CStr};
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::Mutex;

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};

use crate::error::{Error, Result, VkContext};

use caps::query_caps;
pub use caps::{list_devices, Caps, CoopMatrixShape};

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// Device extensions Relit cannot run without.
const REQUIRED_EXTENSIONS: &[&CStr] = &[
    ash::khr::acceleration_structure::NAME,
    ash::khr::ray_query::NAME,
    ash::khr::deferred_host_operations::NAME,
    ash::khr::push_descriptor::NAME,
];

/// Which physical device to use: `--device` / `RELIT_DEVICE` take an index or part of a name.
#[derive(Clone, Debug, Default)]
pub enum DeviceChoice {
    #[default]
    Auto,
    Index(usize),
    Name(String),
}

impl DeviceChoice {
    pub fn parse(s: &str) -> Self {
        match s.trim().parse::<usize>() {
            Ok(i) => DeviceChoice::Index(i),
            Err(_) if s.trim().is_empty() => DeviceChoice::Auto,
            Err(_) => DeviceChoice::Name(s.trim().to_string()),
        }
    }

    /// `RELIT_DEVICE` when set, otherwise automatic.
    pub fn from_env() -> Self {
        std::env::var("RELIT_DEVICE")
            .map(|s| Self::parse(&s))
            .unwrap_or_default()
    }
}

#[derive(Clone, Debug)]
pub struct GpuOptions {
    pub device: DeviceChoice,
    /// Turn on the Khronos validation layer (errors if it is not installed).
    pub validation: bool,
    /// Extra instance extensions (a window system's surface extensions, for `relit view`).
    pub instance_extensions: Vec<&'static CStr>,
    /// Enable VK_KHR_swapchain (presenting to a window).
    pub swapchain: bool,
}

impl Default for GpuOptions {
    /// Validation follows `RELIT_VALIDATE=1`; the device follows `RELIT_DEVICE`.
    fn default() -> Self {
        GpuOptions {
            device: DeviceChoice::from_env(),
            validation: std::env::var("RELIT_VALIDATE").is_ok_and(|v| v == "1"),
            instance_extensions: Vec::new(),
            swapchain: false,
        }
    }
}

/// The Vulkan device and everything that lives as long as it. Resources hold an `Arc<Gpu>`.
pub struct Gpu {
    pub entry: ash::Entry,
    pub instance: ash::Instance,
    pub pdevice: vk::PhysicalDevice,
    pub device: ash::Device,
    pub queue: vk::Queue,
    pub queue_family: u32,
    pub caps: Caps,
    pub accel: ash::khr::acceleration_structure::Device,
    pub push_desc: ash::khr::push_descriptor::Device,
    pub(crate) allocator: Mutex<Option<Allocator>>,
    pub(crate) cmd_pool: Mutex<vk::CommandPool>,
    debug: Option<Messenger>,
    /// Counts validation errors; boxed so its address (the messenger's user data) is stable.
    validation_errors: Box<AtomicU32>,
    validation: bool,
    /// Treat all memory as device-only, so uploads and readbacks go through staging buffers
    /// (lavapipe has a single host-visible type; tests set this to exercise that path).
    force_staging: AtomicBool,
}

unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _ty: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    let msg = if data.is_null() || (*data).p_message.is_null() {
        "(no message)".into()
    } else {
        CStr::from_ptr((*data).p_message).to_string_lossy()
    };
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        if !user.is_null() {
            (*(user as *const AtomicU32)).fetch_add(1, Ordering::SeqCst);
        }
        eprintln!("[vulkan validation error] {msg}");
    } else {
        eprintln!("[vulkan validation warning] {msg}");
    }
    vk::FALSE
}

/// Is the Khronos validation layer installed?
pub fn validation_layer_available(entry: &ash::Entry) -> bool {
    unsafe { entry.enumerate_instance_layer_properties() }
        .map(|layers| {
            layers
                .iter()
                .any(|l| l.layer_name_as_c_str() == Ok(VALIDATION_LAYER))
        })
        .unwrap_or(false)
}

pub fn load_entry() -> Result<ash::Entry> {
    unsafe { ash::Entry::load() }.map_err(|e| {
        Error::Device(format!(
            "cannot load the Vulkan loader (libvulkan.so.1): {e}; install libvulkan1 and a driver \
             (tools/setup.sh installs Mesa's lavapipe)"
        ))
    })
}

fn type_rank(t: vk::PhysicalDeviceType) -> u32 {
    match t {
        vk::PhysicalDeviceType::DISCRETE_GPU => 0,
        vk::PhysicalDeviceType::INTEGRATED_GPU => 1,
        vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
        vk::PhysicalDeviceType::CPU => 3,
        _ => 4,
    }
}

fn create_instance(
    entry: &ash::Entry,
    validation: bool,
    extra: &[&'static CStr],
) -> Result<ash::Instance> {
    let app = vk::ApplicationInfo::default()
        .application_name(c"relit")
        .engine_name(c"relit")
        .api_version(vk::API_VERSION_1_3);
    let layers = if validation {
        vec![VALIDATION_LAYER.as_ptr()]
    } else {
        vec![]
    };
    let mut exts: Vec<*const std::ffi::c_char> = extra.iter().map(|e| e.as_ptr()).collect();
    if validation {
        exts.push(ash::ext::debug_utils::NAME.as_ptr());
    }
    let info = vk::InstanceCreateInfo::default()
        .application_info(&app)
        .enabled_layer_names(&layers)
        .enabled_extension_names(&exts);
    unsafe { entry.create_instance(&info, None) }.vk("create instance")
}

/// The validation messenger and the extension functions that destroy it.
type Messenger = (ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT);

/// Routes validation errors and warnings to `debug_callback`, which counts errors in `errors`.
fn create_messenger(
    entry: &ash::Entry,
    instance: &ash::Instance,
    errors: &AtomicU32,
) -> Result<Messenger> {
    let du = ash::ext::debug_utils::Instance::new(entry, instance);
    let info = vk::DebugUtilsMessengerCreateInfoEXT::default()
        .message_severity(
            vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
                | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
        )
        .message_type(
            vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE
                | vk::DebugUtilsMessageTypeFlagsEXT::GENERAL,
        )
        .pfn_user_callback(Some(debug_callback))
        .user_data(errors as *const AtomicU32 as *mut c_void);
    let m = unsafe { du.create_debug_utils_messenger(&info, None) }.vk("create debug messenger")?;
    Ok((du, m))
}

/// Destroys the messenger and the instance: `Gpu::new` failed after creating them.
fn tear_down(instance: &ash::Instance, debug: &Option<Messenger>) {
    unsafe {
        if let Some((du, m)) = debug {
            du.destroy_debug_utils_messenger(*m, None);
        }
        instance.destroy_instance(None);
    }
}

/// The device `choice` names, or the best one that has everything; errors say what is missing.
fn pick_device(
    entry: &ash::Entry,
    instance: &ash::Instance,
    choice: &DeviceChoice,
) -> Result<(vk::PhysicalDevice, Caps)> {
    let pds = unsafe { instance.enumerate_physical_devices() }.vk("enumerate devices")?;
    if pds.is_empty() {
        return Err(Error::Device(
            "no Vulkan device found; install Mesa's lavapipe (tools/setup.sh)".into(),
        ));
    }
    let mut all = Vec::new();
    for &pd in &pds {
        all.push((pd, query_caps(entry, instance, pd)?));
    }
    let describe = |c: &Caps| {
        let m = c.missing();
        if m.is_empty() {
            format!("{}: has everything", c.name)
        } else {
            format!("{}: missing {}", c.name, m.join(", "))
        }
    };
    match chosen_device(&all, choice)? {
        Some((pd, caps)) if caps.missing().is_empty() => Ok((pd, caps)),
        Some((_, caps)) => Err(Error::Device(format!(
            "device \"{}\" cannot run Relit; missing: {}",
            caps.name,
            caps.missing().join(", ")
        ))),
        None => Err(Error::Device(format!(
            "no Vulkan device has what Relit needs ({}); on Debian 12 install \
             mesa-vulkan-drivers >= 24.1 from bookworm-backports (tools/setup.sh)",
            all.iter()
                .map(|(_, c)| describe(c))
                .collect::<Vec<_>>()
                .join("; ")
        ))),
    }
}

/// The device `choice` names among `all` (an error when none matches), or for `Auto` the most
/// capable type that has everything (`None` when no device does).
fn chosen_device(
    all: &[(vk::PhysicalDevice, Caps)],
    choice: &DeviceChoice,
) -> Result<Option<(vk::PhysicalDevice, Caps)>> {
    Ok(match choice {
        DeviceChoice::Index(i) => Some(all.get(*i).cloned().ok_or_else(|| {
            Error::Device(format!(
                "device index {i} out of range: {} device(s) present",
                all.len()
            ))
        })?),
        DeviceChoice::Name(n) => Some(
            all.iter()
                .find(|(_, c)| c.name.to_lowercase().contains(&n.to_lowercase()))
                .cloned()
                .ok_or_else(|| {
                    Error::Device(format!(
                        "no device name contains \"{n}\"; present: {}",
                        all.iter()
                            .map(|(_, c)| c.name.clone())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ))
                })?,
        ),
        DeviceChoice::Auto => all
            .iter()
            .filter(|(_, c)| c.missing().is_empty())
            .min_by_key(|(_, c)| type_rank(c.device_type))
            .cloned(),
    })
}

/// The first queue family that does graphics and compute (family 0 when none does).
fn graphics_compute_family(instance: &ash::Instance, pdevice: vk::PhysicalDevice) -> u32 {
    let qf = unsafe { instance.get_physical_device_queue_family_properties(pdevice) };
    qf.iter()
        .position(|q| {
            q.queue_flags
                .contains(vk::QueueFlags::COMPUTE | vk::QueueFlags::GRAPHICS)
        })
        .unwrap_or(0) as u32
}

/// The logical device with the required extensions and features, cooperative matrices when
/// the device has them, and the swapchain when asked for.
fn create_device(
    instance: &ash::Instance,
    pdevice: vk::PhysicalDevice,
    caps: &Caps,
    queue_family: u32,
    swapchain: bool,
) -> std::result::Result<ash::Device, vk::Result> {
    let mut ext_names: Vec<*const std::ffi::c_char> =
        REQUIRED_EXTENSIONS.iter().map(|e| e.as_ptr()).collect();
    if !caps.coop_matrix.is_empty() {
        ext_names.push(ash::khr::cooperative_matrix::NAME.as_ptr());
    }
    if swapchain {
        ext_names.push(ash::khr::swapchain::NAME.as_ptr());
    }
    let mut f11 = vk::PhysicalDeviceVulkan11Features::default().storage_buffer16_bit_access(true);
    let mut f12 = vk::PhysicalDeviceVulkan12Features::default()
        .buffer_device_address(true)
        .shader_float16(true)
        .scalar_block_layout(true)
        .host_query_reset(true)
        .vulkan_memory_model(caps.vulkan_memory_model);
    // maintenance4 (mandatory in 1.3): the `*_cm.comp` kernels size their workgroup to the
    // subgroup with a specialization constant (LocalSizeId).
    let mut f13 = vk::PhysicalDeviceVulkan13Features::default()
        .synchronization2(true)
        .dynamic_rendering(true)
        .maintenance4(true);
    let mut fas =
        vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default().acceleration_structure(true);
    let mut frq = vk::PhysicalDeviceRayQueryFeaturesKHR::default().ray_query(true);
    let mut fcm =
        vk::PhysicalDeviceCooperativeMatrixFeaturesKHR::default().cooperative_matrix(true);
    let base = vk::PhysicalDeviceFeatures::default()
        .texture_compression_bc(caps.bc_compression)
        .shader_int64(false);
    let prio = [1.0f32];
    let qinfo = [vk::DeviceQueueCreateInfo::default()
        .queue_family_index(queue_family)
        .queue_priorities(&prio)];
    let mut dinfo = vk::DeviceCreateInfo::default()
        .queue_create_infos(&qinfo)
        .enabled_extension_names(&ext_names)
        .enabled_features(&base)
        .push_next(&mut f11)
        .push_next(&mut f12)
        .push_next(&mut f13)
        .push_next(&mut fas)
        .push_next(&mut frq);
    if !caps.coop_matrix.is_empty() {
        dinfo = dinfo.push_next(&mut fcm);
    }
    unsafe { instance.create_device(pdevice, &dinfo, None) }
}

/// A command pool on `queue_family` whose buffers can be reset one by one.
fn create_cmd_pool(device: &ash::Device, queue_family: u32) -> Result<vk::CommandPool> {
    unsafe {
        device.create_command_pool(
            &vk::CommandPoolCreateInfo::default()
                .queue_family_index(queue_family)
                .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
            None,
        )
    }
    .vk("create command pool")
}

impl Gpu {
    pub fn new(opts: &GpuOptions) -> Result<std::sync::Arc<Gpu>> {
        let entry = load_entry()?;
        if opts.validation && !validation_layer_available(&entry) {
            return Err(Error::Device(
                "validation requested but VK_LAYER_KHRONOS_validation is not installed \
                 (Debian: apt-get install vulkan-validationlayers)"
                    .into(),
            ));
        }
        let instance = create_instance(&entry, opts.validation, &opts.instance_extensions)?;
        let validation_errors = Box::new(AtomicU32::new(0));
        let debug = if opts.validation {
            Some(create_messenger(&entry, &instance, &validation_errors)?)
        } else {
            None
        };

        // From here on, failures must tear down what exists.
        let (pdevice, caps) = match pick_device(&entry, &instance, &opts.device) {
            Ok(p) => p,
            Err(e) => {
                tear_down(&instance, &debug);
                return Err(e);
            }
        };
        let queue_family = graphics_compute_family(&instance, pdevice);
        let device = match create_device(&instance, pdevice, &caps, queue_family, opts.swapchain) {
            Ok(d) => d,
            Err(e) => {
                tear_down(&instance, &debug);
                return Err(Error::Vk {
                    what: "create device",
                    result: e,
                });
            }
        };
        let queue = unsafe { device.get_device_queue(queue_family, 0) };
        let accel = ash::khr::acceleration_structure::Device::new(&instance, &device);
        let push_desc = ash::khr::push_descriptor::Device::new(&instance, &device);

        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.clone(),
            device: device.clone(),
            physical_device: pdevice,
            debug_settings: Default::default(),
            buffer_device_address: true,
            allocation_sizes: Default::default(),
        })?;
        let cmd_pool = create_cmd_pool(&device, queue_family)?;

        Ok(std::sync::Arc::new(Gpu {
            entry,
            instance,
            pdevice,
            device,
            queue,
            queue_family,
            caps,
            accel,
            push_desc,
            allocator: Mutex::new(Some(allocator)),
            cmd_pool: Mutex::new(cmd_pool),
            debug,
            validation_errors,
            validation: opts.validation,
            force_staging: AtomicBool::new(false),
        }))
    }

    /// Validation errors reported so far (always 0 without validation).
    pub fn validation_errors(&self) -> u32 {
        self.validation_errors.load(Ordering::SeqCst)
    }

    pub fn validation_enabled(&self) -> bool {
        self.validation
    }

    pub fn set_force_staging(&self, on: bool) {
        self.force_staging.store(on, Ordering::SeqCst);
    }

    pub fn force_staging(&self) -> bool {
        self.force_staging.load(Ordering::SeqCst)
    }
}

impl Drop for Gpu {
    fn drop(&mut self) {
        unsafe {
            let _ = self.device.device_wait_idle();
            // The allocator frees its memory blocks; it must go before the device.
            drop(self.allocator.lock().map(|mut a| a.take()));
            if let Ok(pool) = self.cmd_pool.lock() {
                self.device.destroy_command_pool(*pool, None);
            }
            self.device.destroy_device(None);
            if let Some((du, m)) = self.debug.take() {
                du.destroy_debug_utils_messenger(m, None);
            }
            self.instance.destroy_instance(None);
        }
    }
}
