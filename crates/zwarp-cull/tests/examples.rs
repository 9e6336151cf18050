//! The teaching example runs as a test: its image is written and its figures hold.

#[path = "../examples/cull_with_warp.rs"]
mod cull_with_warp;

#[test]
fn cull_with_warp_example_culls_more_than_vfc_and_draws_the_same_image() {
    let guard = tempfile::Builder::new().prefix("zwarp-example-cull-").tempdir().unwrap();
    let out = guard.path().to_path_buf();
    let f = cull_with_warp::run(0.02, 192, 108, &out).unwrap();
    let img = zwarp_viz::read_png(out.join("cull_with_warp.png")).unwrap();
    assert_eq!(img.width(), 4 * 192 + 3 * zwarp_viz::GAP);
    // WOC keeps every visible object (the frame it draws is the full render) and fewer than VFC.
    assert_eq!(f.culled_visible, 0);
    assert_eq!(f.differing_pixels, 0);
    assert!(
        f.visible <= f.woc && f.woc < f.vfc && f.vfc <= f.objects,
        "{} {} {} {}",
        f.visible,
        f.woc,
        f.vfc,
        f.objects
    );
}
