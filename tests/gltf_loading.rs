//! glTF loading through the `gltf` crate: the three container forms, the
//! node transform chain, triangle topologies, index widths, skipped point
//! and line primitives and instancing, each checked both through
//! `load_gltf` and through a `*.scene.json` spec next to the file.

mod common;

use approx::abs_diff_eq;
use common::*;
use glam::DVec3;
use izb::scene::{load_gltf, Scene, Triangle};
use serde_json::json;
use std::path::Path;

/// Transforms here are exact in binary floating point except rotations,
/// whose f32 quaternion components (√½) leave ~1e-7 relative error.
const ROTATION_TOLERANCE: f64 = 1e-5;

fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

/// Whether `b` is `a` with its corners cyclically rotated: the same
/// triangle with the same winding, whichever corner the loader lists first.
fn same_triangle(a: &Triangle, b: &Triangle, tolerance: f64) -> bool {
    (0..3).any(|shift| {
        (0..3).all(|k| {
            abs_diff_eq!(
                a[k].to_array()[..],
                b[(k + shift) % 3].to_array()[..],
                epsilon = tolerance
            )
        })
    })
}

/// Asserts the triangles match `expected` in order, each up to a cyclic
/// rotation of its corners.
fn assert_triangles(actual: &[Triangle], expected: &[Triangle], tolerance: f64) {
    assert_eq!(
        actual.len(),
        expected.len(),
        "triangle count; got {actual:?}"
    );
    for (i, (a, e)) in actual.iter().zip(expected).enumerate() {
        assert!(
            same_triangle(a, e, tolerance),
            "triangle {i}: got {a:?}, expected {e:?} (tolerance {tolerance:e})"
        );
    }
}

/// Loads the spec written next to `gltf_path` and checks the counts every
/// fixture here shares: nothing degenerate, source ids 0..n.
fn load_through_spec(dir: &Path, gltf_path: &Path) -> Scene {
    let file = gltf_path.file_name().unwrap().to_str().unwrap();
    let stem = file.split('.').next().unwrap();
    let spec_path = write_spec(dir, stem, &spec_json(file));
    let scene = load_path(&spec_path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.name, stem);
    assert_eq!(scene.stats.dropped_degenerate, 0);
    assert_eq!(scene.triangles.len(), scene.stats.source_triangles);
    let ids: Vec<u32> = (0..scene.triangles.len() as u32).collect();
    assert_eq!(scene.source_ids[..], ids[..]);
    assert_eq!(scene.resolution, [64, 48]);
    scene
}

/// Checks a file through both entry points against `expected`.
fn check_both_ways(dir: &Path, gltf_path: &Path, expected: &[Triangle], tolerance: f64) -> Scene {
    let meshes = load_gltf(gltf_path).unwrap_or_else(|e| panic!("{e}"));
    assert_triangles(&meshes.triangles, expected, tolerance);
    assert_eq!(meshes.skipped_non_triangle_primitives, 0);
    assert!(meshes.warnings.is_empty(), "{:?}", meshes.warnings);
    let scene = load_through_spec(dir, gltf_path);
    assert_eq!(scene.stats.source_triangles, expected.len());
    assert_triangles(&scene.triangles, expected, tolerance);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    scene
}

/// A unit quad (two triangles, u16 indices) under a node translated by
/// (1, 2, 3): the fixture of the container tests.
fn translated_quad() -> (Gltf, Vec<Triangle>) {
    let mut gltf = Gltf::default();
    let positions = gltf.positions(&[
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ]);
    let indices = gltf.indices(&[0, 1, 2, 0, 2, 3], UNSIGNED_SHORT);
    let mesh = gltf.mesh(&[Primitive::triangles(positions, Some(indices))]);
    let node = gltf.node(json!({ "mesh": mesh, "translation": [1.0, 2.0, 3.0] }));
    gltf.scene_roots = Some(vec![node]);
    let expected = vec![
        [v(1.0, 2.0, 3.0), v(2.0, 2.0, 3.0), v(2.0, 3.0, 3.0)],
        [v(1.0, 2.0, 3.0), v(2.0, 3.0, 3.0), v(1.0, 3.0, 3.0)],
    ];
    (gltf, expected)
}

#[test]
fn base64_encoder_matches_rfc_4648_vectors() {
    // The embedded-buffer fixture depends on it.
    for (input, encoded) in [
        ("", ""),
        ("f", "Zg=="),
        ("fo", "Zm8="),
        ("foo", "Zm9v"),
        ("foob", "Zm9vYg=="),
        ("fooba", "Zm9vYmE="),
        ("foobar", "Zm9vYmFy"),
    ] {
        assert_eq!(base64_encode(input.as_bytes()), encoded, "input {input:?}");
    }
    assert_eq!(base64_encode(&[0xfb, 0xff, 0xbf]), "+/+/");
}

#[test]
fn gltf_with_external_bin_buffer() {
    let dir = TempDir::new("external-bin");
    let (gltf, expected) = translated_quad();
    let path = gltf.write_external(dir.path(), "quad");
    check_both_ways(dir.path(), &path, &expected, 0.0);
}

#[test]
fn gltf_with_base64_data_uri_buffer() {
    let dir = TempDir::new("base64");
    let (gltf, expected) = translated_quad();
    let path = gltf.write_embedded(dir.path(), "quad");
    // Nothing but the .gltf may be read.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    check_both_ways(dir.path(), &path, &expected, 0.0);
}

#[test]
fn glb_container() {
    let dir = TempDir::new("glb");
    let (mut gltf, expected) = translated_quad();
    // An odd-length BIN payload exercises the zero padding of the chunk.
    gltf.view(&[1, 2, 3]);
    let path = gltf.write_glb(dir.path(), "quad");
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(bytes.len() % 4, 0);
    assert_eq!(
        u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize,
        bytes.len()
    );
    check_both_ways(dir.path(), &path, &expected, 0.0);
}

#[test]
fn node_hierarchy_composes_trs_and_matrix_transforms() {
    let dir = TempDir::new("hierarchy");
    let mut gltf = Gltf::default();
    let positions = gltf.positions(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let mesh = gltf.mesh(&[Primitive::triangles(positions, None)]);
    let half_sqrt2 = std::f32::consts::FRAC_1_SQRT_2;
    // Parent: world = T(10,0,0) · R_y(90°) · S(2,3,4). The non-uniform scale
    // makes the order of R and S visible; R_y(90°) maps (x,y,z) to (z,y,-x).
    gltf.node(json!({
        "mesh": mesh,
        "translation": [10.0, 0.0, 0.0],
        "rotation": [0.0, half_sqrt2, 0.0, half_sqrt2],
        "scale": [2.0, 3.0, 4.0],
        "children": [1],
    }));
    // Child: column-major matrix scaling x by 3, then translating by (0,1,0).
    gltf.node(json!({
        "mesh": mesh,
        "matrix": [3.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 1.0],
        "children": [2],
    }));
    // Grandchild: translation (0,0,5) under both.
    gltf.node(json!({ "mesh": mesh, "translation": [0.0, 0.0, 5.0] }));
    // Not in the scene: must not be loaded.
    gltf.node(json!({ "mesh": mesh, "translation": [100.0, 0.0, 0.0] }));
    gltf.scene_roots = Some(vec![0]);
    let path = gltf.write_external(dir.path(), "hierarchy");

    // Worked by hand, corner by corner: local → each matrix up the chain.
    let expected = [
        // Parent: (0,0,0)→(10,0,0); (1,0,0)→S(2,0,0)→R(0,0,-2)→(10,0,-2);
        // (0,1,0)→S(0,3,0)→R(0,3,0)→(10,3,0).
        [v(10.0, 0.0, 0.0), v(10.0, 0.0, -2.0), v(10.0, 3.0, 0.0)],
        // Child: M(x,y,z) = (3x, y+1, z), then the parent.
        // (0,0,0)→(0,1,0)→(0,3,0)→(10,3,0); (1,0,0)→(3,1,0)→(6,3,0)→(0,3,-6)→(10,3,-6);
        // (0,1,0)→(0,2,0)→(0,6,0)→(10,6,0).
        [v(10.0, 3.0, 0.0), v(10.0, 3.0, -6.0), v(10.0, 6.0, 0.0)],
        // Grandchild: (x,y,z+5), then the child, then the parent.
        // (0,0,0)→(0,0,5)→(0,1,5)→(0,3,20)→(20,3,0)→(30,3,0);
        // (1,0,0)→(1,0,5)→(3,1,5)→(6,3,20)→(20,3,-6)→(30,3,-6);
        // (0,1,0)→(0,1,5)→(0,2,5)→(0,6,20)→(20,6,0)→(30,6,0).
        [v(30.0, 3.0, 0.0), v(30.0, 3.0, -6.0), v(30.0, 6.0, 0.0)],
    ];
    check_both_ways(dir.path(), &path, &expected, ROTATION_TOLERANCE);
}

#[test]
fn without_scenes_every_root_node_is_loaded_once() {
    let dir = TempDir::new("no-scenes");
    let mut gltf = Gltf::default();
    let positions = gltf.positions(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let mesh = gltf.mesh(&[Primitive::triangles(positions, None)]);
    gltf.node(json!({ "mesh": mesh, "children": [1] }));
    gltf.node(json!({ "mesh": mesh, "translation": [0.0, 0.0, 2.0] }));
    gltf.node(json!({ "mesh": mesh, "translation": [0.0, 0.0, 4.0] }));
    gltf.scene_roots = None;
    let path = gltf.write_external(dir.path(), "noscene");
    // Node 1 is a child of node 0, so it is reached once, through node 0.
    let expected = [0.0, 2.0, 4.0].map(|z| [v(0.0, 0.0, z), v(1.0, 0.0, z), v(0.0, 1.0, z)]);
    check_both_ways(dir.path(), &path, &expected, 0.0);
}

#[test]
fn triangle_list_strip_and_fan() {
    let dir = TempDir::new("topologies");
    let mut gltf = Gltf::default();
    // List: a quad at z = 0 with indices (0,1,2) (2,1,3).
    let list_positions = gltf.positions(&[
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
    ]);
    let list_indices = gltf.indices(&[0, 1, 2, 2, 1, 3], UNSIGNED_SHORT);
    // Strip (non-indexed): a zigzag of 5 vertices at z = 1 → 3 triangles.
    let strip_positions = gltf.positions(&[
        [0.0, 0.0, 1.0],
        [0.0, 1.0, 1.0],
        [1.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
        [2.0, 0.0, 1.0],
    ]);
    // Fan (indexed, deliberately not in vertex order): centre and four rim
    // vertices at z = 2 → 3 triangles.
    let fan_positions = gltf.positions(&[
        [1.0, 0.0, 2.0],
        [0.0, 0.0, 2.0],
        [1.0, 1.0, 2.0],
        [0.0, 1.0, 2.0],
        [-1.0, 1.0, 2.0],
    ]);
    let fan_indices = gltf.indices(&[1, 0, 2, 3, 4], UNSIGNED_SHORT);
    let mesh = gltf.mesh(&[
        Primitive::triangles(list_positions, Some(list_indices)),
        Primitive {
            positions: strip_positions,
            indices: None,
            mode: TRIANGLE_STRIP,
        },
        Primitive {
            positions: fan_positions,
            indices: Some(fan_indices),
            mode: TRIANGLE_FAN,
        },
    ]);
    let node = gltf.node(json!({ "mesh": mesh }));
    gltf.scene_roots = Some(vec![node]);
    let path = gltf.write_external(dir.path(), "topologies");

    let (s0, s1, s2, s3, s4) = (
        v(0.0, 0.0, 1.0),
        v(0.0, 1.0, 1.0),
        v(1.0, 0.0, 1.0),
        v(1.0, 1.0, 1.0),
        v(2.0, 0.0, 1.0),
    );
    let (c, r1, r2, r3, r4) = (
        v(0.0, 0.0, 2.0),
        v(1.0, 0.0, 2.0),
        v(1.0, 1.0, 2.0),
        v(0.0, 1.0, 2.0),
        v(-1.0, 1.0, 2.0),
    );
    let expected = [
        [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)],
        [v(0.0, 1.0, 0.0), v(1.0, 0.0, 0.0), v(1.0, 1.0, 0.0)],
        // glTF §3.7.2.1: strip triangle i is (i, i+1+i%2, i+2-i%2), so odd
        // triangles swap two corners and every triangle keeps the winding.
        [s0, s1, s2],
        [s2, s1, s3],
        [s2, s3, s4],
        // Fan triangle i is (i+1, i+2, 0): the centre with consecutive rim
        // vertices.
        [c, r1, r2],
        [c, r2, r3],
        [c, r3, r4],
    ];
    let scene = check_both_ways(dir.path(), &path, &expected, 0.0);
    assert_eq!(scene.stats.source_triangles, 2 + 3 + 3);
}

#[test]
fn u8_u16_u32_and_no_indices_give_the_same_triangles() {
    let dir = TempDir::new("index-widths");
    let quad = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    let quad_indices = [0, 1, 2, 0, 2, 3];
    let mut gltf = Gltf::default();
    let mut primitives = Vec::new();

    // u8: the quad's four vertices are the whole accessor.
    let positions = gltf.positions(&quad);
    let indices = gltf.indices(&quad_indices, UNSIGNED_BYTE);
    primitives.push(Primitive::triangles(positions, Some(indices)));

    // u16 and u32: the quad sits past the previous width's range (at 300
    // and at 70,000), so an index read with too few bytes would hit the
    // decoy vertices instead.
    for (first, component_type) in [(300u32, UNSIGNED_SHORT), (70_000u32, UNSIGNED_INT)] {
        let mut points = vec![[9.0f32, 9.0, 9.0]; first as usize];
        points.extend_from_slice(&quad);
        let positions = gltf.positions(&points);
        let shifted: Vec<u32> = quad_indices.iter().map(|i| i + first).collect();
        let indices = gltf.indices(&shifted, component_type);
        primitives.push(Primitive::triangles(positions, Some(indices)));
    }

    // Non-indexed: every three vertices make a triangle.
    let flat: Vec<[f32; 3]> = quad_indices.iter().map(|&i| quad[i as usize]).collect();
    let positions = gltf.positions(&flat);
    primitives.push(Primitive::triangles(positions, None));

    let mesh = gltf.mesh(&primitives);
    let node = gltf.node(json!({ "mesh": mesh }));
    gltf.scene_roots = Some(vec![node]);
    let path = gltf.write_external(dir.path(), "widths");

    let pair = [
        [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(1.0, 1.0, 0.0)],
        [v(0.0, 0.0, 0.0), v(1.0, 1.0, 0.0), v(0.0, 1.0, 0.0)],
    ];
    let expected: Vec<Triangle> = pair.iter().cycle().take(8).copied().collect();
    check_both_ways(dir.path(), &path, &expected, 0.0);
}

#[test]
fn points_and_lines_are_skipped_with_one_warning() {
    let dir = TempDir::new("points-lines");
    let mut gltf = Gltf::default();
    let triangle = gltf.positions(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let points = gltf.positions(&[[5.0, 0.0, 0.0], [6.0, 0.0, 0.0], [7.0, 0.0, 0.0]]);
    let line_indices = gltf.indices(&[0, 1, 1, 2], UNSIGNED_BYTE);
    let mesh = gltf.mesh(&[
        Primitive {
            positions: points,
            indices: None,
            mode: POINTS,
        },
        Primitive::triangles(triangle, None),
        Primitive {
            positions: points,
            indices: Some(line_indices),
            mode: LINES,
        },
    ]);
    let node = gltf.node(json!({ "mesh": mesh }));
    gltf.scene_roots = Some(vec![node]);
    let path = gltf.write_external(dir.path(), "pointslines");
    let expected = [[v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)]];

    let meshes = load_gltf(&path).unwrap();
    assert_triangles(&meshes.triangles, &expected, 0.0);
    assert_eq!(meshes.skipped_non_triangle_primitives, 2);
    assert_eq!(meshes.warnings.len(), 1, "{:?}", meshes.warnings);
    assert_mentions(&meshes.warnings[0], &["pointslines.gltf", "2 point/line"]);

    let scene = load_through_spec(dir.path(), &path);
    assert_triangles(&scene.triangles, &expected, 0.0);
    assert_eq!(scene.stats.source_triangles, 1);
    assert_eq!(scene.stats.skipped_non_triangle_primitives, 2);
    assert_eq!(scene.warnings, meshes.warnings);
}

#[test]
fn a_mesh_instanced_by_two_nodes_gives_twice_the_triangles() {
    let dir = TempDir::new("instancing");
    let (mut gltf, one) = translated_quad();
    // A second node referencing the same mesh, 5 units further along x.
    let second = gltf.node(json!({ "mesh": 0, "translation": [6.0, 2.0, 3.0] }));
    gltf.scene_roots.as_mut().unwrap().push(second);
    let path = gltf.write_glb(dir.path(), "instanced");
    let shift = v(5.0, 0.0, 0.0);
    let mut expected = one.clone();
    expected.extend(one.iter().map(|t| t.map(|p| p + shift)));
    let scene = check_both_ways(dir.path(), &path, &expected, 0.0);
    assert_eq!(scene.stats.source_triangles, 4);
    assert_eq!(scene.source_ids[..], [0, 1, 2, 3]);
}
