//! Cross-check against scikit-image (the independent reference implementation): the committed
//! fixture `tests/fixtures/skimage_cases.{json,bin}` was produced by
//! `tests/fixtures/make_fixture.py` with skimage's `peak_signal_noise_ratio` and
//! `structural_similarity(..., gaussian_weights=True, sigma=1.5, use_sample_covariance=False)`.
//! Python is not needed to run this test.

use std::path::PathBuf;

use serde_json::Value;
use zwarp_core::Image;
use zwarp_metrics::{mse, mse_rgb, psnr, psnr_rgb, ssim, ssim_map, ssim_rgb};

/// The brief asks for 1e-4; both sides compute in f64 on the same f32 inputs, so the agreement is
/// far tighter and the test holds it there to catch subtle deviations (window, borders, crop).
const TOL: f64 = 1e-8;

struct Fixture {
    meta: Value,
    data: Vec<f32>,
}

fn load() -> Fixture {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let meta: Value = serde_json::from_str(&std::fs::read_to_string(dir.join("skimage_cases.json")).unwrap()).unwrap();
    let bytes = std::fs::read(dir.join("skimage_cases.bin")).unwrap();
    let data: Vec<f32> = bytes.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    assert_eq!(data.len() as u64, meta["total_f32"].as_u64().unwrap());
    Fixture { meta, data }
}

fn slice<'a>(f: &'a Fixture, case: &Value, key: &str, n: usize) -> &'a [f32] {
    let off = case[key].as_u64().unwrap() as usize;
    &f.data[off..off + n]
}

fn gray(f: &Fixture, case: &Value, key: &str) -> Image<f32> {
    let (w, h) = (case["width"].as_u64().unwrap() as u32, case["height"].as_u64().unwrap() as u32);
    Image::from_vec(w, h, slice(f, case, key, (w * h) as usize).to_vec()).unwrap()
}

fn rgb(f: &Fixture, case: &Value, key: &str) -> Image<[f32; 3]> {
    let (w, h) = (case["width"].as_u64().unwrap() as u32, case["height"].as_u64().unwrap() as u32);
    let s = slice(f, case, key, (w * h * 3) as usize);
    Image::from_vec(w, h, s.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect()).unwrap()
}

#[test]
fn matches_scikit_image() {
    let f = load();
    let cases = f.meta["cases"].as_array().unwrap();
    assert_eq!(cases.len(), 6);
    let mut checked_map = false;
    for case in cases {
        let name = case["name"].as_str().unwrap();
        let range = case["data_range"].as_f64().unwrap() as f32;
        let (want_psnr, want_ssim, want_mse) =
            (case["psnr"].as_f64().unwrap(), case["ssim"].as_f64().unwrap(), case["mse"].as_f64().unwrap());
        let (got_psnr, got_ssim, got_mse) = if case["channels"].as_u64().unwrap() == 3 {
            let (a, b) = (rgb(&f, case, "a_offset"), rgb(&f, case, "b_offset"));
            // Per-channel SSIMs too (skimage's channel_axis loop).
            let per = case["ssim_per_channel"].as_array().unwrap();
            for (c, want) in per.iter().enumerate() {
                let (ca, cb) = (a.map(|p| p[c]), b.map(|p| p[c]));
                let got = ssim(&ca, &cb, range).unwrap();
                assert!((got - want.as_f64().unwrap()).abs() < TOL, "{name} channel {c}: {got} vs {want}");
            }
            (psnr_rgb(&a, &b, range).unwrap(), ssim_rgb(&a, &b, range).unwrap(), mse_rgb(&a, &b).unwrap())
        } else {
            let (a, b) = (gray(&f, case, "a_offset"), gray(&f, case, "b_offset"));
            if case.get("ssim_map_offset").is_some() {
                let want = gray(&f, case, "ssim_map_offset");
                let got = ssim_map(&a, &b, range).unwrap();
                for (i, (g, w)) in got.data().iter().zip(want.data()).enumerate() {
                    assert!((g - w).abs() < 1e-5, "{name} ssim map pixel {i}: {g} vs {w}");
                }
                checked_map = true;
            }
            (psnr(&a, &b, range).unwrap(), ssim(&a, &b, range).unwrap(), mse(&a, &b).unwrap())
        };
        assert!((got_mse - want_mse).abs() <= 1e-12 + 1e-9 * want_mse, "{name} mse {got_mse} vs {want_mse}");
        assert!((got_psnr - want_psnr).abs() < TOL, "{name} psnr {got_psnr} vs {want_psnr}");
        assert!((got_ssim - want_ssim).abs() < TOL, "{name} ssim {got_ssim} vs {want_ssim}");
        eprintln!("{name:24} psnr {got_psnr:.6} (skimage {want_psnr:.6})  ssim {got_ssim:.8} (skimage {want_ssim:.8})");
    }
    assert!(checked_map);
}
