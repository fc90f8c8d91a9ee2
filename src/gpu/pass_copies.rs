//! The shadow pass's copies outside frames: the scene uploaded once when
//! the pass is made, and results copied back for tests and tools. Both
//! allocate, submit and wait — never inside a frame.

use super::frame::GpuRenderer;
use super::resources::{BufferDesc, BufferDomain, GpuBuffer};
use super::shared::BINDING_COUNT;
use super::GpuError;
use ash::vk;
use std::sync::Arc;

const BINDINGS: usize = BINDING_COUNT as usize;

/// Copies `uploads` (binding, bytes) into the pass's buffers through
/// staging buffers, and waits.
pub(super) fn upload_into(
    renderer: &GpuRenderer,
    buffers: &[Arc<GpuBuffer>; BINDINGS],
    uploads: &[(u32, Vec<u8>)],
) -> Result<(), GpuError> {
    let shared = renderer.shared();
    let mut staged = Vec::new();
    for (b, bytes) in uploads.iter().filter(|(_, bytes)| !bytes.is_empty()) {
        staged.push((GpuBuffer::staging(shared, bytes)?, *b));
    }
    let record = |cmd| {
        for (staging, b) in &staged {
            let region = [vk::BufferCopy::default().size(staging.size())];
            let to = buffers[*b as usize].buffer;
            // SAFETY: `cmd` is recording; each copy fits both buffers.
            unsafe {
                shared
                    .device
                    .cmd_copy_buffer(cmd, staging.buffer, to, &region)
            };
        }
        Ok(())
    };
    // SAFETY: the staging and device buffers outlive the call, which
    // waits for the copies.
    unsafe { renderer.context.submit_and_wait(record) }
}

/// A read-back buffer kept between calls: made (or made larger) when a
/// read-back needs more than it holds, so a tool reading every frame back
/// (the viewer) makes and maps no buffer per frame.
#[derive(Default)]
pub(super) struct ReadbackBuffer(std::sync::Mutex<Option<GpuBuffer>>);

/// The first `words[k]` words of binding `bindings[k]`'s buffer, copied
/// back through `kept`'s one read-back buffer (waits).
pub(super) fn read_back<const N: usize>(
    renderer: &GpuRenderer,
    buffers: &[Arc<GpuBuffer>; BINDINGS],
    kept: &ReadbackBuffer,
    bindings: [u32; N],
    words: [usize; N],
) -> Result<[Vec<u32>; N], GpuError> {
    let shared = renderer.shared();
    // Each copy's first word in the one buffer.
    let mut starts = [0usize; N];
    let mut total = 0;
    for k in 0..N {
        starts[k] = total;
        total += words[k];
    }
    let mut kept = kept.0.lock().unwrap_or_else(|e| e.into_inner());
    if kept.as_ref().is_none_or(|b| b.size() < total as u64 * 4) {
        let desc = BufferDesc {
            name: "readback",
            pass: "readback",
            size: total as u64 * 4,
            domain: BufferDomain::Readback,
        };
        *kept = Some(GpuBuffer::new(shared, desc)?);
    }
    let readback = kept.as_ref().expect("made above");
    let record = |cmd| {
        let d = &shared.device;
        for k in (0..N).filter(|&k| words[k] > 0) {
            let region = [vk::BufferCopy::default()
                .dst_offset(starts[k] as u64 * 4)
                .size(words[k] as u64 * 4)];
            let from = buffers[bindings[k] as usize].buffer;
            // SAFETY: `cmd` is recording; the copy fits both buffers.
            unsafe { d.cmd_copy_buffer(cmd, from, readback.buffer, &region) };
        }
        // SAFETY: `cmd` is recording.
        unsafe { super::transfers_visible_to_host(d, cmd) };
        Ok(())
    };
    // The copies read what earlier frames wrote: the barrier at the end of
    // every frame (`resolve`) made it visible to transfers.
    // SAFETY: the read-back and device buffers outlive the call, which
    // waits for the copies; the lock keeps other read-backs out of the
    // buffer meanwhile.
    unsafe { renderer.context.submit_and_wait(record) }?;
    let bytes = readback.mapped()?;
    Ok(std::array::from_fn(|k| {
        bytemuck::pod_collect_to_vec(&bytes[starts[k] * 4..(starts[k] + words[k]) * 4])
    }))
}
