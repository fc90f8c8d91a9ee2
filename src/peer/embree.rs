//! `rt32-embree`: Intel Embree 3 (Wald et al. 2014) tracing the 32 µQuad
//! sample rays of every shadow-tested pixel with occlusion queries — the
//! CPU ray tracer a user would run instead of the IZB for the same
//! samples.
//!
//! Rays: [`super::shadow_rays::sample_rays`] of the shared G-buffer's
//! µQuads (eye-relative `f32`, the very samples the IZB tests), computed
//! sixteen lanes at a time straight into two packets of 16 per pixel
//! with `rtcOccluded16` (the samples of a pixel are coherent: one origin
//! neighbourhood, one light), on every rayon thread. Plain shadow rays:
//! unlike `rt32` they do not apply the IZB's per-pixel depth rule, so the
//! two differ where a neighbour meets the receiver (reported as the sample
//! mismatch against `rt32`).
//!
//! Only the handful of Embree 3 entry points used are declared here
//! (`rtcore.h` of Embree 3.13, the version Debian ships).

#[cfg(doc)]
use super::shadow_rays::sample_rays;
use super::shadow_rays::{ray_offset, trace_pixels};
use crate::gbuffer::GBuffer;
use crate::scene::{Light, Scene};
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

/// The packet's valid mask (−1: lane active), 64-byte aligned like the
/// packet. Embree's manual asks alignment of the packet only, but its
/// 16-wide kernels read the mask as one vector: a probe build whose
/// `[c_int; 16]` mask landed off a 64-byte boundary crashed on each of the
/// four scenes it ran (session 37); earlier builds were aligned by luck.
#[repr(C, align(64))]
struct ValidMask16([c_int; 16]);

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

    /// Which of the 16 rays of `ray` hit something: bit i set = lane i
    /// occluded.
    fn occluded16(&self, ray: &mut RtcRay16) -> u32 {
        let valid = ValidMask16([-1; 16]);
        let mut context = RtcIntersectContext {
            flags: RTC_INTERSECT_CONTEXT_FLAG_COHERENT,
            filter: std::ptr::null(),
            inst_id: [RTC_INVALID_GEOMETRY_ID],
        };
        // SAFETY: the scene is committed and alive (`&self`); `valid`,
        // `context` and `ray` are live, correctly laid out (`repr(C)`,
        // packet and valid mask 64-byte aligned) and exclusively borrowed
        // for the call.
        unsafe { rtcOccluded16(valid.0.as_ptr(), self.scene, &mut context, ray) };
        // Embree marks an occluded ray by setting its tfar to −∞.
        (0..16).fold(0, |m, i| {
            m | (u32::from(ray.tfar[i] == f32::NEG_INFINITY) << i)
        })
    }
}

/// The sample pattern as offsets from the µQuad centre, `u − ½` and
/// `v − ½`, sixteen lanes per packet: samples 0–15, then 16–31.
struct PatternLanes {
    du: [[f32; 16]; 2],
    dv: [[f32; 16]; 2],
}

impl PatternLanes {
    fn new(pattern: &[[f32; 2]; 32]) -> PatternLanes {
        let lanes = |axis: usize, half: usize| -> [f32; 16] {
            std::array::from_fn(|i| pattern[16 * half + i][axis] - 0.5)
        };
        PatternLanes {
            du: [lanes(0, 0), lanes(0, 1)],
            dv: [lanes(1, 0), lanes(1, 1)],
        }
    }
}

impl RtcRay16 {
    /// Packet `half` of [`sample_rays`]`(light, p, ex, ey, pattern)`, bit
    /// for bit (the same operations in the same order, see the unit
    /// test), written lane by lane so that the compiler computes sixteen
    /// rays per instruction. Built one ray at a time and then copied into
    /// the packet, our setup was 20–43 % of `rt32-embree`'s time at
    /// 1920×1080 (session 36), a handicap no renderer feeding Embree would
    /// carry; built so, everything but Embree's call is 9–22 % (session
    /// 37: the G-buffer's reads, the packet, the mask).
    fn sample_rays(
        light: &Light,
        p: Vec3,
        ex: Vec3,
        ey: Vec3,
        lanes: &PatternLanes,
        half: usize,
    ) -> RtcRay16 {
        let (du, dv) = (&lanes.du[half], &lanes.dv[half]);
        let offset = ray_offset(ex, ey);
        let mut ray = RtcRay16 {
            org_x: [0.0; 16],
            org_y: [0.0; 16],
            org_z: [0.0; 16],
            tnear: [offset; 16],
            dir_x: [0.0; 16],
            dir_y: [0.0; 16],
            dir_z: [0.0; 16],
            time: [0.0; 16],
            tfar: [f32::INFINITY; 16],
            mask: [u32::MAX; 16],
            id: std::array::from_fn(|i| i as u32),
            flags: [0; 16],
        };
        for i in 0..16 {
            ray.org_x[i] = p.x + du[i] * ex.x + dv[i] * ey.x;
            ray.org_y[i] = p.y + du[i] * ex.y + dv[i] * ey.y;
            ray.org_z[i] = p.z + du[i] * ex.z + dv[i] * ey.z;
        }
        match *light {
            Light::Directional { direction } => {
                let direction = -direction.as_vec3();
                ray.dir_x = [direction.x; 16];
                ray.dir_y = [direction.y; 16];
                ray.dir_z = [direction.z; 16];
            }
            Light::Point { position } => {
                let position = position.as_vec3();
                for i in 0..16 {
                    // t in units of the sample-to-light vector.
                    let x = position.x - ray.org_x[i];
                    let y = position.y - ray.org_y[i];
                    let z = position.z - ray.org_z[i];
                    let length = (x * x + y * y + z * z).sqrt();
                    let reach = offset / length.max(f32::MIN_POSITIVE);
                    (ray.dir_x[i], ray.dir_y[i], ray.dir_z[i]) = (x, y, z);
                    ray.tnear[i] = reach;
                    ray.tfar[i] = 1.0 - reach;
                }
            }
        }
        ray
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
    let lanes = PatternLanes::new(pattern);
    trace_pixels(scene, g, |light, p, ex, ey| {
        let packet = |half| RtcRay16::sample_rays(light, p, ex, ey, &lanes, half);
        embree.occluded16(&mut packet(0)) | embree.occluded16(&mut packet(1)) << 16
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::peer::shadow_rays::sample_rays;
    use glam::DVec3;

    /// The packets hold [`sample_rays`]' rays bit for bit, for both kinds
    /// of light, on pixels of very different scales.
    #[test]
    fn packets_hold_the_sample_rays_bit_for_bit() {
        let pattern: [[f32; 2]; 32] =
            std::array::from_fn(|k| [(k as f32 * 0.618_034).fract(), (k as f32 + 0.5) / 32.0]);
        let lanes = PatternLanes::new(&pattern);
        let lights = [
            Light::Directional {
                direction: DVec3::new(0.3, -0.8, 0.2).normalize(),
            },
            Light::Point {
                position: DVec3::new(3.0, 40.0, -7.5),
            },
        ];
        let pixels = [
            (
                Vec3::new(0.1, -2.0, 5.0),
                Vec3::new(0.01, 0.0, 0.003),
                Vec3::new(0.0, 0.011, 0.0),
            ),
            (
                Vec3::new(-812.5, 3.25, 1e4),
                Vec3::new(1.7, 0.2, 0.0),
                Vec3::new(0.0, 0.9, -2.1),
            ),
            (
                Vec3::new(3.0, 40.0, -7.5),
                Vec3::new(1e-6, 0.0, 0.0),
                Vec3::new(0.0, 0.0, 1e-6),
            ),
        ];
        let mut checked = 0;
        for light in &lights {
            for &(p, ex, ey) in &pixels {
                let rays = sample_rays(light, p, ex, ey, &pattern);
                for half in 0..2 {
                    let packet = RtcRay16::sample_rays(light, p, ex, ey, &lanes, half);
                    for (i, r) in rays[16 * half..16 * half + 16].iter().enumerate() {
                        let lane = [
                            packet.org_x[i],
                            packet.org_y[i],
                            packet.org_z[i],
                            packet.dir_x[i],
                            packet.dir_y[i],
                            packet.dir_z[i],
                            packet.tnear[i],
                            packet.tfar[i],
                        ];
                        let ray = [
                            r.origin.x,
                            r.origin.y,
                            r.origin.z,
                            r.direction.x,
                            r.direction.y,
                            r.direction.z,
                            r.t_near,
                            r.t_far,
                        ];
                        assert_eq!(
                            lane.map(f32::to_bits),
                            ray.map(f32::to_bits),
                            "light {light:?}, pixel {p}, sample {}",
                            16 * half + i
                        );
                        checked += 1;
                    }
                }
            }
        }
        assert_eq!(checked, 2 * 3 * 32);
    }
}
