//! Property tests of the max-depth structures (thesis Sec. III.2): on random depth images of
//! odd, prime and degenerate sizes (1x1 included), the N-buffer answer equals the brute-force
//! max over any rectangle, and the mipmap / Y-map answers are conservative (never below it).

use proptest::prelude::*;
use zwarp_core::Image;
use zwarp_cull::{erode_max, max_in_rect, MaxDepthQuery, MaxMipmap, NBuffer, PixelRect, YMap};

/// A random depth image of size 1..=41 x 1..=41 with values in [0, 1] (some exactly 1 = holes).
fn depth_image() -> impl Strategy<Value = Image<f32>> {
    (1u32..=41, 1u32..=41).prop_flat_map(|(w, h)| {
        proptest::collection::vec(prop_oneof![4 => 0.0f32..1.0, 1 => Just(1.0f32)], (w * h) as usize)
            .prop_map(move |v| Image::from_vec(w, h, v).unwrap())
    })
}

/// An image plus a batch of rectangles inside it.
fn image_and_rects() -> impl Strategy<Value = (Image<f32>, Vec<PixelRect>)> {
    depth_image().prop_flat_map(|img| {
        let (w, h) = img.size();
        let rect = (0..w, 0..h, 1..=w, 1..=h)
            .prop_map(move |(x0, y0, dx, dy)| PixelRect::new(x0, y0, (x0 + dx).min(w), (y0 + dy).min(h)).unwrap());
        (Just(img), proptest::collection::vec(rect, 1..24))
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    #[test]
    fn nbuffer_is_exact((img, rects) in image_and_rects()) {
        let nb = NBuffer::build(&img).unwrap();
        for r in rects {
            prop_assert_eq!(nb.max_depth(r), max_in_rect(&img, r), "rect {:?} on {:?}", r, img.size());
        }
    }

    #[test]
    fn mipmap_and_ymap_are_conservative((img, rects) in image_and_rects(), switch in 0u32..5) {
        let mip = MaxMipmap::build(&img).unwrap();
        let ym = YMap::build(&img, switch).unwrap();
        // A Y-map with switch 0 is exactly an N-buffer.
        let exact = switch == 0;
        for r in rects {
            let truth = max_in_rect(&img, r);
            prop_assert!(mip.max_depth(r) >= truth, "mipmap below truth at {:?}", r);
            // The answer is a real depth of the image, not an invented bound.
            prop_assert!(img.data().contains(&mip.max_depth(r)));
            let y = ym.max_depth(r);
            prop_assert!(y >= truth, "Y-map below truth at {:?}", r);
            if exact {
                prop_assert_eq!(y, truth);
            }
            // Occlusion answers follow: conservative structures never cull what the exact one keeps.
            for nearest in [truth, truth + 1e-3, 0.5] {
                if mip.is_occluded(r, nearest) || ym.is_occluded(r, nearest) {
                    prop_assert!(truth < nearest);
                }
            }
        }
    }

    #[test]
    fn every_mip_level_covers_the_level_below(img in depth_image()) {
        let mip = MaxMipmap::build(&img).unwrap();
        let levels = mip.levels();
        prop_assert_eq!(levels.last().unwrap().size(), (1, 1));
        let global = img.data().iter().copied().fold(f32::NEG_INFINITY, f32::max);
        prop_assert_eq!(*levels.last().unwrap().get(0, 0), global);
        for k in 1..levels.len() {
            let (fine, coarse) = (&levels[k - 1], &levels[k]);
            for y in 0..fine.height() {
                for x in 0..fine.width() {
                    prop_assert!(*coarse.get(x / 2, y / 2) >= *fine.get(x, y));
                }
            }
        }
    }

    #[test]
    fn erosion_is_the_exact_3x3_max(img in depth_image()) {
        let e = erode_max(&img);
        let (w, h) = img.size();
        for y in 0..h {
            for x in 0..w {
                let r = PixelRect::new(x.saturating_sub(1), y.saturating_sub(1), (x + 2).min(w), (y + 2).min(h)).unwrap();
                prop_assert_eq!(*e.get(x, y), max_in_rect(&img, r));
            }
        }
    }
}
