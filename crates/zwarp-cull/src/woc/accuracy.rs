//! Culling accuracy against REF (thesis Sec. V): culling ratio, false negatives (visible
//! objects culled).

use serde::Serialize;

/// Culling accuracy of a visible set against REF (thesis Sec. V.1, Table 1 and 3).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CullAccuracy {
    /// Objects in the scene.
    pub objects: usize,
    /// Objects the method keeps.
    pub visible: usize,
    /// Objects REF keeps.
    pub reference: usize,
    /// Visible in REF but culled (culling errors, unsafe).
    pub false_negatives: usize,
    /// Kept but invisible in REF (wasted draws, safe).
    pub false_positives: usize,
    /// Object error: `false_negatives / objects` (thesis Table 1).
    pub object_error: f64,
    /// Culling ratio CR: culled objects over the objects REF culls (thesis Table 3: NOCULL 0,
    /// REF 1); 1 when REF culls nothing.
    pub culling_ratio: f64,
}

/// Compares a visible set with the reference one (both increasing or not; duplicates ignored).
pub fn accuracy(visible: &[u32], reference: &[u32], n_objects: usize) -> CullAccuracy {
    let mut v = vec![false; n_objects];
    let mut r = vec![false; n_objects];
    for &id in visible.iter().filter(|&&i| (i as usize) < n_objects) {
        v[id as usize] = true;
    }
    for &id in reference.iter().filter(|&&i| (i as usize) < n_objects) {
        r[id as usize] = true;
    }
    let (mut nv, mut nr, mut fneg, mut fpos) = (0, 0, 0, 0);
    for i in 0..n_objects {
        nv += v[i] as usize;
        nr += r[i] as usize;
        fneg += (r[i] && !v[i]) as usize;
        fpos += (v[i] && !r[i]) as usize;
    }
    let ref_culled = n_objects - nr;
    CullAccuracy {
        objects: n_objects,
        visible: nv,
        reference: nr,
        false_negatives: fneg,
        false_positives: fpos,
        object_error: if n_objects == 0 { 0.0 } else { fneg as f64 / n_objects as f64 },
        culling_ratio: if ref_culled == 0 { 1.0 } else { (n_objects - nv) as f64 / ref_culled as f64 },
    }
}
