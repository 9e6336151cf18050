//! The teaching example runs as a test: its image is written and its figures hold.

#[path = "../examples/soft_shadows.rs"]
mod soft_shadows;

#[test]
fn soft_shadows_example_writes_its_strip_and_zwarp_tracks_the_reference() {
    let guard = tempfile::Builder::new().prefix("zwarp-example-soft-shadows-").tempdir().unwrap();
    let out = guard.path().to_path_buf();
    let f = soft_shadows::run(0.05, 160, 90, 16, 256, &out).unwrap();
    let img = zwarp_viz::read_png(out.join("soft_shadows.png")).unwrap();
    // Four labelled 160x90 panels side by side.
    assert_eq!(img.width(), 4 * 160 + 3 * zwarp_viz::GAP);
    assert!(img.height() > 90);
    // zwarp's synthesized maps shade like the rendered ones, closer than PCSS's filtering.
    assert!(f.ssim_zwarp > 0.97, "zwarp SSIM {}", f.ssim_zwarp);
    assert!(f.ssim_zwarp > f.ssim_pcss, "zwarp {} vs PCSS {}", f.ssim_zwarp, f.ssim_pcss);
}
