//! The embedded edge LUT and its proven misclassification bound, end to end
//! (Wyman et al. 2015, §4, paper-notes/frustum-test.md and §8: LUT mode must match the exact samples
//! within the LUT's proven quantisation bound); the same for the light
//! table of soft shadows (paper-notes/light-pattern.md).

use glam::DVec3;
use izb::frustum::soft::{cone_orientation, light_edge_function};
use izb::lut::{
    edge_lut, exact_mask, light_lut, light_lut_statistics, light_pattern, lut_statistics,
    regenerate, regenerate_tables, sample_pattern, signed_distance, EdgeLut, SamplePattern,
    ALL_SAMPLES, DEFAULT_ANGLES, DEFAULT_DISTANCES, LIGHT_DISK_RADIUS, LOOKUP_SLACK,
    REGENERATE_STATISTICS_LINES,
};
use izb::scene::light_disk;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

/// (a) What `build.rs` baked in is what the generator makes today.
#[test]
fn embedded_table_and_pattern_match_the_generator_bit_for_bit() {
    let generated_pattern = izb_lut::sample_pattern();
    let embedded_pattern = sample_pattern();
    for (i, (e, g)) in embedded_pattern.iter().zip(&generated_pattern).enumerate() {
        assert_eq!(
            e.map(f32::to_bits),
            g.map(f32::to_bits),
            "sample {i}: embedded {e:?}, generated {g:?}"
        );
    }
    let generated = EdgeLut::generate(DEFAULT_ANGLES, DEFAULT_DISTANCES, &generated_pattern);
    let embedded = edge_lut();
    assert_eq!(
        (embedded.angles, embedded.distances),
        (DEFAULT_ANGLES, DEFAULT_DISTANCES)
    );
    let differing = embedded
        .masks
        .iter()
        .zip(&generated.masks)
        .filter(|(a, b)| a != b)
        .count();
    assert_eq!(differing, 0, "{differing} cells differ from the generator");
    assert_eq!(*embedded, generated);
}

/// (a′) The same for the light samples and their table.
#[test]
fn embedded_light_table_and_pattern_match_the_generator_bit_for_bit() {
    let generated_pattern = izb_lut::light_pattern();
    for (i, (e, g)) in light_pattern().iter().zip(&generated_pattern).enumerate() {
        assert_eq!(
            e.map(f32::to_bits),
            g.map(f32::to_bits),
            "light sample {i}: embedded {e:?}, generated {g:?}"
        );
    }
    let generated = EdgeLut::generate(DEFAULT_ANGLES, DEFAULT_DISTANCES, &generated_pattern);
    assert_eq!(*light_lut(), generated);
}

fn unit_vector(rng: &mut Pcg64) -> DVec3 {
    let z: f64 = rng.random_range(-1.0..1.0);
    let phi: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let r = (1.0 - z * z).sqrt();
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

fn log_uniform(rng: &mut Pcg64, lo: f64, hi: f64) -> f64 {
    (lo.ln() + (hi.ln() - lo.ln()) * rng.random::<f64>()).exp()
}

/// One random pixel and occluder: µQuad (P, Ex, Ey), directional light ω
/// (toward the light) and a triangle placed so that its shadow lands on or
/// near the µQuad, from sub-pixel to several pixels in size.
struct Configuration {
    p: DVec3,
    ex: DVec3,
    ey: DVec3,
    omega: DVec3,
    triangle: [DVec3; 3],
}

impl Configuration {
    fn random(rng: &mut Pcg64) -> Self {
        let p = DVec3::new(
            rng.random_range(-2.0..2.0),
            rng.random_range(-2.0..2.0),
            rng.random_range(-2.0..2.0),
        );
        let ex = unit_vector(rng) * log_uniform(rng, 0.01, 10.0);
        let ey = unit_vector(rng) * log_uniform(rng, 0.01, 10.0);
        let omega = unit_vector(rng);
        // Triangle in µQuad-relative coordinates (a, b) around a centre in
        // [−1, 1]², lifted toward the light, plus an off-plane jitter.
        let centre = [rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)];
        let size = log_uniform(rng, 0.05, 3.0);
        let reach = ex.length().max(ey.length());
        let triangle = std::array::from_fn(|_| {
            let a: f64 = centre[0] + size * rng.random_range(-1.0..1.0);
            let b: f64 = centre[1] + size * rng.random_range(-1.0..1.0);
            let lift = rng.random_range(0.1..3.0) * reach;
            p + a * ex + b * ey + lift * omega + 0.2 * reach * unit_vector(rng)
        });
        Self {
            p,
            ex,
            ey,
            omega,
            triangle,
        }
    }

    /// (α, β, γ) of each edge as paper-notes/frustum-test.md defines them, in f64: n =
    /// (B − A) × ω, flipped so the third vertex is inside; α = n·(P − A),
    /// β = n·Ex, γ = n·Ey.
    fn edges(&self) -> [[f64; 3]; 3] {
        std::array::from_fn(|k| {
            let (a, b, c) = (
                self.triangle[k],
                self.triangle[(k + 1) % 3],
                self.triangle[(k + 2) % 3],
            );
            let mut n = (b - a).cross(self.omega);
            if n.dot(c - a) < 0.0 {
                n = -n;
            }
            [n.dot(self.p - a), n.dot(self.ex), n.dot(self.ey)]
        })
    }
}

/// (b) Over random pixel/triangle configurations, LUT mode (AND of three
/// f32 lookups) differs from the exact f64 mask only at samples within the
/// proven bound (plus the f32 allowance) of some edge whose own bit the
/// LUT got wrong.
#[test]
fn triangle_masks_differ_from_exact_only_within_the_bound() {
    const CONFIGURATIONS: usize = 200_000;
    let pattern = sample_pattern();
    let lut = edge_lut();
    let mut rng = Pcg64::seed_from_u64(0x1b_2015);
    let (mut partial, mut mismatched_samples, mut worst_excess) = (0usize, 0usize, f64::MIN);
    for n in 0..CONFIGURATIONS {
        let config = Configuration::random(&mut rng);
        let edges = config.edges();
        let exact_edges = edges.map(|[a, b, c]| exact_mask(a, b, c, pattern));
        let lut_edges = edges.map(|[a, b, c]| lut.lookup(a as f32, b as f32, c as f32));
        let exact = exact_edges.iter().fold(ALL_SAMPLES, |m, e| m & e);
        let by_lut = lut_edges.iter().fold(ALL_SAMPLES, |m, e| m & e);
        partial += usize::from(exact != 0 && exact != ALL_SAMPLES);
        let mut differing = exact ^ by_lut;
        while differing != 0 {
            let i = differing.trailing_zeros() as usize;
            differing &= differing - 1;
            mismatched_samples += 1;
            let bound = lut.misclassification_bound(pattern[i]);
            // The smallest excess over the bound among the edges whose bit
            // at sample i the LUT got wrong (at least one must have).
            let excess = (0..3)
                .filter(|&k| (exact_edges[k] ^ lut_edges[k]) >> i & 1 == 1)
                .map(|k| {
                    let [a, b, c] = edges[k];
                    signed_distance(a, b, c, pattern[i]).abs() - bound
                })
                .fold(f64::INFINITY, f64::min);
            worst_excess = worst_excess.max(excess);
            assert!(
                excess <= LOOKUP_SLACK,
                "configuration {n}, sample {i}: |g| exceeds the bound {bound:.5} by {excess:.3e} \
                 (edges {edges:?}, exact {exact:#010x}, LUT {by_lut:#010x})"
            );
        }
    }
    let partial_fraction = partial as f64 / CONFIGURATIONS as f64;
    eprintln!(
        "{CONFIGURATIONS} configurations: {partial_fraction:.3} partly shadowed, \
         {mismatched_samples} samples LUT != exact, worst excess over the bound {worst_excess:.3e}"
    );
    assert!(
        partial_fraction > 0.25,
        "only {partial_fraction:.3} of the configurations cut the pixel: the test would be vacuous"
    );
    assert!(
        mismatched_samples > 0,
        "no mismatches met: the bound was never exercised"
    );
}

/// (c) `regenerate` writes the table and its picture and reports sane
/// statistics; a bad resolution is refused without writing anything.
#[test]
fn regenerate_writes_table_and_picture_and_measures_them() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("lut_bound_regenerate_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let (angles, distances) = (16, 8);
    let both = regenerate_tables(angles, distances, &dir).expect("regenerate_tables");
    let stats = both.edge;

    let bytes = std::fs::read(dir.join("edge_lut.bin")).expect("edge_lut.bin written");
    let lut = EdgeLut::from_bytes(&bytes).expect("edge_lut.bin decodes");
    assert_eq!(
        lut,
        EdgeLut::generate(angles, distances, &izb_lut::sample_pattern())
    );

    let png = image::open(dir.join("edge_lut.png"))
        .expect("edge_lut.png written")
        .to_rgb8();
    // 16 rows × 8 columns, scaled by 32 so the longer side is 512.
    assert_eq!(png.dimensions(), (8 * 32, 16 * 32));
    // Brightness is the fraction inside (70 %) plus a faint tint (30 %).
    let left = png.get_pixel(0, 0).0;
    assert_eq!(left, [0; 3], "d = −√2/2, no sample inside: {left:?}");
    let right = png.get_pixel(8 * 32 - 1, 0).0;
    assert!(
        right.iter().all(|&c| c >= 178),
        "d = √2/2, all inside: {right:?}"
    );

    eprintln!("{stats}");
    assert_eq!((stats.angles, stats.distances), (angles, distances));
    assert_eq!(stats.lines, REGENERATE_STATISTICS_LINES);
    assert!(
        stats.mismatch_rate > 0.0 && stats.mismatch_rate < 0.5,
        "mismatch rate {}",
        stats.mismatch_rate
    );
    assert_eq!(stats.bound_violations, 0, "{stats}");
    assert!(
        stats.worst_misclassified_distance <= stats.max_bound + LOOKUP_SLACK,
        "worst misclassified distance {} beyond the largest bound {}",
        stats.worst_misclassified_distance,
        stats.max_bound
    );
    assert!(
        stats.lut_coverage_rms >= stats.exact_coverage_rms * 0.9
            && stats.exact_coverage_rms > 0.0
            && stats.exact_coverage_rms < 0.05,
        "coverage RMS: LUT {} exact {}",
        stats.lut_coverage_rms,
        stats.exact_coverage_rms
    );

    // The light table: same resolution, same picture layout, its own
    // pattern and statistics over edges crossing the disk.
    let bytes = std::fs::read(dir.join("light_lut.bin")).expect("light_lut.bin written");
    let light = EdgeLut::from_bytes(&bytes).expect("light_lut.bin decodes");
    assert_eq!(
        light,
        EdgeLut::generate(angles, distances, &izb_lut::light_pattern())
    );
    let png = image::open(dir.join("light_lut.png"))
        .expect("light_lut.png written")
        .to_rgb8();
    assert_eq!(png.dimensions(), (8 * 32, 16 * 32));
    let light_stats = both.light;
    eprintln!("{light_stats:#?}");
    assert_eq!(
        (light_stats.angles, light_stats.distances),
        (angles, distances)
    );
    assert_eq!(light_stats.lines, REGENERATE_STATISTICS_LINES);
    assert_eq!(light_stats.bound_violations, 0, "{light_stats}");
    assert!(light_stats.mismatch_rate > 0.0 && light_stats.mismatch_rate < 0.5);
    assert!(
        light_stats.exact_coverage_rms > 0.0 && light_stats.exact_coverage_rms < 0.05,
        "light coverage RMS {}",
        light_stats.exact_coverage_rms
    );
    // The older entry point writes the same files and returns the pixel
    // table's statistics.
    std::fs::remove_file(dir.join("light_lut.bin")).expect("removing");
    assert_eq!(
        regenerate(angles, distances, &dir).expect("regenerate"),
        stats
    );
    assert!(dir.join("light_lut.bin").is_file());

    let refused = std::env::temp_dir().join(format!("lut_bound_refused_{}", std::process::id()));
    let error = regenerate(0, 8, &refused).expect_err("0 angles must be refused");
    assert!(error.to_string().contains("0x8"), "{error}");
    assert!(!refused.exists(), "a refused resolution wrote files");
    std::fs::remove_dir_all(&dir).expect("cleaning up");
}

/// (d) The light table's bound, edge by edge: 10⁶ random edges crossing the
/// light disk (θ uniform, d uniform over (−½, ½), scale log-uniform in
/// [10⁻³, 10³], rounded to f32), each looked up in the embedded light
/// table and compared with the f64 exact mask of the light pattern; every
/// misclassified sample lies within the proven bound. Also measures the
/// table both ways: over edges crossing the disk, and with
/// [`lut_statistics`] over edges crossing the whole square (a superset;
/// the extra edges cut no sample or almost none, so its rates are lower).
#[test]
fn light_table_misclassifies_only_within_the_bound() {
    const EDGES: usize = 1_000_000;
    let (pattern, lut) = (light_pattern(), light_lut());
    let mut rng = Pcg64::seed_from_u64(0x1164_2015);
    let (mut checked, mut split, mut mismatched, mut worst_excess) =
        (0usize, 0usize, 0usize, f64::MIN);
    for n in 0..EDGES {
        let theta: f64 = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
        let d: f64 = rng.random_range(-LIGHT_DISK_RADIUS..LIGHT_DISK_RADIUS);
        let scale = log_uniform(&mut rng, 1e-3, 1e3);
        let [alpha, beta, gamma] =
            [scale * d, scale * theta.cos(), scale * theta.sin()].map(|x| f64::from(x as f32));
        let c = lut.compare_with_exact(alpha, beta, gamma, pattern);
        checked += 1;
        split += usize::from(c.exact_mask != 0 && c.exact_mask != ALL_SAMPLES);
        mismatched += c.mismatched().count_ones() as usize;
        worst_excess = worst_excess.max(c.worst_excess);
        assert!(
            c.within_bound(),
            "edge {n} (θ={theta}, d={d}): excess {:.3e} over the bound",
            c.worst_excess
        );
    }
    assert_eq!(checked, EDGES);
    assert!(split > EDGES / 2, "only {split} edges split the samples");
    assert!(
        mismatched > 0,
        "no mismatches met: the bound was never exercised"
    );
    let disk = light_lut_statistics(lut, pattern, EDGES);
    let square = lut_statistics(lut, pattern, EDGES);
    eprintln!(
        "{checked} edges across the disk: {split} split the samples, {mismatched} samples \
         misclassified, worst excess over the bound {worst_excess:.3e}\n\
         across the disk:   {disk:?}\nacross the square: {square:?}"
    );
    for stats in [disk, square] {
        assert_eq!(stats.bound_violations, 0, "{stats}");
        assert!(stats.worst_bound_excess <= LOOKUP_SLACK, "{stats}");
    }
    // Every light sample is within ½ of the centre, so no sample's bound
    // exceeds Δd/2 + (Δθ/2)·½ light-disk diameters.
    let limit = 0.5 * lut.distance_step() + 0.25 * lut.angle_step();
    assert!(disk.max_bound < limit, "{} vs {limit}", disk.max_bound);
    assert!(disk.mismatch_rate > square.mismatch_rate);
}

/// One random receiver point P = 0, area light and occluder triangle whose
/// cone from P cuts the light's disk, from a sliver to several disks wide.
fn random_soft_configuration(rng: &mut Pcg64) -> (izb::scene::LightDisk<DVec3>, [DVec3; 3]) {
    let omega = unit_vector(rng);
    let radius = log_uniform(rng, 1e-3, 0.3);
    let disk = light_disk(omega, radius);
    let (e_u, e_v) = (disk.axis_u / (2.0 * radius), disk.axis_v / (2.0 * radius));
    let centre = [rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)];
    let size = log_uniform(rng, 0.05, 3.0);
    let triangle = std::array::from_fn(|_| {
        let a: f64 = centre[0] + size * rng.random_range(-1.0..1.0);
        let b: f64 = centre[1] + size * rng.random_range(-1.0..1.0);
        // Each vertex at its own depth: the cone is the same, the floats
        // are not.
        log_uniform(rng, 0.01, 100.0) * (omega + radius * (a * e_u + b * e_v))
    });
    (disk, triangle)
}

/// (e) Soft shadows end to end: over random receiver/light/triangle
/// configurations, the light-LUT mask of a triangle (AND of three f32
/// lookups of [`light_edge_function`]) differs from the f64 exact mask
/// only at light samples within the proven bound of an edge whose own bit
/// the table got wrong.
#[test]
fn soft_triangle_masks_differ_from_exact_only_within_the_bound() {
    const CONFIGURATIONS: usize = 200_000;
    let (pattern, lut): (&SamplePattern, _) = (light_pattern(), light_lut());
    let mut rng = Pcg64::seed_from_u64(0x50f7_2015);
    let (mut partial, mut mismatched_samples, mut worst_excess) = (0usize, 0usize, f64::MIN);
    for n in 0..CONFIGURATIONS {
        let (disk, t) = random_soft_configuration(&mut rng);
        let flip = cone_orientation(&t) < 0.0;
        let edges: [[f64; 3]; 3] = std::array::from_fn(|k| light_edge_function(&t, k, &disk, flip));
        let exact_edges = edges.map(|[a, b, c]| exact_mask(a, b, c, pattern));
        let lut_edges = edges.map(|[a, b, c]| lut.lookup(a as f32, b as f32, c as f32));
        let exact = exact_edges.iter().fold(ALL_SAMPLES, |m, e| m & e);
        let by_lut = lut_edges.iter().fold(ALL_SAMPLES, |m, e| m & e);
        partial += usize::from(exact != 0 && exact != ALL_SAMPLES);
        let mut differing = exact ^ by_lut;
        while differing != 0 {
            let i = differing.trailing_zeros() as usize;
            differing &= differing - 1;
            mismatched_samples += 1;
            let bound = lut.misclassification_bound(pattern[i]);
            let excess = (0..3)
                .filter(|&k| (exact_edges[k] ^ lut_edges[k]) >> i & 1 == 1)
                .map(|k| {
                    let [a, b, c] = edges[k];
                    signed_distance(a, b, c, pattern[i]).abs() - bound
                })
                .fold(f64::INFINITY, f64::min);
            worst_excess = worst_excess.max(excess);
            assert!(
                excess <= LOOKUP_SLACK,
                "configuration {n}, light sample {i}: |g| exceeds the bound {bound:.5} by \
                 {excess:.3e} (edges {edges:?})"
            );
        }
    }
    let partial_fraction = partial as f64 / CONFIGURATIONS as f64;
    eprintln!(
        "{CONFIGURATIONS} soft configurations: {partial_fraction:.3} partly occluding the light, \
         {mismatched_samples} light samples LUT != exact, worst excess {worst_excess:.3e}"
    );
    assert!(
        partial_fraction > 0.25,
        "only {partial_fraction:.3} cut the disk"
    );
    assert!(mismatched_samples > 0, "the bound was never exercised");
}
