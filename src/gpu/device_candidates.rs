//! Which physical devices can run the passes, best first: Vulkan ≥ 1.2,
//! a compute queue (with graphics beside it when there is one, for the
//! baselines' raster passes), the scalar block layout and the subgroup
//! operations the shaders use.

use super::context::DeviceInfo;
use super::GpuError;
use ash::vk;

/// `DeviceInfo::kind` of a CPU implementation (lavapipe).
pub(super) const CPU_KIND: &str = "CPU";

fn device_kind(t: vk::PhysicalDeviceType) -> (u32, &'static str) {
    match t {
        vk::PhysicalDeviceType::DISCRETE_GPU => (0, "discrete GPU"),
        vk::PhysicalDeviceType::INTEGRATED_GPU => (1, "integrated GPU"),
        vk::PhysicalDeviceType::VIRTUAL_GPU => (2, "virtual GPU"),
        vk::PhysicalDeviceType::CPU => (3, CPU_KIND),
        _ => (4, "other"),
    }
}

/// Subgroup operations the shaders use in compute: `subgroupElect`
/// (basic), `subgroupAllEqual`/`Any` (vote), `subgroupAdd`/`Min`/`Max`/`Or`
/// (arithmetic), `subgroupBallot`/`Broadcast` (ballot).
const REQUIRED_SUBGROUP_OPERATIONS: vk::SubgroupFeatureFlags = vk::SubgroupFeatureFlags::from_raw(
    vk::SubgroupFeatureFlags::BASIC.as_raw()
        | vk::SubgroupFeatureFlags::VOTE.as_raw()
        | vk::SubgroupFeatureFlags::ARITHMETIC.as_raw()
        | vk::SubgroupFeatureFlags::BALLOT.as_raw(),
);

/// A suitable physical device: Vulkan ≥ 1.2, a compute queue, the scalar
/// block layout, the subgroup operations of [`REQUIRED_SUBGROUP_OPERATIONS`].
pub(super) struct Candidate {
    pub(super) physical: vk::PhysicalDevice,
    pub(super) queue_family: u32,
    pub(super) raster_missing: Option<String>,
    pub(super) depth_clamp: bool,
    pub(super) rank: u32,
    pub(super) info: DeviceInfo,
    pub(super) limits: vk::PhysicalDeviceLimits,
    pub(super) timestamps: bool,
}

pub(super) fn candidates(instance: &ash::Instance) -> Result<Vec<Candidate>, GpuError> {
    // SAFETY: `instance` is a live instance.
    let physicals = unsafe { instance.enumerate_physical_devices() }.map_err(GpuError::vk)?;
    let mut out: Vec<Candidate> = physicals
        .into_iter()
        // SAFETY: `physical` was enumerated from this live instance, made
        // with API 1.2 (`create_instance`).
        .filter_map(|physical| unsafe { candidate(instance, physical, None) }.ok())
        .collect();
    out.sort_by_key(|c| c.rank);
    for (i, c) in out.iter_mut().enumerate() {
        c.info.index = i;
    }
    Ok(out)
}

/// `physical` as a candidate, or why it cannot run the passes. Its queue
/// family is `given_family` when given (a host's device: it must have
/// compute), else one with graphics beside compute when there is one.
///
/// # Safety
/// `instance` is live, created with `apiVersion` ≥ 1.2 (the queries below
/// chain Vulkan 1.2 structures), and `physical` was enumerated from it.
pub(super) unsafe fn candidate(
    instance: &ash::Instance,
    physical: vk::PhysicalDevice,
    given_family: Option<u32>,
) -> Result<Candidate, String> {
    // SAFETY: the caller's promise (here and in the queries below); the
    // out-structures outlive the calls.
    let props = unsafe { instance.get_physical_device_properties(physical) };
    if props.api_version < vk::API_VERSION_1_2 {
        return Err("the device's Vulkan version is below 1.2".into());
    }
    let mut f12 = vk::PhysicalDeviceVulkan12Features::default();
    let mut f2 = vk::PhysicalDeviceFeatures2::default().push_next(&mut f12);
    // SAFETY: as above; the feature chain outlives the call.
    unsafe { instance.get_physical_device_features2(physical, &mut f2) };
    let depth_clamp = f2.features.depth_clamp == vk::TRUE;
    if f12.scalar_block_layout == vk::FALSE {
        return Err("the device has no scalarBlockLayout".into());
    }
    // The passes reduce their counters and atomics per subgroup
    // (votes, arithmetic) before touching memory.
    let mut subgroup = vk::PhysicalDeviceSubgroupProperties::default();
    let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut subgroup);
    // SAFETY: as above; the property chain outlives the call.
    unsafe { instance.get_physical_device_properties2(physical, &mut p2) };
    if !subgroup
        .supported_stages
        .contains(vk::ShaderStageFlags::COMPUTE)
        || !subgroup
            .supported_operations
            .contains(REQUIRED_SUBGROUP_OPERATIONS)
    {
        return Err(
            "the device lacks compute subgroups with basic, vote, arithmetic and ballot \
             operations"
                .into(),
        );
    }
    // SAFETY: as above.
    let families = unsafe { instance.get_physical_device_queue_family_properties(physical) };
    // A family with graphics beside compute when there is one: the
    // shadow-map baselines draw their maps on the rasteriser.
    let graphics = vk::QueueFlags::COMPUTE | vk::QueueFlags::GRAPHICS;
    let compute = |f: &vk::QueueFamilyProperties| f.queue_flags.contains(vk::QueueFlags::COMPUTE);
    let (family, family_props) = match given_family {
        Some(i) => match families.get(i as usize) {
            Some(f) if compute(f) => (i as usize, f),
            Some(_) => return Err(format!("queue family {i} has no compute")),
            None => {
                return Err(format!(
                    "queue family {i}: the device has {}",
                    families.len()
                ))
            }
        },
        None => families
            .iter()
            .enumerate()
            .find(|(_, f)| f.queue_flags.contains(graphics))
            .or_else(|| families.iter().enumerate().find(|(_, f)| compute(f)))
            .ok_or("no queue family has compute")?,
    };
    let raster_missing = if !family_props.queue_flags.contains(graphics) {
        Some(match given_family {
            Some(i) => format!("queue family {i} has no graphics beside compute"),
            None => "no queue family of this device has graphics beside compute".to_string(),
        })
    } else if !depth_clamp {
        Some("this device has no depthClamp (a directional light's map clamps casters in front of its depth range)".to_string())
    } else {
        None
    };
    let (rank, kind) = device_kind(props.device_type);
    let name = props
        .device_name_as_c_str()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|_| "unnamed device".into());
    Ok(Candidate {
        physical,
        queue_family: family as u32,
        raster_missing,
        depth_clamp,
        rank,
        info: DeviceInfo {
            index: 0,
            name,
            kind: kind.into(),
            api_version: format!(
                "{}.{}.{}",
                vk::api_version_major(props.api_version),
                vk::api_version_minor(props.api_version),
                vk::api_version_patch(props.api_version)
            ),
            max_storage_buffer_range: props.limits.max_storage_buffer_range,
            max_compute_work_group_count: props.limits.max_compute_work_group_count,
        },
        limits: props.limits,
        timestamps: family_props.timestamp_valid_bits > 0 && props.limits.timestamp_period > 0.0,
    })
}
