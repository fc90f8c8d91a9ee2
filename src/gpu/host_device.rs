//! The passes on the host's own device (issue 29, point 1): an engine
//! hands its `ash::Instance`, `ash::Device`, physical device, queue
//! family and queue, and izb makes its pipelines, buffers and command
//! pool there. Nothing else is created on the host's behalf: no instance,
//! device or debug messenger (validation is the host's layer, reported to
//! the host's messenger), and nothing waits on the device idle or
//! destroys it — the host does, after the pass is dropped.
//!
//! The queue is shared under the host's lock ([`HostDevice::queue`]):
//! izb submits only while making a pass (its one upload) and in the
//! read-backs of tests and tools, and holds the lock only around
//! `vkQueueSubmit`, never across its fence wait.

use super::context::{DeviceShared, GpuContext, SharedQueue};
use super::device_candidates::candidate;
use super::GpuError;
use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use std::mem::ManuallyDrop;
use std::sync::{Arc, Mutex};

/// The host's device, as [`GpuContext::on_host_device`] takes it.
#[derive(Clone)]
pub struct HostDevice {
    pub instance: ash::Instance,
    pub device: ash::Device,
    pub physical_device: vk::PhysicalDevice,
    /// The family of `queue`; it has compute.
    pub queue_family: u32,
    /// The host's queue, behind the lock the host itself submits under
    /// (Vulkan queues are externally synchronised). izb takes it when a
    /// pass is made and in read-backs: the host must not hold it across
    /// those calls (`std::sync::Mutex` is not re-entrant), and izb's wait
    /// after such a submission ([`super::options::frame_timeout`]) also
    /// waits for whatever the host queued before it.
    pub queue: SharedQueue,
}

impl GpuContext {
    /// The context on the host's device: a command pool of its own on the
    /// host's queue family and a memory allocator. The baselines' raster
    /// passes are not built on it (izb does not know the features the
    /// host enabled).
    ///
    /// Checked, and refused by name: what the physical device supports,
    /// as [`super::context::list_devices`] checks its own (Vulkan ≥ 1.2,
    /// `scalarBlockLayout`, compute subgroups with vote, arithmetic and
    /// ballot), and that `host.queue_family` is one of its families and
    /// has compute.
    ///
    /// # Safety
    /// What izb cannot query: `host.instance` was created with
    /// `apiVersion` ≥ 1.2 and `host.physical_device` enumerated from it;
    /// `host.device` was created on that physical device with the
    /// `scalarBlockLayout` feature enabled; if `host.queue_family` is one
    /// of the device's families, the device was created with a queue of
    /// it, which `host.queue` holds; the host submits to that queue only
    /// while holding its lock; the instance and device outlive this
    /// context and everything made on it (pipelines, buffers, passes),
    /// which the host drops with the device idle.
    pub unsafe fn on_host_device(host: HostDevice) -> Result<Self, GpuError> {
        // SAFETY: the instance and physical device as the caller promises.
        let chosen = unsafe {
            candidate(
                &host.instance,
                host.physical_device,
                Some(host.queue_family),
            )
        }
        .map_err(|why| GpuError::Unsupported(format!("the host's device: {why}")))?;
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: host.instance.clone(),
            device: host.device.clone(),
            physical_device: host.physical_device,
            debug_settings: Default::default(),
            buffer_device_address: false,
            allocation_sizes: Default::default(),
        })
        .map_err(|e| GpuError::Allocation(e.to_string()))?;
        let shared = Arc::new(DeviceShared {
            entry: ManuallyDrop::new(None),
            instance: host.instance,
            device: host.device,
            physical_device: host.physical_device,
            queue: host.queue,
            owned: false,
            queue_family: host.queue_family,
            allocator: ManuallyDrop::new(Mutex::new(allocator)),
            debug_instance: None,
            debug_device: None,
            messenger: vk::DebugUtilsMessengerEXT::null(),
            messages: ManuallyDrop::new(Arc::default()),
            poisoned: Default::default(),
            allocations: Default::default(),
            timestamp_period_ns: chosen
                .timestamps
                .then_some(chosen.limits.timestamp_period as f64),
            info: chosen.info,
            limits: chosen.limits,
            raster_missing: Some(
                "the passes run on the host's device, whose enabled features izb does not \
                 know: the baselines' raster passes are not built there"
                    .into(),
            ),
        });
        GpuContext::with_command_pool(shared)
    }

    /// Whether the device is the host's ([`Self::on_host_device`]).
    pub fn on_hosts_device(&self) -> bool {
        !self.shared.owned
    }
}
