//! What `zwarp upsample`, `stereo` and `blur` share: the methods (seed 001's two variants and
//! the baselines), colour rendering on either backend, the pixels a source did not see, the
//! warps on either backend, the table columns of a row's quality and speed, images. Frames,
//! timing and the quality comparison itself are the harness's (`crate::harness`).

use std::path::Path;

use anyhow::{bail, Context, Result};
use zwarp_color::{ColorWarpOutput, Field, HeuristicParams, RobustParams, Subdivision};
use zwarp_core::{Camera, Image, Motion, Scene};

use crate::args::Backend;
use crate::device::{Device, DeviceScene};
use crate::harness::Quality;
use crate::output::fmt;

/// A prediction method (JSON `method`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Seed 001 Sec. 3.3: one seed, 3 iterations, orbit in-painting.
    Heuristic,
    /// Seed 001 Sec. 3.4: rho, subdivision, quads rasterised with a depth test.
    Robust,
    /// The source frame shown again.
    Repeat,
    /// Per-pixel forward mesh warp (Mark et al. 1997).
    Mesh,
    /// Reverse reprojection caching (Nehab et al. 2007): re-render of the target's depth.
    Reproject,
    /// FSR3-like forward scatter with push-pull in-painting.
    Scatter,
}

impl Method {
    /// Every method, in table order.
    pub const ALL: [Method; 6] =
        [Method::Heuristic, Method::Robust, Method::Repeat, Method::Mesh, Method::Reproject, Method::Scatter];

    /// The JSON / CLI name.
    pub fn name(self) -> &'static str {
        match self {
            Method::Heuristic => "heuristic",
            Method::Robust => "robust",
            Method::Repeat => "repeat",
            Method::Mesh => "mesh",
            Method::Reproject => "reproject",
            Method::Scatter => "scatter",
        }
    }
}

/// Parses `--methods` (comma list of the names, or `all`).
pub fn parse_methods(s: &str) -> Result<Vec<Method>> {
    let mut out = Vec::new();
    for name in crate::args::parse_list::<String>(s, "--methods")? {
        if name == "all" {
            out.extend(Method::ALL);
            continue;
        }
        match Method::ALL.iter().find(|m| m.name() == name) {
            Some(m) => out.push(*m),
            None => {
                bail!("--methods: unknown method '{name}' (heuristic, robust, repeat, mesh, reproject, scatter, all)")
            }
        }
    }
    out.dedup();
    Ok(out)
}

/// One rendered view: colour, depth and item ids.
pub struct View {
    /// The camera.
    pub cam: Camera,
    /// Scene time.
    pub t: f32,
    /// Linear RGB.
    pub color: Image<[f32; 3]>,
    /// Depth, `[0, 1]`.
    pub depth: Image<f32>,
    /// Instance ids.
    pub items: Image<u32>,
}

/// Renders views and runs the two colour warps on the chosen backend through the
/// [`Device`] seam (baselines stay on the CPU).
pub struct Backends<'a> {
    /// The scene.
    pub scene: &'a Scene,
    device: Device,
    on_device: DeviceScene<'a>,
}

impl<'a> Backends<'a> {
    /// CPU, or the first GPU adapter (one clear error if there is none).
    pub fn new(scene: &'a Scene, backend: Backend) -> Result<Self> {
        let device = Device::open(backend)?;
        let on_device = device.load(scene)?;
        Ok(Backends { scene, device, on_device })
    }

    /// `"cpu"` or the adapter's name.
    pub fn name(&self) -> String {
        self.device.adapter().map_or("cpu".into(), |a| format!("gpu ({a})"))
    }

    /// Colour, depth and ids of the scene at `t` seen by `cam`.
    pub fn view(&self, cam: &Camera, t: f32) -> Result<View> {
        let (depth, items, color) = self.device.render_view(&self.on_device, cam, t)?;
        let color = zwarp_color::require_color(color.as_ref(), "the rendered frame")?.clone();
        Ok(View { cam: *cam, t, color, depth, items })
    }

    /// Depth and ids only (the re-render of reverse reprojection caching), on the CPU.
    pub fn depth_items(&self, cam: &Camera, t: f32) -> Result<(Image<f32>, Image<u32>)> {
        let f = zwarp_raster::render_frame(self.scene, cam, t, &zwarp_raster::FrameOptions::default())?;
        Ok((f.depth, f.items))
    }

    /// The motion field of `view` towards `cam_b` at `t_b` (camera and object motion).
    pub fn motion(&self, view: &View, cam_b: &Camera, t_b: f32) -> Result<Image<Motion>> {
        Ok(zwarp_core::motion_field(
            &view.depth,
            Some(&view.items),
            &view.cam,
            cam_b,
            &self.scene.object_deltas(view.t, t_b),
        )?)
    }

    /// The heuristic warp (WGSL twin on the GPU).
    pub fn heuristic(
        &self,
        field: &Field<'_>,
        color: &Image<[f32; 3]>,
        p: &HeuristicParams,
    ) -> Result<ColorWarpOutput> {
        let mut out = ColorWarpOutput::empty();
        self.device.heuristic_into(field, color, p, &mut out)?;
        Ok(out)
    }

    /// The heuristic warp into `out`, whose buffers a CPU warp reuses (an engine's steady state).
    pub fn heuristic_into(
        &self,
        field: &Field<'_>,
        color: &Image<[f32; 3]>,
        p: &HeuristicParams,
        out: &mut ColorWarpOutput,
    ) -> Result<()> {
        self.device.heuristic_into(field, color, p, out)
    }

    /// The robust warp (its subdivision included) into `out` (buffers reused on the CPU).
    pub fn robust_into(
        &self,
        field: &Field<'_>,
        color: &Image<[f32; 3]>,
        p: &RobustParams,
        out: &mut ColorWarpOutput,
    ) -> Result<()> {
        self.device.robust_into(None, field, color, p, out)
    }

    /// The robust warp with a given subdivision into `out` (WGSL twin on the GPU).
    pub fn robust_with_into(
        &self,
        sub: &Subdivision,
        field: &Field<'_>,
        color: &Image<[f32; 3]>,
        p: &RobustParams,
        out: &mut ColorWarpOutput,
    ) -> Result<()> {
        self.device.robust_into(Some(sub), field, color, p, out)
    }

    /// The robust warp including its subdivision.
    pub fn robust(&self, field: &Field<'_>, color: &Image<[f32; 3]>, p: &RobustParams) -> Result<ColorWarpOutput> {
        let mut out = ColorWarpOutput::empty();
        self.device.robust_into(None, field, color, p, &mut out)?;
        Ok(out)
    }
}

/// Errors unless the view shows at least one surface (a colour warp of pure sky has nothing to
/// move; a path looking away from the scene is bad input).
pub fn check_has_surface(view: &View, what: &str) -> Result<()> {
    if view.depth.data().iter().all(|&d| d >= 1.0) {
        bail!("{what} shows no surface of the scene (only sky): nothing to warp; check --path");
    }
    Ok(())
}

/// The header of a colour command's table: its own `keys`, then the quality columns (with the
/// warp's convergence and the unseen pixels' share and PSNR where `convergence`), then the
/// timing columns of [`speed_cells`] (`time`: the header of the method's own time), so every
/// colour command's table reads alike.
pub fn columns<'a>(keys: &[&'a str], convergence: bool, time: &'a str) -> Vec<&'a str> {
    let mut c = keys.to_vec();
    c.extend(["PSNR", "PSNR Y", "SSIM", "FLIP", "CIE94"]);
    if convergence {
        c.extend(["conv", "unseen", "unseen PSNR"]);
    }
    c.extend([time, "floor ms", "x floor", "render ms", "speedup"]);
    c
}

/// The quality cells of [`columns`].
pub fn quality_cells(q: &Quality, convergence: bool) -> Vec<String> {
    let mut c = vec![fmt(q.psnr, 2), fmt(q.psnr_y, 2), fmt(q.ssim, 4), fmt(q.flip, 4), fmt(q.cie94, 2)];
    if convergence {
        c.extend([fmt(q.converged, 3), fmt(q.disocc_fraction, 4), fmt(q.disocc_psnr, 2)]);
    }
    c
}

/// The speed figures of a colour-warp row, measured in the same run (JSON fields of the row).
#[derive(Clone, Debug, serde::Serialize)]
pub struct WarpSpeed {
    /// Median prediction time (ms), warm (what it covers: the row's documentation).
    pub warp_ms: f64,
    /// Fastest prediction.
    pub warp_ms_min: f64,
    /// Slowest prediction.
    pub warp_ms_max: f64,
    /// Median time (ms) of rendering the predicted view with colour.
    pub render_ms: f64,
    /// `render_ms / warp_ms`.
    pub speedup: f64,
    /// Median streaming floor (ms) of the prediction: read the field's planes, depth and colour
    /// once, write the colour (`zwarp_color::floor`).
    pub floor_ms: f64,
    /// `warp_ms / floor_ms`.
    pub floor_ratio: f64,
}

impl WarpSpeed {
    /// The figures from the prediction times `ms` and the medians of the render and the floor.
    pub fn of(ms: &[f64], render_ms: f64, floor_ms: f64) -> Self {
        let t = crate::harness::Timing::of(ms);
        WarpSpeed {
            warp_ms: t.median,
            warp_ms_min: t.min,
            warp_ms_max: t.max,
            render_ms,
            speedup: render_ms / t.median.max(1e-9),
            floor_ms,
            floor_ratio: t.median / floor_ms.max(1e-9),
        }
    }

    /// The table cells of [`speed_cells`].
    pub fn cells(&self, time_decimals: usize) -> Vec<String> {
        speed_cells(self.warp_ms, self.floor_ms, self.floor_ratio, self.render_ms, self.speedup, time_decimals)
    }
}

/// The timing cells of [`columns`]: the method's time and its floor (`time_decimals`), the ratio
/// of the two, the same-run render and the speedup over it.
pub fn speed_cells(
    ms: f64,
    floor_ms: f64,
    floor_ratio: f64,
    render_ms: f64,
    speedup: f64,
    time_decimals: usize,
) -> Vec<String> {
    vec![fmt(ms, time_decimals), fmt(floor_ms, time_decimals), fmt(floor_ratio, 1), fmt(render_ms, 1), fmt(speedup, 2)]
}

/// The pixels of the target view `target` the source view did not see: its depth reprojected
/// into the source (`to_source`) lands off-screen or behind another surface.
pub fn unseen(
    target_depth: &Image<f32>,
    to_source: &Image<Motion>,
    source_depth: &Image<f32>,
    source_cam: &Camera,
) -> Result<Image<bool>> {
    Ok(zwarp_color::source_visibility(target_depth, to_source, source_depth, source_cam)?.map(|&v| !v))
}

/// Writes a linear RGB image as sRGB PNG `dir/name.png`.
pub fn write_color(dir: &Path, name: &str, img: &Image<[f32; 3]>) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create folder", dir.display()))?;
    zwarp_viz::write_png(dir.join(format!("{name}.png")), &zwarp_viz::color_to_rgb8(img))?;
    Ok(())
}

/// Writes the FLIP error map of `pred` against `reference` (turbo, 0..1) as `dir/name.png`.
pub fn write_flip(dir: &Path, name: &str, reference: &Image<[f32; 3]>, pred: &Image<[f32; 3]>) -> Result<()> {
    let f = zwarp_metrics::flip(reference, pred, zwarp_metrics::FLIP_DEFAULT_PPD)?;
    zwarp_viz::write_png(dir.join(format!("{name}.png")), &zwarp_viz::scalar_to_rgb8(&f.map, 0.0, 1.0)?)?;
    Ok(())
}

/// A file-name-safe form of a scene spec.
pub fn safe_name(s: &str) -> String {
    let base = Path::new(s).file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_else(|| s.into());
    base.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect()
}

/// The camera `cam` moved by `(u, v)` world units along its right and up axes, with the
/// projection sheared so that the plane at view distance `focus` maps to itself (a thin-lens
/// sample for defocus; `None`: parallel cameras, the stereo eyes of ARCHITECTURE.md "Stereo/VR").
pub fn offset_camera(cam: &Camera, u: f32, v: f32, focus: Option<f32>) -> Camera {
    let view = glam::Mat4::from_translation(glam::Vec3::new(-u, -v, 0.0)) * cam.view;
    let proj = match focus {
        None => cam.proj,
        Some(f) => {
            let (sx, sy) = (cam.proj.x_axis.x * u / f, cam.proj.y_axis.y * v / f);
            glam::Mat4::from_cols(glam::Vec4::X, glam::Vec4::Y, glam::Vec4::Z, glam::Vec4::new(sx, sy, 0.0, 1.0))
                * cam.proj
        }
    };
    Camera { view, proj, ..*cam }
}

/// Panels of overview images, keyed by (mode, strategy) flags: two rows per key (predictions,
/// FLIP maps), the reference first.
pub type Strips = Vec<((bool, u32), Panels)>;

/// One strip: predictions (the reference first) above their FLIP maps.
pub type Panels = (Vec<Image<[u8; 3]>>, Vec<Image<[u8; 3]>>);

/// Appends `pred` (labelled `label`, and its FLIP map with the map's colour bar) to the strip of
/// `key`, starting it with `reference`. Panels are reduced to at most [`PANEL_WIDTH`] pixels
/// before they are labelled, so the text stays legible.
pub fn add_panel(
    strips: &mut Strips,
    key: (bool, u32),
    reference: &Image<[f32; 3]>,
    pred: &Image<[f32; 3]>,
    label: &str,
) -> Result<()> {
    let panel = |img: &Image<[f32; 3]>, label: &str| -> Result<Image<[u8; 3]>> {
        let small = zwarp_viz::fit_width(&zwarp_viz::color_to_rgb8(img), PANEL_WIDTH)?;
        Ok(zwarp_viz::labelled(&small, label, zwarp_viz::figure::label_scale(small.width()))?)
    };
    let i = match strips.iter().position(|(k, _)| *k == key) {
        Some(i) => i,
        None => {
            let r = panel(reference, "reference (render)")?;
            let black = Image::new(r.width(), r.height(), [255u8; 3]);
            strips.push((key, (vec![r], vec![black])));
            strips.len() - 1
        }
    };
    let f = zwarp_metrics::flip(reference, pred, zwarp_metrics::FLIP_DEFAULT_PPD)?;
    let map = zwarp_viz::fit_width(&zwarp_viz::scalar_to_rgb8(&f.map, 0.0, 1.0)?, PANEL_WIDTH)?;
    let s = zwarp_viz::figure::label_scale(map.width());
    let ticks = [(0.0, "0".to_string()), (0.5, "0.5".to_string()), (1.0, "1".to_string())];
    let bar = zwarp_viz::colorbar(map.width(), s, zwarp_viz::turbo, &ticks)?;
    let flip =
        zwarp_viz::labelled(&zwarp_viz::stacked(&[&map, &bar])?, &format!("FLIP {label} (mean {:.3})", f.mean), s)?;
    let (a, b) = &mut strips[i].1;
    a.push(panel(pred, label)?);
    b.push(flip);
    Ok(())
}

/// Width in pixels of one panel of a strip: full-size frames side by side make files of tens of
/// megabytes that no page shows at that size.
const PANEL_WIDTH: u32 = 480;

/// Writes one strip (predictions above their FLIP maps, each panel reduced to at most
/// [`PANEL_WIDTH`] pixels) as `dir/name.png`.
pub fn write_strip(dir: &Path, name: &str, panels: &Panels) -> Result<()> {
    let row = |images: &[Image<[u8; 3]>]| -> Result<Image<[u8; 3]>> {
        let fitted =
            images.iter().map(|i| zwarp_viz::fit_width(i, PANEL_WIDTH)).collect::<zwarp_core::Result<Vec<_>>>()?;
        Ok(zwarp_viz::strip(&fitted)?)
    };
    let gap = Image::new(1, zwarp_viz::GAP, zwarp_viz::GAP_COLOR);
    let out = zwarp_viz::stacked(&[&row(&panels.0)?, &gap, &row(&panels.1)?])?;
    zwarp_viz::write_png(dir.join(format!("{name}.png")), &out)?;
    Ok(())
}
