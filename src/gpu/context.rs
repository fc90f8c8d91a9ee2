//! Instance, device and queue on any Vulkan ≥ 1.2 device (a discrete GPU
//! first, then integrated, virtual, and CPU implementations such as Mesa's
//! lavapipe), with the validation layer and debug-utils names when asked
//! for (`IZB_VALIDATION=1`). Everything the device owns lives in one
//! reference-counted [`DeviceShared`]; buffers and pipelines hold an `Arc`
//! to it, so nothing can outlive the device and no caller keeps a destroy
//! list.

use super::device_candidates::{candidates, CPU_KIND};
use super::instance::create_instance;
pub use super::instance::list_devices;
pub(crate) use super::instance::load_entry;
pub(crate) use super::validation_messages::messenger_info;
use super::GpuError;
use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use std::ffi::{CStr, CString};
use std::mem::ManuallyDrop;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

pub use super::options::{frame_timeout, GpuOptions, FRAME_TIMEOUT};

/// The validation layer's name.
pub(crate) const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// A suitable device as enumerated.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct DeviceInfo {
    pub index: usize,
    pub name: String,
    pub kind: String,
    pub api_version: String,
    pub max_storage_buffer_range: u32,
    pub max_compute_work_group_count: [u32; 3],
}

impl DeviceInfo {
    /// Whether the device is a CPU implementation: its subgroups run as
    /// SIMD loops on a core, its clocks do not idle, its frames take
    /// seconds, and its arithmetic is the CPU twin's IEEE `f32`.
    pub fn is_cpu(&self) -> bool {
        self.kind == CPU_KIND
    }
}

/// What the device owns, destroyed in order when the last user drops it.
pub struct DeviceShared {
    /// The loader, kept for the function pointers of everything below:
    /// unloaded last, and never while a poisoned device lives on.
    /// `None` on a host's device (the host loaded it).
    pub(super) entry: ManuallyDrop<Option<ash::Entry>>,
    pub instance: ash::Instance,
    pub device: ash::Device,
    pub physical_device: vk::PhysicalDevice,
    /// The queue behind its lock (a queue is externally synchronised),
    /// held only around a submission; on a host's device the host's own
    /// lock ([`super::host_device::HostDevice::queue`]). Not public.
    pub(super) queue: SharedQueue,
    /// Whether izb created the instance and device (and destroys them
    /// last); a host's device is the host's to wait on and destroy.
    pub(super) owned: bool,
    pub queue_family: u32,
    pub allocator: ManuallyDrop<Mutex<Allocator>>,
    pub(super) debug_instance: Option<ash::ext::debug_utils::Instance>,
    pub debug_device: Option<ash::ext::debug_utils::Device>,
    pub(super) messenger: vk::DebugUtilsMessengerEXT,
    /// Validation messages since the device was created (the callback's
    /// `user_data` points at this `Mutex`, shared so its address is stable;
    /// freed only after the messenger is destroyed, and never while a
    /// poisoned device's messenger lives on).
    pub(super) messages: ManuallyDrop<Arc<Mutex<Vec<String>>>>,
    pub info: DeviceInfo,
    pub limits: vk::PhysicalDeviceLimits,
    /// Why the shadow-map baselines cannot draw on this device's
    /// rasteriser (no graphics queue beside compute, no depth clamp), or
    /// `None` when they can (`crate::gpu::shadow_raster`).
    pub raster_missing: Option<String>,
    /// Nanoseconds per timestamp tick; `None` when the queue has no
    /// timestamps.
    pub timestamp_period_ns: Option<f64>,
    /// Set when a submission timed out or the device was lost: work may
    /// still be running, so nothing it might touch is destroyed any more
    /// (every `Drop` leaks instead; the process exit reclaims it).
    pub(super) poisoned: std::sync::atomic::AtomicBool,
    /// Buffers created, descriptor sets allocated, host mappings made and
    /// submissions waited for on the device so far ([`Allocation`]).
    pub(super) allocations: [std::sync::atomic::AtomicU64; 4],
}

/// A queue and the lock every submission to it holds.
pub type SharedQueue = Arc<Mutex<vk::Queue>>;

/// What [`DeviceShared::allocations`] counts.
#[derive(Clone, Copy, Debug)]
pub enum Allocation {
    /// A `GpuBuffer`: one memory allocation, and for an upload or
    /// read-back buffer one mapping.
    Buffer,
    /// A `DescriptorSet` (with its own pool).
    DescriptorSet,
    /// A buffer in host-visible memory: mapped once when made.
    Mapping,
    /// A submission izb made and waited for (`submit_and_wait`): an
    /// upload, a read-back, or a batch frame.
    Submission,
}

/// What izb did on the host so far, per device ([`DeviceShared::host_counts`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct HostCounts {
    pub buffers: u64,
    pub descriptor_sets: u64,
    /// Host mappings (each a host-visible buffer made).
    pub mappings: u64,
    /// Submissions izb made and waited for; every read-back is one.
    pub waits: u64,
}

impl HostCounts {
    /// What was added since `before`.
    pub fn since(&self, before: HostCounts) -> HostCounts {
        HostCounts {
            buffers: self.buffers - before.buffers,
            descriptor_sets: self.descriptor_sets - before.descriptor_sets,
            mappings: self.mappings - before.mappings,
            waits: self.waits - before.waits,
        }
    }

    /// Adds `other` to these counts.
    pub fn add(&mut self, other: HostCounts) {
        self.buffers += other.buffers;
        self.descriptor_sets += other.descriptor_sets;
        self.mappings += other.mappings;
        self.waits += other.waits;
    }
}

impl DeviceShared {
    /// Whether the device may still be executing abandoned work.
    pub fn is_poisoned(&self) -> bool {
        self.poisoned.load(std::sync::atomic::Ordering::Acquire)
    }

    /// Counts one allocation of `kind`.
    pub(crate) fn count_allocation(&self, kind: Allocation) {
        self.allocations[kind as usize].fetch_add(1, Ordering::Relaxed);
    }

    /// Buffers created and descriptor sets allocated on this device so
    /// far: what a pass inside a host's frame must not add to per frame.
    pub fn allocations(&self) -> [u64; 2] {
        let c = self.host_counts();
        [c.buffers, c.descriptor_sets]
    }

    /// Buffers, descriptor sets, mappings and waited submissions so far:
    /// a host checks that its frames add none.
    pub fn host_counts(&self) -> HostCounts {
        let [buffers, descriptor_sets, mappings, waits] = self
            .allocations
            .each_ref()
            .map(|a| a.load(Ordering::Relaxed));
        HostCounts {
            buffers,
            descriptor_sets,
            mappings,
            waits,
        }
    }

    /// Marks the device as possibly busy forever (see `poisoned`).
    pub fn poison(&self) {
        self.poisoned
            .store(true, std::sync::atomic::Ordering::Release);
    }

    /// Names a Vulkan object for validation messages and GPU debuggers.
    pub fn set_name<H: vk::Handle>(&self, handle: H, name: &str) {
        if let Some(debug) = &self.debug_device {
            let name = CString::new(name).unwrap_or_default();
            let info = vk::DebugUtilsObjectNameInfoEXT::default()
                .object_handle(handle)
                .object_name(&name);
            // Naming is a debugging aid: a failure is not worth an error.
            // SAFETY: `handle` belongs to this device (callers name objects they
            // just created) and `info` outlives the call.
            unsafe {
                let _ = debug.set_debug_utils_object_name(&info);
            }
        }
    }

    /// Validation messages collected so far (and clears them).
    pub fn take_messages(&self) -> Vec<String> {
        std::mem::take(&mut *self.messages.lock().unwrap_or_else(|e| e.into_inner()))
    }
}

impl Drop for DeviceShared {
    fn drop(&mut self) {
        if self.is_poisoned() {
            // The device, its messenger (which may still call back into
            // `messages`) and the loader's code stay: leaked, not freed.
            return;
        }
        if !self.owned {
            // SAFETY: the last owner drops: every buffer and pipeline made
            // here is gone (each held an Arc), so their memory blocks are
            // free; the host's device outlives this
            // (`GpuContext::on_host_device`), and is the host's to wait
            // on and destroy. No messenger uses `messages` (none was made).
            unsafe {
                ManuallyDrop::drop(&mut self.allocator);
                ManuallyDrop::drop(&mut self.messages);
            }
            return;
        }
        // SAFETY: the last owner drops: every buffer, pipeline, pool and the
        // GpuContext hold an Arc to this, so they are gone; the device is not
        // poisoned, so after the idle wait nothing is in flight. The allocator
        // is dropped once, before its device; the messages after the
        // messenger; the loader after the instance; each exactly once.
        unsafe {
            let _ = self.device.device_wait_idle();
            ManuallyDrop::drop(&mut self.allocator);
            self.device.destroy_device(None);
            if let Some(debug) = &self.debug_instance {
                debug.destroy_debug_utils_messenger(self.messenger, None);
            }
            self.instance.destroy_instance(None);
            ManuallyDrop::drop(&mut self.messages);
            ManuallyDrop::drop(&mut self.entry);
        }
    }
}

/// The Vulkan context: a shared device plus the command pool of its queue.
pub struct GpuContext {
    pub shared: Arc<DeviceShared>,
    /// The command pool, behind the lock every submission holds from
    /// allocation to the end of its wait: a command pool is an externally
    /// synchronised object (Vulkan spec, "Threading Behavior"), and ash's
    /// handles are `Send + Sync`, so without it two threads rendering with
    /// one `GpuRenderer` would allocate from the pool at once. Frames are
    /// serialised. The queue has its own lock, held only around the submit
    /// (on a host's device the host's: its frames are not held up by a
    /// wait here).
    command_pool: Mutex<vk::CommandPool>,
    /// Submissions between allocation and wait right now, and the most
    /// ever seen: 1 while the lock does its job (`tests/gpu_threads.rs`).
    submissions: [AtomicU32; 2],
}

impl Drop for GpuContext {
    fn drop(&mut self) {
        if self.shared.is_poisoned() {
            return;
        }
        let pool = *self
            .command_pool
            .get_mut()
            .unwrap_or_else(|e| e.into_inner());
        // SAFETY: the device is not poisoned, so every submission from the
        // pool was waited on (`submit_and_wait`) and none of its command
        // buffers is in flight; `&mut self` means no other thread holds the
        // pool. A host's device is not ours to wait on idle.
        unsafe {
            if self.shared.owned {
                let _ = self.shared.device.device_wait_idle();
            }
            self.shared.device.destroy_command_pool(pool, None);
        }
    }
}

impl GpuContext {
    /// Opens the chosen (or best) device.
    pub fn new(options: &GpuOptions) -> Result<Self, GpuError> {
        let entry = load_entry()?;
        let instance = create_instance(&entry, options.validation, options.sync_validation)?;
        let fail = |instance: &ash::Instance, e: GpuError| {
            // SAFETY: called on the failure paths of `new`, when nothing created
            // from the instance is alive any more.
            unsafe { instance.destroy_instance(None) };
            Err(e)
        };
        let mut list = match candidates(&instance) {
            Ok(l) => l,
            Err(e) => return fail(&instance, e),
        };
        if list.is_empty() {
            return fail(
                &instance,
                GpuError::NoVulkan(
                    "no Vulkan 1.2 device with compute and the scalar block layout".into(),
                ),
            );
        }
        let index = options.device_index.unwrap_or(0);
        if index >= list.len() {
            let n = list.len();
            return fail(
                &instance,
                GpuError::NoVulkan(format!("--device {index}: only {n} device(s) found")),
            );
        }
        let chosen = list.swap_remove(index);

        let messages: Arc<Mutex<Vec<String>>> = Arc::default();
        let (debug_instance, messenger) = if options.validation {
            let debug = ash::ext::debug_utils::Instance::new(&entry, &instance);
            let info = messenger_info(&messages);
            // SAFETY: `info`'s user data points at `messages`, which `DeviceShared`
            // keeps alive until after the messenger is destroyed.
            match unsafe { debug.create_debug_utils_messenger(&info, None) } {
                Ok(m) => (Some(debug), m),
                Err(e) => return fail(&instance, GpuError::vk(e)),
            }
        } else {
            (None, vk::DebugUtilsMessengerEXT::null())
        };

        let priorities = [1.0f32];
        let queue_info = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(chosen.queue_family)
            .queue_priorities(&priorities)];
        let mut f12 = vk::PhysicalDeviceVulkan12Features::default().scalar_block_layout(true);
        let features = vk::PhysicalDeviceFeatures::default().depth_clamp(chosen.depth_clamp);
        let device_info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queue_info)
            .enabled_features(&features)
            .push_next(&mut f12);
        // SAFETY: `chosen.physical` comes from `instance`; `device_info` and
        // the feature chain it points to outlive the call.
        let device = match unsafe { instance.create_device(chosen.physical, &device_info, None) } {
            Ok(d) => d,
            Err(e) => {
                if let Some(debug) = &debug_instance {
                    // SAFETY: the messenger was created above and nothing else uses it.
                    unsafe { debug.destroy_debug_utils_messenger(messenger, None) };
                }
                return fail(&instance, GpuError::vk(e));
            }
        };
        // SAFETY: the device was created with one queue of this family.
        let queue = unsafe { device.get_device_queue(chosen.queue_family, 0) };
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.clone(),
            device: device.clone(),
            physical_device: chosen.physical,
            debug_settings: Default::default(),
            buffer_device_address: false,
            allocation_sizes: Default::default(),
        })
        .map_err(|e| GpuError::Allocation(e.to_string()));
        let allocator = match allocator {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: the device and messenger were created above and nothing
                // else holds them yet.
                unsafe {
                    device.destroy_device(None);
                    if let Some(debug) = &debug_instance {
                        debug.destroy_debug_utils_messenger(messenger, None);
                    }
                }
                return fail(&instance, e);
            }
        };
        let debug_device = options
            .validation
            .then(|| ash::ext::debug_utils::Device::new(&instance, &device));
        let shared = Arc::new(DeviceShared {
            entry: ManuallyDrop::new(Some(entry)),
            instance,
            device,
            physical_device: chosen.physical,
            queue: Arc::new(Mutex::new(queue)),
            owned: true,
            queue_family: chosen.queue_family,
            allocator: ManuallyDrop::new(Mutex::new(allocator)),
            debug_instance,
            debug_device,
            messenger,
            messages: ManuallyDrop::new(messages),
            poisoned: Default::default(),
            allocations: Default::default(),
            timestamp_period_ns: chosen
                .timestamps
                .then_some(chosen.limits.timestamp_period as f64),
            info: chosen.info,
            limits: chosen.limits,
            raster_missing: chosen.raster_missing,
        });
        Self::with_command_pool(shared)
    }

    /// The context of `shared`: a command pool of its own on the device's
    /// queue family (a family of the device: its candidate check).
    pub(super) fn with_command_pool(shared: Arc<DeviceShared>) -> Result<Self, GpuError> {
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(shared.queue_family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        // SAFETY: the queue family is one of the device's (checked when
        // `shared` was made, by `candidate`).
        let command_pool =
            unsafe { shared.device.create_command_pool(&pool_info, None) }.map_err(GpuError::vk)?;
        Ok(GpuContext {
            shared,
            command_pool: Mutex::new(command_pool),
            submissions: Default::default(),
        })
    }

    /// The device's name and kind.
    pub fn info(&self) -> &DeviceInfo {
        &self.shared.info
    }

    /// Records commands with `record` into a fresh command buffer, submits
    /// them, and waits (at most [`frame_timeout`]). One submission at a
    /// time: the pool's lock is held throughout. When the wait fails after
    /// a submission (a timeout, a lost device, any other error) the device
    /// is poisoned: the command buffer, its fence and every object the
    /// commands use are then leaked rather than freed under work that may
    /// still be running.
    ///
    /// # Safety
    /// `record` records into the command buffer it is given, only on this
    /// thread, and every object those commands use (buffers, sets,
    /// pipelines, query pools, images) was made before this call and
    /// outlives it: an object made and dropped inside `record` is gone
    /// before the submission.
    pub unsafe fn submit_and_wait(
        &self,
        record: impl FnOnce(vk::CommandBuffer) -> Result<(), GpuError>,
    ) -> Result<(), GpuError> {
        let pool = self.command_pool.lock().unwrap_or_else(|e| e.into_inner());
        let [now, most] = &self.submissions;
        most.fetch_max(now.fetch_add(1, Ordering::SeqCst) + 1, Ordering::SeqCst);
        // SAFETY: the caller's promise (`# Safety` above).
        let result = unsafe { self.submit_and_wait_locked(*pool, record) };
        now.fetch_sub(1, Ordering::SeqCst);
        result
    }

    /// The most submissions ever in progress at once (1 unless the
    /// command pool's lock failed to serialise them).
    pub fn max_concurrent_submissions(&self) -> u32 {
        self.submissions[1].load(Ordering::SeqCst)
    }

    /// [`Self::submit_and_wait`] with the pool's lock held.
    ///
    /// # Safety
    /// As [`Self::submit_and_wait`]; `pool` is the context's, locked.
    unsafe fn submit_and_wait_locked(
        &self,
        pool: vk::CommandPool,
        record: impl FnOnce(vk::CommandBuffer) -> Result<(), GpuError>,
    ) -> Result<(), GpuError> {
        self.shared.count_allocation(Allocation::Submission);
        let device = &self.shared.device;
        let timeout = frame_timeout();
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: the pool is alive and its lock is held (the caller).
        let cmd = unsafe { device.allocate_command_buffers(&alloc) }.map_err(GpuError::vk)?[0];
        let result = (|| {
            let begin = vk::CommandBufferBeginInfo::default()
                .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            let not_submitted = |e| Submission::NotSubmitted(GpuError::vk(e));
            // SAFETY: `cmd` was just allocated from the locked pool and is
            // in the initial state.
            unsafe { device.begin_command_buffer(cmd, &begin) }.map_err(not_submitted)?;
            // The caller records into `cmd` only (`# Safety`).
            record(cmd).map_err(Submission::NotSubmitted)?;
            // SAFETY: `cmd` is recording (begun above, on this thread).
            unsafe { device.end_command_buffer(cmd) }.map_err(not_submitted)?;
            // SAFETY: creating a fence needs only a live device.
            let fence = unsafe { device.create_fence(&vk::FenceCreateInfo::default(), None) }
                .map_err(not_submitted)?;
            let cmds = [cmd];
            let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
            let queue = self.shared.queue.lock().unwrap_or_else(|e| e.into_inner());
            // SAFETY: the queue is used only under its lock, held here;
            // `cmd` is executable and `fence` unsignalled.
            let submitted = unsafe { device.queue_submit(*queue, &submit, fence) };
            drop(queue);
            if let Err(e) = submitted {
                // SAFETY: nothing was submitted, so nothing refers to the fence.
                unsafe { device.destroy_fence(fence, None) };
                return Err(Submission::NotSubmitted(GpuError::vk(e)));
            }
            // SAFETY: `fence` is alive; it is destroyed only after a
            // successful wait.
            let waited =
                unsafe { device.wait_for_fences(&[fence], true, timeout.as_nanos() as u64) };
            let ended = Submission::after_wait(waited, timeout);
            if ended.is_ok() {
                // SAFETY: the wait succeeded: the submission is done.
                unsafe { device.destroy_fence(fence, None) };
            }
            // Otherwise the work may still run and signal the fence: keep it.
            ended
        })();
        match result {
            Ok(()) | Err(Submission::NotSubmitted(_)) => {
                // SAFETY: the fence wait succeeded or the buffer was never
                // submitted, so `cmd` is not pending; the pool's lock is held.
                unsafe { device.free_command_buffers(pool, &[cmd]) };
            }
            // The buffer may still be in flight: leak it rather than free
            // it under the GPU (the device is unusable anyway).
            Err(Submission::InFlight(_)) => self.shared.poison(),
        }
        result.map_err(|(Submission::NotSubmitted(e) | Submission::InFlight(e))| e)
    }
}

/// How a submission ended when it failed: before the queue had it (its
/// command buffer and fence can be freed), or after (they may be in use).
enum Submission {
    NotSubmitted(GpuError),
    InFlight(GpuError),
}

impl Submission {
    /// A fence wait's result as the submission's: any failure leaves the
    /// work possibly running — a timeout, a lost device, and any other
    /// error alike (an out-of-memory wait says nothing of the work).
    fn after_wait(waited: Result<(), vk::Result>, timeout: Duration) -> Result<(), Submission> {
        waited.map_err(|e| {
            Submission::InFlight(match e {
                vk::Result::TIMEOUT => GpuError::Timeout(timeout),
                e => GpuError::vk(e),
            })
        })
    }
}

/// A context for the library's own unit tests, or `None` with a printed
/// skip — a failure under `IZB_REQUIRE_GPU=1` (CI).
#[cfg(test)]
pub(crate) fn test_context() -> Option<GpuContext> {
    match GpuContext::new(&GpuOptions::from_env()) {
        Ok(c) => Some(c),
        Err(e) if std::env::var("IZB_REQUIRE_GPU").is_ok_and(|v| v == "1") => {
            panic!("IZB_REQUIRE_GPU=1 but the Vulkan backend did not open: {e}")
        }
        Err(e) => {
            eprintln!("skipped: {e}");
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A poisoned device leaks its message list (its messenger may still
    /// call back into it), a healthy one frees it; an earlier version
    /// freed it, and unloaded the loader, under a poisoned device.
    #[test]
    fn a_poisoned_device_keeps_what_its_messenger_and_device_use() {
        let mut checked = 0;
        for poison in [false, true] {
            let Some(context) = test_context() else {
                return;
            };
            let messages = Arc::downgrade(&context.shared.messages);
            if poison {
                context.shared.poison();
            }
            drop(context);
            assert_eq!(messages.upgrade().is_some(), poison, "poisoned: {poison}");
            checked += 1;
        }
        assert_eq!(checked, 2);
    }

    /// Every failed wait keeps the fence and the command buffer and
    /// poisons the device; an earlier version destroyed the fence on any
    /// error but a timeout or a lost device.
    #[test]
    fn every_failed_wait_leaves_the_work_in_flight() {
        let timeout = Duration::from_secs(1);
        let errors = [
            vk::Result::TIMEOUT,
            vk::Result::ERROR_DEVICE_LOST,
            vk::Result::ERROR_OUT_OF_HOST_MEMORY,
            vk::Result::ERROR_OUT_OF_DEVICE_MEMORY,
        ];
        for e in errors {
            let ended = Submission::after_wait(Err(e), timeout);
            assert!(matches!(ended, Err(Submission::InFlight(_))), "{e:?}");
        }
        assert!(Submission::after_wait(Ok(()), timeout).is_ok());
    }
}
