//! Error of a lit-fraction image against the ground truth (paper-notes/reference-estimator.md).
//!
//! Only pixels shadow-tested in both images count. Pixel classes come from
//! the reference's `smooth` channel: a *smooth* pixel's sub-pixel hits all
//! lie on the centre hit's plane, the rest are *edge* pixels (silhouettes,
//! creases, sub-pixel geometry) where any µQuad extrapolates across
//! geometry. Antialiasing is judged on smooth *penumbra* pixels
//! (0 < truth < 1).

/// Error metrics of one method on one scene.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Metrics {
    pub pixels: usize,
    #[serde(deserialize_with = "crate::output::nan_if_null")]
    pub mae: f64,
    #[serde(deserialize_with = "crate::output::nan_if_null")]
    pub rmse: f64,
    #[serde(deserialize_with = "crate::output::nan_if_null")]
    pub max_error: f64,
    /// Percentage of pixels whose error exceeds 1/32 (one sample).
    #[serde(deserialize_with = "crate::output::nan_if_null")]
    pub percent_over_one_sample: f64,
    pub smooth_penumbra_pixels: usize,
    #[serde(deserialize_with = "crate::output::nan_if_null")]
    pub smooth_penumbra_mae: f64,
    pub edge_pixels: usize,
    #[serde(deserialize_with = "crate::output::nan_if_null")]
    pub edge_mae: f64,
    /// Samples that differ from the same-sample reference, over all
    /// samples of shadow-tested pixels (32-sample methods only).
    pub sample_mismatch_rate: Option<f64>,
}

/// Metrics of `estimate` against `truth` with the reference's `smooth`
/// classes.
pub fn metrics(estimate: &[f32], truth: &[f32], smooth: &[f32]) -> Metrics {
    let mut m = Metrics::default();
    let (mut sum, mut sum_sq, mut over) = (0.0f64, 0.0f64, 0usize);
    let (mut smooth_sum, mut edge_sum) = (0.0f64, 0.0f64);
    for i in 0..truth.len() {
        let (e, t) = (estimate[i], truth[i]);
        if e.is_nan() || t.is_nan() {
            continue;
        }
        let err = (e as f64 - t as f64).abs();
        m.pixels += 1;
        sum += err;
        sum_sq += err * err;
        m.max_error = m.max_error.max(err);
        over += (err > 1.0 / 32.0) as usize;
        if smooth[i] == 1.0 {
            if t > 0.0 && t < 1.0 {
                m.smooth_penumbra_pixels += 1;
                smooth_sum += err;
            }
        } else {
            m.edge_pixels += 1;
            edge_sum += err;
        }
    }
    let n = m.pixels.max(1) as f64;
    m.mae = sum / n;
    m.rmse = (sum_sq / n).sqrt();
    m.percent_over_one_sample = 100.0 * over as f64 / n;
    m.smooth_penumbra_mae = smooth_sum / m.smooth_penumbra_pixels.max(1) as f64;
    m.edge_mae = edge_sum / m.edge_pixels.max(1) as f64;
    m
}

/// Differing samples between two mask images over the pixels where
/// `tested` holds: (differing samples, samples compared).
pub fn sample_mismatches(a: &[u32], b: &[u32], tested: impl Fn(usize) -> bool) -> (u64, u64) {
    let (mut diff, mut total) = (0u64, 0u64);
    for i in 0..a.len() {
        if tested(i) {
            diff += (a[i] ^ b[i]).count_ones() as u64;
            total += 32;
        }
    }
    (diff, total)
}

/// Heat map of |estimate − truth|: black 0, through red and yellow, to
/// white at `full_scale`; blue where not shadow-tested.
pub fn error_heat_map(
    estimate: &[f32],
    truth: &[f32],
    width: u32,
    height: u32,
    full_scale: f32,
) -> image::RgbImage {
    let mut img = image::RgbImage::new(width, height);
    for (i, p) in img.pixels_mut().enumerate() {
        let (e, t) = (estimate[i], truth[i]);
        *p = if e.is_nan() || t.is_nan() {
            image::Rgb(crate::output::UNTESTED_RGB)
        } else {
            let x = ((e - t).abs() / full_scale).clamp(0.0, 1.0);
            // Black-body-like ramp: red rises first, then green, then blue.
            let r = (3.0 * x).min(1.0);
            let g = (3.0 * x - 1.0).clamp(0.0, 1.0);
            let b = (3.0 * x - 2.0).clamp(0.0, 1.0);
            image::Rgb([r, g, b].map(|c| (c * 255.0).round() as u8))
        };
    }
    img
}
