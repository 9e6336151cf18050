//! Triangle soups: the raw `VertexBuffer.bin` + `IndexBuffer.bin` format of
//! `shared/scenes/sponza` and splitting a soup into objects.
//!
//! Occlusion culling (seed 000 Sec. 5, seed 002) works per object, but a soup has no object
//! structure. [`split_soup`] recovers objects:
//! - [`SplitMode::Components`]: connected components by shared vertex index (union-find).
//!   Scanned or exported soups often hold tens of thousands of tiny components (single
//!   quads, leaves), which would make per-object work explode, so when there are more than
//!   [`MAX_OBJECTS`] components, the `MAX_OBJECTS / 2` largest (by triangle count) stay
//!   objects of their own and all others are merged into `MAX_OBJECTS / 2` spatial clusters
//!   (a balanced kd split of their centroids). The result never has more than
//!   `MAX_OBJECTS` objects and every object is spatially compact.
//! - [`SplitMode::Clusters`]`(k)`: ignores connectivity; triangles are grouped into `k`
//!   spatially compact clusters of (nearly) equal size by a kd split of their centroids.
//! - [`SplitMode::None`]: one object.

use std::path::Path;

use glam::Vec3;
use zwarp_core::{Error, Result};

use crate::SplitMode;

/// Upper bound on the objects [`SplitMode::Components`] produces.
pub const MAX_OBJECTS: usize = 4096;

/// Reads the raw soup of a folder: `VertexBuffer.bin` (little-endian f32 x4 per vertex, w
/// unused) and `IndexBuffer.bin` (little-endian u32 x3 per triangle).
pub fn read_raw_soup(dir: &Path) -> Result<(Vec<Vec3>, Vec<[u32; 3]>)> {
    let vpath = dir.join("VertexBuffer.bin");
    let ipath = dir.join("IndexBuffer.bin");
    let vb = std::fs::read(&vpath).map_err(|e| Error::io(&vpath, e))?;
    let ib = std::fs::read(&ipath).map_err(|e| Error::io(&ipath, e))?;
    if vb.len() % 16 != 0 {
        return Err(Error::parse(
            &vpath,
            format!("size {} is not a multiple of 16 bytes (f32 x4 per vertex): truncated?", vb.len()),
        ));
    }
    if ib.len() % 12 != 0 {
        return Err(Error::parse(
            &ipath,
            format!("size {} is not a multiple of 12 bytes (u32 x3 per triangle): truncated?", ib.len()),
        ));
    }
    let f = |c: &[u8]| f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
    let u = |c: &[u8]| u32::from_le_bytes([c[0], c[1], c[2], c[3]]);
    let positions: Vec<Vec3> = vb.chunks_exact(16).map(|c| Vec3::new(f(&c[0..4]), f(&c[4..8]), f(&c[8..12]))).collect();
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(Error::parse(&vpath, format!("vertex {i} is not finite ({})", positions[i])));
    }
    let n = positions.len() as u32;
    let indices: Vec<[u32; 3]> = ib.chunks_exact(12).map(|c| [u(&c[0..4]), u(&c[4..8]), u(&c[8..12])]).collect();
    if let Some(t) = indices.iter().position(|t| t.iter().any(|&i| i >= n)) {
        return Err(Error::parse(
            &ipath,
            format!("triangle {t} indexes vertex {:?} but there are only {n} vertices", indices[t]),
        ));
    }
    Ok((positions, indices))
}

/// Splits a soup into objects (see the module docs); each returned group is a list of triangle
/// indices in ascending order, groups are sorted by their first triangle so the result is
/// deterministic.
pub fn split_soup(positions: &[Vec3], indices: &[[u32; 3]], mode: SplitMode) -> Vec<Vec<u32>> {
    let all: Vec<u32> = (0..indices.len() as u32).collect();
    let centroid = |t: u32| {
        let [a, b, c] = indices[t as usize];
        (positions[a as usize] + positions[b as usize] + positions[c as usize]) / 3.0
    };
    let mut groups = match mode {
        SplitMode::None => vec![all],
        SplitMode::Clusters(k) => {
            // Item i is triangle i, so the clusters of items are clusters of triangles.
            let items: Vec<(Vec3, u32, u32)> = all.iter().map(|&t| (centroid(t), 1, t)).collect();
            kd_cluster(items, k.max(1))
        }
        SplitMode::Components => {
            let comps = connected_components(positions.len(), indices);
            if comps.len() <= MAX_OBJECTS {
                comps
            } else {
                let mut comps = comps;
                // Largest first; ties broken by first triangle for determinism.
                comps.sort_by_key(|c| (std::cmp::Reverse(c.len()), c[0]));
                let small = comps.split_off(MAX_OBJECTS / 2);
                let items: Vec<(Vec3, u32, u32)> = small
                    .iter()
                    .enumerate()
                    .map(|(i, c)| {
                        let cen = c.iter().map(|&t| centroid(t)).sum::<Vec3>() / c.len() as f32;
                        (cen, c.len() as u32, i as u32)
                    })
                    .collect();
                for leaf in kd_cluster(items, MAX_OBJECTS / 2) {
                    comps.push(leaf.iter().flat_map(|&i| small[i as usize].iter().copied()).collect());
                }
                comps
            }
        }
    };
    groups.retain(|g| !g.is_empty());
    for g in &mut groups {
        g.sort_unstable();
    }
    groups.sort_by_key(|g| g[0]);
    groups
}

/// Connected components of triangles sharing a vertex index (union-find with path halving).
fn connected_components(vertex_count: usize, indices: &[[u32; 3]]) -> Vec<Vec<u32>> {
    let mut parent: Vec<u32> = (0..vertex_count as u32).collect();
    fn find(p: &mut [u32], mut x: u32) -> u32 {
        while p[x as usize] != x {
            p[x as usize] = p[p[x as usize] as usize];
            x = p[x as usize];
        }
        x
    }
    for t in indices {
        let r0 = find(&mut parent, t[0]);
        for &v in &t[1..] {
            let r = find(&mut parent, v);
            if r != r0 {
                parent[r as usize] = r0;
            }
        }
    }
    let mut slot = vec![u32::MAX; vertex_count];
    let mut comps: Vec<Vec<u32>> = Vec::new();
    for (ti, t) in indices.iter().enumerate() {
        let r = find(&mut parent, t[0]) as usize;
        if slot[r] == u32::MAX {
            slot[r] = comps.len() as u32;
            comps.push(Vec::new());
        }
        comps[slot[r] as usize].push(ti as u32);
    }
    comps
}

/// Balanced kd clustering: recursively splits `(centroid, weight, item id)` items at the
/// weighted median of the longest axis of their centroids until `k` leaves; returns the item
/// ids of each leaf. Items are small plain values so sorting them is cheap (Sponza's 262K
/// triangles into 1024 clusters).
fn kd_cluster(items: Vec<(Vec3, u32, u32)>, k: usize) -> Vec<Vec<u32>> {
    let mut out = Vec::new();
    fn rec(items: &mut [(Vec3, u32, u32)], k: usize, out: &mut Vec<Vec<u32>>) {
        if items.is_empty() {
            return;
        }
        if k <= 1 || items.len() == 1 {
            out.push(items.iter().map(|i| i.2).collect());
            return;
        }
        let (lo, hi) = items.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), i| (a.min(i.0), b.max(i.0)));
        let ext = hi - lo;
        let axis = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        // Ties broken by item id so the split is deterministic.
        let cmp = |a: &(Vec3, u32, u32), b: &(Vec3, u32, u32)| a.0[axis].total_cmp(&b.0[axis]).then(a.2.cmp(&b.2));
        // Split the weight proportionally to the leaves each side gets.
        let k_left = k / 2;
        if items.iter().all(|i| i.1 == 1) {
            // Unit weights (triangles): the split is a plain quantile, found in linear time.
            let cut = (items.len() * k_left / k).clamp(1, items.len() - 1);
            items.select_nth_unstable_by(cut, cmp);
            let (left, right) = items.split_at_mut(cut);
            rec(left, k_left, out);
            rec(right, k - k_left, out);
            return;
        }
        items.sort_unstable_by(cmp);
        let total: u64 = items.iter().map(|i| i.1 as u64).sum();
        let want = total * k_left as u64 / k as u64;
        let mut acc = 0u64;
        let mut cut = 0;
        while cut < items.len() - 1 && acc + (items[cut].1 as u64) <= want.max(1) {
            acc += items[cut].1 as u64;
            cut += 1;
        }
        let (left, right) = items.split_at_mut(cut.max(1));
        rec(left, k_left, out);
        rec(right, k - k_left, out);
    }
    let mut items = items;
    rec(&mut items, k, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` separate unit quads (2 triangles each) along x.
    fn quads(n: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut p = Vec::new();
        let mut t = Vec::new();
        for i in 0..n {
            let x = i as f32 * 2.0;
            let b = p.len() as u32;
            p.extend([
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x + 1.0, 0.0, 0.0),
                Vec3::new(x + 1.0, 1.0, 0.0),
                Vec3::new(x, 1.0, 0.0),
            ]);
            t.push([b, b + 1, b + 2]);
            t.push([b, b + 2, b + 3]);
        }
        (p, t)
    }

    #[test]
    fn components_find_each_quad() {
        let (p, t) = quads(5);
        let g = split_soup(&p, &t, SplitMode::Components);
        assert_eq!(g, vec![vec![0, 1], vec![2, 3], vec![4, 5], vec![6, 7], vec![8, 9]]);
        assert_eq!(split_soup(&p, &t, SplitMode::None), vec![(0..10).collect::<Vec<u32>>()]);
    }

    #[test]
    fn components_are_capped_and_cover_every_triangle_once() {
        let (p, t) = quads(MAX_OBJECTS as u32 + 500);
        let g = split_soup(&p, &t, SplitMode::Components);
        assert!(g.len() <= MAX_OBJECTS, "{}", g.len());
        assert!(g.len() >= MAX_OBJECTS / 2);
        let mut seen: Vec<u32> = g.iter().flatten().copied().collect();
        seen.sort_unstable();
        assert_eq!(seen, (0..t.len() as u32).collect::<Vec<_>>());
        // Components are never cut: both triangles of a quad stay together.
        for grp in &g {
            for &tri in grp {
                assert!(grp.contains(&(tri ^ 1)));
            }
        }
    }

    proptest::proptest! {
        /// For random soups, every split mode partitions the triangles (each exactly once) and
        /// Components never separates two triangles that share a vertex.
        #[test]
        fn splits_partition_the_soup(
            tris in proptest::collection::vec((0u32..60, 0u32..60, 0u32..60), 1..200),
            k in 1usize..20,
        ) {
            let positions: Vec<Vec3> = (0..60).map(|i| Vec3::new((i * 7 % 13) as f32, (i * 5 % 11) as f32, i as f32 * 0.1)).collect();
            let indices: Vec<[u32; 3]> = tris.iter().map(|&(a, b, c)| [a, b, c]).collect();
            for mode in [SplitMode::None, SplitMode::Components, SplitMode::Clusters(k)] {
                let g = split_soup(&positions, &indices, mode);
                let mut all: Vec<u32> = g.iter().flatten().copied().collect();
                all.sort_unstable();
                proptest::prop_assert_eq!(all, (0..indices.len() as u32).collect::<Vec<_>>());
                if let SplitMode::Clusters(k) = mode {
                    proptest::prop_assert!(g.len() <= k);
                }
                if mode == SplitMode::Components {
                    let mut owner = vec![usize::MAX; 60];
                    for (gi, grp) in g.iter().enumerate() {
                        for &t in grp {
                            for v in indices[t as usize] {
                                proptest::prop_assert!(owner[v as usize] == usize::MAX || owner[v as usize] == gi);
                                owner[v as usize] = gi;
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn clusters_are_balanced_and_spatially_ordered() {
        let (p, t) = quads(64);
        let g = split_soup(&p, &t, SplitMode::Clusters(8));
        assert_eq!(g.len(), 8);
        for (i, grp) in g.iter().enumerate() {
            assert_eq!(grp.len(), 16, "cluster {i}");
            // Quads lie along x, so each cluster is a contiguous run of 8 quads.
            assert_eq!(grp[0], i as u32 * 16);
            assert_eq!(*grp.last().unwrap(), i as u32 * 16 + 15);
        }
    }
}
