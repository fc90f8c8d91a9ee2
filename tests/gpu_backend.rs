//! The Vulkan backend against its CPU twins, pass by pass and sample by
//! sample, on every procedural and shared scene (reduced resolution).
//!
//! Two comparisons per scene and mode:
//! - **uploaded G-buffer**: the CPU G-buffer goes to the GPU, so
//!   light_setup, bin, evaluate and resolve see exactly the CPU twin's
//!   input; masks must agree on ≥ 99.99% of samples;
//! - **GPU G-buffer**: the `gbuffer` pass casts the rays itself; the
//!   triangle id must agree on ≥ 99.9% of pixels, the µQuad axes within
//!   their tolerance where it does, and the masks again on ≥ 99.99% of
//!   samples.
//!
//! No Vulkan device: each test prints that it skipped — unless
//! `IZB_REQUIRE_GPU=1` (CI), where that fails. Every test also fails on any
//! validation-layer message (`IZB_VALIDATION=1` turns the layer on).

use izb::gbuffer::{flags, GBuffer};
mod common;

use common::gpu::{assert_no_validation_messages, renderer};
use izb::bvh::SceneBvh;
use izb::cpu::{render_cpu, CascadeCount, IzbSettings, ReceiverCull, SampleMode};
use izb::gpu::{GBufferSource, GpuError, GpuRenderer};
use izb::scene::{self, Scene};

/// Test resolution; `IZB_GPU_TEST_RESOLUTION=scene` runs each scene at its
/// own resolution (slow on lavapipe: for measurements, not CI).
const RESOLUTION: [u32; 2] = [240, 135];

fn test_resolution(scene: &Scene) -> [u32; 2] {
    match std::env::var("IZB_GPU_TEST_RESOLUTION").as_deref() {
        Ok("scene") => scene.resolution,
        _ => RESOLUTION,
    }
}
/// Whether to run scene `name`: all, or those listed in
/// `IZB_GPU_TEST_SCENES=a,b,…` (for full-resolution measurements).
fn selected(name: &str) -> bool {
    match std::env::var("IZB_GPU_TEST_SCENES") {
        Ok(list) => list.split(',').any(|s| s.trim() == name),
        Err(_) => true,
    }
}

/// Largest fraction of samples GPU and CPU masks may disagree on, on a
/// GPU: Vulkan allows 2.5 ulp for division and square roots and leaves
/// `atan`'s precision open, which can move a LUT cell or a tolerance
/// comparison that sits within rounding of its boundary.
const MAX_SAMPLE_MISMATCH: f64 = 1e-4;

/// The allowance when the GPU saw the CPU's own G-buffer: none on a CPU
/// device (lavapipe: IEEE `f32` arithmetic, as the CPU twin, and 0 samples
/// measured on every scene and mode), [`MAX_SAMPLE_MISMATCH`] on a GPU.
fn uploaded_allowance(r: &GpuRenderer) -> f64 {
    if r.context.info().is_cpu() {
        0.0
    } else {
        MAX_SAMPLE_MISMATCH
    }
}
/// Largest fraction of hit pixels whose triangle id may differ.
const MAX_ID_MISMATCH: f64 = 1e-3;
/// µQuad axes: |gpu − cpu| ≤ max(this, 32 ε₃₂ κ) × |cpu| × stretch, where
/// stretch ≥ 1 is the axis length over the pixel's footprint on a plane
/// facing the ray (1/|cos| of the view angle, clamped at 64: the axis
/// divides by n·D, so the f32 ray cast's rounding grows with exactly that
/// factor) and κ = (distance of the hit triangle from the eye) / (its
/// shortest edge), the conditioning of its f32 normal.
const AXIS_RELATIVE_TOLERANCE: f32 = 1e-3;

/// (differing samples, compared samples) over pixels shadow-tested in `g`.
fn mask_mismatch(a: &[u32], b: &[u32], g: &GBuffer) -> (u64, u64) {
    izb::metrics::sample_mismatches(a, b, |i| g.flags[i] & flags::SHADOW_TESTED != 0)
}

/// The settings of a comparison: 32-sample modes with two cascades (so
/// the per-cascade grids, splits and overflow tags are compared too), 1 spp
/// with `auto`.
fn settings(mode: SampleMode) -> IzbSettings {
    IzbSettings {
        mode,
        cascades: match mode {
            SampleMode::One => CascadeCount::Auto,
            _ => CascadeCount::Fixed(2),
        },
        ..Default::default()
    }
}

/// Cells of each cascade's grid.
fn grids_of<T>(grids: &[T], cells: impl Fn(&T) -> [u32; 2]) -> Vec<[u32; 2]> {
    grids.iter().map(cells).collect()
}

/// Whether triangles `a` and `b` are the same surface: equal, or exact
/// duplicates (the same three vertices in any order — double-sided
/// exports, e.g. the deckchair). Which duplicate a ray reports depends only
/// on rounding and traversal order, and neither can shadow the other.
fn same_surface(scene: &Scene, a: u32, b: u32) -> bool {
    if a == b {
        return true;
    }
    let (Some(ta), Some(tb)) = (
        scene.triangles.get(a as usize),
        scene.triangles.get(b as usize),
    ) else {
        return false;
    };
    let key = |t: &izb::scene::Triangle| {
        let mut k = t.map(|v| v.to_array().map(f64::to_bits));
        k.sort();
        k
    };
    key(ta) == key(tb)
}

/// Runs both comparisons on one scene and every mode; returns how many
/// modes it compared.
fn check_scene(r: &GpuRenderer, name: &str, scene: Scene) -> usize {
    let mut compared = 0;
    let resolution = test_resolution(&scene);
    let scene = scene.with_resolution(resolution).unwrap();
    let bvh = SceneBvh::build(&scene);
    for mode in [SampleMode::One, SampleMode::Lut32, SampleMode::Exact32] {
        // The requested settings or a failure: a frame the device refuses
        // (lavapipe's loop cap) is not compared with other settings instead.
        let s = settings(mode);
        let cpu = render_cpu(&scene, &bvh, s);
        let gpu = r
            .render(&scene, s, GBufferSource::Upload(&cpu.gbuffer))
            .unwrap_or_else(|e| panic!("{name} {mode:?}: {e}"));
        assert_no_validation_messages(r, name);
        let (diff, total) = mask_mismatch(&gpu.masks, &cpu.masks, &cpu.gbuffer);
        let rate = diff as f64 / total.max(1) as f64;
        println!(
            "{name} {mode:?} (uploaded G-buffer): {diff} of {total} samples differ ({rate:.2e}); \
             grid GPU {:?} CPU {:?}; tests GPU {} CPU {}",
            grids_of(&gpu.report.light.cascades, |g| g.cells),
            grids_of(&cpu.report.light.cascades, |g| g.cells),
            gpu.report.counters.tests_spawned,
            cpu.report.evaluate.tests_spawned
        );
        let allowed = uploaded_allowance(r);
        assert!(
            rate <= allowed,
            "{name} {mode:?}: {diff} of {total} samples differ ({rate:.2e} > {allowed:.0e})"
        );
        compared += 1;
        // resolve: lit fraction bit for bit from the same masks, and the
        // shaded image within one 8-bit level of the CPU twin.
        let cpu_visibility = izb::cpu::resolve(&gpu.masks, &cpu.gbuffer);
        for (i, (g, c)) in gpu.visibility.iter().zip(&cpu_visibility).enumerate() {
            assert!(
                g.to_bits() == c.to_bits() || (g.is_nan() && c.is_nan()),
                "{name}: visibility of pixel {i}: GPU {g}, CPU {c}"
            );
        }
        let light = scene.light.relative_to(scene.camera.eye);
        for (i, g) in gpu.shaded.iter().enumerate() {
            let c = izb::output::shade_pixel(&cpu.gbuffer, i, &light, gpu.visibility[i]);
            let off = (0..3).map(|k| g[k].abs_diff(c[k])).max().unwrap();
            assert!(off <= 1, "{name}: shaded pixel {i}: GPU {g:?}, CPU {c:?}");
        }
    }

    // The GPU G-buffer against the CPU twin.
    let cpu = render_cpu(&scene, &bvh, settings(SampleMode::Lut32));
    let gpu = r
        .render(&scene, settings(SampleMode::Lut32), GBufferSource::Gpu)
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    assert_no_validation_messages(r, name);
    let (g, c) = (&gpu.gbuffer, &cpu.gbuffer);
    let hits = c.flags.iter().filter(|&&f| f & flags::HIT != 0).count();
    let mut id_diff = 0usize;
    let mut duplicates = 0usize;
    let mut worst_axis = 0.0f32;
    let frame = scene.camera.frame(scene.resolution);
    let eye_triangles = scene.eye_relative_triangles();
    for i in 0..c.flags.len() {
        if g.triangle_id[i] != c.triangle_id[i] {
            if same_surface(&scene, g.triangle_id[i], c.triangle_id[i]) {
                duplicates += 1;
            } else {
                id_diff += 1;
                continue;
            }
        }
        if c.flags[i] & flags::HIT == 0 {
            continue;
        }
        assert_eq!(g.flags[i], c.flags[i], "{name}: flags of pixel {i}");
        let (x, y) = (
            (i as u32 % c.width) as f64 + 0.5,
            (i as u32 / c.width) as f64 + 0.5,
        );
        let footprint = (f64::from(c.depth[i])
            * frame.direction_dx().length()
            * frame.direction(x, y).length()) as f32;
        // Conditioning of the f32 normal: the hit triangle's distance from
        // the eye over its shortest edge.
        let t = eye_triangles[c.triangle_id[i] as usize];
        let reach = t.iter().map(|v| v.length()).fold(0.0, f64::max);
        let edge = [t[1] - t[0], t[2] - t[1], t[0] - t[2]]
            .iter()
            .map(|e| e.length())
            .fold(f64::INFINITY, f64::min);
        let conditioning = (reach / edge) as f32;
        for (ga, ca) in [(g.axis_x[i], c.axis_x[i]), (g.axis_y[i], c.axis_y[i])] {
            let stretch = (ca.length() / footprint).max(1.0);
            let tolerance = AXIS_RELATIVE_TOLERANCE.max(32.0 * f32::EPSILON * conditioning);
            let rel = (ga - ca).length() / ca.length().max(f32::MIN_POSITIVE) / stretch / tolerance;
            worst_axis = worst_axis.max(rel);
        }
    }
    let id_rate = id_diff as f64 / hits.max(1) as f64;
    let (diff, total) = mask_mismatch(&gpu.masks, &cpu.masks, c);
    println!(
        "{name} (GPU G-buffer): triangle id differs on {id_diff} of {hits} hit pixels ({id_rate:.2e}; \
         {duplicates} more hit an exact duplicate), \
         worst µQuad-axis error {worst_axis:.2} of its tolerance; masks differ on {diff} of {total} samples \
         ({:.2e})",
        diff as f64 / total.max(1) as f64
    );
    assert!(
        diff as f64 <= MAX_SAMPLE_MISMATCH * total as f64,
        "{name}: full GPU pipeline masks differ on {diff} of {total} samples"
    );
    assert!(
        id_rate <= MAX_ID_MISMATCH,
        "{name}: {id_diff} of {hits} pixels hit another triangle"
    );
    assert!(
        worst_axis <= 1.0,
        "{name}: µQuad axes off by {worst_axis:.2} times their tolerance"
    );
    compared
}

#[test]
fn gpu_matches_cpu_on_procedural_scenes() {
    let Some(r) = renderer() else { return };
    let r = r.lock().unwrap_or_else(|e| e.into_inner());
    let names: Vec<_> = scene::procedural::NAMES
        .iter()
        .filter(|n| selected(n))
        .collect();
    let compared: usize = names
        .iter()
        .map(|name| check_scene(&r, name, scene::load(name).unwrap()))
        .sum();
    assert_eq!(compared, 3 * names.len(), "every mode of every scene");
}

#[test]
fn gpu_matches_cpu_on_shared_scenes() {
    let Some(dir) = common::shared_scenes_dir() else {
        return;
    };
    let dir = dir.display();
    let Some(r) = renderer() else { return };
    let r = r.lock().unwrap_or_else(|e| e.into_inner());
    let names: Vec<_> = common::SHARED_SCENES
        .into_iter()
        .filter(|n| selected(n))
        .collect();
    let compared: usize = names
        .iter()
        .map(|name| {
            let scene = scene::load(&format!("{dir}/{name}.scene.json")).unwrap();
            check_scene(&r, name, scene)
        })
        .sum();
    assert_eq!(compared, 3 * names.len(), "every mode of every scene");
}

#[test]
fn grid_capacity_overrun_reruns_with_room() {
    // A fine grid and a 40 000-cell overflow threshold make triangles'
    // rectangles cover many cells (the ground's nearly the whole grid):
    // whatever the first guess, the result must equal the CPU's. This also
    // caught a loop in the bin pass's cover test that lavapipe counted
    // toward its loop cap per cell and so cut the count loop silently.
    let Some(r) = renderer() else { return };
    let r = r.lock().unwrap_or_else(|e| e.into_inner());
    let scene = scene::load("hairball")
        .unwrap()
        .with_resolution([96, 64])
        .unwrap();
    let bvh = SceneBvh::build(&scene);
    // The GPU twin takes the behind-receivers skip whatever the density.
    let s = IzbSettings {
        mode: SampleMode::Exact32,
        cells: Some(200),
        level_cells: Some(200 * 200),
        receiver_cull: ReceiverCull::Always,
        ..Default::default()
    };
    let cpu = render_cpu(&scene, &bvh, s);
    let gpu = r
        .render(&scene, s, GBufferSource::Upload(&cpu.gbuffer))
        .unwrap();
    assert_no_validation_messages(&r, "capacity");
    println!(
        "hairball, 200-cell grid: {} cell entries ({} on the CPU), {} frame(s); grids GPU {:?} \
         CPU {:?}; behind receivers GPU {} CPU {}",
        gpu.report.counters.cell_entries,
        cpu.report.bin.cell_entries,
        gpu.report.frames_run,
        grids_of(&gpu.report.light.cascades, |g| g.cells),
        grids_of(&cpu.report.light.cascades, |g| g.cells),
        gpu.report.counters.entries_behind_receivers,
        cpu.report.bin.entries_behind_receivers
    );
    assert_eq!(
        gpu.report.frames_run, 2,
        "the first cell-list guess was big enough: nothing was rerun"
    );
    assert_eq!(
        gpu.report.counters.cell_entries as usize,
        cpu.report.bin.cell_entries
    );
    let (diff, total) = mask_mismatch(&gpu.masks, &cpu.masks, &cpu.gbuffer);
    assert!(diff as f64 <= uploaded_allowance(&r) * total as f64);
}

#[test]
fn an_overrun_cell_list_stays_exact_the_slow_way() {
    // A cell list far too small and never grown (a pass inside a host's
    // frame cannot rerun it): the bin puts every placed triangle in the
    // overflow list instead, so the one frame's masks are the grown
    // frame's bit for bit, in the exact and the LUT mode, and the report
    // names the need.
    let Some(r) = renderer() else { return };
    let r = r.lock().unwrap_or_else(|e| e.into_inner());
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([96, 54])
        .unwrap();
    let bvh = SceneBvh::build(&scene);
    let mut checked = 0;
    for mode in [SampleMode::Exact32, SampleMode::Lut32] {
        let s = settings(mode);
        let cpu = render_cpu(&scene, &bvh, s);
        let source = GBufferSource::Upload(&cpu.gbuffer);
        let grown = r.render(&scene, s, source).unwrap();
        let small = r.render_with_cell_capacity(&scene, s, source, 64).unwrap();
        assert_no_validation_messages(&r, "overrun");
        let (c, g) = (&small.report.counters, &grown.report.counters);
        println!(
            "{mode:?}: need {} entries, 64 given; overflow entries {} (grown frame {}), tests \
             {} (grown frame {})",
            c.cell_entries, c.overflow, g.overflow, c.tests_spawned, g.tests_spawned
        );
        assert!(c.cell_list_overrun && !g.cell_list_overrun);
        assert_eq!(small.report.frames_run, 1);
        assert_eq!(c.cell_entries, g.cell_entries, "the need is the grown list");
        assert!(c.overflow > g.overflow, "placed triangles went to the list");
        assert!(c.tests_spawned > g.tests_spawned, "the slow way");
        // Every triangle of the pixel's cascade is a superset of its grid
        // candidates, so the masks hold the grown frame's bits; exact
        // masks of triangles the grid did not offer are empty.
        let lost = (small.masks.iter().zip(&grown.masks)).filter(|&(s, g)| s & g != *g);
        assert_eq!(lost.count(), 0, "{mode:?}: a grid candidate's bit was lost");
        let (extra, total) = mask_mismatch(&small.masks, &grown.masks, &cpu.gbuffer);
        println!("{mode:?}: {extra} of {total} samples set by triangles off the grid");
        if mode == SampleMode::Exact32 {
            assert_eq!(small.masks, grown.masks, "exact masks of the overrun frame");
            let (diff, total) = mask_mismatch(&small.masks, &cpu.masks, &cpu.gbuffer);
            assert!(diff as f64 <= uploaded_allowance(&r) * total as f64);
        } else {
            // The LUT's masks of a triangle just outside a µQuad's
            // footprint may hold samples within the LUT's bound of its
            // edges.
            assert!(extra as f64 <= 1e-3 * total as f64);
        }
        checked += 1;
    }
    assert_eq!(checked, 2);
}

#[test]
fn gpu_reports_memory_and_counters() {
    let Some(r) = renderer() else { return };
    let r = r.lock().unwrap_or_else(|e| e.into_inner());
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([160, 90])
        .unwrap();
    let gpu = r
        .render(&scene, IzbSettings::default(), GBufferSource::Gpu)
        .unwrap();
    assert_no_validation_messages(&r, "memory");
    let rep = &gpu.report;
    let per_pass: u64 = rep.memory.iter().map(|m| m.bytes).sum();
    assert_eq!(per_pass, rep.memory_total_bytes);
    // `izb info --gpu-memory`'s plan, made without a device, is what the
    // frame allocated (its cell list did not grow), pass by pass; the
    // batch pass for one view lets the bin's lists reuse the BVH's
    // memory, which a resident pass keeps.
    assert_eq!(rep.frames_run, 1);
    let plan =
        izb::gpu::shadow_pass::planned_memory(&scene, IzbSettings::default(), None, true).unwrap();
    let by_pass = |m: &[izb::gpu::frame::PassMemory]| {
        let mut v: Vec<(&str, u64)> = m.iter().map(|m| (m.pass, m.bytes)).collect();
        v.sort();
        v
    };
    assert_eq!(by_pass(&plan), by_pass(&rep.memory));
    let resident =
        izb::gpu::shadow_pass::planned_memory(&scene, IzbSettings::default(), None, false).unwrap();
    let resident: u64 = resident.iter().map(|m| m.bytes).sum();
    assert!(
        resident > per_pass,
        "resident {resident} B, one view {per_pass} B"
    );
    for pass in ["gbuffer", "light_setup", "bin", "evaluate", "resolve"] {
        assert!(
            rep.memory.iter().any(|m| m.pass == pass && m.bytes > 0),
            "no memory recorded for {pass}"
        );
    }
    assert_eq!(rep.counters.shadow_tested, rep.counters.pixels_tested);
    assert!(rep.counters.tests_spawned > 0);
    assert_eq!(
        rep.counters.triangles_binned + rep.counters.overflow + rep.counters.culled,
        scene.triangles.len() as u32
    );
}

#[test]
fn oversized_buffers_are_refused_by_name() {
    let Some(r) = renderer() else { return };
    let r = r.lock().unwrap_or_else(|e| e.into_inner());
    let limit = r.context.info().max_storage_buffer_range as u64;
    // The µQuad-axis arrays take 12 bytes a pixel: pick a square image just
    // past the limit, if one fits under 16384 per side.
    let side = ((limit / 12) as f64).sqrt().ceil() as u32 + 1;
    if side > 16384 {
        eprintln!("skipped: this device's storage-buffer range ({limit} bytes) holds 16384²");
        return;
    }
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([side, side])
        .unwrap();
    let err = r
        .render(&scene, IzbSettings::default(), GBufferSource::Gpu)
        .err()
        .expect("an image past the storage-buffer range must be refused");
    println!("{side}x{side}: {err}");
    assert!(
        matches!(err, GpuError::BufferTooLarge { .. }),
        "unexpected error {err}"
    );
    assert!(err.to_string().contains("lower the resolution"));
    assert_no_validation_messages(&r, "oversized");
}

#[test]
fn a_lost_device_is_reported_as_such() {
    // Vulkan reports a lost device through VK_ERROR_DEVICE_LOST on any
    // call; every call site maps results through `GpuError::vk`.
    let e = GpuError::vk(ash::vk::Result::ERROR_DEVICE_LOST);
    assert!(matches!(e, GpuError::DeviceLost));
    assert!(e.to_string().contains("lost"));
}

/// A frame timed over several repetitions in one submission returns the
/// results of a single frame: every repetition starts from the same state,
/// including the BVH, whose memory the bin's lists reuse (copied in again
/// before each repetition).
#[test]
fn timed_repetitions_give_a_single_frames_results() {
    let Some(r) = renderer() else { return };
    let r = r.lock().unwrap_or_else(|e| e.into_inner());
    let Some(timed) = common::gpu::own_renderer(&izb::gpu::GpuOptions::from_env()) else {
        return;
    };
    let timed = timed.timed(3);
    let settings = IzbSettings {
        mode: SampleMode::Exact32,
        edge_surfaces: true,
        ..Default::default()
    };
    let mut compared = 0;
    for name in ["default", "city"] {
        let scene = scene::load(name)
            .unwrap()
            .with_resolution([96, 64])
            .unwrap();
        let once = r.render(&scene, settings, GBufferSource::Gpu).unwrap();
        let thrice = timed.render(&scene, settings, GBufferSource::Gpu).unwrap();
        assert_no_validation_messages(&r, name);
        assert_no_validation_messages(&timed, name);
        assert!(once.masks.iter().any(|&m| m != 0), "{name}: no shadow");
        assert_eq!(once.masks, thrice.masks, "{name}: masks");
        assert_eq!(
            once.gbuffer.triangle_id, thrice.gbuffer.triangle_id,
            "{name}: ids"
        );
        assert_eq!(
            once.report.counters.cell_entries, thrice.report.counters.cell_entries,
            "{name}: cell entries"
        );
        compared += 1;
    }
    assert_eq!(compared, 2);
}
