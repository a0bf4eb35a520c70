//! Instance, physical-device choice, logical device and the validation messenger.

use std::ffi::{c_void, CStr};
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::Mutex;

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};

use crate::error::{Error, Result, VkContext};

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

/// A cooperative-matrix shape the device offers (VK_KHR_cooperative_matrix).
#[derive(Clone, Debug)]
pub struct CoopMatrixShape {
    pub m: u32,
    pub n: u32,
    pub k: u32,
    pub a: vk::ComponentTypeKHR,
    pub b: vk::ComponentTypeKHR,
    pub c: vk::ComponentTypeKHR,
    pub result: vk::ComponentTypeKHR,
    pub scope: vk::ScopeKHR,
}

/// What the chosen device can do: required features (all present once a `Gpu` exists),
/// optional ones, and the limits the engine sizes its work by.
#[derive(Clone, Debug)]
pub struct Caps {
    pub name: String,
    pub device_type: vk::PhysicalDeviceType,
    pub api_version: u32,
    pub driver_name: String,
    pub driver_info: String,
    pub required: Vec<(&'static str, bool)>,
    pub bc_compression: bool,
    pub bc6h_sampled_linear: bool,
    /// The `vulkanMemoryModel` feature: the cooperative-matrix modules declare its capability.
    pub vulkan_memory_model: bool,
    pub coop_matrix: Vec<CoopMatrixShape>,
    pub subgroup_size: u32,
    /// Compute shaders may use subgroupBroadcast (the ballot subgroup operations).
    pub subgroup_broadcast: bool,
    pub timestamp_period_ns: f32,
    pub timestamp_valid_bits: u32,
    pub max_storage_buffer_range: u32,
    pub max_image_dimension_2d: u32,
    pub max_image_array_layers: u32,
    pub max_push_constants_size: u32,
    pub max_compute_workgroup_invocations: u32,
    pub max_compute_shared_memory: u32,
    pub min_as_scratch_alignment: u32,
    pub max_primitive_count: u64,
    pub memory_types: Vec<(vk::MemoryPropertyFlags, u32)>,
}

impl Caps {
    pub fn missing(&self) -> Vec<&'static str> {
        self.required
            .iter()
            .filter(|(_, ok)| !ok)
            .map(|(n, _)| *n)
            .collect()
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
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
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

fn cstr_field(bytes: &[std::ffi::c_char]) -> String {
    let bytes: Vec<u8> = bytes
        .iter()
        .take_while(|&&c| c != 0)
        .map(|&c| c as u8)
        .collect();
    String::from_utf8_lossy(&bytes).into_owned()
}

/// Reads the capabilities of one physical device.
fn query_caps(
    entry: &ash::Entry,
    instance: &ash::Instance,
    pd: vk::PhysicalDevice,
) -> Result<Caps> {
    unsafe {
        let exts = instance
            .enumerate_device_extension_properties(pd)
            .vk("enumerate device extensions")?;
        let has_ext = |name: &CStr| exts.iter().any(|e| e.extension_name_as_c_str() == Ok(name));

        let mut f11 = vk::PhysicalDeviceVulkan11Features::default();
        let mut f12 = vk::PhysicalDeviceVulkan12Features::default();
        let mut f13 = vk::PhysicalDeviceVulkan13Features::default();
        let mut fas = vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default();
        let mut frq = vk::PhysicalDeviceRayQueryFeaturesKHR::default();
        let has_as = has_ext(ash::khr::acceleration_structure::NAME);
        let has_rq = has_ext(ash::khr::ray_query::NAME);
        let mut f2 = vk::PhysicalDeviceFeatures2::default()
            .push_next(&mut f11)
            .push_next(&mut f12)
            .push_next(&mut f13);
        if has_as {
            f2 = f2.push_next(&mut fas);
        }
        if has_rq {
            f2 = f2.push_next(&mut frq);
        }
        instance.get_physical_device_features2(pd, &mut f2);
        let base = f2.features;

        let mut pas = vk::PhysicalDeviceAccelerationStructurePropertiesKHR::default();
        let mut p11 = vk::PhysicalDeviceVulkan11Properties::default();
        let mut drv = vk::PhysicalDeviceDriverProperties::default();
        let mut p2 = vk::PhysicalDeviceProperties2::default()
            .push_next(&mut p11)
            .push_next(&mut drv);
        if has_as {
            p2 = p2.push_next(&mut pas);
        }
        instance.get_physical_device_properties2(pd, &mut p2);
        let props = p2.properties;
        let limits = props.limits;

        let qf = instance.get_physical_device_queue_family_properties(pd);
        let ts_bits = qf
            .iter()
            .find(|q| {
                q.queue_flags
                    .contains(vk::QueueFlags::COMPUTE | vk::QueueFlags::GRAPHICS)
            })
            .map(|q| q.timestamp_valid_bits)
            .unwrap_or(0);

        let required = vec![
            ("Vulkan 1.3", props.api_version >= vk::API_VERSION_1_3),
            (
                "VK_KHR_acceleration_structure",
                has_as && fas.acceleration_structure == vk::TRUE,
            ),
            (
                "VK_KHR_ray_query (ray query)",
                has_rq && frq.ray_query == vk::TRUE,
            ),
            (
                "VK_KHR_deferred_host_operations",
                has_ext(ash::khr::deferred_host_operations::NAME),
            ),
            (
                "VK_KHR_push_descriptor",
                has_ext(ash::khr::push_descriptor::NAME),
            ),
            ("bufferDeviceAddress", f12.buffer_device_address == vk::TRUE),
            (
                "storageBuffer16BitAccess",
                f11.storage_buffer16_bit_access == vk::TRUE,
            ),
            ("shaderFloat16", f12.shader_float16 == vk::TRUE),
            ("synchronization2", f13.synchronization2 == vk::TRUE),
            ("dynamicRendering", f13.dynamic_rendering == vk::TRUE),
            ("scalarBlockLayout", f12.scalar_block_layout == vk::TRUE),
            (
                "graphics+compute queue",
                qf.iter().any(|q| {
                    q.queue_flags
                        .contains(vk::QueueFlags::COMPUTE | vk::QueueFlags::GRAPHICS)
                }),
            ),
        ];

        let bc_compression = base.texture_compression_bc == vk::TRUE;
        let fmt = instance.get_physical_device_format_properties(pd, vk::Format::BC6H_UFLOAT_BLOCK);
        let bc6h_sampled_linear = bc_compression
            && fmt.optimal_tiling_features.contains(
                vk::FormatFeatureFlags::SAMPLED_IMAGE
                    | vk::FormatFeatureFlags::SAMPLED_IMAGE_FILTER_LINEAR,
            );

        let mut coop_matrix = Vec::new();
        if has_ext(ash::khr::cooperative_matrix::NAME) {
            let cm = ash::khr::cooperative_matrix::Instance::new(entry, instance);
            if let Ok(list) = cm.get_physical_device_cooperative_matrix_properties(pd) {
                for p in list {
                    coop_matrix.push(CoopMatrixShape {
                        m: p.m_size,
                        n: p.n_size,
                        k: p.k_size,
                        a: p.a_type,
                        b: p.b_type,
                        c: p.c_type,
                        result: p.result_type,
                        scope: p.scope,
                    });
                }
            }
        }

        let mem = instance.get_physical_device_memory_properties(pd);
        let memory_types = mem.memory_types[..mem.memory_type_count as usize]
            .iter()
            .map(|t| (t.property_flags, t.heap_index))
            .collect();

        Ok(Caps {
            name: cstr_field(&props.device_name),
            device_type: props.device_type,
            api_version: props.api_version,
            driver_name: cstr_field(&drv.driver_name),
            driver_info: cstr_field(&drv.driver_info),
            required,
            bc_compression,
            bc6h_sampled_linear,
            vulkan_memory_model: f12.vulkan_memory_model == vk::TRUE,
            coop_matrix,
            subgroup_size: p11.subgroup_size,
            subgroup_broadcast: p11
                .subgroup_supported_stages
                .contains(vk::ShaderStageFlags::COMPUTE)
                && p11
                    .subgroup_supported_operations
                    .contains(vk::SubgroupFeatureFlags::BALLOT),
            timestamp_period_ns: limits.timestamp_period,
            timestamp_valid_bits: ts_bits,
            max_storage_buffer_range: limits.max_storage_buffer_range,
            max_image_dimension_2d: limits.max_image_dimension2_d,
            max_image_array_layers: limits.max_image_array_layers,
            max_push_constants_size: limits.max_push_constants_size,
            max_compute_workgroup_invocations: limits.max_compute_work_group_invocations,
            max_compute_shared_memory: limits.max_compute_shared_memory_size,
            min_as_scratch_alignment: pas.min_acceleration_structure_scratch_offset_alignment,
            max_primitive_count: pas.max_primitive_count,
            memory_types,
        })
    }
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

/// Every Vulkan device on this machine with its capabilities (for `relit info`).
pub fn list_devices() -> Result<Vec<Caps>> {
    let entry = load_entry()?;
    let instance = create_instance(&entry, false, &[])?;
    let out = (|| {
        let pds = unsafe { instance.enumerate_physical_devices() }.vk("enumerate devices")?;
        pds.iter()
            .map(|&pd| query_caps(&entry, &instance, pd))
            .collect::<Result<Vec<_>>>()
    })();
    unsafe { instance.destroy_instance(None) };
    out
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
            let du = ash::ext::debug_utils::Instance::new(&entry, &instance);
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
                .user_data(&*validation_errors as *const AtomicU32 as *mut c_void);
            let m = unsafe { du.create_debug_utils_messenger(&info, None) }
                .vk("create debug messenger")?;
            Some((du, m))
        } else {
            None
        };

        // From here on, failures must tear down what exists: do it in one place.
        let fail = |instance: &ash::Instance,
                    debug: &Option<(
            ash::ext::debug_utils::Instance,
            vk::DebugUtilsMessengerEXT,
        )>| unsafe {
            if let Some((du, m)) = debug {
                du.destroy_debug_utils_messenger(*m, None);
            }
            instance.destroy_instance(None);
        };

        let picked = (|| -> Result<(vk::PhysicalDevice, Caps)> {
            let pds = unsafe { instance.enumerate_physical_devices() }.vk("enumerate devices")?;
            if pds.is_empty() {
                return Err(Error::Device(
                    "no Vulkan device found; install Mesa's lavapipe (tools/setup.sh)".into(),
                ));
            }
            let mut all = Vec::new();
            for &pd in &pds {
                all.push((pd, query_caps(&entry, &instance, pd)?));
            }
            let describe = |c: &Caps| {
                let m = c.missing();
                if m.is_empty() {
                    format!("{}: has everything", c.name)
                } else {
                    format!("{}: missing {}", c.name, m.join(", "))
                }
            };
            let chosen = match &opts.device {
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
            };
            match chosen {
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
        })();
        let (pdevice, caps) = match picked {
            Ok(p) => p,
            Err(e) => {
                fail(&instance, &debug);
                return Err(e);
            }
        };

        let qf = unsafe { instance.get_physical_device_queue_family_properties(pdevice) };
        let queue_family = qf
            .iter()
            .position(|q| {
                q.queue_flags
                    .contains(vk::QueueFlags::COMPUTE | vk::QueueFlags::GRAPHICS)
            })
            .unwrap_or(0) as u32;

        let mut ext_names: Vec<*const std::ffi::c_char> =
            REQUIRED_EXTENSIONS.iter().map(|e| e.as_ptr()).collect();
        if !caps.coop_matrix.is_empty() {
            ext_names.push(ash::khr::cooperative_matrix::NAME.as_ptr());
        }
        if opts.swapchain {
            ext_names.push(ash::khr::swapchain::NAME.as_ptr());
        }
        let mut f11 =
            vk::PhysicalDeviceVulkan11Features::default().storage_buffer16_bit_access(true);
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
        let mut fas = vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default()
            .acceleration_structure(true);
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
        let device = match unsafe { instance.create_device(pdevice, &dinfo, None) } {
            Ok(d) => d,
            Err(e) => {
                fail(&instance, &debug);
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
        let cmd_pool = unsafe {
            device.create_command_pool(
                &vk::CommandPoolCreateInfo::default()
                    .queue_family_index(queue_family)
                    .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                None,
            )
        }
        .vk("create command pool")?;

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
