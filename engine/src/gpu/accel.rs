//! Acceleration structures for ray queries: one BLAS per triangle mesh, one TLAS over it.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::MemoryLocation;

use super::memory::{full_barrier, Buffer};
use super::Gpu;
use crate::error::{Error, Result, VkContext};

pub struct AccelStruct {
    gpu: Arc<Gpu>,
    pub raw: vk::AccelerationStructureKHR,
    pub address: u64,
    _storage: Buffer,
}

impl Drop for AccelStruct {
    fn drop(&mut self) {
        unsafe {
            self.gpu
                .accel
                .destroy_acceleration_structure(self.raw, None)
        };
    }
}

/// A mesh ready for ray queries: the BLAS, a TLAS with one identity instance, and the vertex
/// and index buffers (shaders read them to interpolate at hits).
pub struct RayScene {
    pub tlas: AccelStruct,
    pub blas: AccelStruct,
    pub positions: Buffer,
    pub indices: Buffer,
    /// Per triangle corner (three per triangle, in order): its position and the triangle's
    /// geometric normal (counter-clockwise = front), 6 floats: a vertex buffer, so rasterizing
    /// needs no index lookups in shaders (a per-lane loop each on Mesa 25's llvmpipe).
    pub corners: Buffer,
    pub triangle_count: u32,
}

/// The [`RayScene::corners`] of a mesh.
pub fn corners(positions: &[[f32; 3]], indices: &[[u32; 3]]) -> Vec<[f32; 6]> {
    let mut out = Vec::with_capacity(3 * indices.len());
    for t in indices {
        let p = t.map(|i| glam::Vec3::from(positions.get(i as usize).copied().unwrap_or_default()));
        let c = (p[1] - p[0]).cross(p[2] - p[0]);
        let n = c / c.length();
        for q in p {
            out.push([q.x, q.y, q.z, n.x, n.y, n.z]);
        }
    }
    out
}

fn build(
    gpu: &Arc<Gpu>,
    ty: vk::AccelerationStructureTypeKHR,
    geometry: vk::AccelerationStructureGeometryKHR,
    primitive_count: u32,
) -> Result<AccelStruct> {
    let geoms = [geometry];
    let mut info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
        .ty(ty)
        .flags(vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE)
        .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
        .geometries(&geoms);
    let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
    unsafe {
        gpu.accel.get_acceleration_structure_build_sizes(
            vk::AccelerationStructureBuildTypeKHR::DEVICE,
            &info,
            &[primitive_count],
            &mut sizes,
        )
    };
    let storage = Buffer::new(
        gpu,
        "accel storage",
        sizes.acceleration_structure_size,
        vk::BufferUsageFlags::ACCELERATION_STRUCTURE_STORAGE_KHR
            | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
        MemoryLocation::GpuOnly,
    )?;
    let raw = unsafe {
        gpu.accel.create_acceleration_structure(
            &vk::AccelerationStructureCreateInfoKHR::default()
                .buffer(storage.raw)
                .size(sizes.acceleration_structure_size)
                .ty(ty),
            None,
        )
    }
    .vk("create acceleration structure")?;
    let align = gpu.caps.min_as_scratch_alignment.max(1) as u64;
    let scratch = Buffer::new(
        gpu,
        "accel scratch",
        sizes.build_scratch_size + align,
        vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
        MemoryLocation::GpuOnly,
    );
    let scratch = match scratch {
        Ok(s) => s,
        Err(e) => {
            unsafe { gpu.accel.destroy_acceleration_structure(raw, None) };
            return Err(e);
        }
    };
    info = info
        .dst_acceleration_structure(raw)
        .scratch_data(vk::DeviceOrHostAddressKHR {
            device_address: scratch.address.div_ceil(align) * align,
        });
    let range =
        [vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(primitive_count)];
    let ranges: [&[vk::AccelerationStructureBuildRangeInfoKHR]; 1] = [&range];
    let built = gpu.submit(|cmd| unsafe {
        gpu.accel
            .cmd_build_acceleration_structures(cmd, std::slice::from_ref(&info), &ranges);
        full_barrier(gpu, cmd);
    });
    if let Err(e) = built {
        unsafe { gpu.accel.destroy_acceleration_structure(raw, None) };
        return Err(e);
    }
    let address = unsafe {
        gpu.accel.get_acceleration_structure_device_address(
            &vk::AccelerationStructureDeviceAddressInfoKHR::default().acceleration_structure(raw),
        )
    };
    Ok(AccelStruct {
        gpu: gpu.clone(),
        raw,
        address,
        _storage: storage,
    })
}

impl RayScene {
    /// Builds BLAS and TLAS for a triangle mesh. `positions` are xyz triples, `indices` three
    /// per triangle. Triangle ids seen by shaders (`rayQueryGetIntersectionPrimitiveIndexEXT`)
    /// are indices into `indices / 3`.
    pub fn new(gpu: &Arc<Gpu>, positions: &[[f32; 3]], indices: &[[u32; 3]]) -> Result<RayScene> {
        if indices.is_empty() {
            return Err(Error::Other(
                "cannot build an acceleration structure of an empty mesh".into(),
            ));
        }
        if indices.len() as u64 > gpu.caps.max_primitive_count {
            return Err(Error::Device(format!(
                "mesh has {} triangles; the device's BLAS limit is {}",
                indices.len(),
                gpu.caps.max_primitive_count
            )));
        }
        // The same buffers feed the BLAS build and shaders (hit interpolation, rasterization).
        let input = vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
            | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS
            | vk::BufferUsageFlags::STORAGE_BUFFER;
        let pos = Buffer::from_slice(gpu, "mesh positions", input, positions)?;
        let idx = Buffer::from_slice(gpu, "mesh indices", input, indices)?;
        let tris = vk::AccelerationStructureGeometryTrianglesDataKHR::default()
            .vertex_format(vk::Format::R32G32B32_SFLOAT)
            .vertex_data(vk::DeviceOrHostAddressConstKHR {
                device_address: pos.address,
            })
            .vertex_stride(12)
            .max_vertex(positions.len().saturating_sub(1) as u32)
            .index_type(vk::IndexType::UINT32)
            .index_data(vk::DeviceOrHostAddressConstKHR {
                device_address: idx.address,
            });
        let geom = vk::AccelerationStructureGeometryKHR::default()
            .geometry_type(vk::GeometryTypeKHR::TRIANGLES)
            .geometry(vk::AccelerationStructureGeometryDataKHR { triangles: tris })
            .flags(vk::GeometryFlagsKHR::OPAQUE);
        let blas = build(
            gpu,
            vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
            geom,
            indices.len() as u32,
        )?;

        let instance = vk::AccelerationStructureInstanceKHR {
            transform: vk::TransformMatrixKHR {
                matrix: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
            },
            instance_custom_index_and_mask: vk::Packed24_8::new(0, 0xff),
            instance_shader_binding_table_record_offset_and_flags: vk::Packed24_8::new(
                0,
                vk::GeometryInstanceFlagsKHR::TRIANGLE_FACING_CULL_DISABLE.as_raw() as u8,
            ),
            acceleration_structure_reference: vk::AccelerationStructureReferenceKHR {
                device_handle: blas.address,
            },
        };
        // SAFETY: the instance struct is plain data laid out as the spec requires (64 bytes).
        let bytes = unsafe {
            std::slice::from_raw_parts(
                &instance as *const _ as *const u8,
                std::mem::size_of::<vk::AccelerationStructureInstanceKHR>(),
            )
        };
        let inst_buf = Buffer::new(
            gpu,
            "tlas instances",
            bytes.len() as u64,
            vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
                | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
            MemoryLocation::GpuOnly,
        )?;
        inst_buf.upload(bytes)?;
        let inst = vk::AccelerationStructureGeometryInstancesDataKHR::default()
            .array_of_pointers(false)
            .data(vk::DeviceOrHostAddressConstKHR {
                device_address: inst_buf.address,
            });
        let geom = vk::AccelerationStructureGeometryKHR::default()
            .geometry_type(vk::GeometryTypeKHR::INSTANCES)
            .geometry(vk::AccelerationStructureGeometryDataKHR { instances: inst });
        let tlas = build(gpu, vk::AccelerationStructureTypeKHR::TOP_LEVEL, geom, 1)?;
        let vertex = vk::BufferUsageFlags::VERTEX_BUFFER;
        let corners =
            Buffer::from_slice(gpu, "mesh corners", vertex, &corners(positions, indices))?;
        Ok(RayScene {
            tlas,
            blas,
            positions: pos,
            indices: idx,
            corners,
            triangle_count: indices.len() as u32,
        })
    }
}
