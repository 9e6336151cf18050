//! The examples run as tests: their images are written and their figures hold.

#[path = "../examples/predict_depth.rs"]
mod predict_depth;

#[test]
fn predict_depth_writes_its_images_and_matches_the_render() {
    let guard = tempfile::Builder::new().prefix("zwarp-example-predict-depth-").tempdir().unwrap();
    let out = guard.path().to_path_buf();
    let r = predict_depth::run(zwarp::Backend::Cpu, 160, 90, &out).unwrap();
    for name in ["source", "predicted", "reference", "error"] {
        let img = zwarp_viz::read_png(out.join(format!("{name}.png"))).unwrap();
        assert_eq!(img.size(), (160, 90), "{name}");
    }
    // The prediction is close to the render (three layers of an analytic scene; at 160x90
    // silhouette pixels weigh in SSIM: 0.96).
    assert!(r.psnr > 30.0 && r.ssim > 0.95 && r.converged > 0.95, "{} {} {}", r.psnr, r.ssim, r.converged);
    // A different image than the source: the camera and the box moved.
    let src = zwarp_viz::read_png(out.join("source.png")).unwrap();
    let pred = zwarp_viz::read_png(out.join("predicted.png")).unwrap();
    assert_ne!(src, pred);
}

#[test]
fn predict_depth_on_the_gpu_matches_the_cpu() {
    let Some(ctx) = zwarp::gpu::test_context() else { return };
    let guard = tempfile::Builder::new().prefix("zwarp-example-").tempdir().unwrap();
    let dir = |b: &str| guard.path().join(b);
    let c = predict_depth::run(zwarp::Backend::Cpu, 160, 90, &dir("cpu")).unwrap();
    let g = predict_depth::run(zwarp::Backend::Gpu(ctx), 160, 90, &dir("gpu")).unwrap();
    assert!(
        (c.psnr - g.psnr).abs() < 0.5 && (c.ssim - g.ssim).abs() < 1e-3,
        "{} {} / {} {}",
        c.psnr,
        c.ssim,
        g.psnr,
        g.ssim
    );
}
