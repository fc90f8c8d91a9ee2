//! glTF 2.0 loading (`.gltf` with external or base64 buffers, `.glb`)
//! through the `gltf` crate: every node of the scene with its full transform
//! chain, triangles/strips/fans, any index width or none, flattened into one
//! world-space `f64` array.

use super::{SceneError, Triangle};
use glam::{DMat4, DVec3};
use gltf::mesh::Mode;
use std::path::Path;

/// Triangles read from a glTF file, before degenerate ones are dropped.
#[derive(Debug, Default)]
pub struct GltfMeshes {
    /// World-space triangles in traversal order (the stable source id is the
    /// index here).
    pub triangles: Vec<Triangle>,
    pub skipped_non_triangle_primitives: usize,
    pub warnings: Vec<String>,
}

/// Loads every mesh instance of the file's default scene (or its first
/// scene; or every root node when it declares no scene).
pub fn load_gltf(path: &Path) -> Result<GltfMeshes, SceneError> {
    let shown = path.display().to_string();
    let gltf_error = |message: String| SceneError::Gltf {
        path: shown.clone(),
        message,
    };
    let bytes = std::fs::read(path).map_err(|source| SceneError::Io {
        path: shown.clone(),
        source,
    })?;
    let gltf = gltf::Gltf::from_slice(&bytes).map_err(|e| gltf_error(e.to_string()))?;
    let base = path.parent().unwrap_or(Path::new("."));
    let buffers = gltf::import_buffers(&gltf.document, Some(base), gltf.blob.clone())
        .map_err(|e| gltf_error(format!("loading buffers: {e}")))?;
    let document = &gltf.document;

    let roots: Vec<gltf::Node> = match document
        .default_scene()
        .or_else(|| document.scenes().next())
    {
        Some(scene) => scene.nodes().collect(),
        None => {
            let mut is_child = vec![false; document.nodes().len()];
            for node in document.nodes() {
                for child in node.children() {
                    is_child[child.index()] = true;
                }
            }
            document.nodes().filter(|n| !is_child[n.index()]).collect()
        }
    };

    let mut out = GltfMeshes::default();
    // Explicit stack: (node, parent transform, depth). Depth guards against
    // a (spec-violating) cyclic node graph.
    let mut stack: Vec<(gltf::Node, DMat4, usize)> = roots
        .into_iter()
        .rev()
        .map(|n| (n, DMat4::IDENTITY, 0))
        .collect();
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > document.nodes().len() {
            return Err(gltf_error(format!(
                "node {} is part of a cycle in the node hierarchy",
                node.index()
            )));
        }
        let local = DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from)));
        let world = parent * local;
        if let Some(mesh) = node.mesh() {
            for primitive in mesh.primitives() {
                read_primitive(&node, &mesh, &primitive, &world, &buffers, &mut out)
                    .map_err(&gltf_error)?;
            }
        }
        for child in node.children().collect::<Vec<_>>().into_iter().rev() {
            stack.push((child, world, depth + 1));
        }
    }
    if out.skipped_non_triangle_primitives > 0 {
        out.warnings.push(format!(
            "{shown}: skipped {} point/line primitive(s); only triangles cast shadows",
            out.skipped_non_triangle_primitives
        ));
    }
    Ok(out)
}

fn describe(node: &gltf::Node, mesh: &gltf::Mesh, primitive: &gltf::Primitive) -> String {
    format!(
        "node {}{} mesh {}{} primitive {}",
        node.index(),
        node.name().map(|n| format!(" '{n}'")).unwrap_or_default(),
        mesh.index(),
        mesh.name().map(|n| format!(" '{n}'")).unwrap_or_default(),
        primitive.index()
    )
}

/// Checks that an accessor's elements lie inside its buffer view and the
/// view inside the loaded buffer, so reading it cannot go out of bounds.
fn check_accessor_bounds(
    accessor: &gltf::Accessor,
    buffers: &[gltf::buffer::Data],
    what: &str,
) -> Result<(), String> {
    let Some(view) = accessor.view() else {
        return Ok(()); // sparse-only or zero-filled accessor: nothing to read
    };
    let buffer_len = buffers[view.buffer().index()].len();
    if view.offset() + view.length() > buffer_len {
        return Err(format!(
            "{what}: buffer view {} (offset {}, length {}) exceeds buffer {} of {buffer_len} bytes",
            view.index(),
            view.offset(),
            view.length(),
            view.buffer().index()
        ));
    }
    let element = accessor.size();
    let stride = view.stride().unwrap_or(element);
    if accessor.count() > 0 {
        let end = accessor.offset() + (accessor.count() - 1) * stride + element;
        if end > view.length() {
            return Err(format!(
                "{what}: accessor {} needs {end} bytes but its buffer view {} has {}",
                accessor.index(),
                view.index(),
                view.length()
            ));
        }
    }
    Ok(())
}

fn read_primitive(
    node: &gltf::Node,
    mesh: &gltf::Mesh,
    primitive: &gltf::Primitive,
    world: &DMat4,
    buffers: &[gltf::buffer::Data],
    out: &mut GltfMeshes,
) -> Result<(), String> {
    let what = describe(node, mesh, primitive);
    match primitive.mode() {
        Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan => {}
        Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip => {
            out.skipped_non_triangle_primitives += 1;
            return Ok(());
        }
    }
    let positions_accessor = primitive
        .get(&gltf::Semantic::Positions)
        .ok_or_else(|| format!("{what}: has no POSITION attribute"))?;
    check_accessor_bounds(&positions_accessor, buffers, &what)?;
    if let Some(indices) = primitive.indices() {
        check_accessor_bounds(&indices, buffers, &what)?;
    }
    let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d[..]));
    let positions: Vec<DVec3> = reader
        .read_positions()
        .ok_or_else(|| format!("{what}: POSITION could not be read"))?
        .map(|p| world.transform_point3(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)))
        .collect();
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(format!(
            "{what}: vertex {i} has a non-finite position {} (NaN or Inf in the file or its transform)",
            positions[i]
        ));
    }
    let indices: Vec<u32> = match reader.read_indices() {
        Some(indices) => indices.into_u32().collect(),
        None => (0..positions.len() as u32).collect(),
    };
    if let Some(bad) = indices.iter().find(|&&i| i as usize >= positions.len()) {
        return Err(format!(
            "{what}: index {bad} is out of range ({} vertices)",
            positions.len()
        ));
    }
    let corner = |i: u32| positions[i as usize];
    match primitive.mode() {
        Mode::Triangles => {
            for t in indices.chunks_exact(3) {
                out.triangles
                    .push([corner(t[0]), corner(t[1]), corner(t[2])]);
            }
        }
        Mode::TriangleStrip => {
            // glTF §3.7.2.1: triangle i is (i, i+1, i+2), odd ones flipped
            // to keep the winding (winding does not matter for shadows, but
            // keeps normals consistent).
            for i in 0..indices.len().saturating_sub(2) {
                let (a, b, c) = (indices[i], indices[i + 1], indices[i + 2]);
                let tri = if i % 2 == 0 { [a, b, c] } else { [b, a, c] };
                out.triangles.push(tri.map(corner));
            }
        }
        Mode::TriangleFan => {
            for i in 1..indices.len().saturating_sub(1) {
                out.triangles.push([
                    corner(indices[0]),
                    corner(indices[i]),
                    corner(indices[i + 1]),
                ]);
            }
        }
        _ => unreachable!("non-triangle modes returned above"),
    }
    Ok(())
}
