//! Fuzzes the glTF/GLB loader and the scene-spec parser with a mutation
//! loop on stable Rust (no `cargo fuzz`: the harness needs nothing but this
//! crate). Seeds: the shared scenes' specs and the one small GLB
//! (`deckchair_1k.glb`; the others take milliseconds each to parse), or a
//! procedural stand-in without `../shared`. Each input is a seed mutated
//! 1–8 times: bit flips, interesting bytes and words, inserted, deleted and
//! duplicated runs, splices of another seed, and — the half of the GLB
//! inputs that reach the loader's checks — edits of the JSON chunk's
//! numbers (extremes, NaN spellings, huge counts and offsets) repacked with
//! correct chunk lengths.
//!
//! Every input must return `Ok` or a named `SceneError` with a message: a
//! panic is a crash (the input is written to `target/fuzz-crashes/`), an
//! input running past `--hang-seconds` is a hang (a watchdog writes it and
//! aborts). Found crashes become regression tests in `tests/bad_input.rs`.
//!
//! `cargo run --release --example fuzz_loaders -- [--target gltf|spec|all]
//! [--inputs N] [--seconds S] [--seed K]`; CI runs it for about 30 s.

use izb::scene::{load_gltf_bytes, Camera, Light, Scene, SceneSpec};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// xorshift64*: deterministic for a `--seed`.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

const INTERESTING_BYTES: [u8; 8] = [0, 1, 0x7F, 0x80, 0xFF, b'-', b'9', b'"'];
const INTERESTING_WORDS: [u32; 8] = [0, 1, 4, 0x7FFF_FFFF, 0x8000_0000, 0xFFFF_FFFF, 12, 1 << 20];
/// Replacements for a JSON number: extremes, edge cases, non-numbers.
const JSON_NUMBERS: [&str; 14] = [
    "0",
    "-1",
    "1",
    "4294967295",
    "4294967296",
    "18446744073709551616",
    "1e309",
    "-1e309",
    "NaN",
    "1e-320",
    "-0",
    "2147483647",
    "3.5",
    "\"x\"",
];

/// One byte-level mutation of `data` (`other`: a seed to splice from).
fn mutate_bytes(rng: &mut Rng, data: &mut Vec<u8>, other: &[u8]) {
    let len = data.len();
    match rng.below(7) {
        0 if len > 0 => {
            let i = rng.below(len);
            data[i] ^= 1 << rng.below(8);
        }
        1 if len > 0 => {
            let i = rng.below(len);
            data[i] = INTERESTING_BYTES[rng.below(INTERESTING_BYTES.len())];
        }
        2 if len >= 4 => {
            let i = rng.below(len - 3);
            let w = INTERESTING_WORDS[rng.below(INTERESTING_WORDS.len())];
            data[i..i + 4].copy_from_slice(&w.to_le_bytes());
        }
        3 if len > 0 => {
            let (i, n) = (rng.below(len), 1 + rng.below(64));
            data.drain(i..(i + n).min(len));
        }
        4 => {
            let i = rng.below(len + 1);
            let n = 1 + rng.below(16);
            let bytes: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
            data.splice(i..i, bytes);
        }
        5 if len > 0 => {
            let (i, n) = (rng.below(len), 1 + rng.below(256));
            let run = data[i..(i + n).min(len)].to_vec();
            let at = rng.below(len + 1);
            data.splice(at..at, run);
        }
        _ if !other.is_empty() => {
            let (i, n) = (rng.below(other.len()), 1 + rng.below(512));
            let piece = &other[i..(i + n).min(other.len())];
            let at = rng.below(len + 1);
            let end = (at + piece.len()).min(len);
            data.splice(at..end, piece.iter().copied());
        }
        _ => {}
    }
}

/// Replaces one JSON number of `text` with an extreme value.
fn mutate_json_number(rng: &mut Rng, text: &mut String) {
    let starts: Vec<usize> = text
        .char_indices()
        .filter(|&(i, c)| {
            (c.is_ascii_digit() || c == '-')
                && !text[..i].ends_with(|p: char| p.is_ascii_alphanumeric() || p == '.')
        })
        .map(|(i, _)| i)
        .collect();
    if starts.is_empty() {
        return;
    }
    let start = starts[rng.below(starts.len())];
    let end = text[start..]
        .find(|c: char| !(c.is_ascii_digit() || "+-.eE".contains(c)))
        .map_or(text.len(), |n| start + n);
    text.replace_range(start..end, JSON_NUMBERS[rng.below(JSON_NUMBERS.len())]);
}

/// The JSON chunk and BIN chunk of a GLB, if it parses as one.
fn glb_chunks(glb: &[u8]) -> Option<(String, Vec<u8>)> {
    let word = |i: usize| Some(u32::from_le_bytes(glb.get(i..i + 4)?.try_into().ok()?) as usize);
    let json_len = word(12)?;
    let json = String::from_utf8(glb.get(20..20 + json_len)?.to_vec()).ok()?;
    let bin_at = 20 + json_len;
    let bin = word(bin_at).and_then(|n| glb.get(bin_at + 8..bin_at + 8 + n));
    Some((json, bin.unwrap_or(&[]).to_vec()))
}

/// A GLB with `json` and `bin` and every length field consistent.
fn glb_pack(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut json = json.as_bytes().to_vec();
    json.resize(json.len().next_multiple_of(4), b' ');
    let total = 12 + 8 + json.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(bin);
    }
    out
}

/// What a target does with one input: `Err` is a rejection message.
type Target = fn(&[u8], &Path) -> Result<(), String>;

fn run_gltf(bytes: &[u8], dir: &Path) -> Result<(), String> {
    let meshes = load_gltf_bytes(bytes, &dir.join("fuzz.glb")).map_err(|e| e.to_string())?;
    let camera = Camera {
        eye: glam::DVec3::new(0.0, 1.0, 3.0),
        target: glam::DVec3::ZERO,
        up: glam::DVec3::Y,
        fov_y_deg: 45.0,
        near: 0.01,
        far: 100.0,
    };
    let light = Light::directional(glam::DVec3::new(-1.0, -1.0, -0.5));
    Scene::new("fuzz", meshes.triangles, camera, light, [16, 16])
        .map(|_| ())
        .map_err(|e| e.to_string())
}

fn run_spec(bytes: &[u8], dir: &Path) -> Result<(), String> {
    let text = std::str::from_utf8(bytes).map_err(|e| format!("not UTF-8: {e}"))?;
    let mut spec = SceneSpec::parse(text)?;
    // Geometry paths resolve in an empty folder: a spec never loads a
    // real model here (procedural geometry does build).
    spec.path = dir.join("fuzz.scene.json");
    spec.build().map(|_| ()).map_err(|e| e.to_string())
}

struct Seeds {
    gltf: Vec<Vec<u8>>,
    spec: Vec<Vec<u8>>,
}

fn seeds() -> Seeds {
    let shared = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes");
    let read = |name: &str| std::fs::read(shared.join(name)).ok();
    let mut gltf: Vec<Vec<u8>> = read("deckchair_1k.glb").into_iter().collect();
    let mut spec: Vec<Vec<u8>> = ["deckchair", "tablefan", "ficus", "engine", "courtyard"]
        .iter()
        .filter_map(|n| read(&format!("{n}.scene.json")))
        .collect();
    if gltf.is_empty() {
        eprintln!("fuzz: ../shared/scenes not found; seeding with a built-in GLB");
        let json = r#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":36}],"bufferViews":[{"buffer":0,"byteLength":36}],"accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}],"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],"nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}]}"#;
        let bin: Vec<u8> = [0f32, 0., 0., 1., 0., 0., 0., 1., 0.]
            .iter()
            .flat_map(|f| f.to_le_bytes())
            .collect();
        gltf.push(glb_pack(json, &bin));
    }
    spec.push(
        br#"{"procedural":"default","camera":{"eye":[0,2,6],"target":[0,0,0],"fov_y_deg":45,"near":0.05,"far":100},"light":{"type":"directional","direction":[-1,-2,-1]},"resolution":[64,36]}"#
            .to_vec(),
    );
    Seeds { gltf, spec }
}

/// One mutated input from `seeds`.
fn next_input(rng: &mut Rng, seeds: &[Vec<u8>], glb: bool) -> Vec<u8> {
    let mut data = seeds[rng.below(seeds.len())].clone();
    let other = &seeds[rng.below(seeds.len())];
    let structured = glb && rng.below(2) == 0;
    let chunks = if structured { glb_chunks(&data) } else { None };
    for _ in 0..1 + rng.below(8) {
        if chunks.is_none() && !glb && rng.below(2) == 0 {
            if let Ok(mut text) = String::from_utf8(data.clone()) {
                mutate_json_number(rng, &mut text);
                data = text.into_bytes();
                continue;
            }
        }
        mutate_bytes(rng, &mut data, other);
    }
    if let Some((mut json, bin)) = chunks {
        for _ in 0..1 + rng.below(4) {
            mutate_json_number(rng, &mut json);
        }
        data = glb_pack(&json, &bin);
    }
    data
}

struct Args {
    target: String,
    inputs: u64,
    seconds: f64,
    seed: u64,
    hang_seconds: f64,
}

fn args() -> Args {
    let mut a = Args {
        target: "all".into(),
        inputs: u64::MAX,
        seconds: 30.0,
        seed: 1,
        hang_seconds: 10.0,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let value = it.next().unwrap_or_else(|| panic!("{flag} needs a value"));
        let number = || {
            value
                .parse::<f64>()
                .unwrap_or_else(|e| panic!("{flag} {value}: {e}"))
        };
        match flag.as_str() {
            "--target" => a.target = value.clone(),
            "--inputs" => a.inputs = number() as u64,
            "--seconds" => a.seconds = number(),
            "--seed" => a.seed = number() as u64,
            "--hang-seconds" => a.hang_seconds = number(),
            other => panic!("unknown flag {other}"),
        }
    }
    a
}

fn save(dir: &Path, name: &str, input: &[u8]) -> PathBuf {
    let _ = std::fs::create_dir_all(dir);
    let path = dir.join(name);
    let _ = std::fs::write(&path, input);
    path
}

fn main() {
    // `--replay TARGET FILE`: one input, panics not caught (a backtrace).
    let argv: Vec<String> = std::env::args().collect();
    if argv.get(1).map(String::as_str) == Some("--replay") {
        let run: Target = if argv[2] == "spec" {
            run_spec
        } else {
            run_gltf
        };
        let input = std::fs::read(&argv[3]).expect("replay file");
        println!("{:?}", run(&input, &std::env::temp_dir()));
        return;
    }
    let a = args();
    let seeds = seeds();
    let crashes = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/fuzz-crashes");
    let empty = std::env::temp_dir().join(format!("izb-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&empty).expect("temp dir");
    let targets: Vec<(&str, Target, &[Vec<u8>], bool)> = [
        ("gltf", run_gltf as Target, &seeds.gltf[..], true),
        ("spec", run_spec as Target, &seeds.spec[..], false),
    ]
    .into_iter()
    .filter(|(n, ..)| a.target == "all" || a.target == *n)
    .collect();
    assert!(!targets.is_empty(), "--target must be gltf, spec or all");
    // The current input, for the watchdog to save when one runs too long.
    let current: Arc<Mutex<(String, Vec<u8>)>> = Default::default();
    let progress = Arc::new(AtomicU64::new(0));
    {
        let (current, progress, crashes) = (current.clone(), progress.clone(), crashes.clone());
        let limit = Duration::from_secs_f64(a.hang_seconds);
        std::thread::spawn(move || loop {
            let before = progress.load(Ordering::SeqCst);
            std::thread::sleep(limit);
            if progress.load(Ordering::SeqCst) == before {
                let (target, input) = current.lock().unwrap_or_else(|e| e.into_inner()).clone();
                let path = save(&crashes, &format!("{target}-hang.bin"), &input);
                eprintln!(
                    "HANG: {target} input ran over {limit:?}; saved to {}",
                    path.display()
                );
                std::process::abort();
            }
        });
    }
    std::panic::set_hook(Box::new(|_| {}));
    let share = a.seconds / targets.len() as f64;
    let mut failures = 0u64;
    for (name, run, target_seeds, glb) in targets {
        let mut rng = Rng(a.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
        let (start, mut n, mut accepted) = (Instant::now(), 0u64, 0u64);
        let mut reasons: std::collections::BTreeMap<String, u64> = Default::default();
        while n < a.inputs && start.elapsed().as_secs_f64() < share {
            let input = next_input(&mut rng, target_seeds, glb);
            *current.lock().unwrap_or_else(|e| e.into_inner()) = (name.to_string(), input.clone());
            match std::panic::catch_unwind(|| run(&input, &empty)) {
                Ok(Ok(())) => accepted += 1,
                Ok(Err(message)) if !message.trim().is_empty() => {
                    // The error's kind: the text before its first detail.
                    let kind: String = message.split(':').take(2).collect::<Vec<_>>().join(":");
                    *reasons.entry(kind.chars().take(60).collect()).or_default() += 1;
                }
                Ok(Err(_)) => {
                    failures += 1;
                    let path = save(&crashes, &format!("{name}-{n}-unnamed.bin"), &input);
                    eprintln!("UNNAMED REJECTION: {name} input {n} -> {}", path.display());
                }
                Err(panic) => {
                    failures += 1;
                    let what = panic
                        .downcast_ref::<String>()
                        .cloned()
                        .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                        .unwrap_or_default();
                    let path = save(&crashes, &format!("{name}-{n}-panic.bin"), &input);
                    eprintln!("PANIC: {name} input {n}: {what} -> {}", path.display());
                }
            }
            n += 1;
            progress.fetch_add(1, Ordering::SeqCst);
        }
        let secs = start.elapsed().as_secs_f64();
        println!(
            "fuzz {name}: {n} inputs in {secs:.1} s ({:.0}/s), {accepted} accepted, {} rejected \
             with a named error, seed {}",
            n as f64 / secs,
            reasons.values().sum::<u64>(),
            a.seed
        );
        let mut top: Vec<_> = reasons.into_iter().collect();
        top.sort_by_key(|r| std::cmp::Reverse(r.1));
        for (reason, count) in top.iter().take(6) {
            println!("  {count:>9}  {reason}");
        }
    }
    let _ = std::fs::remove_dir_all(&empty);
    if failures > 0 {
        eprintln!("fuzz: {failures} failing input(s) in {}", crashes.display());
        std::process::exit(1);
    }
}
