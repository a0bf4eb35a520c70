//! What a physical device can do: the required and optional features and the limits the
//! engine sizes its work by, read before (and without) creating a device.

use std::ffi::CStr;

use ash::vk;

use super::{create_instance, load_entry};
use crate::error::{Result, VkContext};

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

fn cstr_field(bytes: &[std::ffi::c_char]) -> String {
    let bytes: Vec<u8> = bytes
        .iter()
        .take_while(|&&c| c != 0)
        .map(|&c| c as u8)
        .collect();
    String::from_utf8_lossy(&bytes).into_owned()
}

/// The feature structs `query_caps` reads, filled by one vkGetPhysicalDeviceFeatures2 (their
/// `p_next` chains point into that call's frame: read the fields only).
struct Features {
    base: vk::PhysicalDeviceFeatures,
    f11: vk::PhysicalDeviceVulkan11Features<'static>,
    f12: vk::PhysicalDeviceVulkan12Features<'static>,
    f13: vk::PhysicalDeviceVulkan13Features<'static>,
    fas: vk::PhysicalDeviceAccelerationStructureFeaturesKHR<'static>,
    frq: vk::PhysicalDeviceRayQueryFeaturesKHR<'static>,
}

/// The device's features; the acceleration-structure and ray-query ones only where the device
/// has those extensions (otherwise they read as absent).
fn query_features(
    instance: &ash::Instance,
    pd: vk::PhysicalDevice,
    has_as: bool,
    has_rq: bool,
) -> Features {
    let mut f11 = vk::PhysicalDeviceVulkan11Features::default();
    let mut f12 = vk::PhysicalDeviceVulkan12Features::default();
    let mut f13 = vk::PhysicalDeviceVulkan13Features::default();
    let mut fas = vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default();
    let mut frq = vk::PhysicalDeviceRayQueryFeaturesKHR::default();
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
    unsafe { instance.get_physical_device_features2(pd, &mut f2) };
    let base = f2.features;
    Features {
        base,
        f11,
        f12,
        f13,
        fas,
        frq,
    }
}

/// The property structs `query_caps` reads, filled by one vkGetPhysicalDeviceProperties2 (their
/// `p_next` chains point into that call's frame: read the fields only).
struct Properties {
    props: vk::PhysicalDeviceProperties,
    p11: vk::PhysicalDeviceVulkan11Properties<'static>,
    drv: vk::PhysicalDeviceDriverProperties<'static>,
    pas: vk::PhysicalDeviceAccelerationStructurePropertiesKHR<'static>,
}

/// The device's properties; the acceleration-structure ones only where it has the extension.
fn query_properties(instance: &ash::Instance, pd: vk::PhysicalDevice, has_as: bool) -> Properties {
    let mut pas = vk::PhysicalDeviceAccelerationStructurePropertiesKHR::default();
    let mut p11 = vk::PhysicalDeviceVulkan11Properties::default();
    let mut drv = vk::PhysicalDeviceDriverProperties::default();
    let mut p2 = vk::PhysicalDeviceProperties2::default()
        .push_next(&mut p11)
        .push_next(&mut drv);
    if has_as {
        p2 = p2.push_next(&mut pas);
    }
    unsafe { instance.get_physical_device_properties2(pd, &mut p2) };
    let props = p2.properties;
    Properties {
        props,
        p11,
        drv,
        pas,
    }
}

/// The features and extensions Relit cannot run without, each with whether the device has it
/// (`Caps::required`; `Caps::missing` names the absent ones).
fn required_table(
    props: &vk::PhysicalDeviceProperties,
    f: &Features,
    has_ext: &dyn Fn(&CStr) -> bool,
    qf: &[vk::QueueFamilyProperties],
) -> Vec<(&'static str, bool)> {
    let has_as = has_ext(ash::khr::acceleration_structure::NAME);
    let has_rq = has_ext(ash::khr::ray_query::NAME);
    vec![
        ("Vulkan 1.3", props.api_version >= vk::API_VERSION_1_3),
        (
            "VK_KHR_acceleration_structure",
            has_as && f.fas.acceleration_structure == vk::TRUE,
        ),
        (
            "VK_KHR_ray_query (ray query)",
            has_rq && f.frq.ray_query == vk::TRUE,
        ),
        (
            "VK_KHR_deferred_host_operations",
            has_ext(ash::khr::deferred_host_operations::NAME),
        ),
        (
            "VK_KHR_push_descriptor",
            has_ext(ash::khr::push_descriptor::NAME),
        ),
        (
            "bufferDeviceAddress",
            f.f12.buffer_device_address == vk::TRUE,
        ),
        (
            "storageBuffer16BitAccess",
            f.f11.storage_buffer16_bit_access == vk::TRUE,
        ),
        ("shaderFloat16", f.f12.shader_float16 == vk::TRUE),
        ("synchronization2", f.f13.synchronization2 == vk::TRUE),
        ("dynamicRendering", f.f13.dynamic_rendering == vk::TRUE),
        ("scalarBlockLayout", f.f12.scalar_block_layout == vk::TRUE),
        (
            "graphics+compute queue",
            qf.iter().any(|q| {
                q.queue_flags
                    .contains(vk::QueueFlags::COMPUTE | vk::QueueFlags::GRAPHICS)
            }),
        ),
    ]
}

/// The cooperative-matrix shapes the device offers (none without VK_KHR_cooperative_matrix or
/// when the query fails).
fn coop_matrix_shapes(
    entry: &ash::Entry,
    instance: &ash::Instance,
    pd: vk::PhysicalDevice,
    has_cm: bool,
) -> Vec<CoopMatrixShape> {
    let mut coop_matrix = Vec::new();
    if has_cm {
        let cm = ash::khr::cooperative_matrix::Instance::new(entry, instance);
        if let Ok(list) = unsafe { cm.get_physical_device_cooperative_matrix_properties(pd) } {
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
    coop_matrix
}

/// Reads the capabilities of one physical device.
pub(super) fn query_caps(
    entry: &ash::Entry,
    instance: &ash::Instance,
    pd: vk::PhysicalDevice,
) -> Result<Caps> {
    unsafe {
        let exts = instance
            .enumerate_device_extension_properties(pd)
            .vk("enumerate device extensions")?;
        let has_ext = |name: &CStr| exts.iter().any(|e| e.extension_name_as_c_str() == Ok(name));

        let has_as = has_ext(ash::khr::acceleration_structure::NAME);
        let has_rq = has_ext(ash::khr::ray_query::NAME);
        let features = query_features(instance, pd, has_as, has_rq);
        let Properties {
            props,
            p11,
            drv,
            pas,
        } = query_properties(instance, pd, has_as);
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

        let required = required_table(&props, &features, &has_ext, &qf);

        let bc_compression = features.base.texture_compression_bc == vk::TRUE;
        let fmt = instance.get_physical_device_format_properties(pd, vk::Format::BC6H_UFLOAT_BLOCK);
        let bc6h_sampled_linear = bc_compression
            && fmt.optimal_tiling_features.contains(
                vk::FormatFeatureFlags::SAMPLED_IMAGE
                    | vk::FormatFeatureFlags::SAMPLED_IMAGE_FILTER_LINEAR,
            );

        let has_cm = has_ext(ash::khr::cooperative_matrix::NAME);
        let coop_matrix = coop_matrix_shapes(entry, instance, pd, has_cm);

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
            vulkan_memory_model: features.f12.vulkan_memory_model == vk::TRUE,
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
