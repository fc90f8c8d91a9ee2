//! glTF 2.0 loading (`.gltf` with external or base64 buffers, `.glb`)
//! through the `gltf` crate: every node of the scene with its full transform
//! chain, triangles/strips/fans, any index width or none, flattened into one
//! world-space `f64` array.

use super::{GltfMeshes, SceneError};
use glam::{DMat4, DVec3};
use gltf::mesh::Mode;
use std::path::Path;

/// Loads every mesh instance of the file's default scene (or its first
/// scene; or every root node when it declares no scene).
pub fn load_gltf(path: &Path) -> Result<GltfMeshes, SceneError> {
    let bytes = std::fs::read(path).map_err(|cause| SceneError::Io {
        path: path.display().to_string(),
        cause,
    })?;
    load_gltf_bytes(&bytes, path)
}

/// [`load_gltf`] of the file's bytes, already read: `path` names it in
/// messages and its folder resolves external buffers (the fuzz harness,
/// `examples/fuzz_loaders.rs`, feeds it mutated files this way).
pub fn load_gltf_bytes(bytes: &[u8], path: &Path) -> Result<GltfMeshes, SceneError> {
    let shown = path.display().to_string();
    let gltf_error = |message: String| SceneError::Gltf {
        path: shown.clone(),
        message,
    };
    check_glb_header(bytes).map_err(&gltf_error)?;
    // Parsed without validation, then validated once the POSITION accessor
    // indices are known to exist: gltf-json 1.4's validation indexes the
    // accessor array with them unchecked and would panic.
    let gltf::Gltf { document, blob } =
        gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| gltf_error(e.to_string()))?;
    let json = document.into_json();
    check_position_accessor_indices(&json).map_err(&gltf_error)?;
    // Its validation message starts with "invalid glTF:", as ours does.
    let document = gltf::Document::from_json(json)
        .map_err(|e| gltf_error(e.to_string().replacen("invalid glTF: ", "", 1)))?;
    let base = path.parent().unwrap_or(Path::new("."));
    let buffers = load_buffers(&document, base, blob).map_err(&gltf_error)?;
    let document = &document;

    // glTF requires the node hierarchy to be disjoint strict trees. A node
    // with two parents would be instanced once per path to it, and a crafted
    // file can make the number of paths exponential in the node count.
    let mut parent: Vec<Option<usize>> = vec![None; document.nodes().len()];
    for node in document.nodes() {
        for child in node.children() {
            if let Some(first) = parent[child.index()].replace(node.index()) {
                return Err(gltf_error(format!(
                    "node {} has more than one parent (nodes {first} and {}): the node \
                     hierarchy must be a tree",
                    child.index(),
                    node.index()
                )));
            }
        }
    }
    let roots: Vec<gltf::Node> = match document
        .default_scene()
        .or_else(|| document.scenes().next())
    {
        Some(scene) => scene.nodes().collect(),
        None => document
            .nodes()
            .filter(|n| parent[n.index()].is_none())
            .collect(),
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

/// The `gltf` crate reports a cut-short GLB only as "could not completely
/// read the object" (and its debug build underflows on a declared length
/// below the header's): check the header here to say what is wrong.
fn check_glb_header(bytes: &[u8]) -> Result<(), String> {
    const HEADER: usize = 12;
    if !bytes.starts_with(b"glTF") {
        return Ok(()); // JSON glTF
    }
    if bytes.len() < HEADER {
        return Err(format!(
            "truncated GLB: the file has {} bytes, less than the {HEADER}-byte header",
            bytes.len()
        ));
    }
    let declared = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize;
    if declared < HEADER {
        return Err(format!(
            "GLB header declares {declared} bytes, less than the {HEADER}-byte header itself"
        ));
    }
    if declared > bytes.len() {
        return Err(format!(
            "truncated GLB: the header declares {declared} bytes but the file has {}",
            bytes.len()
        ));
    }
    Ok(())
}

/// Rejects a primitive whose POSITION accessor does not exist, before
/// gltf-json's validation would panic on it.
fn check_position_accessor_indices(root: &gltf::json::Root) -> Result<(), String> {
    use gltf::json::{mesh::Semantic, validation::Checked};
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let Some(index) = primitive
                .attributes
                .get(&Checked::Valid(Semantic::Positions))
            else {
                continue; // reported as missing by validation
            };
            if index.value() >= root.accessors.len() {
                return Err(format!(
                    "meshes[{m}].primitives[{p}].attributes.POSITION: accessor {} does not exist \
                     ({} accessors)",
                    index.value(),
                    root.accessors.len()
                ));
            }
        }
    }
    Ok(())
}

/// Reads every buffer (external file, data URI or GLB BIN chunk); an error
/// names the buffer and its file, which `gltf::import_buffers` does not.
fn load_buffers(
    document: &gltf::Document,
    base: &Path,
    mut blob: Option<Vec<u8>>,
) -> Result<Vec<gltf::buffer::Data>, String> {
    document
        .buffers()
        .map(|buffer| {
            let source = match buffer.source() {
                gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                    "data URI".to_string()
                }
                gltf::buffer::Source::Uri(uri) => format!("'{uri}'"),
                gltf::buffer::Source::Bin => "GLB BIN chunk".to_string(),
            };
            let what = format!("buffer {} ({source})", buffer.index());
            if let gltf::buffer::Source::Uri(uri) = buffer.source() {
                check_buffer_uri(uri).map_err(|e| format!("{what}: {e}"))?;
            }
            let data =
                gltf::buffer::Data::from_source_and_blob(buffer.source(), Some(base), &mut blob)
                    .map_err(|e| format!("{what}: {e}"))?;
            if data.len() < buffer.length() {
                return Err(format!(
                    "{what}: byteLength is {} but only {} bytes could be read",
                    buffer.length(),
                    data.len()
                ));
            }
            Ok(data)
        })
        .collect()
}

/// A buffer URI the loader follows: a data URI, or a relative path that
/// stays in the glTF file's folder. Refused, before anything is read: an
/// absolute path (`/etc/passwd`), a URI with a scheme (`file:`, `http:`)
/// and a path with a `..` segment (`../../../../etc/hostname`), percent-
/// encoded or not, with `/` or `\` between segments: a scene file is
/// input from anywhere, and must not make the renderer read other files
/// as geometry.
fn check_buffer_uri(uri: &str) -> Result<(), String> {
    if uri.starts_with("data:") {
        return Ok(());
    }
    let decoded = percent_decoded(uri);
    let refuse = |why: &str| {
        Err(format!("URI '{uri}' {why}; only data URIs and relative paths inside the glTF's folder are read"))
    };
    if decoded.starts_with('/') || decoded.starts_with('\\') {
        return refuse("is an absolute path");
    }
    let first_segment = decoded.split(['/', '\\']).next().unwrap_or("");
    if first_segment.contains(':') {
        return refuse("has a scheme or a drive letter");
    }
    if decoded.split(['/', '\\']).any(|segment| segment == "..") {
        return refuse("climbs out of the glTF's folder (a '..' segment)");
    }
    Ok(())
}

/// `uri` with its `%XX` escapes decoded (an invalid escape stays as it is);
/// bytes that do not form UTF-8 become U+FFFD.
fn percent_decoded(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |b: u8| (b as char).to_digit(16);
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            if let (Some(h), Some(l)) = (hex(bytes[i + 1]), hex(bytes[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Checks that an accessor's elements (and its sparse indices and values)
/// lie inside their buffer views and the views inside the loaded buffers,
/// so that reading it can neither go out of bounds nor trip the `gltf`
/// reader's own assertions.
fn check_accessor_bounds(
    accessor: &gltf::Accessor,
    buffers: &[gltf::buffer::Data],
    what: &str,
) -> Result<(), String> {
    let index = accessor.index();
    // glTF requires count >= 1, and the `gltf` reader computes `count - 1`.
    if accessor.count() == 0 {
        return Err(format!("{what}: accessor {index} has count 0"));
    }
    let element = accessor.size();
    let in_view = |view: &gltf::buffer::View, offset: usize, count: usize, element: usize| {
        check_view_range(view, offset, count, element, buffers)
            .map_err(|e| format!("{what}: accessor {index}: {e}"))
    };
    if let Some(view) = accessor.view() {
        in_view(&view, accessor.offset(), accessor.count(), element)?;
    }
    if let Some(sparse) = accessor.sparse() {
        if sparse.count() == 0 {
            return Err(format!("{what}: accessor {index} has a sparse count of 0"));
        }
        let indices = sparse.indices();
        let index_size = indices.index_type().size();
        in_view(
            &indices.view(),
            indices.offset(),
            sparse.count(),
            index_size,
        )?;
        let values = sparse.values();
        in_view(&values.view(), values.offset(), sparse.count(), element)?;
    }
    Ok(())
}

/// Checks that `count` elements of `element` bytes, `offset` bytes into
/// `view` at its stride, lie inside it, and `view` inside its buffer.
/// Sizes come from the file: the arithmetic is checked.
fn check_view_range(
    view: &gltf::buffer::View,
    offset: usize,
    count: usize,
    element: usize,
    buffers: &[gltf::buffer::Data],
) -> Result<(), String> {
    let buffer_len = buffers[view.buffer().index()].len();
    if view
        .offset()
        .checked_add(view.length())
        .is_none_or(|end| end > buffer_len)
    {
        return Err(format!(
            "buffer view {} (offset {}, length {}) exceeds buffer {} of {buffer_len} bytes",
            view.index(),
            view.offset(),
            view.length(),
            view.buffer().index()
        ));
    }
    let stride = view.stride().unwrap_or(element);
    if stride < element {
        return Err(format!(
            "buffer view {} has byte stride {stride}, less than its {element}-byte elements",
            view.index()
        ));
    }
    let end = (count - 1)
        .checked_mul(stride)
        .and_then(|n| n.checked_add(offset))
        .and_then(|n| n.checked_add(element));
    match end {
        Some(end) if end <= view.length() => Ok(()),
        _ => Err(format!(
            "needs {} bytes but its buffer view {} has {}",
            end.map_or_else(|| "over 2^64".to_string(), |end| end.to_string()),
            view.index(),
            view.length()
        )),
    }
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
        // The gltf crate's index reader assumes an unsigned component type
        // (it has `unreachable!()` for the others): found by the fuzz
        // harness, `examples/fuzz_loaders.rs`.
        use gltf::accessor::{DataType, Dimensions};
        let unsigned = matches!(
            indices.data_type(),
            DataType::U8 | DataType::U16 | DataType::U32
        );
        if !unsigned || indices.dimensions() != Dimensions::Scalar {
            return Err(format!(
                "{what}: index accessor {} is {:?} {:?}; glTF indices are unsigned byte, \
                 short or int scalars",
                indices.index(),
                indices.data_type(),
                indices.dimensions()
            ));
        }
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
