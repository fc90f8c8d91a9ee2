//! GPU pass 0, `gbuffer` (`shaders/gbuffer.comp`): primary visibility —
//! triangle id, hit point, camera-facing normal, shadow-tested flag and
//! µQuad axes — the twin of [`crate::gbuffer::gbuffer`].
//!
//! Why a compute visibility pass rather than a raster pipeline: the CPU
//! twin casts the pixel-centre ray and differentiates the ray/tangent-plane
//! intersection (README, Conventions); casting the same ray on the GPU reproduces
//! that exactly, with no rasterisation fill rules, no depth-buffer
//! quantisation and no graphics pipeline to maintain. The price is a BVH,
//! built here on the host by `obvhs` (a static scene builds it once per
//! run) and traversed in `f32`.

use super::shared::{BvhNode, GpuTriangle};
use super::{GpuError, Kernels, Recorder};
#[cfg(feature = "cli")]
use obvhs::{aabb::Aabb, BvhBuildParams};
#[cfg(feature = "cli")]
use std::time::Duration;

/// Deepest BVH the shader's traversal stack holds (`STACK_SIZE`).
pub const MAX_BVH_DEPTH: usize = 64;

/// The flattened BVH2 the shader traverses.
pub struct GpuBvh {
    pub nodes: Vec<BvhNode>,
    /// Triangle id per leaf slot.
    pub prims: Vec<u32>,
    pub depth: usize,
}

impl GpuBvh {
    /// No nodes: an empty scene, or a frame whose G-buffer is uploaded.
    pub const EMPTY: GpuBvh = GpuBvh {
        nodes: Vec::new(),
        prims: Vec::new(),
        depth: 0,
    };
}

/// The BVH a frame uploads: built when the `gbuffer` pass casts the
/// primary rays, empty when the CPU's G-buffer is uploaded instead.
pub fn frame_bvh(
    source: super::GBufferSource,
    triangles: &[GpuTriangle],
) -> Result<GpuBvh, GpuError> {
    match source {
        super::GBufferSource::Gpu => build_bvh(triangles),
        super::GBufferSource::Upload(_) => Ok(GpuBvh::EMPTY),
    }
}

/// Without the `cli` feature (the pass alone) there is no BVH builder: a
/// ray-cast G-buffer is refused by name, and the host's G-buffer is the
/// input.
#[cfg(not(feature = "cli"))]
pub fn build_bvh(triangles: &[GpuTriangle]) -> Result<GpuBvh, GpuError> {
    if triangles.is_empty() {
        return Ok(GpuBvh::EMPTY);
    }
    Err(GpuError::Unsupported(
        "the ray-cast G-buffer builds its BVH with obvhs, part of the `cli` feature: build izb \
         with it, or give the pass the host's G-buffer (depth + normal or a visibility buffer)"
            .into(),
    ))
}

/// Builds the BVH over eye-relative `f32` triangles.
#[cfg(feature = "cli")]
pub fn build_bvh(triangles: &[GpuTriangle]) -> Result<GpuBvh, GpuError> {
    if triangles.is_empty() {
        return Ok(GpuBvh::EMPTY);
    }
    let boxes: Vec<Aabb> = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = [t.a, t.b, t.c].map(glam::Vec3A::from);
            Aabb::new(a.min(b).min(c), a.max(b).max(c))
        })
        .collect();
    let clusters = crate::bvh::identical_boxes(&boxes);
    let heads: Vec<Aabb> = match &clusters {
        Some(c) => (0..c.len())
            .map(|r| boxes[c.members(r)[0] as usize])
            .collect(),
        None => boxes,
    };
    let bvh = obvhs::bvh2::builder::build_bvh2(
        &heads,
        BvhBuildParams::medium_build(),
        &mut Duration::default(),
    );
    let mut nodes: Vec<BvhNode> = bvh
        .nodes
        .iter()
        .map(|n| BvhNode {
            lo: n.aabb.min.to_array(),
            prim_count: n.prim_count,
            hi: n.aabb.max.to_array(),
            first: n.first_index,
        })
        .collect();
    let prims = match &clusters {
        Some(c) => expand_leaves(&mut nodes, &bvh.primitive_indices, c),
        None => bvh.primitive_indices,
    };
    // Depth by an explicit walk from the root (node 0).
    let mut depth = 0;
    let mut stack = vec![(0usize, 1usize)];
    while let Some((i, d)) = stack.pop() {
        depth = depth.max(d);
        let n = &nodes[i];
        if n.prim_count == 0 {
            stack.push((n.first as usize, d + 1));
            stack.push((n.first as usize + 1, d + 1));
        }
    }
    if depth > MAX_BVH_DEPTH {
        return Err(GpuError::Unsupported(format!(
            "the G-buffer BVH is {depth} levels deep, above the shader's stack of {MAX_BVH_DEPTH}"
        )));
    }
    Ok(GpuBvh {
        nodes,
        prims,
        depth,
    })
}

/// Leaves over grouped primitives (`crate::bvh::identical_boxes`) list
/// every member: a group of identical boxes becomes one leaf's flat run,
/// which the shader's leaf loop tests one by one (no tree over identical
/// boxes could cull any of them).
#[cfg(feature = "cli")]
fn expand_leaves(
    nodes: &mut [BvhNode],
    heads: &[u32],
    clusters: &crate::bvh::Clusters,
) -> Vec<u32> {
    let mut prims = Vec::with_capacity(clusters.members.len());
    for n in nodes.iter_mut().filter(|n| n.prim_count > 0) {
        let first = prims.len() as u32;
        for &r in &heads[n.first as usize..(n.first + n.prim_count) as usize] {
            prims.extend_from_slice(clusters.members(r as usize));
        }
        n.first = first;
        n.prim_count = prims.len() as u32 - first;
    }
    prims
}

/// Records the pass: one thread per pixel; with `edge_surfaces` then the
/// edge pixels' sample rays (`shaders/edge_surfaces.comp`, the twin of
/// [`crate::gbuffer::edge_surfaces`]), which read the neighbours' centre
/// hits.
pub fn gbuffer(rec: &Recorder, kernels: &Kernels, size: [u32; 2], edge_surfaces: bool) {
    rec.begin_label("gbuffer");
    rec.dispatch_pixels(&kernels.gbuffer, size);
    rec.barrier();
    if edge_surfaces {
        rec.dispatch_pixels(&kernels.edge_surfaces, size);
        rec.barrier();
    }
    rec.end_label();
}

/// Records the G-buffer from the host's visibility buffer
/// (`shaders/gbuffer_from_visibility.comp`, the twin of
/// [`crate::gbuffer::gbuffer_from_visibility`]): one thread per pixel,
/// each entry from its centre ray and the triangle the host's raster saw.
/// The caller has bound the host-image set holding the visibility buffer
/// (`Recorder::bind_host_images`): crate-only, as the shadow pass records
/// it, since a recorder without that set would read an unbound image.
pub(crate) fn gbuffer_from_visibility(rec: &Recorder, kernels: &Kernels, size: [u32; 2]) {
    rec.begin_label("gbuffer_from_visibility");
    rec.dispatch_pixels(&kernels.gbuffer_from_visibility, size);
    rec.barrier();
    rec.end_label();
}

/// Records the G-buffer from the host's multisampled visibility buffer
/// (`shaders/gbuffer_from_visibility.comp` built with `MULTISAMPLED`, the
/// twin of [`crate::gbuffer::gbuffer_from_multisampled_visibility`]): one
/// thread per pixel, each centre's triangle chosen among the ids its
/// samples (or its 3×3 pixels' samples) saw by the watertight test; with
/// `edge_surfaces` then the edge pixels' sample rays among the 3×3
/// pixels' ids (`edge_surfaces.comp` built with `CANDIDATE_HITS`). The
/// caller has bound the host-image set holding the visibility buffer.
pub(crate) fn gbuffer_from_multisampled_visibility(
    rec: &Recorder,
    kernels: &Kernels,
    size: [u32; 2],
    edge_surfaces: bool,
) {
    rec.begin_label("gbuffer_from_multisampled_visibility");
    rec.dispatch_pixels(&kernels.gbuffer_from_multisampled_visibility, size);
    rec.barrier();
    if edge_surfaces {
        rec.dispatch_pixels(&kernels.edge_surfaces_from_candidates, size);
        rec.barrier();
    }
    rec.end_label();
}

/// Records the G-buffer from the host's depth and normal images
/// (`shaders/gbuffer_from_depth.comp`, the twin of
/// [`crate::gbuffer::gbuffer_from_depth`]): one thread per pixel, each
/// entry from its centre ray at the view depth the host's depth encodes,
/// with the host's normal kept per entry (`B_G_NORMAL`). The caller has
/// bound the host-image set holding both images.
pub(crate) fn gbuffer_from_depth(rec: &Recorder, kernels: &Kernels, size: [u32; 2]) {
    rec.begin_label("gbuffer_from_depth");
    rec.dispatch_pixels(&kernels.gbuffer_from_depth, size);
    rec.barrier();
    rec.end_label();
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Without the `cli` feature the ray cast's BVH is refused by name
    /// (an empty scene needs none); with it, one triangle is one leaf.
    #[test]
    fn the_bvh_is_built_or_refused_by_name() {
        let triangle = GpuTriangle {
            a: [0.0, 0.0, -1.0],
            b: [1.0, 0.0, -1.0],
            c: [0.0, 1.0, -1.0],
        };
        assert!(build_bvh(&[]).is_ok_and(|b| b.nodes.is_empty()));
        let built = build_bvh(&[triangle]);
        if cfg!(feature = "cli") {
            let bvh = built.expect("one triangle");
            assert_eq!((bvh.prims, bvh.depth), (vec![0], 1));
        } else {
            let message = built.err().expect("refused").to_string();
            assert!(message.contains("`cli` feature"), "{message}");
        }
    }
}
