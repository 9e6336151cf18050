//! The teaching example runs as an image test.

#[path = "../examples/stereo_warp.rs"]
mod stereo_warp;

#[test]
fn stereo_warp_writes_both_eyes_close_to_their_renders() {
    let guard = tempfile::Builder::new().prefix("zwarp-vr-example-").tempdir().unwrap();
    let out = guard.path().to_path_buf();
    let r = stereo_warp::run(160, 96, 0.3, &out).unwrap();
    for f in ["centre.png", "left.png", "right.png", "anaglyph.png", "reference_left.png", "grid.png"] {
        let img = zwarp_viz::read_png(out.join(f)).unwrap();
        assert_eq!(img.size(), (160, 96), "{f}");
    }
    // The warped eyes match their renders closely, with far fewer cells than pixels.
    assert!(r.psnr.iter().all(|&p| p > 25.0), "PSNR {:?}", r.psnr);
    assert!(r.cells * 4 < r.pixels, "{} cells for {} pixels", r.cells, r.pixels);
    // A warped eye is not the centre view: it differs from it by more than from its render.
    let centre = zwarp_viz::read_png(out.join("centre.png")).unwrap();
    let left = zwarp_viz::read_png(out.join("left.png")).unwrap();
    assert_ne!(centre.data(), left.data());
}
