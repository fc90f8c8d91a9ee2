//! Helpers shared by the integration tests: a throw-away directory, a small
//! glTF assembler (JSON + one binary buffer, written as `.gltf` with an
//! external or base64 buffer, or as `.glb`), scene specs and error checks.
//!
//! The fixtures are built in code rather than checked in so that each test
//! shows the exact bytes it feeds the loader and can corrupt them at will.

// Each test binary uses a different subset of these helpers.
#![allow(dead_code)]

pub mod gpu;
pub mod host_geometry;
pub mod shadow_pass;

use izb::scene::{Scene, SceneError};
use serde_json::{json, Value};
use std::fmt::Display;
use std::path::{Path, PathBuf};

/// The five shared scenes (`../shared/scenes/NAME.scene.json`), smallest
/// first.
pub const SHARED_SCENES: [&str; 5] = ["deckchair", "tablefan", "ficus", "engine", "courtyard"];

/// Shadow-tested pixels of G-buffer `g` whose mask is partly set: the
/// penumbra a soft-shadow comparison must have something of.
pub fn penumbra_pixels(masks: &[u32], g: &izb::gbuffer::GBuffer) -> usize {
    let tested = |i: usize| g.flags[i] & izb::gbuffer::flags::SHADOW_TESTED != 0;
    (0..masks.len())
        .filter(|&i| tested(i) && masks[i] != 0 && masks[i] != u32::MAX)
        .count()
}

/// `../shared/scenes`, or `None` with a printed skip when it is missing;
/// with `IZB_REQUIRE_SCENES=1` (CI) a missing folder fails the test.
/// Asserts that the `diff` of `total` samples where exact masks and the
/// same-sample reference disagree (each already checked to lie within
/// float rounding of a boundary) stay below 1e-5 of all samples.
pub fn assert_boundary_rate(diff: u64, total: u64) {
    let rate = diff as f64 / total as f64;
    println!("all: {diff} of {total} samples within float rounding of a boundary ({rate:.2e})");
    assert!(rate < 1e-5, "{diff} of {total} samples differ ({rate:.2e})");
}

pub fn shared_scenes_dir() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes");
    if dir.is_dir() {
        return Some(dir);
    }
    if std::env::var("IZB_REQUIRE_SCENES").is_ok_and(|v| v == "1") {
        panic!("IZB_REQUIRE_SCENES=1 but {} is missing", dir.display());
    }
    eprintln!("skipped: {} not found", dir.display());
    None
}

/// Shared scene `name` loaded through its spec, or `None` as
/// [`shared_scenes_dir`] says.
pub fn shared_scene(name: &str) -> Option<Scene> {
    let spec = shared_scenes_dir()?.join(format!("{name}.scene.json"));
    let spec = spec.to_str().expect("UTF-8 path");
    Some(izb::scene::load(spec).unwrap_or_else(|e| panic!("{spec}: {e}")))
}

/// Runs the `izb` binary this test build made with `args`.
pub fn izb_cli(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_izb"))
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("izb {args:?} did not start: {e}"))
}

/// Runs `izb args`, which must fail without a panic and with `expected`
/// in its stderr; returns that stderr.
pub fn assert_cli_refuses(args: &[&str], expected: &str) -> String {
    let run = izb_cli(args);
    let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
    assert!(!run.status.success(), "{args:?} should fail");
    assert!(
        stderr.contains(expected),
        "{args:?}: expected '{expected}' in: {stderr}"
    );
    assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
    stderr
}

/// glTF `componentType` values.
pub const UNSIGNED_BYTE: u32 = 5121;
pub const UNSIGNED_SHORT: u32 = 5123;
pub const UNSIGNED_INT: u32 = 5125;
pub const FLOAT: u32 = 5126;

/// glTF primitive `mode` values.
pub const POINTS: u32 = 0;
pub const LINES: u32 = 1;
pub const TRIANGLES: u32 = 4;
pub const TRIANGLE_STRIP: u32 = 5;
pub const TRIANGLE_FAN: u32 = 6;

/// A directory under the system temp dir, removed on drop. The name holds
/// the test name and the process id: tests of one binary run in parallel
/// threads of one process, and several binaries may run at once.
pub struct TempDir {
    path: PathBuf,
}

impl TempDir {
    pub fn new(test_name: &str) -> Self {
        let path =
            std::env::temp_dir().join(format!("izb-test-{test_name}-{}", std::process::id()));
        // A leftover from a crashed run with a recycled pid must not leak in.
        let _ = std::fs::remove_dir_all(&path);
        std::fs::create_dir_all(&path).unwrap();
        TempDir { path }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn join(&self, file: impl AsRef<Path>) -> PathBuf {
        self.path.join(file)
    }
}

impl std::ops::Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.path
    }
}

impl AsRef<Path> for TempDir {
    fn as_ref(&self) -> &Path {
        &self.path
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.path);
    }
}

/// One primitive of a mesh: accessor indices and topology.
#[derive(Clone, Copy, Debug)]
pub struct Primitive {
    pub positions: usize,
    pub indices: Option<usize>,
    pub mode: u32,
}

impl Primitive {
    pub fn triangles(positions: usize, indices: Option<usize>) -> Self {
        Primitive {
            positions,
            indices,
            mode: TRIANGLES,
        }
    }
}

/// A glTF document under construction, with a single buffer (`bin`).
/// Every field is public so that a test can corrupt any part of it.
#[derive(Clone, Debug, Default)]
pub struct Gltf {
    pub bin: Vec<u8>,
    pub buffer_views: Vec<Value>,
    pub accessors: Vec<Value>,
    pub meshes: Vec<Value>,
    pub nodes: Vec<Value>,
    /// Root nodes of the one scene; `None` writes no `scenes` at all.
    pub scene_roots: Option<Vec<usize>>,
}

impl Gltf {
    /// Appends a buffer view over `bytes`; returns its index.
    pub fn view(&mut self, bytes: &[u8]) -> usize {
        // Accessor offsets must be multiples of their component size: start
        // every view on a 4-byte boundary.
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.buffer_views.push(json!({
            "buffer": 0,
            "byteOffset": offset,
            "byteLength": bytes.len(),
        }));
        self.buffer_views.len() - 1
    }

    /// Appends a VEC3 float POSITION accessor; returns its index.
    pub fn positions(&mut self, points: &[[f32; 3]]) -> usize {
        let bytes: Vec<u8> = points
            .iter()
            .flatten()
            .flat_map(|c| c.to_le_bytes())
            .collect();
        let view = self.view(&bytes);
        // glTF requires min/max on POSITION. JSON cannot hold NaN or Inf, so
        // bounds are taken over the finite components only.
        let mut min = [f32::MAX; 3];
        let mut max = [f32::MIN; 3];
        for p in points {
            for k in 0..3 {
                if p[k].is_finite() {
                    min[k] = min[k].min(p[k]);
                    max[k] = max[k].max(p[k]);
                }
            }
        }
        self.accessors.push(json!({
            "bufferView": view,
            "componentType": FLOAT,
            "count": points.len(),
            "type": "VEC3",
            "min": min,
            "max": max,
        }));
        self.accessors.len() - 1
    }

    /// Appends a SCALAR index accessor of `component_type` (u8, u16 or u32);
    /// returns its index.
    pub fn indices(&mut self, indices: &[u32], component_type: u32) -> usize {
        let bytes: Vec<u8> = match component_type {
            UNSIGNED_BYTE => indices.iter().map(|&i| u8::try_from(i).unwrap()).collect(),
            UNSIGNED_SHORT => indices
                .iter()
                .flat_map(|&i| u16::try_from(i).unwrap().to_le_bytes())
                .collect(),
            UNSIGNED_INT => indices.iter().flat_map(|i| i.to_le_bytes()).collect(),
            other => panic!("not an index component type: {other}"),
        };
        let view = self.view(&bytes);
        self.accessors.push(json!({
            "bufferView": view,
            "componentType": component_type,
            "count": indices.len(),
            "type": "SCALAR",
        }));
        self.accessors.len() - 1
    }

    /// Appends a mesh; returns its index.
    pub fn mesh(&mut self, primitives: &[Primitive]) -> usize {
        let primitives: Vec<Value> = primitives
            .iter()
            .map(|p| {
                let mut primitive = json!({
                    "attributes": { "POSITION": p.positions },
                    "mode": p.mode,
                });
                if let Some(indices) = p.indices {
                    primitive["indices"] = json!(indices);
                }
                primitive
            })
            .collect();
        self.meshes.push(json!({ "primitives": primitives }));
        self.meshes.len() - 1
    }

    /// Appends a node given as raw glTF JSON; returns its index.
    pub fn node(&mut self, node: Value) -> usize {
        self.nodes.push(node);
        self.nodes.len() - 1
    }

    /// A one-mesh, one-node document with the given triangle list
    /// (non-indexed), its node the scene root.
    pub fn single_mesh(triangles: &[[[f32; 3]; 3]]) -> Self {
        let mut gltf = Gltf::default();
        let points: Vec<[f32; 3]> = triangles.iter().flatten().copied().collect();
        let positions = gltf.positions(&points);
        let mesh = gltf.mesh(&[Primitive::triangles(positions, None)]);
        let node = gltf.node(json!({ "mesh": mesh }));
        gltf.scene_roots = Some(vec![node]);
        gltf
    }

    /// The document's JSON; its buffer (if any) has `buffer_uri`, or none
    /// for the BIN chunk of a `.glb`.
    pub fn to_json(&self, buffer_uri: Option<&str>) -> Value {
        let mut root = json!({
            "asset": { "version": "2.0", "generator": "izb tests" },
            "accessors": self.accessors,
            "bufferViews": self.buffer_views,
            "meshes": self.meshes,
            "nodes": self.nodes,
        });
        if !self.bin.is_empty() {
            let mut buffer = json!({ "byteLength": self.bin.len() });
            if let Some(uri) = buffer_uri {
                buffer["uri"] = json!(uri);
            }
            root["buffers"] = json!([buffer]);
        }
        if let Some(roots) = &self.scene_roots {
            root["scene"] = json!(0);
            root["scenes"] = json!([{ "nodes": roots }]);
        }
        root
    }

    /// Writes `<stem>.gltf` and its external buffer `<stem>.bin` into `dir`;
    /// returns the `.gltf` path.
    pub fn write_external(&self, dir: &Path, stem: &str) -> PathBuf {
        let bin_name = format!("{stem}.bin");
        std::fs::write(dir.join(&bin_name), &self.bin).unwrap();
        write_json(
            &dir.join(format!("{stem}.gltf")),
            &self.to_json(Some(&bin_name)),
        )
    }

    /// Writes `<stem>.gltf` with the buffer inline as a base64 data URI.
    pub fn write_embedded(&self, dir: &Path, stem: &str) -> PathBuf {
        let uri = format!(
            "data:application/octet-stream;base64,{}",
            base64_encode(&self.bin)
        );
        write_json(&dir.join(format!("{stem}.gltf")), &self.to_json(Some(&uri)))
    }

    /// Writes `<stem>.glb` (buffer in the BIN chunk).
    pub fn write_glb(&self, dir: &Path, stem: &str) -> PathBuf {
        let path = dir.join(format!("{stem}.glb"));
        std::fs::write(&path, glb_bytes(&self.to_json(None), &self.bin)).unwrap();
        path
    }
}

/// Writes pretty JSON to `path` and returns it.
pub fn write_json(path: &Path, value: &Value) -> PathBuf {
    std::fs::write(path, serde_json::to_string_pretty(value).unwrap()).unwrap();
    path.to_path_buf()
}

/// A binary glTF container (glTF 2.0 §4.4): 12-byte header, a JSON chunk
/// padded with spaces to 4 bytes, and a BIN chunk padded with zeros (left
/// out when `bin` is empty).
pub fn glb_bytes(json: &Value, bin: &[u8]) -> Vec<u8> {
    let mut json_chunk = serde_json::to_vec(json).unwrap();
    while !json_chunk.len().is_multiple_of(4) {
        json_chunk.push(b' ');
    }
    let mut bin_chunk = bin.to_vec();
    while !bin_chunk.len().is_multiple_of(4) {
        bin_chunk.push(0);
    }
    let mut total = 12 + 8 + json_chunk.len();
    if !bin_chunk.is_empty() {
        total += 8 + bin_chunk.len();
    }
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_chunk.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_chunk);
    if !bin_chunk.is_empty() {
        out.extend_from_slice(&(bin_chunk.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin_chunk);
    }
    out
}

/// Standard base64 with `=` padding (RFC 4648 §4), as glTF data URIs use.
pub fn base64_encode(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let group = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            // A chunk of n bytes yields n + 1 significant sextets.
            if k <= chunk.len() {
                out.push(ALPHABET[(group >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// A valid spec around `gltf_file` (relative to the spec): a camera looking
/// at the origin from +Z, a sun from above, a small image.
pub fn spec_json(gltf_file: &str) -> Value {
    json!({
        "gltf": gltf_file,
        "camera": {
            "eye": [0.0, 1.0, 10.0],
            "target": [0.0, 0.0, 0.0],
            "up": [0.0, 1.0, 0.0],
            "fov_y_deg": 45.0,
            "near": 0.05,
            "far": 100.0,
        },
        "light": { "type": "directional", "direction": [0.3, -1.0, -0.2] },
        "resolution": [64, 48],
    })
}

/// Writes `<stem>.scene.json` into `dir`; returns its path.
pub fn write_spec(dir: &Path, stem: &str, spec: &Value) -> PathBuf {
    write_json(&dir.join(format!("{stem}.scene.json")), spec)
}

/// Loads a scene the way the CLI does, from a path argument.
pub fn load_path(path: &Path) -> Result<Scene, SceneError> {
    izb::scene::load(path.to_str().expect("temp paths are UTF-8"))
}

/// The error's message, panicking (without printing a whole scene) if the
/// result is `Ok`.
pub fn error_message<T, E: Display>(result: Result<T, E>, what: &str) -> String {
    match result {
        Ok(_) => panic!("{what}: expected an error, got Ok"),
        Err(e) => e.to_string(),
    }
}

/// Asserts that `message` contains every part, showing the whole message
/// when it does not.
pub fn assert_mentions(message: &str, parts: &[&str]) {
    for part in parts {
        assert!(
            message.contains(part),
            "message does not mention {part:?}:\n  {message}"
        );
    }
}

/// Loads `path` expecting an error; checks that both the plain message and
/// the anyhow chain (`{:#}`, as the CLI prints it) mention every part.
/// Returns the plain message.
pub fn expect_load_error(path: &Path, parts: &[&str]) -> String {
    let err = match load_path(path) {
        Ok(_) => panic!("{}: expected an error, got Ok", path.display()),
        Err(e) => e,
    };
    let message = err.to_string();
    assert_mentions(&message, parts);
    let chain = format!("{:#}", anyhow::Error::new(err));
    assert_mentions(&chain, parts);
    message
}
