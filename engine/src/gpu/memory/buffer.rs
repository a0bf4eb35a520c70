//! Buffers, and the host-visible staging buffers that uploads and readbacks go through when
//! a resource's memory is not mapped.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::vulkan::Allocation;
use gpu_allocator::MemoryLocation;

use super::{creation_error, Gpu};
use crate::error::{Error, Result};

/// A buffer with its memory. Every buffer can be a transfer source and destination, so that
/// uploads and readbacks work whatever memory it landed in.
pub struct Buffer {
    pub gpu: Arc<Gpu>,
    pub raw: vk::Buffer,
    pub size: u64,
    /// Device address (0 unless created with SHADER_DEVICE_ADDRESS usage).
    pub address: u64,
    alloc: Option<Allocation>,
}

impl Buffer {
    pub fn new(
        gpu: &Arc<Gpu>,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Result<Buffer> {
        let size = size.max(4);
        // Shaders bind whole buffers: a storage buffer beyond the device's range cannot be bound.
        if usage.contains(vk::BufferUsageFlags::STORAGE_BUFFER)
            && size > gpu.caps.max_storage_buffer_range as u64
        {
            return Err(Error::Device(format!(
                "buffer \"{name}\" needs {:.1} MiB; the device binds at most {:.1} MiB per storage \
                 buffer (maxStorageBufferRange): use a smaller resolution, fewer views or fp16 storage",
                size as f64 / 1048576.0,
                gpu.caps.max_storage_buffer_range as f64 / 1048576.0
            )));
        }
        let usage = usage | vk::BufferUsageFlags::TRANSFER_SRC | vk::BufferUsageFlags::TRANSFER_DST;
        let d = &gpu.device;
        let raw = unsafe {
            d.create_buffer(
                &vk::BufferCreateInfo::default()
                    .size(size)
                    .usage(usage)
                    .sharing_mode(vk::SharingMode::EXCLUSIVE),
                None,
            )
        }
        .map_err(|r| creation_error(name, size, r))?;
        let req = unsafe { d.get_buffer_memory_requirements(raw) };
        let alloc = match gpu.allocate(name, req, location, true) {
            Ok(a) => a,
            Err(e) => {
                unsafe { d.destroy_buffer(raw, None) };
                return Err(e);
            }
        };
        if let Err(e) = unsafe { d.bind_buffer_memory(raw, alloc.memory(), alloc.offset()) } {
            unsafe { d.destroy_buffer(raw, None) };
            gpu.free(alloc);
            return Err(Error::Vk {
                what: "bind buffer memory",
                result: e,
            });
        }
        let address = if usage.contains(vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS) {
            unsafe {
                d.get_buffer_device_address(&vk::BufferDeviceAddressInfo::default().buffer(raw))
            }
        } else {
            0
        };
        Ok(Buffer {
            gpu: gpu.clone(),
            raw,
            size,
            address,
            alloc: Some(alloc),
        })
    }

    /// A device-local storage buffer filled with `data`.
    pub fn from_slice<T: bytemuck::Pod>(
        gpu: &Arc<Gpu>,
        name: &str,
        usage: vk::BufferUsageFlags,
        data: &[T],
    ) -> Result<Buffer> {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        let b = Buffer::new(
            gpu,
            name,
            bytes.len() as u64,
            usage,
            MemoryLocation::GpuOnly,
        )?;
        b.upload(bytes)?;
        Ok(b)
    }

    /// Host access to the memory, when it is host-visible and coherent and staging is not forced.
    fn direct(&self) -> bool {
        let a = self.alloc.as_ref().expect("buffer allocation");
        !self.gpu.force_staging()
            && a.mapped_ptr().is_some()
            && a.memory_properties()
                .contains(vk::MemoryPropertyFlags::HOST_COHERENT)
    }

    pub fn upload(&self, bytes: &[u8]) -> Result<()> {
        self.upload_at(0, bytes)
    }

    /// Writes `bytes` at byte `offset` (a buffer filled piece by piece, without a host copy of
    /// the whole).
    pub fn upload_at(&self, offset: u64, bytes: &[u8]) -> Result<()> {
        if offset + bytes.len() as u64 > self.size {
            return Err(Error::Other(format!(
                "upload of {} bytes at {offset} into a {}-byte buffer",
                bytes.len(),
                self.size
            )));
        }
        if self.direct() {
            let a = self.alloc.as_ref().expect("allocation");
            let p = a.mapped_ptr().expect("mapped").as_ptr() as *mut u8;
            unsafe {
                std::ptr::copy_nonoverlapping(bytes.as_ptr(), p.add(offset as usize), bytes.len())
            };
            return Ok(());
        }
        let staging = Staging::new(&self.gpu, bytes.len() as u64, MemoryLocation::CpuToGpu)?;
        staging.write(bytes);
        self.gpu.submit(|cmd| unsafe {
            let region = [vk::BufferCopy::default()
                .dst_offset(offset)
                .size(bytes.len() as u64)];
            self.gpu
                .device
                .cmd_copy_buffer(cmd, staging.0.raw, self.raw, &region);
        })
    }

    pub fn download(&self) -> Result<Vec<u8>> {
        self.download_range(0, self.size)
    }

    pub fn download_range(&self, offset: u64, len: u64) -> Result<Vec<u8>> {
        let len = len.min(self.size.saturating_sub(offset));
        if self.direct() {
            let a = self.alloc.as_ref().expect("allocation");
            let p = a.mapped_ptr().expect("mapped").as_ptr() as *const u8;
            let mut out = vec![0u8; len as usize];
            unsafe {
                std::ptr::copy_nonoverlapping(
                    p.add(offset as usize),
                    out.as_mut_ptr(),
                    len as usize,
                )
            };
            return Ok(out);
        }
        let staging = Staging::new(&self.gpu, len, MemoryLocation::GpuToCpu)?;
        self.gpu.submit(|cmd| unsafe {
            let region = [vk::BufferCopy::default().src_offset(offset).size(len)];
            self.gpu
                .device
                .cmd_copy_buffer(cmd, self.raw, staging.0.raw, &region);
        })?;
        Ok(staging.read(len as usize))
    }

    pub fn download_vec<T: bytemuck::Pod>(&self) -> Result<Vec<T>> {
        let bytes = self.download()?;
        let n = bytes.len() / std::mem::size_of::<T>();
        Ok(bytemuck::pod_collect_to_vec(
            &bytes[..n * std::mem::size_of::<T>()],
        ))
    }

    pub fn fill_zero(&self) -> Result<()> {
        self.gpu.submit(|cmd| unsafe {
            self.gpu
                .device
                .cmd_fill_buffer(cmd, self.raw, 0, vk::WHOLE_SIZE, 0)
        })
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        unsafe { self.gpu.device.destroy_buffer(self.raw, None) };
        if let Some(a) = self.alloc.take() {
            self.gpu.free(a);
        }
    }
}

/// A host-visible transfer buffer: always mapped, whatever `force_staging` says.
pub(super) struct Staging(pub(super) Buffer);

impl Staging {
    pub(super) fn new(gpu: &Arc<Gpu>, size: u64, location: MemoryLocation) -> Result<Staging> {
        let b = Buffer::new(
            gpu,
            "staging",
            size,
            vk::BufferUsageFlags::empty(),
            location,
        )?;
        Ok(Staging(b))
    }

    fn ptr(&self) -> *mut u8 {
        let a = self.0.alloc.as_ref().expect("allocation");
        a.mapped_ptr()
            .expect("staging memory is host-visible")
            .as_ptr() as *mut u8
    }

    pub(super) fn write(&self, bytes: &[u8]) {
        unsafe { std::ptr::copy_nonoverlapping(bytes.as_ptr(), self.ptr(), bytes.len()) };
    }

    pub(super) fn read(&self, len: usize) -> Vec<u8> {
        let mut out = vec![0u8; len];
        unsafe { std::ptr::copy_nonoverlapping(self.ptr(), out.as_mut_ptr(), len) };
        out
    }
}
