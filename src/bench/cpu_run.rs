//! One CPU run of one benchmarked method: its lit fractions (and masks),
//! its seconds per pass and its details, as `bench_scene_cpu` repeats it.

use super::{run_placeholder, MethodKind, Runs, SceneTruth};
use crate::baseline::render_shadow_map;
use crate::cpu::render_cpu;
use crate::reference::same_samples::{edge_same_sample_masks, same_sample_masks};
use crate::scene::Scene;
use serde_json::json;
use std::time::Instant;

/// The same-sample reference of `scene`: `rt32` (the µQuad's samples,
/// with `edge_surfaces` each edge pixel's on its own surfaces), or under an
/// area light `rt-soft` (the light's samples at P). With it, the samples
/// that count per pixel when not all do.
pub(super) fn same_sample_masks_of(
    scene: &Scene,
    bvh: &crate::bvh::SceneBvh,
    edge_surfaces: bool,
) -> (Vec<u32>, Option<Vec<u32>>) {
    if scene.has_area_light() {
        let masks = crate::reference::soft_samples::soft_same_sample_masks(
            scene,
            bvh,
            crate::lut::light_pattern(),
            None,
        );
        (masks, None)
    } else if edge_surfaces {
        let m = edge_same_sample_masks(scene, bvh, crate::lut::sample_pattern());
        (m.masks, Some(m.counted))
    } else {
        (
            same_sample_masks(scene, bvh, crate::lut::sample_pattern()),
            None,
        )
    }
}

/// Runs one method once on the CPU: (visibility, masks, per-pass seconds,
/// shadow seconds, total seconds, details).
pub(super) fn run_once(
    scene: &Scene,
    shared: &SceneTruth,
    kind: &MethodKind,
) -> Result<Runs, String> {
    let mut r = run_placeholder();
    match kind {
        MethodKind::Izb(settings) => {
            let out = render_cpu(scene, &shared.bvh, *settings);
            let s = &out.report.seconds;
            r.shadow.push(s.shadow());
            r.total.push(s.total);
            r.seconds.push(json!(s));
            r.details = json!({
                "bin": out.report.bin,
                "evaluate": out.report.evaluate,
                "work_per_pixel": out.report.work_per_pixel,
                "evaluate_ns_per_test_per_thread": out.report.evaluate_ns_per_test_per_thread,
                "ns_per_receiver_outside_evaluate_per_thread":
                    out.report.ns_per_receiver_outside_evaluate_per_thread,
                "cascades": out.report.light.cascade_choice,
                "grids": out.report.light.cascades,
            });
            r.visibility = out.visibility;
            r.masks = Some(out.masks);
        }
        MethodKind::RayTraced32 { edge_surfaces } => {
            let t = Instant::now();
            let (masks, counted) = same_sample_masks_of(scene, &shared.bvh, *edge_surfaces);
            // rt32 casts its own primary rays: its whole run is its time.
            r.record_trace(masks, t.elapsed().as_secs_f64(), 0.0, shared);
            if let Some(counted) = counted {
                r.visibility = crate::cpu::resolve_counted(
                    r.masks.as_deref().unwrap_or_default(),
                    &counted,
                    &shared.gbuffer,
                );
            }
        }
        MethodKind::Embree32 | MethodKind::ShadowRays32 if scene.has_area_light() => {
            return Err(
                "traces the µQuad's 32 samples toward the light's centre: under an \
                        area light the peer is rt-soft"
                    .into(),
            )
        }
        MethodKind::Embree32 => embree_once(scene, shared, &mut r)?,
        MethodKind::ShadowRays32 => {
            let t = Instant::now();
            let masks = crate::peer::shadow_rays::shadow_rays(
                scene,
                &shared.bvh,
                &shared.gbuffer,
                crate::lut::sample_pattern(),
            );
            r.record_trace(
                masks,
                t.elapsed().as_secs_f64(),
                shared.gbuffer_seconds,
                shared,
            );
        }
        MethodKind::ShadowVolumes => {
            let out = crate::baseline::volumes::shadow_volumes(scene, &shared.gbuffer);
            let s = out.report.seconds;
            let seconds = json!({ "shadow_volumes": s });
            r.record_baseline(s, seconds, json!(out.report), out.visibility, shared);
        }
        MethodKind::ShadowMap(settings) => {
            let out = render_shadow_map(scene, &shared.gbuffer, *settings)?;
            let s = out.report.seconds.shadow;
            let seconds = json!(out.report.seconds);
            r.record_baseline(s, seconds, json!(out.report), out.visibility, shared);
        }
    }
    Ok(r)
}

/// `rt32-embree` once: Embree's BVH over the eye-relative triangles, then
/// the shared G-buffer's sample rays (shadow seconds: the tracing alone).
#[cfg(feature = "embree")]
fn embree_once(scene: &Scene, shared: &SceneTruth, r: &mut Runs) -> Result<(), String> {
    use crate::peer::embree::{rt32_embree_masks, EmbreeScene};
    let embree = EmbreeScene::new(&crate::cpu::eye_relative_f32(scene))?;
    let t = Instant::now();
    let masks = rt32_embree_masks(
        scene,
        &embree,
        &shared.gbuffer,
        crate::lut::sample_pattern(),
    );
    r.record_trace(
        masks,
        t.elapsed().as_secs_f64(),
        shared.gbuffer_seconds,
        shared,
    );
    r.details = json!({ "bvh_build_seconds": embree.build_seconds, "threads": rayon::current_num_threads() });
    Ok(())
}

#[cfg(not(feature = "embree"))]
fn embree_once(_: &Scene, _: &SceneTruth, _: &mut Runs) -> Result<(), String> {
    Err("rt32-embree needs izb built with `--features embree`".into())
}
