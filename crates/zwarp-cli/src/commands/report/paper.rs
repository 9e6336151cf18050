//! The papers' published numbers that the report puts beside ours (seed 000: Lee, Kim &
//! Eisemann, Iterative Depth Warping, TOG 2018; measured on a GeForce GTX 1080 at 1920x1080).

/// The paper's four scenes, in table order.
pub const SCENES: [&str; 4] = ["yr", "mo", "bl", "cb"];

fn scene_index(scene: &str) -> Option<usize> {
    SCENES.iter().position(|s| *s == scene)
}

/// Table 1 (N = 16): `(SSIM, PSNR dB)` of (ours, VFW, AFW) at L = 1 and L = 4, per scene.
const TABLE1: [[[(f64, f64); 3]; 2]; 4] = [
    [[(0.968, 27.5), (0.934, 23.3), (0.950, 24.3)], [(0.996, 36.1), (0.997, 28.2), (0.993, 27.9)]],
    [[(0.992, 30.3), (0.982, 26.0), (0.983, 25.8)], [(0.998, 34.8), (0.998, 30.0), (0.995, 28.8)]],
    [[(0.954, 23.3), (0.935, 21.1), (0.945, 21.2)], [(0.994, 29.4), (0.993, 26.7), (0.985, 25.1)]],
    [[(0.994, 31.3), (0.979, 25.5), (0.985, 25.7)], [(0.999, 36.7), (0.998, 27.6), (0.998, 27.9)]],
];

/// Table 1 quality `(SSIM, PSNR)` of `method` (`ours`, `vfw`, `afw`) at `l` (1 or 4).
pub fn table1(scene: &str, method: &str, l: usize) -> Option<(f64, f64)> {
    let m = ["ours", "vfw", "afw"].iter().position(|x| *x == method)?;
    let li = match l {
        1 => 0,
        4 => 1,
        _ => return None,
    };
    Some(TABLE1[scene_index(scene)?][li][m])
}

/// Table 2 (MO): `(SSIM, PSNR dB)` gained by the tight bound over the global one, per L (1-4)
/// and N (1, 2, 4, 8, 16, 32).
const TABLE2: [[(f64, f64); 6]; 4] = [
    [(0.04, 4.66), (0.02, 2.63), (0.01, 1.24), (0.01, 0.91), (0.01, 1.26), (0.01, 1.46)],
    [(0.04, 6.03), (0.02, 3.84), (0.01, 1.95), (0.00, 1.00), (0.01, 1.18), (0.01, 1.46)],
    [(0.04, 9.48), (0.02, 6.17), (0.00, 2.56), (0.00, 0.54), (0.00, 0.37), (0.00, 0.28)],
    [(0.03, 9.68), (0.02, 6.54), (0.00, 2.64), (0.00, 0.58), (0.00, 0.12), (0.00, 0.11)],
];

/// The N values of Tables 2 and 3.
pub const TABLE_NS: [u32; 6] = [1, 2, 4, 8, 16, 32];

fn n_index(n: u32) -> Option<usize> {
    TABLE_NS.iter().position(|x| *x == n)
}

/// Table 2: tight minus global `(SSIM, PSNR)` on MO at `(l, n)`.
pub fn table2(l: usize, n: u32) -> Option<(f64, f64)> {
    TABLE2.get(l.checked_sub(1)?).and_then(|row| row.get(n_index(n)?)).copied()
}

/// Table 3: warp ms with the tight bound, per scene, L (1-4), N.
const TABLE3_TIGHT: [[[f64; 6]; 4]; 4] = [
    [
        [0.26, 0.28, 0.31, 0.38, 0.53, 0.81],
        [0.27, 0.29, 0.33, 0.43, 0.61, 0.95],
        [0.27, 0.29, 0.35, 0.46, 0.65, 1.05],
        [0.27, 0.30, 0.35, 0.47, 0.70, 1.12],
    ],
    [
        [0.27, 0.28, 0.31, 0.36, 0.48, 0.73],
        [0.27, 0.29, 0.32, 0.40, 0.55, 0.87],
        [0.28, 0.30, 0.34, 0.44, 0.63, 1.02],
        [0.28, 0.30, 0.35, 0.45, 0.66, 1.08],
    ],
    [
        [0.30, 0.31, 0.35, 0.45, 0.65, 1.09],
        [0.31, 0.36, 0.46, 0.64, 0.99, 1.66],
        [0.32, 0.37, 0.47, 0.67, 1.05, 1.79],
        [0.32, 0.38, 0.49, 0.71, 1.12, 1.87],
    ],
    [
        [0.27, 0.28, 0.30, 0.34, 0.43, 0.62],
        [0.27, 0.29, 0.32, 0.40, 0.55, 0.87],
        [0.27, 0.29, 0.34, 0.42, 0.59, 0.96],
        [0.28, 0.30, 0.34, 0.43, 0.64, 1.05],
    ],
];

/// Table 3: the depth-only render (REF, ms) per scene.
const TABLE3_REF: [f64; 4] = [1.44, 3.21, 15.78, 37.52];

/// Table 3: tight-bound warp ms of `scene` at `(l, n)`.
pub fn table3_tight_ms(scene: &str, l: usize, n: u32) -> Option<f64> {
    TABLE3_TIGHT[scene_index(scene)?].get(l.checked_sub(1)?).and_then(|row| row.get(n_index(n)?)).copied()
}

/// Table 3: REF ms of `scene`.
pub fn table3_ref_ms(scene: &str) -> Option<f64> {
    Some(TABLE3_REF[scene_index(scene)?])
}

/// Table 5: frame ms of (NOCULL, VFC, CHC++, WOC, REF) per scene.
const TABLE5: [[f64; 5]; 4] =
    [[2.0, 1.9, 1.8, 2.9, 1.8], [3.8, 2.6, 4.3, 2.5, 1.2], [14.6, 15.4, 27.1, 4.5, 2.2], [38.4, 43.8, 18.3, 6.2, 4.2]];

/// Table 5 frame ms of `method` (`nocull`, `vfc`, `chc++`, `woc`, `ref`).
pub fn table5_ms(scene: &str, method: &str) -> Option<f64> {
    let m = ["nocull", "vfc", "chc++", "woc", "ref"].iter().position(|x| *x == method)?;
    Some(TABLE5[scene_index(scene)?][m])
}

/// The S values of Table 8.
pub const TABLE8_SAMPLES: [u32; 4] = [4, 16, 64, 256];
/// The shadow-map sizes of Table 8.
pub const TABLE8_SM: [u32; 3] = [512, 1024, 2048];

/// Table 8: relative speed-up per scene, map size (512, 1024, 2048) and S (4, 16, 64, 256).
const TABLE8: [[[f64; 4]; 3]; 4] = [
    [[1.4, 3.0, 2.8, 3.4], [1.2, 2.0, 2.6, 2.9], [0.7, 0.9, 1.0, 1.0]],
    [[1.5, 3.3, 3.7, 5.9], [1.4, 3.0, 3.6, 5.6], [1.0, 1.8, 2.1, 2.2]],
    [[1.2, 3.5, 8.6, 17.4], [1.4, 4.5, 10.1, 17.3], [1.4, 4.4, 5.5, 6.9]],
    [[1.8, 5.7, 11.4, 30.1], [1.8, 5.3, 11.9, 31.3], [1.8, 5.4, 12.5, 24.0]],
];

/// Table 8 speed-up of `scene` at map size `sm` and `samples`.
pub fn table8_speedup(scene: &str, sm: u32, samples: u32) -> Option<f64> {
    let si = TABLE8_SM.iter().position(|x| *x == sm)?;
    let ni = TABLE8_SAMPLES.iter().position(|x| *x == samples)?;
    Some(TABLE8[scene_index(scene)?][si][ni])
}

/// Seed 001 (Bowles et al. 2012) Table 1, Sponza at 720p on a GTX 580: the forward render
/// (15.29 ms) over each reprojection's time: reverse reprojection caching 6.64 ms, Mark 1997's
/// mesh warp 2.49 ms, the robust warp 0.70 ms plus 0.48 ms of quad subdivision; the heuristic warp
/// "under 0.2 ms" (Sec. 5), so its speed-up is a lower bound.
pub fn seed001_speedup(method: &str) -> Option<&'static str> {
    match method {
        "reproject" => Some("2.3"),
        "mesh" => Some("6.1"),
        "robust" => Some("13.0"),
        "heuristic" => Some("> 76"),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lookups_match_the_printed_tables() {
        assert_eq!(table1("bl", "ours", 4), Some((0.994, 29.4)));
        assert_eq!(table1("yr", "afw", 1), Some((0.950, 24.3)));
        assert_eq!(table1("sponza", "ours", 1), None);
        assert_eq!(table1("cb", "ours", 3), None);
        assert_eq!(table2(4, 1), Some((0.03, 9.68)));
        assert_eq!(table2(5, 1), None);
        assert_eq!(table3_tight_ms("cb", 1, 16), Some(0.43));
        assert_eq!(table3_ref_ms("bl"), Some(15.78));
        assert_eq!(table5_ms("cb", "woc"), Some(6.2));
        assert_eq!(table8_speedup("cb", 1024, 256), Some(31.3));
        assert_eq!(table8_speedup("yr", 2048, 4), Some(0.7));
        assert_eq!(seed001_speedup("robust"), Some("13.0"));
        assert_eq!(seed001_speedup("repeat"), None);
    }
}
