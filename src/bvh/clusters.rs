//! Groups of primitives whose `f32` bounding boxes are bit-identical,
//! handed to the BVH builder as one primitive each.
//!
//! Why: `obvhs`'s PLOC builder (Meister & Bittner 2018) pairs each node
//! with the neighbour, within 14 places of the Morton order, whose union
//! box has the least surface area, and merges two nodes only when each
//! chose the other. Among identical boxes every union costs the same;
//! ties go to the last candidate (`cost <= best`), so each node picks the
//! one 14 places ahead (in the first passes, with a search distance of 1,
//! the next one) and only the last pair of the group agrees: one merge per
//! pass, so a group of m boxes needs ~m passes over every node (time
//! ~ N·m) and becomes a chain m deep (`bvh2_to_cwbvh` recurses once per
//! level; 30 000 overflowed the stack). Such a group gains nothing from a
//! tree anyway: a ray that enters one of the boxes enters all of them, so
//! its members are tested as a flat list under one box.

use obvhs::aabb::Aabb;
use rayon::prelude::*;

/// Groups smaller than this are left to the builder: their chains are at
/// most this deep, and scenes made of ordinary meshes (a quad's two
/// triangles share a box, as do a double-sided face's copies) never reach
/// it, so their BVHs stay exactly as `obvhs` builds them (bit-identical
/// renders). The largest group in the shared scenes is reported by the
/// `bvh_build_times` example.
pub const MIN_CLUSTER: usize = 16;

/// Primitives regrouped for the builder: builder primitive `r` stands for
/// the input primitives `members[starts[r]..starts[r + 1]]`, all with the
/// same box.
#[derive(Debug)]
pub struct Clusters {
    pub starts: Vec<u32>,
    pub members: Vec<u32>,
}

impl Clusters {
    /// Number of builder primitives.
    pub fn len(&self) -> usize {
        self.starts.len() - 1
    }

    /// The input primitives of builder primitive `r`.
    pub fn members(&self, r: usize) -> &[u32] {
        &self.members[self.starts[r] as usize..self.starts[r + 1] as usize]
    }
}

/// The box as bits: equal keys are bit-identical boxes (a box holding a NaN
/// never reaches here: `Scene::new` refuses non-finite vertices).
fn key(b: &Aabb) -> [u32; 6] {
    let (lo, hi) = (b.min.to_array(), b.max.to_array());
    [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]].map(f32::to_bits)
}

fn hash(k: &[u32; 6]) -> u64 {
    // Multiply-rotate mixing (as FxHash): only spreads the keys over the
    // counting table, so collisions merely cost a false alarm.
    k.iter().fold(0u64, |h, &w| {
        (h.rotate_left(5) ^ w as u64).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95)
    })
}

/// Groups of at least [`MIN_CLUSTER`] identical boxes, or `None` when there
/// is none (then the builder sees the input unchanged).
///
/// A table of saturating counters indexed by the boxes' hashes finds
/// candidates in one pass: a group of m identical boxes puts at least m
/// into its bucket, so when no bucket reaches [`MIN_CLUSTER`] there is no
/// group (the usual case, ~1 ms per 100k boxes). Only the boxes of full
/// buckets are then sorted to find the exact groups.
pub fn identical_boxes(boxes: &[Aabb]) -> Option<Clusters> {
    let hashes: Vec<u64> = boxes.par_iter().map(|b| hash(&key(b))).collect();
    // The hash's top bits: the multiply mixes into them best.
    let bits = (2 * boxes.len())
        .next_power_of_two()
        .max(64)
        .trailing_zeros();
    let bucket = |h: u64| (h >> (64 - bits)) as usize;
    let mut counts = vec![0u8; 1 << bits];
    for &h in &hashes {
        let c = &mut counts[bucket(h)];
        *c = c.saturating_add(1);
    }
    let full = |h: u64| counts[bucket(h)] as usize >= MIN_CLUSTER;
    let mut suspects: Vec<u32> = (0..boxes.len() as u32)
        .filter(|&i| full(hashes[i as usize]))
        .collect();
    if suspects.is_empty() {
        return None;
    }
    // Sorted by box, then by index: each group in input order.
    suspects.par_sort_unstable_by_key(|&i| (key(&boxes[i as usize]), i));
    // The group each input primitive heads (its first member) or joins.
    let mut head: Vec<u32> = (0..boxes.len() as u32).collect();
    let mut grouped = false;
    for run in suspects.chunk_by(|&a, &b| key(&boxes[a as usize]) == key(&boxes[b as usize])) {
        if run.len() >= MIN_CLUSTER {
            grouped = true;
            for &i in &run[1..] {
                head[i as usize] = run[0];
            }
        }
    }
    if !grouped {
        return None;
    }
    // Builder primitives in input order of their heads; members of a group
    // in input order (the order `suspects` holds them in).
    let mut sizes = vec![0u32; boxes.len()];
    for &h in &head {
        sizes[h as usize] += 1;
    }
    let mut slot = vec![u32::MAX; boxes.len()];
    let mut starts = Vec::new();
    let mut next = 0u32;
    for (i, &size) in sizes.iter().enumerate() {
        if size > 0 {
            slot[i] = starts.len() as u32;
            starts.push(next);
            next += size;
        }
    }
    starts.push(next);
    let mut fill = starts.clone();
    let mut members = vec![0u32; boxes.len()];
    for (i, &h) in head.iter().enumerate() {
        let r = slot[h as usize] as usize;
        members[fill[r] as usize] = i as u32;
        fill[r] += 1;
    }
    Some(Clusters { starts, members })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3A;

    fn unit(offset: f32) -> Aabb {
        Aabb::new(Vec3A::splat(offset), Vec3A::splat(offset + 1.0))
    }

    #[test]
    fn small_groups_are_left_alone_and_large_ones_grouped() {
        // 15 copies of one box, 40 of another, 100 distinct ones between.
        let mut boxes = vec![unit(0.0); MIN_CLUSTER - 1];
        boxes.extend((0..100).map(|i| unit(2.0 + i as f32)));
        boxes.extend(std::iter::repeat_n(unit(-5.0), 40));
        assert!(identical_boxes(&boxes[..MIN_CLUSTER - 1 + 100]).is_none());
        let c = identical_boxes(&boxes).expect("the group of 40");
        assert_eq!(c.len(), MIN_CLUSTER - 1 + 100 + 1);
        let mut seen = vec![false; boxes.len()];
        let mut checked = 0;
        for r in 0..c.len() {
            let m = c.members(r);
            assert!(m.windows(2).all(|w| w[0] < w[1]), "members in input order");
            for &i in m {
                assert_eq!(key(&boxes[i as usize]), key(&boxes[m[0] as usize]));
                assert!(!std::mem::replace(&mut seen[i as usize], true));
                checked += 1;
            }
        }
        assert_eq!(checked, boxes.len());
        assert_eq!(c.members(c.len() - 1).len(), 40);
    }
}
