//! zwarp-raster: the exact, fast, multithreaded CPU rasterizer of zwarp.
//!
//! It produces the input buffers every warp uses (depth, item ids, colour, motion, peeled layers
//! for the deep depth buffer of seed 000, Sec. 3.4) and the reference buffers every warp is judged
//! against (ARCHITECTURE.md "Evaluation protocol": the reference is the buffer rendered directly
//! at the target view).
//!
//! Conventions (ARCHITECTURE.md "Conventions"): depth is post-projection depth in `[0, 1]`,
//! 0 = near, 1 = far and also "no surface" ([`zwarp_core::EMPTY_DEPTH`]); pixel `(x, y)` samples
//! at its centre `(x + 0.5, y + 0.5)`, row 0 at the top; the item id of a pixel is the instance
//! index ([`zwarp_core::NO_ITEM`] where empty).
//!
//! Exactness: vertices are snapped to 1/256 pixel, coverage uses exact integer edge functions
//! with the top-left fill rule (shared edges are drawn exactly once), depth is `z_clip / w`
//! interpolated linearly in screen space (perspective-correct), triangles crossing the near plane
//! are clipped, fragments beyond the far plane (depth > 1) are discarded, both faces are drawn.
//!
//! Speed: per-instance frustum culling, front-to-back instance order, parallel vertex transform
//! and projection (once per vertex), parallel set-up into fixed chunks of 4096 triangles (so the
//! result never depends on the thread count), binning into 64x32 tiles, tiles rasterized in
//! parallel bands (no locks) into L1-resident tile buffers with 8-wide incremental i32 edge
//! functions and a branch-free depth blend (an AVX2 build selected at run time; the portable build
//! gives bit-identical results), per-tile early-z (max depth) and, for peeling, per-tile rejection
//! of triangles entirely in front of the previous layer. Crytek Sponza (262K triangles) at
//! 1920x1080 costs about 45 ms of CPU time per depth-only frame (9 ms set-up, 35 ms tiles), i.e.
//! about 25 ms on two idle cores; side by side with Mesa llvmpipe (lavapipe) on the same loaded
//! machine it takes 0.64x llvmpipe's time. What limits it: the ~2.8 M 8-pixel chunks that the
//! ~200 K triangle/tile pairs of Sponza touch (depth complexity ~5; many tiny triangles make
//! per-row and per-triangle overhead comparable to the blend itself) and the f64 set-up.
//!
//! Colour ([`FrameOptions::color`]) is a visibility-buffer resolve after the depth pass: each
//! covered pixel names its source triangle, and one parallel pass computes perspective-correct
//! barycentrics at the pixel centre (2-D homogeneous, from the unclipped clip-space vertices)
//! and shades with vertex normals, base-colour textures or the triplanar pattern ([`shading`]).
//!
//! Entry points: [`render_depth`], [`render_frame`], [`render_motion`], [`render_layers`],
//! [`draw_into`], [`any_fragment_visible`].

#![deny(missing_docs)]

mod kernel;
mod peel;
pub mod scenes;
mod setup;
mod shade;
mod simd;

use glam::Vec3;
use zwarp_core::{Camera, Error, Image, Motion, Result, Scene, NO_ITEM};

pub use peel::{
    render_ground_layer, render_layers, render_source_layers, Layer, PeelOptions, UmbraPeeling, ViewRegion,
};
pub use shade::shading;

use kernel::{run_pass, Mode, Targets};
use setup::{bin_scene, setup_world_triangles, SetupParams};

/// The buffers of one rendered view.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Post-projection depth in `[0, 1]`, 1 = empty.
    pub depth: Image<f32>,
    /// Instance index per pixel, [`NO_ITEM`] where empty (the item buffer of seed 000, Sec. 3.1).
    pub items: Image<u32>,
    /// Textured, shaded linear RGB (see [`shading`]), when requested; sky where empty.
    pub color: Option<Image<[f32; 3]>>,
}

/// Options of [`render_frame`].
#[derive(Clone, Copy, Debug, Default)]
pub struct FrameOptions<'a> {
    /// Also produce the colour buffer (the input of colour warping, seed 001): per pixel,
    /// `Instance::albedo * Material::base_color * (base-colour texture at the interpolated UV |
    /// the triplanar [`shading::pattern`] | 1)` times `ambient + Lambert` with the headlight
    /// [`shading::LIGHT_DIR_VIEW`] and the interpolated vertex normal (the flat triangle normal
    /// without normals), two-sided; sky colour where empty. Position, normal and UV are
    /// interpolated perspective-correctly at the pixel centre by a resolve pass over the
    /// triangle ids of the depth pass (colour work only runs when this is set).
    pub color: bool,
    /// Draw only these instance ids (e.g. the visible set of an occlusion-culling pass); `None`
    /// draws all instances.
    pub objects: Option<&'a [u32]>,
}

fn check_camera(cam: &Camera) -> Result<()> {
    if cam.width == 0 || cam.height == 0 {
        return Err(Error::invalid(format!("zero-size camera image {}x{}", cam.width, cam.height)));
    }
    Ok(())
}

/// Renders the depth buffer of `scene` at time `t` seen by `cam` (depth only: the fast,
/// benchmarked path). Errors on an empty scene or an unusable camera.
pub fn render_depth(scene: &Scene, cam: &Camera, t: f32) -> Result<Image<f32>> {
    let mut depth = Image::new(0, 0, 1.0f32);
    render_depth_into(scene, cam, t, &mut depth)?;
    Ok(depth)
}

/// [`render_depth`] into `depth`, an earlier target recycled as an engine keeps its depth
/// buffer from frame to frame (replaced when its size differs from the camera's); every pixel
/// is written, so the result is the same. What it saves is faulting in a fresh target.
pub fn render_depth_into(scene: &Scene, cam: &Camera, t: f32, depth: &mut Image<f32>) -> Result<()> {
    scene.check_nonempty()?;
    check_camera(cam)?;
    let binned = bin_scene(scene, cam, t, &SetupParams { objects: None, color: false })?;
    if depth.size() != (cam.width, cam.height) {
        *depth = Image::filled(cam.width, cam.height, 1.0f32);
    }
    run_pass(&binned, Mode::Depth, Targets { depth, items: None, handles: None, threshold: None, load: false });
    Ok(())
}

/// Renders depth, item ids and (optionally) colour of `scene` at time `t` seen by `cam`.
pub fn render_frame(scene: &Scene, cam: &Camera, t: f32, opts: &FrameOptions) -> Result<Frame> {
    scene.check_nonempty()?;
    check_camera(cam)?;
    let binned = bin_scene(scene, cam, t, &SetupParams { objects: opts.objects, color: opts.color })?;
    let mut depth = Image::filled(cam.width, cam.height, 1.0f32);
    let mut items = Image::filled(cam.width, cam.height, NO_ITEM);
    let mut handles = opts.color.then(|| Image::filled(cam.width, cam.height, NO_ITEM));
    run_pass(
        &binned,
        Mode::Depth,
        Targets { depth: &mut depth, items: Some(&mut items), handles: handles.as_mut(), threshold: None, load: false },
    );
    let color = handles.map(|h| shade::resolve(&binned, scene, cam, &h));
    Ok(Frame { depth, items, color })
}

/// Renders view A (depth + items, no colour) and its motion field towards view B (seed 000,
/// Sec. 3.1: `v(q) = C P^-1 q - q` with per-object motion through the item buffer), using the one
/// implementation in [`zwarp_core::motion_field`] with `scene.object_deltas(t_a, t_b)`.
pub fn render_motion(
    scene: &Scene,
    cam_a: &Camera,
    t_a: f32,
    cam_b: &Camera,
    t_b: f32,
) -> Result<(Frame, Image<Motion>)> {
    if !t_b.is_finite() {
        return Err(Error::invalid(format!("target time t_b must be finite, got {t_b}")));
    }
    check_camera(cam_b)?;
    let frame = render_frame(scene, cam_a, t_a, &FrameOptions::default())?;
    let motion =
        zwarp_core::motion_field(&frame.depth, Some(&frame.items), cam_a, cam_b, &scene.object_deltas(t_a, t_b))?;
    Ok((frame, motion))
}

/// Depth-tested draw of the instances `objects` at time `t` into existing buffers (`depth` and,
/// if given, `items`, both `cam.width x cam.height`). Pixels no fragment wins keep their values.
/// Used by culling (rapid-motion objects drawn directly into a predicted depth, thesis seed 002).
pub fn draw_into(
    depth: &mut Image<f32>,
    items: Option<&mut Image<u32>>,
    scene: &Scene,
    cam: &Camera,
    t: f32,
    objects: &[u32],
) -> Result<()> {
    check_camera(cam)?;
    if depth.size() != (cam.width, cam.height) {
        return Err(Error::invalid(format!(
            "depth buffer is {}x{} but the camera renders {}x{}",
            depth.width(),
            depth.height(),
            cam.width,
            cam.height
        )));
    }
    if let Some(it) = items.as_deref() {
        depth.check_same_size(it, "draw_into depth vs item buffer")?;
    }
    if depth.data().iter().any(|d| d.is_nan()) {
        return Err(Error::invalid("draw_into: depth buffer holds NaN"));
    }
    let binned = bin_scene(scene, cam, t, &SetupParams { objects: Some(objects), color: false })?;
    run_pass(&binned, Mode::Depth, Targets { depth, items, handles: None, threshold: None, load: true });
    Ok(())
}

/// CPU occlusion query (the analogue of a hardware occlusion query, seed 002 hybrid test):
/// rasterizes the world-space `triangles` with `cam` using exactly the coverage and depth rules of
/// the renderer and returns `true` iff some covered pixel centre has a fragment depth strictly
/// less than the stored `depth` there (early out on the first one).
///
/// If `depth` does not have the camera's size the answer is `true` (visible), the safe answer
/// for culling.
pub fn any_fragment_visible(depth: &Image<f32>, cam: &Camera, triangles: &[[Vec3; 3]]) -> bool {
    if depth.size() != (cam.width, cam.height) {
        return true;
    }
    let Ok((_, tris)) = setup_world_triangles(cam, triangles) else {
        return true;
    };
    let w = cam.width as usize;
    for t in &tris {
        for y in t.y0 as u32..=t.y1 as u32 {
            let row = &depth.data()[y as usize * w..(y as usize + 1) * w];
            let mut e = [0i64; 3];
            for (i, ei) in e.iter_mut().enumerate() {
                *ei = t.edge_at(i, t.x0 as i64, y as i64);
            }
            for x in t.x0 as u32..=t.x1 as u32 {
                if e[0] >= 0 && e[1] >= 0 && e[2] >= 0 && t.depth_at(x, y) < row[x as usize] {
                    return true;
                }
                for (i, ei) in e.iter_mut().enumerate() {
                    *ei += t.a[i] as i64;
                }
            }
        }
    }
    false
}

/// Enables (default) or disables the run-time selected AVX2 builds of the set-up and tile
/// kernels. Results are bit-identical either way; this exists for tests and for timing the
/// portable build.
#[doc(hidden)]
pub fn set_simd(enabled: bool) {
    simd::set_simd(enabled)
}

/// Diagnostic: `(source triangles after instance culling, set-up triangles that cover at least
/// one pixel-centre bounding box, tile-bin entries, setup ms, raster ms)` of a depth-only render.
#[doc(hidden)]
pub fn pipeline_stats(scene: &Scene, cam: &Camera, t: f32) -> Result<(usize, usize, usize, f64, f64)> {
    let t0 = std::time::Instant::now();
    let binned = bin_scene(scene, cam, t, &SetupParams { objects: None, color: false })?;
    let t1 = std::time::Instant::now();
    let mut depth = Image::filled(cam.width, cam.height, 1.0f32);
    run_pass(
        &binned,
        Mode::Depth,
        Targets { depth: &mut depth, items: None, handles: None, threshold: None, load: false },
    );
    let t2 = std::time::Instant::now();
    let set_up = binned.chunks.iter().map(|c| c.tris.len()).sum();
    let entries = binned.chunks.iter().map(|c| c.bin_items.len()).sum();
    Ok((scene.triangle_count(), set_up, entries, (t1 - t0).as_secs_f64() * 1e3, (t2 - t1).as_secs_f64() * 1e3))
}

/// Diagnostic: runs only the geometry front end (transform, clip, set-up, binning) of a
/// depth-only render and returns the number of bin entries.
#[doc(hidden)]
pub fn setup_only(scene: &Scene, cam: &Camera, t: f32) -> Result<usize> {
    let binned = bin_scene(scene, cam, t, &SetupParams { objects: None, color: false })?;
    Ok(binned.chunks.iter().map(|c| c.bin_items.len()).sum())
}

/// Test/diagnostic helper: how many of the world-space `triangles` cover each pixel centre
/// (no depth test; the fill rule is the renderer's). A closed fan or mesh without overlaps
/// gives exactly 1 inside and 0 outside.
#[doc(hidden)]
pub fn coverage_counts(cam: &Camera, triangles: &[[Vec3; 3]]) -> Result<Image<u32>> {
    let (vp, tris) = setup_world_triangles(cam, triangles)?;
    let (bin_start, bin_items) = setup::bin_tris(&tris, &vp);
    let binned = setup::Binned {
        vp,
        chunks: vec![setup::Chunk { tris, srcs: Vec::new(), insts: Vec::new(), bin_start, bin_items }],
        draws: Vec::new(),
    };
    if binned.chunks[0].tris.len() > u16::MAX as usize {
        return Err(Error::invalid("coverage_counts: too many triangles for one chunk"));
    }
    let mut depth = Image::filled(cam.width, cam.height, 1.0f32);
    let mut counts = Image::filled(cam.width, cam.height, 0u32);
    run_pass(
        &binned,
        Mode::Count,
        Targets { depth: &mut depth, items: Some(&mut counts), handles: None, threshold: None, load: false },
    );
    Ok(counts)
}

#[cfg(test)]
mod colour_tests;
#[cfg(test)]
mod tests;
