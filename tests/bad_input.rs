//! Malformed scenes, specs and glTF files: each must come back as an error
//! whose message names the problem (file, field, index...), never a panic.
//! Degenerate triangles are the exception: they are dropped and counted.

mod common;

use common::*;
use izb::scene::{self, is_degenerate, load_gltf, Triangle, MAX_RESOLUTION};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// A non-degenerate triangle at height `z`.
fn triangle_at(z: f32) -> [[f32; 3]; 3] {
    [[0.0, 0.0, z], [1.0, 0.0, z], [0.0, 1.0, z]]
}

/// Checks that a broken glTF fails both through `load_gltf` and through a
/// spec naming it, each message mentioning `parts` and the file name.
fn expect_gltf_error(dir: &TempDir, gltf_path: &Path, parts: &[&str]) -> String {
    let file = gltf_path.file_name().unwrap().to_str().unwrap();
    let mut all_parts = vec![file];
    all_parts.extend_from_slice(parts);
    let message = error_message(load_gltf(gltf_path), file);
    assert_mentions(&message, &all_parts);
    let spec = write_spec(dir.path(), "broken", &spec_json(file));
    expect_load_error(&spec, &all_parts);
    println!("{message}");
    message
}

/// A spec around a valid one-triangle glb, changed by `edit`, is rejected
/// with a message naming the spec file and `parts`.
fn expect_spec_error(test_name: &str, edit: impl FnOnce(&mut Value), parts: &[&str]) -> String {
    let dir = TempDir::new(test_name);
    Gltf::single_mesh(&[triangle_at(0.0)]).write_glb(dir.path(), "tri");
    let mut spec = spec_json("tri.glb");
    edit(&mut spec);
    let path = write_spec(dir.path(), "edited", &spec);
    let mut all_parts = vec!["edited.scene.json"];
    all_parts.extend_from_slice(parts);
    let message = expect_load_error(&path, &all_parts);
    println!("{message}");
    message
}

// ---- files that are missing or cut short ----

#[test]
fn missing_spec_file() {
    let dir = TempDir::new("missing-spec");
    let path = dir.join("absent.scene.json");
    expect_load_error(&path, &["absent.scene.json", "cannot read"]);
}

#[test]
fn missing_gltf_file_referenced_by_a_spec() {
    let dir = TempDir::new("missing-gltf");
    let spec = write_spec(dir.path(), "orphan", &spec_json("nowhere.glb"));
    expect_load_error(&spec, &["nowhere.glb", "cannot read"]);
}

#[test]
fn truncated_glb() {
    let dir = TempDir::new("truncated-glb");
    let valid =
        Gltf::single_mesh(&[triangle_at(0.0), triangle_at(1.0)]).write_glb(dir.path(), "valid");
    let bytes = std::fs::read(&valid).unwrap();
    assert!(load_gltf(&valid).is_ok());

    let half = dir.join("half.glb");
    std::fs::write(&half, &bytes[..bytes.len() / 2]).unwrap();
    let declared = bytes.len().to_string();
    let actual = (bytes.len() / 2).to_string();
    expect_gltf_error(&dir, &half, &["truncated", &declared, &actual]);

    let ten = dir.join("ten.glb");
    std::fs::write(&ten, &bytes[..10]).unwrap();
    expect_gltf_error(&dir, &ten, &["truncated", "10 bytes"]);
}

#[test]
fn glb_header_declaring_less_than_its_own_header() {
    let dir = TempDir::new("glb-short-length");
    let mut bytes =
        std::fs::read(Gltf::single_mesh(&[triangle_at(0.0)]).write_glb(dir.path(), "valid"))
            .unwrap();
    bytes[8..12].copy_from_slice(&4u32.to_le_bytes());
    let path = dir.join("short.glb");
    std::fs::write(&path, &bytes).unwrap();
    expect_gltf_error(&dir, &path, &["declares 4 bytes"]);
}

#[test]
fn gltf_whose_external_buffer_is_missing() {
    let dir = TempDir::new("missing-bin");
    let gltf = Gltf::single_mesh(&[triangle_at(0.0)]);
    write_json(
        &dir.join("lonely.gltf"),
        &gltf.to_json(Some("lonely-data.bin")),
    );
    expect_gltf_error(
        &dir,
        &dir.join("lonely.gltf"),
        &["buffer 0", "lonely-data.bin"],
    );
}

#[test]
fn buffer_shorter_than_its_declared_byte_length() {
    let dir = TempDir::new("short-buffer");
    // Two triangles: 72 bytes declared, 36 on disk.
    let gltf = Gltf::single_mesh(&[triangle_at(0.0), triangle_at(1.0)]);
    let path = gltf.write_external(dir.path(), "short");
    std::fs::write(dir.join("short.bin"), &gltf.bin[..36]).unwrap();
    expect_gltf_error(&dir, &path, &["buffer 0", "72", "36"]);
}

#[test]
fn accessor_running_past_its_buffer_view() {
    let dir = TempDir::new("accessor-past-view");
    let gltf = Gltf::single_mesh(&[triangle_at(0.0)]);
    let mut root = gltf.to_json(Some("data.bin"));
    // Six vertices of 12 bytes in a view of 36 bytes.
    root["accessors"][0]["count"] = json!(6);
    std::fs::write(dir.join("data.bin"), &gltf.bin).unwrap();
    let path = write_json(&dir.join("past.gltf"), &root);
    expect_gltf_error(
        &dir,
        &path,
        &["accessor 0", "72 bytes", "buffer view 0 has 36"],
    );
}

#[test]
fn accessor_with_an_overflowing_count() {
    let dir = TempDir::new("huge-count");
    let gltf = Gltf::single_mesh(&[triangle_at(0.0)]);
    let mut root = gltf.to_json(Some("data.bin"));
    // count × 12 bytes wraps around 2^64 unless the bound check is exact.
    root["accessors"][0]["count"] = json!(u64::MAX / 6);
    std::fs::write(dir.join("data.bin"), &gltf.bin).unwrap();
    let path = write_json(&dir.join("huge.gltf"), &root);
    expect_gltf_error(&dir, &path, &["accessor 0", "buffer view 0 has 36"]);
}

#[test]
fn accessor_with_zero_count() {
    let dir = TempDir::new("zero-count");
    let gltf = Gltf::single_mesh(&[triangle_at(0.0)]);
    let mut root = gltf.to_json(Some("data.bin"));
    root["accessors"][0]["count"] = json!(0);
    std::fs::write(dir.join("data.bin"), &gltf.bin).unwrap();
    let path = write_json(&dir.join("empty.gltf"), &root);
    expect_gltf_error(&dir, &path, &["accessor 0", "count 0"]);
}

#[test]
fn byte_stride_smaller_than_the_element() {
    let dir = TempDir::new("small-stride");
    let gltf = Gltf::single_mesh(&[triangle_at(0.0)]);
    let mut root = gltf.to_json(Some("data.bin"));
    // 4-byte stride for 12-byte VEC3 floats: elements would overlap.
    root["bufferViews"][0]["byteStride"] = json!(4);
    std::fs::write(dir.join("data.bin"), &gltf.bin).unwrap();
    let path = write_json(&dir.join("stride.gltf"), &root);
    expect_gltf_error(&dir, &path, &["stride 4", "12"]);
}

#[test]
fn buffer_view_running_past_its_buffer() {
    let dir = TempDir::new("view-past-buffer");
    let gltf = Gltf::single_mesh(&[triangle_at(0.0)]);
    let mut root = gltf.to_json(Some("data.bin"));
    root["bufferViews"][0]["byteLength"] = json!(48);
    std::fs::write(dir.join("data.bin"), &gltf.bin).unwrap();
    let path = write_json(&dir.join("view.gltf"), &root);
    expect_gltf_error(
        &dir,
        &path,
        &["buffer view 0", "length 48", "buffer 0 of 36 bytes"],
    );
}

// ---- bad references and values inside the glTF ----

#[test]
fn index_out_of_range() {
    let dir = TempDir::new("index-range");
    let mut gltf = Gltf::default();
    let positions = gltf.positions(&triangle_at(0.0));
    let indices = gltf.indices(&[0, 1, 2, 0, 2, 7], UNSIGNED_SHORT);
    let mesh = gltf.mesh(&[Primitive::triangles(positions, Some(indices))]);
    let node = gltf.node(json!({ "name": "holder", "mesh": mesh }));
    gltf.scene_roots = Some(vec![node]);
    let path = gltf.write_glb(dir.path(), "badindex");
    expect_gltf_error(
        &dir,
        &path,
        &["index 7", "3 vertices", "node 0 'holder'", "primitive 0"],
    );
}

/// Found by `examples/fuzz_loaders.rs`: the gltf crate's index reader hit
/// `unreachable!()` on an index accessor of floats.
#[test]
fn index_accessor_of_floats() {
    let dir = TempDir::new("float-indices");
    let mut gltf = Gltf::default();
    let positions = gltf.positions(&triangle_at(0.0));
    let mesh = gltf.mesh(&[Primitive::triangles(positions, Some(positions))]);
    let node = gltf.node(json!({ "name": "holder", "mesh": mesh }));
    gltf.scene_roots = Some(vec![node]);
    let path = gltf.write_glb(dir.path(), "floatindex");
    expect_gltf_error(
        &dir,
        &path,
        &["index accessor", "F32", "unsigned", "primitive 0"],
    );
}

#[test]
fn position_accessor_index_out_of_range() {
    let dir = TempDir::new("position-accessor");
    let gltf = Gltf::single_mesh(&[triangle_at(0.0)]);
    let mut root = gltf.to_json(Some("data.bin"));
    root["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(99);
    std::fs::write(dir.join("data.bin"), &gltf.bin).unwrap();
    let path = write_json(&dir.join("dangling.gltf"), &root);
    expect_gltf_error(&dir, &path, &["POSITION", "99"]);
}

#[test]
fn primitive_without_positions() {
    let dir = TempDir::new("no-position");
    let gltf = Gltf::single_mesh(&[triangle_at(0.0)]);
    let mut root = gltf.to_json(Some("data.bin"));
    root["meshes"][0]["primitives"][0]["attributes"] = json!({});
    std::fs::write(dir.join("data.bin"), &gltf.bin).unwrap();
    let path = write_json(&dir.join("nopos.gltf"), &root);
    expect_gltf_error(&dir, &path, &["POSITION"]);
}

#[test]
fn cyclic_node_hierarchy() {
    let dir = TempDir::new("cycle");
    let mut gltf = Gltf::single_mesh(&[triangle_at(0.0)]);
    gltf.nodes[0]["children"] = json!([1]);
    gltf.node(json!({ "children": [0] }));
    let path = gltf.write_glb(dir.path(), "cycle");
    expect_gltf_error(&dir, &path, &["cycle"]);
}

#[test]
fn node_with_two_parents() {
    let dir = TempDir::new("two-parents");
    let mut gltf = Gltf::single_mesh(&[triangle_at(0.0)]);
    // 40 levels of two nodes, each the parent of both nodes of the next
    // level: 2^40 paths to the last level if the graph were expanded.
    const LEVELS: usize = 40;
    gltf.nodes.clear();
    for level in 0..LEVELS {
        for _ in 0..2 {
            let mut node = json!({ "mesh": 0 });
            if level + 1 < LEVELS {
                node["children"] = json!([2 * level + 2, 2 * level + 3]);
            }
            gltf.node(node);
        }
    }
    gltf.scene_roots = Some(vec![0, 1]);
    let path = gltf.write_glb(dir.path(), "diamond");
    expect_gltf_error(
        &dir,
        &path,
        &["node 2", "more than one parent", "nodes 0 and 1"],
    );
}

#[test]
fn sparse_accessor_values_running_past_their_view() {
    let dir = TempDir::new("sparse");
    let gltf = Gltf::single_mesh(&[triangle_at(0.0)]);
    let mut root = gltf.to_json(Some("data.bin"));
    // Sparse replacement of 2 vertices: indices in view 0 (bytes 0..4 as
    // u16s), values in view 0 from byte 30, which leaves 6 of 24 bytes.
    root["accessors"][0]["sparse"] = json!({
        "count": 2,
        "indices": { "bufferView": 0, "componentType": UNSIGNED_SHORT },
        "values": { "bufferView": 0, "byteOffset": 30 },
    });
    std::fs::write(dir.join("data.bin"), &gltf.bin).unwrap();
    let path = write_json(&dir.join("sparse.gltf"), &root);
    expect_gltf_error(
        &dir,
        &path,
        &["accessor 0", "needs 54 bytes", "buffer view 0 has 36"],
    );
}

#[test]
fn nan_and_infinite_vertex_positions() {
    let dir = TempDir::new("non-finite");
    for (stem, bad) in [("nan", f32::NAN), ("inf", f32::INFINITY)] {
        let mut triangles = [triangle_at(0.0), triangle_at(1.0)];
        triangles[1][2][1] = bad;
        let path = Gltf::single_mesh(&triangles).write_external(dir.path(), stem);
        // Vertex 5 is the third corner of the second triangle.
        let expected = if bad.is_nan() { "NaN" } else { "inf" };
        expect_gltf_error(&dir, &path, &["vertex 5", "non-finite", expected]);
    }
}

#[test]
fn node_scale_overflowing_f32_gives_non_finite_positions() {
    let dir = TempDir::new("huge-scale");
    let mut gltf = Gltf::single_mesh(&[triangle_at(0.0)]);
    // 1e39 exceeds f32::MAX (3.4e38): the f32 transform becomes infinite.
    gltf.nodes[0]["scale"] = json!([1e39, 1.0, 1.0]);
    let path = gltf.write_glb(dir.path(), "scaled");
    expect_gltf_error(&dir, &path, &["node 0", "non-finite"]);
}

// ---- degenerate geometry: dropped and counted, not an error ----

#[test]
fn degenerate_triangles_are_dropped_and_counted() {
    let dir = TempDir::new("degenerate");
    let collinear_rounded = [[0.1, 0.2, 0.3], [0.2, 0.4, 0.6], [0.3, 0.6, 0.9]];
    let triangles = [
        triangle_at(0.0),
        // Zero area: a repeated corner.
        [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.0, 0.0, 0.0]],
        triangle_at(1.0),
        // Three distinct points on a line, exact in f32.
        [[0.0, 0.0, 0.0], [1.0, 2.0, 3.0], [2.0, 4.0, 6.0]],
        // On a line before rounding to f32, a sliver of ~1e-8 after.
        collinear_rounded,
        triangle_at(2.0),
    ];
    let rounded: Triangle = collinear_rounded.map(|p| p.map(f64::from).into());
    assert!(
        is_degenerate(&rounded),
        "the rounded collinear triangle must count as degenerate"
    );

    let path = Gltf::single_mesh(&triangles).write_external(dir.path(), "mixed");
    // The loader itself keeps everything; dropping is the scene's job.
    assert_eq!(load_gltf(&path).unwrap().triangles.len(), 6);

    let spec = write_spec(dir.path(), "mixed", &spec_json("mixed.gltf"));
    let scene = load_path(&spec).unwrap();
    assert_eq!(scene.stats.source_triangles, 6);
    assert_eq!(scene.stats.dropped_degenerate, 3);
    assert_eq!(scene.triangles.len(), 3);
    // Survivors keep the ids they had in the source.
    assert_eq!(scene.source_ids[..], [0, 2, 5]);
    for (tri, z) in scene.triangles.iter().zip([0.0, 1.0, 2.0]) {
        assert!(tri.iter().all(|p| p.z == z), "{tri:?} not at z = {z}");
    }
}

#[test]
fn scene_of_only_degenerate_triangles() {
    let dir = TempDir::new("all-degenerate");
    let triangles = [
        [[0.0, 0.0, 0.0], [1.0, 2.0, 3.0], [2.0, 4.0, 6.0]],
        [[1.0, 1.0, 1.0], [1.0, 1.0, 1.0], [2.0, 0.0, 0.0]],
    ];
    Gltf::single_mesh(&triangles).write_glb(dir.path(), "flat");
    let spec = write_spec(dir.path(), "flat", &spec_json("flat.glb"));
    expect_load_error(&spec, &["no triangles", "2 in the source", "2 degenerate"]);
}

#[test]
fn gltf_without_meshes() {
    let dir = TempDir::new("no-meshes");
    let root = json!({
        "asset": { "version": "2.0" },
        "nodes": [{ "translation": [1.0, 0.0, 0.0] }],
        "scenes": [{ "nodes": [0] }],
        "scene": 0,
    });
    write_json(&dir.join("empty.gltf"), &root);
    let spec = write_spec(dir.path(), "empty", &spec_json("empty.gltf"));
    expect_load_error(&spec, &["no triangles"]);
}

// ---- spec fields ----

#[test]
fn camera_eye_equal_to_target() {
    expect_spec_error(
        "eye-target",
        |s| s["camera"]["eye"] = json!([0.0, 0.0, 0.0]),
        &["camera.eye", "camera.target"],
    );
}

#[test]
fn camera_up_parallel_to_view() {
    expect_spec_error(
        "up-parallel",
        |s| s["camera"]["up"] = json!([0.0, 2.0, 20.0]),
        &["camera.up", "parallel"],
    );
}

#[test]
fn camera_fov_and_clip_range() {
    expect_spec_error(
        "fov",
        |s| s["camera"]["fov_y_deg"] = json!(180.0),
        &["camera.fov_y_deg", "180"],
    );
    expect_spec_error(
        "near-far",
        |s| s["camera"]["far"] = json!(0.01),
        &["camera.near", "camera.far", "0.01"],
    );
}

#[test]
fn zero_light_direction() {
    expect_spec_error(
        "light-zero",
        |s| s["light"]["direction"] = json!([0.0, 0.0, 0.0]),
        &["light.direction"],
    );
}

#[test]
fn resolution_out_of_range() {
    for (i, resolution) in [[0, 100], [100, 0], [MAX_RESOLUTION + 1, 10]]
        .into_iter()
        .enumerate()
    {
        let shown = format!("{}x{}", resolution[0], resolution[1]);
        expect_spec_error(
            &format!("resolution-{i}"),
            |s| s["resolution"] = json!(resolution),
            &["resolution", &shown, &MAX_RESOLUTION.to_string()],
        );
    }
}

#[test]
fn wrong_field_type() {
    expect_spec_error(
        "wrong-type",
        |s| s["camera"]["eye"] = json!("up"),
        &["camera.eye", "invalid type", "\"up\""],
    );
}

#[test]
fn missing_light_field() {
    expect_spec_error(
        "missing-light",
        |s| {
            s.as_object_mut().unwrap().remove("light");
        },
        &["missing field `light`"],
    );
}

#[test]
fn unknown_spec_field() {
    // A typo must not be silently ignored.
    expect_spec_error(
        "typo",
        |s| s["camera"]["fov"] = json!(45.0),
        &["camera", "unknown field `fov`"],
    );
}

#[test]
fn both_or_neither_geometry_source() {
    expect_spec_error(
        "both",
        |s| s["procedural"] = json!("default"),
        &["`gltf`", "`procedural`"],
    );
    expect_spec_error(
        "neither",
        |s| {
            s.as_object_mut().unwrap().remove("gltf");
        },
        &["no geometry", "`gltf`", "`procedural`"],
    );
}

#[test]
fn unknown_procedural_scene_in_a_spec() {
    let message = expect_spec_error(
        "unknown-procedural",
        |s| {
            s.as_object_mut().unwrap().remove("gltf");
            s["procedural"] = json!("nonexistent-name");
        },
        &["procedural", "nonexistent-name"],
    );
    assert_mentions(&message, scene::procedural::NAMES);
}

#[test]
fn unknown_scene_argument() {
    let message = error_message(scene::load("nonexistent-name"), "nonexistent-name");
    assert_mentions(&message, &["nonexistent-name"]);
    assert_mentions(&message, scene::procedural::NAMES);
}

#[test]
fn malformed_json_spec() {
    let dir = TempDir::new("malformed");
    let text = serde_json::to_string_pretty(&spec_json("tri.glb")).unwrap();
    let path: PathBuf = dir.join("cut.scene.json");
    std::fs::write(&path, &text[..text.len() / 2]).unwrap();
    expect_load_error(&path, &["cut.scene.json", "EOF while parsing"]);
}

#[test]
fn with_resolution_rejects_zero() {
    let scene = scene::load("analytic").unwrap();
    let message = error_message(scene.with_resolution([0, 5]), "with_resolution([0, 5])");
    assert_mentions(&message, &["resolution", "0x5"]);
}

#[test]
fn light_sizes_out_of_range() {
    expect_spec_error(
        "negative-sun",
        |s| s["light"]["angular_radius_deg"] = json!(-1.0),
        &["light.angular_radius_deg", "≥ 0", "-1"],
    );
    expect_spec_error(
        "wide-sun",
        |s| s["light"]["angular_radius_deg"] = json!(45.0),
        &["light.angular_radius_deg", "at most 30"],
    );
    expect_spec_error(
        "negative-sphere",
        |s| s["light"] = json!({ "type": "point", "position": [0.0, 5.0, 0.0], "radius": -2.0 }),
        &["light.radius", "≥ 0"],
    );
    expect_spec_error(
        "sun-with-radius",
        |s| s["light"]["radius"] = json!(1.0),
        &["light", "unknown field `radius`"],
    );
    let scene = scene::load("analytic").unwrap();
    let message = error_message(scene.with_light_size(f64::NAN), "with_light_size(NaN)");
    assert_mentions(&message, &["--light-size", "angular_radius_deg", "NaN"]);
    let output = common::izb_cli(&["render", "analytic", "--light-size=-3", "--backend", "cpu"]);
    assert!(!output.status.success(), "a negative --light-size rendered");
    assert_mentions(
        &String::from_utf8_lossy(&output.stderr),
        &["--light-size", "≥ 0"],
    );
}
