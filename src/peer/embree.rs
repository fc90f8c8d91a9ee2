//! `rt32-embree`: Intel Embree 3 (Wald et al. 2014) tracing the 32 µQuad
//! sample rays of every shadow-tested pixel with occlusion queries — the
//! CPU ray tracer a user would run instead of the IZB for the same
//! samples.
//!
//! Rays: [`super::shadow_rays::sample_rays`] of the shared G-buffer's µQuads (eye-relative
//! `f32`, the very samples the IZB tests), two packets of 16 per pixel
//! with `rtcOccluded16` (the samples of a pixel are coherent: one origin
//! neighbourhood, one light), on every rayon thread. Plain shadow rays:
//! unlike `rt32` they do not apply the IZB's per-pixel depth rule, so the
//! two differ where a neighbour meets the receiver (reported as the sample
//! mismatch against `rt32`).
//!
//! Only the handful of Embree 3 entry points used are declared here
//! (`rtcore.h` of Embree 3.13, the version Debian ships).

use super::shadow_rays::{trace_pixels, ShadowRay};
use crate::gbuffer::GBuffer;
use crate::scene::Scene;
use glam::Vec3;
use std::ffi::c_void;
use std::os::raw::{c_char, c_int, c_uint};

type RtcDevice = *mut c_void;
type RtcScene = *mut c_void;
type RtcGeometry = *mut c_void;

const RTC_GEOMETRY_TYPE_TRIANGLE: c_uint = 0;
const RTC_BUFFER_TYPE_INDEX: c_uint = 0;
const RTC_BUFFER_TYPE_VERTEX: c_uint = 1;
const RTC_FORMAT_UINT3: c_uint = 0x5003;
const RTC_FORMAT_FLOAT3: c_uint = 0x9003;
const RTC_BUILD_QUALITY_HIGH: c_uint = 2;
const RTC_INTERSECT_CONTEXT_FLAG_COHERENT: c_uint = 1;
const RTC_INVALID_GEOMETRY_ID: c_uint = u32::MAX;

/// `RTCIntersectContext` with `RTC_MAX_INSTANCE_LEVEL_COUNT` 1 and
/// `RTC_MIN_WIDTH` 0 (Debian's `rtcore_config.h`).
#[repr(C)]
struct RtcIntersectContext {
    flags: c_uint,
    filter: *const c_void,
    inst_id: [c_uint; 1],
}

/// `RTCRay16`: 16 rays, structure of arrays, 64-byte aligned.
#[repr(C, align(64))]
struct RtcRay16 {
    org_x: [f32; 16],
    org_y: [f32; 16],
    org_z: [f32; 16],
    tnear: [f32; 16],
    dir_x: [f32; 16],
    dir_y: [f32; 16],
    dir_z: [f32; 16],
    time: [f32; 16],
    tfar: [f32; 16],
    mask: [c_uint; 16],
    id: [c_uint; 16],
    flags: [c_uint; 16],
}

#[link(name = "embree3")]
extern "C" {
    fn rtcNewDevice(config: *const c_char) -> RtcDevice;
    fn rtcReleaseDevice(device: RtcDevice);
    fn rtcGetDeviceError(device: RtcDevice) -> c_int;
    fn rtcNewScene(device: RtcDevice) -> RtcScene;
    fn rtcReleaseScene(scene: RtcScene);
    fn rtcSetSceneBuildQuality(scene: RtcScene, quality: c_uint);
    fn rtcCommitScene(scene: RtcScene);
    fn rtcNewGeometry(device: RtcDevice, kind: c_uint) -> RtcGeometry;
    fn rtcSetNewGeometryBuffer(
        geometry: RtcGeometry,
        kind: c_uint,
        slot: c_uint,
        format: c_uint,
        byte_stride: usize,
        item_count: usize,
    ) -> *mut c_void;
    fn rtcCommitGeometry(geometry: RtcGeometry);
    fn rtcAttachGeometry(scene: RtcScene, geometry: RtcGeometry) -> c_uint;
    fn rtcReleaseGeometry(geometry: RtcGeometry);
    fn rtcOccluded16(
        valid: *const c_int,
        scene: RtcScene,
        context: *mut RtcIntersectContext,
        ray: *mut RtcRay16,
    );
}

/// An Embree device and a committed scene of one triangle soup; released
/// on drop.
pub struct EmbreeScene {
    device: RtcDevice,
    scene: RtcScene,
    /// Seconds the BVH build (`rtcCommitScene`) took.
    pub build_seconds: f64,
}

// SAFETY: Embree documents `rtcOccluded*` on a committed scene as safe to
// call from any number of threads at once; the handles are never mutated
// after `new`, and `Drop` needs `&mut self`, so no query can overlap it.
unsafe impl Send for EmbreeScene {}
// SAFETY: as for `Send`: shared use is read-only queries on a committed scene.
unsafe impl Sync for EmbreeScene {}

impl EmbreeScene {
    /// Builds Embree's BVH (high quality, Embree's default builder for
    /// static scenes) over eye-relative `f32` triangles.
    pub fn new(triangles: &[[Vec3; 3]]) -> Result<EmbreeScene, String> {
        if triangles.len() > u32::MAX as usize / 3 {
            return Err(format!(
                "{} triangles are too many for Embree",
                triangles.len()
            ));
        }
        // SAFETY: a null config string asks for Embree's defaults.
        let device = unsafe { rtcNewDevice(std::ptr::null()) };
        if device.is_null() {
            return Err("Embree: rtcNewDevice failed (is libembree3 installed?)".into());
        }
        // SAFETY: `device` is a live device; every handle created below is
        // released before return or owned by the returned value, and the
        // buffers Embree allocates are written within their item counts.
        unsafe {
            let scene = rtcNewScene(device);
            rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
            let geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
            let n = triangles.len().max(1);
            let vertices = rtcSetNewGeometryBuffer(
                geometry,
                RTC_BUFFER_TYPE_VERTEX,
                0,
                RTC_FORMAT_FLOAT3,
                12,
                3 * n,
            ) as *mut f32;
            let indices = rtcSetNewGeometryBuffer(
                geometry,
                RTC_BUFFER_TYPE_INDEX,
                0,
                RTC_FORMAT_UINT3,
                12,
                n,
            ) as *mut u32;
            if vertices.is_null() || indices.is_null() {
                rtcReleaseGeometry(geometry);
                rtcReleaseScene(scene);
                rtcReleaseDevice(device);
                return Err("Embree: could not allocate the triangle buffers".into());
            }
            // An empty scene gets one degenerate triangle Embree ignores.
            let soup = if triangles.is_empty() {
                &[[Vec3::ZERO; 3]][..]
            } else {
                triangles
            };
            let v = std::slice::from_raw_parts_mut(vertices, 9 * n);
            let ix = std::slice::from_raw_parts_mut(indices, 3 * n);
            for (i, t) in soup.iter().enumerate() {
                for (k, p) in t.iter().enumerate() {
                    v[9 * i + 3 * k..9 * i + 3 * k + 3].copy_from_slice(&p.to_array());
                    ix[3 * i + k] = (3 * i + k) as u32;
                }
            }
            rtcCommitGeometry(geometry);
            rtcAttachGeometry(scene, geometry);
            rtcReleaseGeometry(geometry);
            let start = std::time::Instant::now();
            rtcCommitScene(scene);
            let build_seconds = start.elapsed().as_secs_f64();
            let error = rtcGetDeviceError(device);
            if error != 0 {
                rtcReleaseScene(scene);
                rtcReleaseDevice(device);
                return Err(format!(
                    "Embree: building the scene failed (RTCError {error})"
                ));
            }
            Ok(EmbreeScene {
                device,
                scene,
                build_seconds,
            })
        }
    }

    /// Which of up to 16 rays `rays` (lanes beyond them inactive) hit
    /// something: bit i set = ray i occluded. The packet is filled straight
    /// from the rays, with no copies in between.
    fn occluded16(&self, rays: &[ShadowRay]) -> u32 {
        let count = rays.len().min(16);
        let mut ray = RtcRay16 {
            org_x: [0.0; 16],
            org_y: [0.0; 16],
            org_z: [0.0; 16],
            tnear: [0.0; 16],
            dir_x: [0.0; 16],
            dir_y: [0.0; 16],
            dir_z: [1.0; 16],
            time: [0.0; 16],
            tfar: [0.0; 16],
            mask: [u32::MAX; 16],
            id: [0; 16],
            flags: [0; 16],
        };
        let mut valid = [0 as c_int; 16];
        for (i, r) in rays.iter().take(count).enumerate() {
            valid[i] = -1;
            (ray.org_x[i], ray.org_y[i], ray.org_z[i]) = r.origin.into();
            (ray.dir_x[i], ray.dir_y[i], ray.dir_z[i]) = r.direction.into();
            ray.tnear[i] = r.t_near;
            ray.tfar[i] = r.t_far;
            ray.id[i] = i as u32;
        }
        let mut context = RtcIntersectContext {
            flags: RTC_INTERSECT_CONTEXT_FLAG_COHERENT,
            filter: std::ptr::null(),
            inst_id: [RTC_INVALID_GEOMETRY_ID],
        };
        // SAFETY: the scene is committed and alive (`&self`); `valid`,
        // `context` and `ray` are live, correctly laid out (`repr(C)`,
        // 64-byte aligned packet) and exclusively borrowed for the call.
        unsafe { rtcOccluded16(valid.as_ptr(), self.scene, &mut context, &mut ray) };
        // Embree marks an occluded ray by setting its tfar to −∞.
        (0..count).fold(0, |m, i| {
            m | (u32::from(ray.tfar[i] == f32::NEG_INFINITY) << i)
        })
    }
}

impl Drop for EmbreeScene {
    fn drop(&mut self) {
        // SAFETY: both handles were created in `new` and are released once,
        // here; no query can be running (`&mut self`).
        unsafe {
            rtcReleaseScene(self.scene);
            rtcReleaseDevice(self.device);
        }
    }
}

/// The 32-sample masks of every pixel of `g` traced by Embree (0 where not
/// shadow-tested): sample order and positions as the IZB's `pattern`.
pub fn rt32_embree_masks(
    scene: &Scene,
    embree: &EmbreeScene,
    g: &GBuffer,
    pattern: &[[f32; 2]; 32],
) -> Vec<u32> {
    trace_pixels(scene, g, pattern, |rays| {
        embree.occluded16(&rays[..16]) | embree.occluded16(&rays[16..]) << 16
    })
}
