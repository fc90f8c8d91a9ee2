//! Output files (README, Conventions): `visibility.exr`, `visibility.png`,
//! `report.json`. Every file is written under a temporary name in the same
//! folder and renamed into place, so a crash leaves the old file or the new
//! one, never half of one.

use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

/// Colour of pixels that are not shadow-tested in the PNG (sky, surfaces
/// facing away from the light): a blue no grey visibility value can take.
pub const UNTESTED_RGB: [u8; 3] = [40, 70, 140];

/// Writes `path` through `write(tmp_path)` and renames the result into
/// place. On any error the temporary file is removed and `path` untouched.
pub fn write_atomically(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    create_folder(dir)?;
    let name = path.file_name().context("output path has no file name")?;
    let tmp: PathBuf = dir.join(format!(
        ".{}.{}.tmp",
        name.to_string_lossy(),
        std::process::id()
    ));
    let result = write(&tmp).and_then(|()| {
        std::fs::rename(&tmp, path).with_context(|| format!("renaming into {}", path.display()))
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.with_context(|| format!("writing {}", path.display()))
}

/// Creates the output folder `dir` (and its parents); one that names an
/// existing file is refused as such, not as the OS's "File exists".
pub fn create_folder(dir: &Path) -> Result<()> {
    // The ancestors are walked only when the folder cannot be made, to
    // say why in the user's terms (the OS says "File exists").
    std::fs::create_dir_all(dir).or_else(|e| {
        check_folder(dir)?;
        Err(anyhow::Error::new(e).context(format!("creating {}", dir.display())))
    })
}

/// Refuses a folder path that cannot become a folder because it, or a
/// folder above it, is a file; creates nothing (a command checks its
/// `--out` before its expensive work).
pub fn check_folder(dir: &Path) -> Result<()> {
    match dir.ancestors().find(|a| a.is_file()) {
        Some(file) => anyhow::bail!(
            "the output folder {} cannot be made: {} is a file",
            dir.display(),
            file.display()
        ),
        None => Ok(()),
    }
}

/// A folder of outputs written under a temporary name beside its final
/// one and renamed into place by [`StagedDir::commit`]; dropped without a
/// commit (a failed run), it is removed. The folder a run leaves is then
/// whole, the previous one's, or none.
pub struct StagedDir {
    staging: PathBuf,
    target: PathBuf,
    committed: bool,
}

impl StagedDir {
    /// Creates the temporary folder for `target`.
    pub fn new(target: &Path) -> Result<StagedDir> {
        let name = target.file_name().context("output folder has no name")?;
        let parent = target.parent().unwrap_or(Path::new("."));
        let staging = parent.join(format!(
            ".{}.{}.partial",
            name.to_string_lossy(),
            std::process::id()
        ));
        check_folder(target)?;
        let _ = std::fs::remove_dir_all(&staging);
        create_folder(&staging)?;
        Ok(StagedDir {
            staging,
            target: target.to_path_buf(),
            committed: false,
        })
    }

    /// Where the run writes.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// Replaces `target` (and whatever an earlier run left there) with the
    /// written folder.
    pub fn commit(mut self) -> Result<()> {
        if self.target.exists() {
            std::fs::remove_dir_all(&self.target)
                .with_context(|| format!("replacing {}", self.target.display()))?;
        }
        std::fs::rename(&self.staging, &self.target)
            .with_context(|| format!("renaming into {}", self.target.display()))?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.staging);
        }
    }
}

/// Writes a single-layer EXR of `f32` channels, each `width × height`,
/// row-major.
pub fn write_exr(path: &Path, width: u32, height: u32, channels: &[(&str, &[f32])]) -> Result<()> {
    write_exr_with_masks(path, width, height, channels, &[])
}

/// Writes a single-layer EXR of `f32` channels and `u32` channels (the
/// occlusion masks), each `width × height`, row-major.
pub fn write_exr_with_masks(
    path: &Path,
    width: u32,
    height: u32,
    channels: &[(&str, &[f32])],
    masks: &[(&str, &[u32])],
) -> Result<()> {
    use exr::prelude::*;
    let n = width as usize * height as usize;
    let mut list: Vec<AnyChannel<FlatSamples>> = Vec::new();
    for (name, data) in channels {
        anyhow::ensure!(
            data.len() == n,
            "channel {name} has {} values, expected {n}",
            data.len()
        );
        list.push(AnyChannel::new(*name, FlatSamples::F32(data.to_vec())));
    }
    for (name, data) in masks {
        anyhow::ensure!(
            data.len() == n,
            "channel {name} has {} values, expected {n}",
            data.len()
        );
        list.push(AnyChannel::new(*name, FlatSamples::U32(data.to_vec())));
    }
    let layer = Layer::new(
        (width as usize, height as usize),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(list.into()),
    );
    write_atomically(path, |tmp| {
        Image::from_layer(layer)
            .write()
            .to_file(tmp)
            .map_err(|e| anyhow::anyhow!("EXR encoding: {e}"))
    })
}

/// Reads the named `u32` channel of a single-layer EXR (row-major).
pub fn read_exr_mask(path: &Path, channel: &str) -> Result<(u32, u32, Vec<u32>)> {
    use exr::prelude::*;
    let image = read_all_flat_layers_from_file(path)
        .map_err(|e| anyhow::anyhow!("reading {}: {e}", path.display()))?;
    let layer = image.layer_data.first().context("EXR has no layer")?;
    let ch = layer
        .channel_data
        .list
        .iter()
        .find(|c| c.name == *channel)
        .with_context(|| format!("{}: no channel '{channel}'", path.display()))?;
    let FlatSamples::U32(values) = &ch.sample_data else {
        anyhow::bail!("{}: channel '{channel}' is not u32", path.display());
    };
    Ok((
        layer.size.width() as u32,
        layer.size.height() as u32,
        values.clone(),
    ))
}

/// Reads the named `f32` channel of a single-layer EXR (row-major).
pub fn read_exr_channel(path: &Path, channel: &str) -> Result<(u32, u32, Vec<f32>)> {
    use exr::prelude::*;
    let image = read_all_flat_layers_from_file(path)
        .map_err(|e| anyhow::anyhow!("reading {}: {e}", path.display()))?;
    let layer = image.layer_data.first().context("EXR has no layer")?;
    let size = layer.size;
    let ch = layer
        .channel_data
        .list
        .iter()
        .find(|c| c.name == *channel)
        .with_context(|| format!("{}: no channel '{channel}'", path.display()))?;
    let values = ch.sample_data.values_as_f32().collect();
    Ok((size.width() as u32, size.height() as u32, values))
}

/// Writes lit fraction as an 8-bit grey PNG; NaN (untested) pixels in
/// [`UNTESTED_RGB`].
pub fn write_visibility_png(
    path: &Path,
    width: u32,
    height: u32,
    visibility: &[f32],
) -> Result<()> {
    let mut img = image::RgbImage::new(width, height);
    for (p, &v) in img.pixels_mut().zip(visibility) {
        *p = if v.is_nan() {
            image::Rgb(UNTESTED_RGB)
        } else {
            let g = (v.clamp(0.0, 1.0) * 255.0).round() as u8;
            image::Rgb([g, g, g])
        };
    }
    write_png(path, &img)
}

/// Writes any RGB image as PNG, atomically.
pub fn write_png(path: &Path, img: &image::RgbImage) -> Result<()> {
    write_atomically(path, |tmp| {
        let file = std::fs::File::create(tmp)?;
        let mut w = std::io::BufWriter::new(file);
        img.write_to(&mut w, image::ImageFormat::Png)?;
        use std::io::Write;
        w.flush()?;
        Ok(())
    })
}

/// Reads a JSON number that may have been written as `null`: JSON has no
/// NaN or infinity, so `serde_json` writes them as `null`, and they come
/// back as NaN (`#[serde(deserialize_with = "nan_if_null")]`).
pub fn nan_if_null<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    use serde::Deserialize;
    Option::<f64>::deserialize(d).map(|x| x.unwrap_or(f64::NAN))
}

/// [`nan_if_null`] for a pair.
pub fn nan_pair_if_null<'de, D: serde::Deserializer<'de>>(d: D) -> Result<[f64; 2], D::Error> {
    use serde::Deserialize;
    <[Option<f64>; 2]>::deserialize(d).map(|p| p.map(|x| x.unwrap_or(f64::NAN)))
}

/// Writes a serialisable value as pretty JSON, atomically.
pub fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> Result<()> {
    let bytes = serde_json::to_vec_pretty(value)?;
    write_atomically(path, |tmp| Ok(std::fs::write(tmp, &bytes)?))
}

/// Sky colour of `shaded.png`.
pub const SKY_RGB: [f32; 3] = [0.55, 0.7, 0.9];

/// Writes `shaded.png`: a grey Lambert surface lit by the light times the
/// lit fraction, plus a little ambient so shadows keep their shape. Pixels
/// facing away from the light get the ambient term only; misses are sky.
pub fn write_shaded_png(
    path: &Path,
    gbuffer: &crate::gbuffer::GBuffer,
    light: &crate::scene::Light,
    visibility: &[f32],
) -> Result<()> {
    let mut img = image::RgbImage::new(gbuffer.width, gbuffer.height);
    for (i, p) in img.pixels_mut().enumerate() {
        *p = image::Rgb(shade_pixel(gbuffer, i, light, visibility[i]));
    }
    write_png(path, &img)
}

/// Ambient term of the shaded image.
pub const AMBIENT: f32 = 0.18;
/// Diffuse albedo of the shaded image.
pub const DIFFUSE: f32 = 0.85;

/// CPU twin of the GPU `resolve` pass's shading: sky colour for a miss,
/// else ambient + Lambert × lit fraction (NaN counts as 0), display gamma
/// 2.2, rounded to 8 bits.
pub fn shade_pixel(
    gbuffer: &crate::gbuffer::GBuffer,
    i: usize,
    light: &crate::scene::Light,
    visibility: f32,
) -> [u8; 3] {
    let rgb = if gbuffer.flags[i] & crate::gbuffer::flags::HIT == 0 {
        SKY_RGB
    } else {
        let position = gbuffer.position[i].as_dvec3();
        let toward = light.toward(position).0.as_vec3();
        let lambert = gbuffer.normal[i].dot(toward).max(0.0);
        let v = if visibility.is_nan() { 0.0 } else { visibility };
        [AMBIENT + (1.0 - AMBIENT) * DIFFUSE * lambert * v; 3]
    };
    rgb.map(|c| (c.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0).round() as u8)
}

/// Writes `visibility.exr` (lit fraction + masks when not empty; `mask_high` with bits
/// 32–63 when `masks_high` is not empty; `coverage`, the samples that
/// count, when not empty) and `visibility.png`.
pub fn write_mask_outputs(
    out: &Path,
    scene: &crate::scene::Scene,
    visibility: &[f32],
    masks: &[u32],
    masks_high: &[u32],
    coverage: &[u32],
) -> Result<()> {
    let [w, h] = scene.resolution;
    let mut channels = Vec::new();
    if !masks.is_empty() {
        channels.push(("mask", masks));
    }
    if !masks_high.is_empty() {
        channels.push(("mask_high", masks_high));
    }
    // With edge surfaces: which samples hit a surface and count (lit
    // fraction = 1 − popcount(mask) / popcount(coverage)).
    if !coverage.is_empty() {
        channels.push(("coverage", coverage));
    }
    write_exr_with_masks(
        &out.join("visibility.exr"),
        w,
        h,
        &[("visibility", visibility)],
        &channels,
    )?;
    write_visibility_png(&out.join("visibility.png"), w, h, visibility)
}
