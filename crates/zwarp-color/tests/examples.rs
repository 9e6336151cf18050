//! The teaching example runs as an image test.

#[path = "../examples/frame_upsample.rs"]
mod frame_upsample;

#[test]
fn frame_upsample_predicts_the_in_between_frame_better_than_repeating_the_last() {
    let guard = tempfile::Builder::new().prefix("zwarp-color-example-").tempdir().unwrap();
    let out = guard.path().to_path_buf();
    let r = frame_upsample::run(160, 96, &out).unwrap();
    for f in ["source.png", "heuristic.png", "robust.png", "reference.png", "confidence.png"] {
        let img = zwarp_viz::read_png(out.join(f)).unwrap();
        assert_eq!(img.size(), (160, 96), "{f}");
    }
    // Both warps beat repeating the last frame (by ~2 dB at this size, 5.5 dB at 640x360) and
    // are close to the render.
    assert!(r.heuristic > r.repeat + 1.5 && r.robust > r.repeat + 1.5, "{:?}", (r.repeat, r.heuristic, r.robust));
    assert!(r.heuristic > 25.0 && r.robust > 25.0, "{:?}", (r.heuristic, r.robust));
}
