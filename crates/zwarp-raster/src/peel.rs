//! Depth peeling into L layers (seed 000, Sec. 3.4, after Everitt 2001) with optional
//! generalized umbra culling (Sec. 3.4, eq. (1), Fig. 7) and a separate ground layer.
//!
//! The scene is transformed, set up and binned once; each layer is one raster pass over the same
//! bins with a per-pixel threshold (fragments must lie strictly behind it).

use rayon::prelude::*;
use zwarp_core::{Camera, Error, Image, Projection, Result, Scene, NO_ITEM};

use crate::kernel::{run_pass, Mode, Targets};
use crate::setup::{bin_scene, SetupParams};

/// One peeled layer: depth (1 = empty) and item ids ([`NO_ITEM`] = empty).
#[derive(Clone, Debug, PartialEq)]
pub struct Layer {
    /// Post-projection depth, `[0, 1]`, 1 = no fragment in this layer.
    pub depth: Image<f32>,
    /// Instance index per pixel.
    pub items: Image<u32>,
}

impl Layer {
    /// Number of non-empty pixels.
    pub fn coverage(&self) -> usize {
        self.depth.data().iter().filter(|&&d| d < 1.0).count()
    }
}

/// The expected range of novel viewpoints for generalized umbra culling (seed 000, Sec. 3.4,
/// Fig. 7). All distances are in world units, measured in the reference camera's view space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ViewRegion {
    /// Novel viewpoints (perspective cameras, or points of a local area light) anywhere in a disc
    /// of radius `e` perpendicular to the reference view axis (the "center ray") at view depth
    /// `c` (0 = at the reference eye, negative = behind it). Eq. (1)'s `e` is the distance of a
    /// novel camera to the centre ray; the disc's worst case (farthest from a pixel's projector
    /// ray) is `e + h`, which is exactly eq. (1)'s denominator.
    Disc {
        /// Eq. (1) `e`: radius of the viewpoint region around the centre ray.
        e: f32,
        /// Eq. (1) `c`: view depth of the viewpoint region.
        c: f32,
    },
    /// Orthographic novel views (shadow maps of a directional area light) whose direction differs
    /// from the reference view direction by at most `max_angle` radians: the limit of eq. (1)
    /// for `c -> -inf` with `e = (d - c) tan(max_angle)`, i.e. `x = s / tan(max_angle)`.
    Directions {
        /// Largest angle between a novel view direction and the reference direction.
        max_angle: f32,
    },
}

/// Generalized umbra culling for depth peeling (seed 000, Sec. 3.4, eq. (1)).
///
/// Each pixel of the previous layer is back-projected to an opaque quad at linear depth `d` of
/// half side `s` (the pixel footprint: `d tan(fov/2) / H` in perspective, `half_height / H` in
/// orthographic). A deeper fragment on the same projector ray at linear depth `d + z` is hidden
/// from a viewpoint at distance `E` from that ray and depth `c` iff the line to it passes
/// through the quad: `E z / (d - c + z) < s`, i.e. `z < (d - c) s / (E - s)`. With the worst
/// viewpoint `E = e + h` (`h` = offset of the projector ray from the centre ray at depth `c`)
/// this is eq. (1): `x = (d - c) s / ((e + h) - s)`. The next layer keeps the nearest fragment
/// strictly behind `d + x`. When `e + h <= s` the quad blocks every viewpoint for the whole ray
/// (`x = inf`): nothing behind that pixel is peeled, which is what bounds the number of layers.
/// `x = 0` is standard peeling; `c = 0, h = 0` gives the original umbra culling `d s / (e - s)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UmbraPeeling {
    /// The range of novel viewpoints the deep depth buffer must serve.
    pub region: ViewRegion,
}

/// Options of [`render_layers`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeelOptions {
    /// Number of peeled layers L (>= 1). With `ground_separate`, the ground layer comes on top
    /// of these (the result has `layers + 1` entries).
    pub layers: usize,
    /// Ground instances (`Instance::is_ground`) are excluded from the peeled layers and rendered
    /// alone into one extra last layer (seed 000, Sec. 3.4: "adding them as a separate (the last)
    /// depth layer is helpful in widening their connected search areas").
    pub ground_separate: bool,
    /// Generalized umbra culling; `None` = standard peeling (`x = 0`).
    pub umbra: Option<UmbraPeeling>,
}

impl Default for PeelOptions {
    fn default() -> Self {
        PeelOptions { layers: 4, ground_separate: false, umbra: None }
    }
}

impl UmbraPeeling {
    fn validate(&self) -> Result<()> {
        match self.region {
            ViewRegion::Disc { e, c } => {
                if !(e.is_finite() && e >= 0.0 && c.is_finite()) {
                    return Err(Error::invalid(format!(
                        "umbra region needs finite e >= 0 and finite c, got e={e} c={c}"
                    )));
                }
            }
            ViewRegion::Directions { max_angle } => {
                if !(max_angle.is_finite() && (0.0..std::f32::consts::FRAC_PI_2).contains(&max_angle)) {
                    return Err(Error::invalid(format!("umbra max_angle must be in [0, pi/2), got {max_angle}")));
                }
            }
        }
        Ok(())
    }

    /// Eq. (1): umbra extent `x` (world units along the view axis) behind the previous layer's
    /// pixel `(px, py)` (continuous pixel coordinates of its centre) at linear depth `d`.
    /// Returns `f32::INFINITY` when the pixel quad hides the whole ray from every viewpoint.
    pub fn umbra_extent(&self, cam: &Camera, px: f32, py: f32, d: f32) -> f32 {
        self.umbra_extent_with(cam, self.tangents(cam), px, py, d)
    }

    /// The tangents [`Self::umbra_extent`] needs, the same for every pixel of a view: of half
    /// the vertical field of view (perspective views) and of the view region's `max_angle`
    /// (direction regions); `0` where unused. Computed once per peeling pass.
    fn tangents(&self, cam: &Camera) -> (f32, f32) {
        let th = match cam.projection {
            Projection::Perspective { fov_y } => (fov_y * 0.5).tan(),
            Projection::Orthographic { .. } => 0.0,
        };
        let tn = match self.region {
            ViewRegion::Directions { max_angle } => max_angle.tan(),
            ViewRegion::Disc { .. } => 0.0,
        };
        (th, tn)
    }

    /// [`Self::umbra_extent`] with the view's [`Self::tangents`].
    fn umbra_extent_with(&self, cam: &Camera, (th, tn): (f32, f32), px: f32, py: f32, d: f32) -> f32 {
        let (ndc_x, ndc_y) = cam.pixel_to_ndc(px, py);
        let aspect = cam.width as f32 / cam.height as f32;
        // Half side `s` of the pixel quad and the projector ray's lateral offset `r` at depth d.
        let (s, r, perspective) = match cam.projection {
            Projection::Perspective { .. } => {
                let r = d * th * (ndc_x * ndc_x * aspect * aspect + ndc_y * ndc_y).sqrt();
                (d * th / cam.height as f32, r, true)
            }
            Projection::Orthographic { half_height } => {
                let r = half_height * (ndc_x * ndc_x * aspect * aspect + ndc_y * ndc_y).sqrt();
                (half_height / cam.height as f32, r, false)
            }
        };
        match self.region {
            ViewRegion::Disc { e, c } => {
                let dc = d - c;
                if dc <= 0.0 {
                    return 0.0; // viewpoints not in front of the quad: no umbra claim
                }
                // h: offset of the projector ray from the centre ray at depth c. Perspective
                // projector rays pass through the reference eye (offset r at depth d, so
                // r |c| / d at depth c); orthographic ones are parallel to the axis.
                let h = if perspective { r * c.abs() / d } else { r };
                let denom = (e + h) - s;
                if denom <= 0.0 {
                    f32::INFINITY
                } else {
                    dc * s / denom
                }
            }
            ViewRegion::Directions { .. } => {
                if tn <= 0.0 {
                    f32::INFINITY
                } else {
                    s / tn
                }
            }
        }
    }
}

/// The peeling threshold (stored depth) behind a previous-layer sample `d` at pixel `(x, y)`:
/// the next layer keeps fragments strictly behind it. Empty pixels get `+inf` (nothing behind
/// the far plane); standard peeling uses `d` itself (bit-exact, no round trip through linear
/// depth); umbra culling adds eq. (1)'s `x` in linear depth (never less than `d`).
fn next_threshold(cam: &Camera, umbra: Option<(&UmbraPeeling, (f32, f32))>, x: u32, y: u32, d: f32) -> f32 {
    if d >= 1.0 {
        return f32::INFINITY;
    }
    let Some((u, tangents)) = umbra else {
        return d;
    };
    let lin = cam.linear_depth(d);
    let ext = u.umbra_extent_with(cam, tangents, x as f32 + 0.5, y as f32 + 0.5, lin);
    if ext.is_infinite() {
        f32::INFINITY
    } else {
        cam.stored_depth(lin + ext).max(d)
    }
}

/// Peels `scene` at time `t` seen by `cam` into depth layers (seed 000, Sec. 3.4).
///
/// Layer 0 is the ordinary depth/item buffer. Layer k+1 keeps, per pixel, the nearest fragment
/// strictly behind layer k's depth (plus the umbra extent of eq. (1) when `umbra` is set); a pixel
/// empty in layer k stays empty in all later layers. With `ground_separate`, ground instances are
/// left out of these and rendered alone as an extra last layer. The scene is set up and binned
/// once; each layer costs one raster pass over the bins.
pub fn render_layers(scene: &Scene, cam: &Camera, t: f32, opts: &PeelOptions) -> Result<Vec<Layer>> {
    scene.check_nonempty()?;
    if opts.layers == 0 {
        return Err(Error::invalid("depth peeling needs at least one layer (L >= 1)"));
    }
    if opts.layers > 64 {
        return Err(Error::invalid(format!("depth peeling: L = {} layers is unreasonable (max 64)", opts.layers)));
    }
    if let Some(u) = &opts.umbra {
        u.validate()?;
    }
    let (w, h) = (cam.width, cam.height);
    let n = scene.instances.len() as u32;
    let (peeled, ground): (Vec<u32>, Vec<u32>) = if opts.ground_separate {
        (0..n).partition(|&i| !scene.instances[i as usize].is_ground)
    } else {
        ((0..n).collect(), Vec::new())
    };
    let binned = bin_scene(scene, cam, t, &SetupParams { objects: Some(&peeled), color: false })?;
    let mut layers: Vec<Layer> = Vec::with_capacity(opts.layers + 1);
    let mut threshold = Image::filled(w, h, f32::INFINITY);
    for k in 0..opts.layers {
        let mut depth = Image::filled(w, h, 1.0f32);
        let mut items = Image::filled(w, h, NO_ITEM);
        // Once a layer is empty every later one is: skip their passes.
        let prev_empty = layers.last().is_some_and(|l: &Layer| l.items.data().iter().all(|&i| i == NO_ITEM));
        if !prev_empty {
            let (mode, thr) = if k == 0 { (Mode::Depth, None) } else { (Mode::Peel, Some(&threshold)) };
            run_pass(
                &binned,
                mode,
                Targets { depth: &mut depth, items: Some(&mut items), handles: None, threshold: thr, load: false },
            );
        }
        // Threshold of the next pass (per pixel, rows in parallel); none after the last layer.
        if k + 1 == opts.layers {
            layers.push(Layer { depth, items });
            break;
        }
        let umbra = opts.umbra.as_ref().map(|u| (u, u.tangents(cam)));
        threshold.data_mut().par_chunks_mut(w as usize).zip(depth.data().par_chunks(w as usize)).enumerate().for_each(
            |(y, (trow, drow))| {
                for (x, (th, &d)) in trow.iter_mut().zip(drow).enumerate() {
                    *th = next_threshold(cam, umbra, x as u32, y as u32, d);
                }
            },
        );
        layers.push(Layer { depth, items });
    }
    if opts.ground_separate {
        layers.push(render_objects(scene, cam, t, &ground)?);
    }
    Ok(layers)
}

/// The `layers` source layers of seed 000 Sec. 4's measurements ("when a terrain or ground is
/// available, the last layer was peeled without foreground objects"): without ground
/// instances, or for one layer, `layers` layers peeled from the scene; with them, `layers - 1`
/// layers peeled from the whole scene (ground included, so layer 0 is the ordinary frame) and
/// the ground alone as the last ([`render_ground_layer`]). Errors as [`render_layers`].
pub fn render_source_layers(
    scene: &Scene,
    cam: &Camera,
    t: f32,
    layers: usize,
    umbra: Option<UmbraPeeling>,
) -> Result<Vec<Layer>> {
    let ground = layers >= 2 && scene.instances.iter().any(|i| i.is_ground);
    let peel = PeelOptions { layers: layers - ground as usize, ground_separate: false, umbra };
    let mut out = render_layers(scene, cam, t, &peel)?;
    if ground {
        out.push(render_ground_layer(scene, cam, t)?);
    }
    Ok(out)
}

/// The ground instances (`Instance::is_ground`) of `scene` alone, as the separate last layer
/// of seed 000 Sec. 3.4 / 4 ("the last layer was peeled without foreground objects"), for
/// callers that peel the whole scene (ground included) into the layers before it; empty
/// (depth 1, [`NO_ITEM`]) where no ground is seen, and everywhere without ground instances.
pub fn render_ground_layer(scene: &Scene, cam: &Camera, t: f32) -> Result<Layer> {
    scene.check_nonempty()?;
    let ground: Vec<u32> =
        (0..scene.instances.len() as u32).filter(|&i| scene.instances[i as usize].is_ground).collect();
    render_objects(scene, cam, t, &ground)
}

/// Depth and item ids of the listed instances alone (nothing listed: an empty layer).
fn render_objects(scene: &Scene, cam: &Camera, t: f32, objects: &[u32]) -> Result<Layer> {
    if objects.is_empty() {
        let (w, h) = (cam.width, cam.height);
        return Ok(Layer { depth: Image::filled(w, h, 1.0f32), items: Image::filled(w, h, NO_ITEM) });
    }
    let f = crate::render_frame(scene, cam, t, &crate::FrameOptions { color: false, objects: Some(objects) })?;
    Ok(Layer { depth: f.depth, items: f.items })
}
