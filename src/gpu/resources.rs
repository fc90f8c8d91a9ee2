//! Buffers, owned RAII-style and described by intent (after kajiya's
//! `BufferDesc` and Granite's buffer domains): a [`BufferDesc`] names the
//! buffer, the pass that owns it, its size and its [`BufferDomain`];
//! [`GpuBuffer`] frees its memory when dropped.

use super::context::DeviceShared;
use super::GpuError;
use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;
use std::sync::Arc;

/// Where a buffer lives, by what it is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum BufferDomain {
    /// Read and written by shaders only (device-local memory); filled by
    /// copies from an [`BufferDomain::Upload`] buffer.
    Device,
    /// Written by the host, copied to a device buffer.
    Upload,
    /// Copied into from a device buffer, read by the host.
    Readback,
}

/// What a buffer is: the name (also its debug-utils name), the pass whose
/// memory it counts toward, its size in bytes and its domain.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BufferDesc {
    pub name: &'static str,
    pub pass: &'static str,
    pub size: u64,
    pub domain: BufferDomain,
}

impl BufferDesc {
    /// A device-local storage buffer of `size` bytes owned by `pass`.
    pub fn device(pass: &'static str, name: &'static str, size: u64) -> Self {
        BufferDesc {
            name,
            pass,
            size,
            domain: BufferDomain::Device,
        }
    }
}

/// A buffer and its memory; destroyed on drop.
pub struct GpuBuffer {
    shared: Arc<DeviceShared>,
    pub buffer: vk::Buffer,
    allocation: Option<Allocation>,
    pub desc: BufferDesc,
}

impl GpuBuffer {
    /// An upload buffer holding `bytes`, to be copied into a device
    /// buffer.
    pub fn staging(shared: &Arc<DeviceShared>, bytes: &[u8]) -> Result<Self, GpuError> {
        let desc = BufferDesc {
            name: "staging",
            pass: "upload",
            size: bytes.len() as u64,
            domain: BufferDomain::Upload,
        };
        let mut staging = GpuBuffer::new(shared, desc)?;
        staging.mapped_mut()?[..bytes.len()].copy_from_slice(bytes);
        Ok(staging)
    }

    /// Creates the buffer. Sizes are rounded up to 4 bytes (Vulkan forbids
    /// empty buffers; an empty scene still binds its triangle buffer), and a
    /// device buffer larger than the device's storage-buffer range is an
    /// error that names it.
    pub fn new(shared: &Arc<DeviceShared>, desc: BufferDesc) -> Result<Self, GpuError> {
        shared.count_allocation(super::context::Allocation::Buffer);
        if desc.domain != BufferDomain::Device {
            shared.count_allocation(super::context::Allocation::Mapping);
        }
        let size = desc.size.max(4).next_multiple_of(4);
        if desc.domain == BufferDomain::Device
            && size > u64::from(shared.limits.max_storage_buffer_range)
        {
            return Err(GpuError::BufferTooLarge {
                name: desc.name,
                size,
                limit: u64::from(shared.limits.max_storage_buffer_range),
            });
        }
        let (usage, location) = match desc.domain {
            BufferDomain::Device => (
                vk::BufferUsageFlags::STORAGE_BUFFER
                    | vk::BufferUsageFlags::TRANSFER_SRC
                    | vk::BufferUsageFlags::TRANSFER_DST,
                MemoryLocation::GpuOnly,
            ),
            BufferDomain::Upload => (vk::BufferUsageFlags::TRANSFER_SRC, MemoryLocation::CpuToGpu),
            BufferDomain::Readback => {
                (vk::BufferUsageFlags::TRANSFER_DST, MemoryLocation::GpuToCpu)
            }
        };
        let device = &shared.device;
        let info = vk::BufferCreateInfo::default()
            .size(size)
            .usage(usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: `info` outlives the call; a live device (the Arc).
        let buffer = unsafe { device.create_buffer(&info, None) }.map_err(GpuError::vk)?;
        // SAFETY: `buffer` was just created on this device.
        let requirements = unsafe { device.get_buffer_memory_requirements(buffer) };
        let allocation = shared
            .allocator
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .allocate(&AllocationCreateDesc {
                name: desc.name,
                requirements,
                location,
                linear: true,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            });
        let allocation = match allocation {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: created above, never bound nor used.
                unsafe { device.destroy_buffer(buffer, None) };
                return Err(GpuError::Allocation(format!(
                    "buffer `{}` ({size} bytes): {e}",
                    desc.name
                )));
            }
        };
        if let Err(e) =
            // SAFETY: the allocation was made for this buffer's requirements and
            // the buffer is not bound yet.
            unsafe {
                device.bind_buffer_memory(buffer, allocation.memory(), allocation.offset())
            }
        {
            // SAFETY: created above; binding failed, so nothing uses it.
            unsafe { device.destroy_buffer(buffer, None) };
            let _ = shared
                .allocator
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .free(allocation);
            return Err(GpuError::vk(e));
        }
        shared.set_name(buffer, desc.name);
        Ok(GpuBuffer {
            shared: shared.clone(),
            buffer,
            allocation: Some(allocation),
            desc: BufferDesc { size, ..desc },
        })
    }

    /// Size in bytes (after rounding).
    pub fn size(&self) -> u64 {
        self.desc.size
    }

    /// The mapped bytes of a host-visible buffer.
    pub fn mapped(&self) -> Result<&[u8], GpuError> {
        self.allocation
            .as_ref()
            .and_then(|a| a.mapped_slice())
            .ok_or(GpuError::NotMapped(self.desc.name))
    }

    /// The mapped bytes of a host-visible buffer, writable.
    pub fn mapped_mut(&mut self) -> Result<&mut [u8], GpuError> {
        let name = self.desc.name;
        self.allocation
            .as_mut()
            .and_then(|a| a.mapped_slice_mut())
            .ok_or(GpuError::NotMapped(name))
    }
}

impl Drop for GpuBuffer {
    fn drop(&mut self) {
        if self.shared.is_poisoned() {
            return;
        }
        // SAFETY: frames wait for their fence before dropping their buffers,
        // so no pending command buffer uses it (a poisoned device returns
        // above, leaking it); the memory is freed after the buffer.
        unsafe { self.shared.device.destroy_buffer(self.buffer, None) };
        if let Some(a) = self.allocation.take() {
            let _ = self
                .shared
                .allocator
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .free(a);
        }
    }
}
