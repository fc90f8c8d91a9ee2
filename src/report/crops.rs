//! The report's magnified crops: a window of the ground truth and of each
//! method's lit fraction side by side, each with its error heat map.

use super::html_escape;
use crate::bench::MethodRow;
use crate::metrics::error_heat_map;
use crate::output::{read_exr_channel, write_png, UNTESTED_RGB};
use anyhow::Result;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Side of a crop window in image pixels, and its magnification.
pub const CROP_SIDE: u32 = 64;
pub const CROP_ZOOM: u32 = 4;

/// The top-left corner of the `side`² window holding the most penumbra
/// pixels of `truth` (0 < t < 1): a shadow edge.
pub fn penumbra_window(truth: &[f32], width: u32, height: u32, side: u32) -> (u32, u32) {
    densest_window(width, height, side, |i| partly_lit(truth[i]))
}

/// The top-left corner of the `side`² window holding the most edge pixels
/// (`smooth` ≠ 1: the truth's sub-pixel rays leave the centre's plane)
/// that the light partly reaches: where a pixel's samples stand on
/// several surfaces and the µQuad's plane matters.
pub fn edge_window(
    truth: &[f32],
    smooth: &[f32],
    width: u32,
    height: u32,
    side: u32,
) -> (u32, u32) {
    densest_window(width, height, side, |i| {
        smooth[i] != 1.0 && partly_lit(truth[i])
    })
}

fn partly_lit(t: f32) -> bool {
    t > 0.0 && t < 1.0
}

/// The top-left corner, on a 4-pixel step, of the `side`² window holding
/// the most pixels `i` (row-major) for which `counts(i)` holds.
fn densest_window(
    width: u32,
    height: u32,
    side: u32,
    counts: impl Fn(usize) -> bool,
) -> (u32, u32) {
    let (w, h) = (width as usize, height as usize);
    let s = (side as usize).min(w).min(h);
    // Summed-area table of the counted pixels.
    let mut sat = vec![0u32; (w + 1) * (h + 1)];
    for y in 0..h {
        for x in 0..w {
            let p = counts(y * w + x) as u32;
            sat[(y + 1) * (w + 1) + x + 1] =
                p + sat[y * (w + 1) + x + 1] + sat[(y + 1) * (w + 1) + x] - sat[y * (w + 1) + x];
        }
    }
    let count = |x: usize, y: usize| {
        sat[(y + s) * (w + 1) + x + s] + sat[y * (w + 1) + x]
            - sat[y * (w + 1) + x + s]
            - sat[(y + s) * (w + 1) + x]
    };
    let mut best = (0, 0, 0);
    for y in (0..=h - s).step_by(4) {
        for x in (0..=w - s).step_by(4) {
            let c = count(x, y);
            if c > best.2 {
                best = (x, y, c);
            }
        }
    }
    (best.0 as u32, best.1 as u32)
}

/// A magnified crop of a lit-fraction image (grey; untested pixels blue).
fn crop_visibility(v: &[f32], width: u32, (x0, y0): (u32, u32), side: u32) -> image::RgbImage {
    image::RgbImage::from_fn(side * CROP_ZOOM, side * CROP_ZOOM, |x, y| {
        let t = v[((y0 + y / CROP_ZOOM) * width + x0 + x / CROP_ZOOM) as usize];
        if t.is_nan() {
            image::Rgb(UNTESTED_RGB)
        } else {
            image::Rgb([(t.clamp(0.0, 1.0) * 255.0).round() as u8; 3])
        }
    })
}

fn crop_image(img: &image::RgbImage, (x0, y0): (u32, u32), side: u32) -> image::RgbImage {
    image::RgbImage::from_fn(side * CROP_ZOOM, side * CROP_ZOOM, |x, y| {
        *img.get_pixel(x0 + x / CROP_ZOOM, y0 + y / CROP_ZOOM)
    })
}

/// One scene's crops: its truth and where the images are read and written.
pub(super) struct CropSet<'a> {
    pub truth: &'a [f32],
    pub size: (u32, u32),
    pub side: u32,
    /// The bench document's folder (method images are relative to it).
    pub base: &'a Path,
    pub out: &'a Path,
    pub stem: &'a str,
}

impl CropSet<'_> {
    /// A titled row of crops at `corner`, one per `shown` entry (`None`:
    /// the truth), and below it their error heat maps; files
    /// `{stem}-{tag}-{k}.png` and `{stem}-{tag}-{k}-error.png`.
    pub fn write_row(
        &self,
        html: &mut String,
        files: &mut Vec<PathBuf>,
        title: &str,
        tag: &str,
        corner: (u32, u32),
        shown: &[(String, Option<&MethodRow>)],
    ) -> Result<()> {
        let (w, h) = self.size;
        let (side, zoom) = (self.side, self.side * CROP_ZOOM);
        let _ = writeln!(html, "<h3>{}</h3><div>", html_escape(title));
        let mut heat_row = String::new();
        for (k, (label, row)) in shown.iter().enumerate() {
            let visibility = match row {
                None => self.truth.to_vec(),
                Some(r) => {
                    let rel = r.image.as_deref().unwrap_or_default();
                    read_exr_channel(&self.base.join(rel), "visibility")?.2
                }
            };
            if row.is_none() && k > 0 {
                continue; // a method the bench did not run
            }
            let crop_name = format!("{}-{tag}-{k}.png", self.stem);
            let path = self.out.join(&crop_name);
            write_png(&path, &crop_visibility(&visibility, w, corner, side))?;
            files.push(path);
            let _ = writeln!(
                html,
                "<figure><img src=\"{crop_name}\" width=\"{zoom}\" height=\"{zoom}\" alt=\"{0}\" onerror=\"console.error('missing image: ' + this.src)\"><figcaption>{0}</figcaption></figure>",
                html_escape(label)
            );
            if row.is_none() {
                // The truth has no error: a blank cell keeps the columns.
                let _ = writeln!(heat_row, "<figure style=\"width:{zoom}px\"></figure>");
            } else {
                let heat = error_heat_map(&visibility, self.truth, w, h, 0.5);
                let heat_name = format!("{}-{tag}-{k}-error.png", self.stem);
                let path = self.out.join(&heat_name);
                write_png(&path, &crop_image(&heat, corner, side))?;
                files.push(path);
                let _ = writeln!(
                    heat_row,
                    "<figure><img src=\"{heat_name}\" width=\"{zoom}\" height=\"{zoom}\" alt=\"error of {0}\" onerror=\"console.error('missing image: ' + this.src)\"><figcaption>|error| of {0} (white = 0.5)</figcaption></figure>",
                    html_escape(label)
                );
            }
        }
        let _ = writeln!(html, "</div><div>{heat_row}</div>");
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn penumbra_window_finds_the_edge() {
        let (w, h) = (100u32, 80u32);
        let truth: Vec<f32> = (0..w * h)
            .map(|i| {
                if (60..64).contains(&(i % w)) && i / w >= 40 {
                    0.5
                } else {
                    1.0
                }
            })
            .collect();
        let (x, y) = penumbra_window(&truth, w, h, 16);
        assert!((48..=60).contains(&x) && y >= 40, "window at ({x}, {y})");
    }

    /// Partly lit pixels on both sides; only the right-hand ones are edge
    /// pixels, so the edge window goes there and the penumbra one need not.
    #[test]
    fn edge_window_finds_the_partly_lit_edge_pixels() {
        let (w, h) = (128u32, 64u32);
        let truth: Vec<f32> = (0..w * h)
            .map(|i| {
                if (10..30).contains(&(i % w)) || (100..104).contains(&(i % w)) {
                    0.5
                } else {
                    1.0
                }
            })
            .collect();
        let smooth: Vec<f32> = (0..w * h)
            .map(|i| {
                if (100..104).contains(&(i % w)) {
                    0.0
                } else {
                    1.0
                }
            })
            .collect();
        let (x, _) = edge_window(&truth, &smooth, w, h, 16);
        assert!((88..=100).contains(&x), "edge window at x = {x}");
        let (x, _) = penumbra_window(&truth, w, h, 16);
        assert!(x <= 14, "penumbra window at x = {x}");
    }
}
