//! One case's rule (see `main.rs`) and the run's tally.

use crate::generate::Case;
use crate::print_counts;
use izb::bvh::SceneBvh;
use izb::cpu::{render_cpu, IzbSettings, SampleMode};
use izb::gbuffer::{flags, PixelSurface};
use izb::lut::{edge_lut, sample_pattern, LOOKUP_SLACK};
use izb::reference::same_samples::{
    decision_margin, edge_same_sample_masks, nearest_edge_distance, pixel_samples_at,
    FLOAT_DECISION_TOLERANCE,
};
use izb::scene::Scene;
use std::collections::BTreeMap;

/// What one case came to.
pub enum Outcome {
    /// A named error: the error's kind (its text with numbers elided).
    Refused(String),
    /// Rendered, and every rule held.
    Agreed(Counts),
    /// A rule broke: what and where.
    Wrong(String),
    Panic(String),
}

/// Samples compared in an agreeing case, and the allowed exceptions.
#[derive(Default, Clone, Copy)]
pub struct Counts {
    pub samples: u64,
    /// Exact masks against the twin's, differing within float rounding.
    pub twin_within_margin: u64,
    /// Exact masks against the `f64` reference, likewise.
    pub reference_within_margin: u64,
    /// LUT masks against exact ones, within the LUT's bound.
    pub lut_within_bound: u64,
    /// The twin's exact masks against the generator twin's (the inputs'
    /// `f64` rounding), differing within float rounding.
    pub rounding_within_margin: u64,
    /// Samples whose primary ray found another surface, or none, once the
    /// inputs were rounded (not compared: primary visibility is exact on
    /// either scene).
    pub moved_by_rounding: u64,
    /// Whether the twin was refused (the reference was then the scene's).
    pub twin_refused: bool,
}

fn settings(mode: SampleMode) -> IzbSettings {
    IzbSettings {
        mode,
        edge_surfaces: true,
        ..Default::default()
    }
}

/// A refusal's kind: its text with every number elided, so that refusals
/// of one quantity count together.
fn kind(message: &str) -> String {
    let mut out = String::new();
    let mut in_number = false;
    for ch in message.chars() {
        let numeric = ch.is_ascii_digit() || (in_number && matches!(ch, '.' | 'e' | '-' | '+'));
        if numeric {
            if !in_number {
                out.push('#');
            }
        } else {
            out.push(ch);
        }
        in_number = numeric;
    }
    out.chars().take(90).collect()
}

/// A rendered scene as the checks read it.
struct Rendered {
    scene: Scene,
    bvh: SceneBvh,
    exact: izb::cpu::ShadowRender,
}

impl Rendered {
    fn new(scene: Scene) -> Self {
        let bvh = SceneBvh::build(&scene);
        let exact = render_cpu(&scene, &bvh, settings(SampleMode::Exact32));
        Rendered { scene, bvh, exact }
    }

    fn tested(&self, i: usize) -> bool {
        self.exact.gbuffer.flags[i] & flags::SHADOW_TESTED != 0
    }

    fn counted(&self, i: usize) -> u32 {
        self.exact
            .gbuffer
            .edges
            .as_ref()
            .map_or(u32::MAX, |e| e.counted[i])
    }

    /// The surface sample `bit` of pixel `i` stands on, and the samples on
    /// it (the pixel's primary visibility, as the G-buffer found it).
    fn surface(&self, i: usize, bit: usize) -> Option<(PixelSurface, u32)> {
        let w = self.scene.resolution[0] as usize;
        let frame = self.scene.camera.frame(self.scene.resolution);
        let (x, y) = ((i % w) as u32, (i / w) as u32);
        let (centre, samples) =
            pixel_samples_at(&self.bvh, &self.scene, &frame, x, y, sample_pattern())?;
        Some(
            samples
                .extra
                .iter()
                .find(|e| e.coverage & (1 << bit) != 0)
                .map_or((centre, samples.centre_coverage), |e| {
                    (e.surface, e.coverage)
                }),
        )
    }
}

/// Whether primary visibility must agree between the two renders.
#[derive(Clone, Copy, PartialEq)]
enum Primary {
    /// The same `f64` scene: pixels tested or samples counted differently
    /// are a broken rule (primary visibility runs in `f64`).
    MustMatch,
    /// Scenes whose inputs differ by rounding: a sample whose primary ray
    /// found another surface (or none) is counted as moved, not compared.
    MayMove,
}

const MUST: Primary = Primary::MustMatch;

/// What [`differing_within_margin`] found.
#[derive(Default)]
struct Differences {
    /// Samples that differ within float rounding of a boundary (or within
    /// the LUT's bound of an edge).
    within: u64,
    /// Samples whose primary visibility differs ([`Primary::MayMove`]).
    moved: u64,
}

/// Where `a` (`subject`'s masks) and `b` (`judge`'s) differ, over pixels
/// both test and samples both count on the same surface: `Ok` when each
/// lies within float rounding of a boundary in `judge`'s geometry (or, for
/// `lut`, within the LUT's bound of an edge), else what broke.
fn differing_within_margin(
    what: &str,
    judge: &Rendered,
    subject: &Rendered,
    (a, b): (&[u32], &[u32]),
    lut: bool,
    primary: Primary,
) -> Result<Differences, String> {
    let triangles = judge.scene.eye_relative_triangles();
    let light = judge.scene.light.relative_to(judge.scene.camera.eye);
    let pattern = sample_pattern();
    let mut found = Differences::default();
    for i in 0..b.len() {
        let (tested, counted) = (subject.tested(i), subject.counted(i));
        if tested != judge.tested(i) || counted != judge.counted(i) {
            if primary == Primary::MustMatch {
                return Err(format!(
                    "{what}: pixel {i} tested {tested} / counted {counted:#010x} against {} / \
                     {:#010x}",
                    judge.tested(i),
                    judge.counted(i)
                ));
            }
            // The samples one render counts and the other does not (all
            // of the tested one's where only one tests the pixel).
            let counted_by = |r: &Rendered, c: u32| if r.tested(i) { c } else { 0 };
            let moved = counted_by(subject, counted) ^ counted_by(judge, judge.counted(i));
            found.moved += moved.count_ones() as u64;
            if !(tested && judge.tested(i)) {
                continue;
            }
        }
        let differing = (a[i] ^ b[i]) & counted & judge.counted(i);
        if !tested || differing == 0 {
            continue;
        }
        for bit in (0..32).filter(|k| differing >> k & 1 == 1) {
            let (surface, sharing) = judge
                .surface(i, bit)
                .ok_or(format!("{what}: pixel {i} has no surface in the judge"))?;
            // Under rounded inputs a surface is "the same" where the same
            // samples stand on it; its plane moved within the rounding.
            if primary == Primary::MayMove
                && subject.surface(i, bit).map(|(_, s)| s) != Some(sharing)
            {
                found.moved += 1;
                continue;
            }
            let uv = pattern[bit];
            let margin = decision_margin(&triangles, &surface, &light, uv);
            let near_edge = lut && {
                let bound = edge_lut().misclassification_bound(uv) + LOOKUP_SLACK;
                nearest_edge_distance(&triangles, &surface, &light, uv) <= bound
            };
            if margin >= FLOAT_DECISION_TOLERANCE && !near_edge {
                return Err(format!(
                    "{what}: pixel {i} sample {bit} differs with a decision margin {margin:.3e} \
                     (tolerance {FLOAT_DECISION_TOLERANCE:.3e}){}",
                    if lut { ", beyond the LUT's bound" } else { "" }
                ));
            }
            found.within += 1;
        }
    }
    Ok(found)
}

/// Runs `case` through its rule.
pub fn check_case(case: &Case) -> Outcome {
    let scene = match case.extreme() {
        Ok(scene) => scene,
        Err(message) if message.trim().is_empty() => {
            return Outcome::Wrong("refused with an empty message".into())
        }
        Err(message) => return Outcome::Refused(kind(&message)),
    };
    let extreme = Rendered::new(scene);
    let lut = render_cpu(&extreme.scene, &extreme.bvh, settings(SampleMode::Lut32));
    let twin = case.twin().ok().map(Rendered::new);
    // Only an inexact similarity rounds the inputs.
    let generator_twin = (!case.exact_similarity())
        .then(|| case.generator_twin().ok().map(Rendered::new))
        .flatten();
    let mut counts = Counts {
        twin_refused: twin.is_none(),
        ..Default::default()
    };
    let x = &extreme.exact.masks[..];
    counts.samples = (0..extreme.exact.masks.len())
        .filter(|&i| extreme.tested(i))
        .map(|i| extreme.counted(i).count_ones() as u64)
        .sum();
    let judge = twin.as_ref().unwrap_or(&extreme);
    let result = (|| {
        if let Some(twin) = &twin {
            let m = &twin.exact.masks;
            counts.twin_within_margin =
                differing_within_margin("exact vs twin", twin, &extreme, (x, m), false, MUST)?
                    .within;
            if case.exact_similarity() && counts.twin_within_margin > 0 {
                return Err(format!(
                    "exact vs twin under a power-of-two scale: {} samples differ (must be \
                     bit-identical)",
                    counts.twin_within_margin
                ));
            }
        }
        let reference = edge_same_sample_masks(&judge.scene, &judge.bvh, sample_pattern());
        if let Some(i) = (0..reference.counted.len())
            .find(|&i| judge.tested(i) && reference.counted[i] != judge.counted(i))
        {
            return Err(format!(
                "the G-buffer and the reference count different samples at pixel {i}"
            ));
        }
        let r = &reference.masks;
        counts.reference_within_margin =
            differing_within_margin("exact vs reference", judge, &extreme, (x, r), false, MUST)?
                .within;
        counts.lut_within_bound =
            differing_within_margin("LUT vs exact", judge, &extreme, (x, &lut.masks), true, MUST)?
                .within;
        if let (Some(twin), Some(generator)) = (&twin, &generator_twin) {
            let (t, g) = (&twin.exact.masks, &generator.exact.masks);
            let rounding = differing_within_margin(
                "twin vs generator twin",
                generator,
                twin,
                (t, g),
                false,
                Primary::MayMove,
            )?;
            counts.rounding_within_margin = rounding.within;
            counts.moved_by_rounding = rounding.moved;
        }
        Ok(())
    })();
    match result {
        Ok(()) => Outcome::Agreed(counts),
        Err(why) => Outcome::Wrong(why),
    }
}

/// The run's counts.
#[derive(Default)]
pub struct Tally {
    cases: u64,
    refused: BTreeMap<String, u64>,
    refused_by_class: BTreeMap<String, u64>,
    agreed_by_class: BTreeMap<String, u64>,
    agreed: u64,
    twin_refused: u64,
    totals: Counts,
    wrong: u64,
    panics: u64,
    /// The extremes at which accepted cases agreed: (smallest, largest).
    scale: (f64, f64),
    offset: f64,
    light_radii: f64,
    camera_radii: (f64, f64),
}

impl Tally {
    /// Adds a case; returns why it failed, if it did.
    pub fn add(&mut self, case: &Case, outcome: &Outcome) -> Option<String> {
        self.cases += 1;
        let classes = || case.classes.iter().map(|c| c.to_string());
        match outcome {
            Outcome::Refused(kind) => {
                *self.refused.entry(kind.clone()).or_default() += 1;
                for c in classes() {
                    *self.refused_by_class.entry(c).or_default() += 1;
                }
                None
            }
            Outcome::Agreed(c) => {
                self.agreed += 1;
                self.twin_refused += c.twin_refused as u64;
                let t = &mut self.totals;
                t.samples += c.samples;
                t.twin_within_margin += c.twin_within_margin;
                t.reference_within_margin += c.reference_within_margin;
                t.lut_within_bound += c.lut_within_bound;
                t.rounding_within_margin += c.rounding_within_margin;
                t.moved_by_rounding += c.moved_by_rounding;
                for c in classes() {
                    *self.agreed_by_class.entry(c).or_default() += 1;
                }
                if self.agreed == 1 {
                    self.scale = (case.scale, case.scale);
                    self.camera_radii = (case.camera_radii, case.camera_radii);
                }
                self.scale = (self.scale.0.min(case.scale), self.scale.1.max(case.scale));
                self.camera_radii = (
                    self.camera_radii.0.min(case.camera_radii),
                    self.camera_radii.1.max(case.camera_radii),
                );
                self.offset = self.offset.max(case.offset.length());
                self.light_radii = self.light_radii.max(case.light_radii.unwrap_or(0.0));
                None
            }
            Outcome::Wrong(why) => {
                self.wrong += 1;
                Some(format!("wrong answer: {why}"))
            }
            Outcome::Panic(what) => {
                self.panics += 1;
                Some(format!("panic: {what}"))
            }
        }
    }

    pub fn failures(&self) -> u64 {
        self.wrong + self.panics
    }

    pub fn print(&self, seconds: f64, seed: u64) {
        let t = &self.totals;
        println!(
            "fuzz_extremes: {} cases in {seconds:.1} s, seed {seed}: {} rendered and agreeing \
             ({} judged by their own reference: the twin refused), {} refused by name, \
             {} wrong answers, {} panics, 0 hangs",
            self.cases,
            self.agreed,
            self.twin_refused,
            self.refused.values().sum::<u64>(),
            self.wrong,
            self.panics
        );
        println!(
            "  {} samples compared; within float rounding: {} against the twin, {} against the \
             f64 reference; LUT within its bound of exact: {}",
            t.samples, t.twin_within_margin, t.reference_within_margin, t.lut_within_bound
        );
        println!(
            "  the inputs' f64 rounding (twin against generator twin): {} samples within float \
             rounding, {} samples on another surface or none",
            t.rounding_within_margin, t.moved_by_rounding
        );
        if self.agreed > 0 {
            println!(
                "  agreed at scales {:.3e} … {:.3e}, offsets up to {:.3e}, point lights up to \
                 {:.3e} radii, cameras {:.3e} … {:.3e} radii away",
                self.scale.0,
                self.scale.1,
                self.offset,
                self.light_radii,
                self.camera_radii.0,
                self.camera_radii.1
            );
        }
        print_counts("  rendered and agreeing, by extreme", &self.agreed_by_class);
        print_counts("  refused, by extreme", &self.refused_by_class);
        print_counts("  refused, by reason", &self.refused);
    }
}
