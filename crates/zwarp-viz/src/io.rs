//! Files: 8-bit PNG for people, 32-bit float OpenEXR for exact buffers (depth, colour, motion)
//! that other tools (or a later zwarp run) read back. Every error names the file.

use std::path::Path;

use exr::prelude::{self as x, ReadChannels, ReadLayers, WritableImage};
use zwarp_core::{Error, Image, Motion, Result};

fn image_err(path: &Path, e: image::ImageError) -> Error {
    match e {
        image::ImageError::IoError(io) => Error::io(path, io),
        other => Error::parse(path, other.to_string()),
    }
}

fn exr_err(path: &Path, e: exr::error::Error) -> Error {
    match e {
        exr::error::Error::Io(io) => Error::io(path, io),
        other => Error::parse(path, other.to_string()),
    }
}

fn check_writable<T>(img: &Image<T>, path: &Path) -> Result<()> {
    img.check_nonempty(&format!("{}", path.display()))
}

/// Writes an 8-bit RGB image (a colour map, a figure) as PNG.
pub fn write_png(path: impl AsRef<Path>, img: &Image<[u8; 3]>) -> Result<()> {
    let path = path.as_ref();
    check_writable(img, path)?;
    let bytes: &[u8] = img.data().as_flattened();
    image::save_buffer_with_format(
        path,
        bytes,
        img.width(),
        img.height(),
        image::ExtendedColorType::Rgb8,
        image::ImageFormat::Png,
    )
    .map_err(|e| image_err(path, e))
}

/// Writes an 8-bit single-channel image (a mask, a quantized buffer) as grayscale PNG.
pub fn write_png_gray(path: impl AsRef<Path>, img: &Image<u8>) -> Result<()> {
    let path = path.as_ref();
    check_writable(img, path)?;
    image::save_buffer_with_format(
        path,
        img.data(),
        img.width(),
        img.height(),
        image::ExtendedColorType::L8,
        image::ImageFormat::Png,
    )
    .map_err(|e| image_err(path, e))
}

/// Reads a PNG as 8-bit RGB (gray and alpha images are converted), for round trips and tests.
pub fn read_png(path: impl AsRef<Path>) -> Result<Image<[u8; 3]>> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png).map_err(|e| image_err(path, e))?;
    let rgb = img.to_rgb8();
    let (w, h) = rgb.dimensions();
    let px = rgb.into_raw().chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    Image::from_vec(w, h, px)
}

/// Writes named f32 planes of one size as a single-layer, losslessly compressed (ZIP) EXR.
fn write_channels(path: &Path, size: (u32, u32), channels: Vec<(&str, Vec<f32>)>) -> Result<()> {
    if size.0 == 0 || size.1 == 0 {
        return Err(Error::invalid(format!("{}: cannot write a zero-size image", path.display())));
    }
    let mut names = std::collections::HashSet::new();
    for (name, _) in &channels {
        if name.is_empty() || !name.is_ascii() || !names.insert(*name) {
            return Err(Error::invalid(format!(
                "{}: EXR channel names must be non-empty, ASCII and distinct, got {name:?}",
                path.display()
            )));
        }
    }
    let list: x::SmallVec<[x::AnyChannel<x::FlatSamples>; 4]> =
        channels.into_iter().map(|(name, samples)| x::AnyChannel::new(name, x::FlatSamples::F32(samples))).collect();
    let layer = x::Layer::new(
        (size.0 as usize, size.1 as usize),
        x::LayerAttributes::default(),
        x::Encoding::SMALL_LOSSLESS,
        x::AnyChannels::sort(list),
    );
    x::Image::from_layer(layer).write().to_file(path).map_err(|e| exr_err(path, e))
}

/// Named f32 planes of one EXR layer.
type Channels = Vec<(String, Vec<f32>)>;

/// Reads the first valid layer of an EXR: its size and every channel as f32 planes
/// (f16 / u32 samples converted), row-major.
fn read_channels(path: &Path) -> Result<((u32, u32), Channels)> {
    let img = x::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| exr_err(path, e))?;
    let layer = img.layer_data;
    let size = (layer.size.width() as u32, layer.size.height() as u32);
    let channels = layer
        .channel_data
        .list
        .into_iter()
        .map(|c| (c.name.to_string(), c.sample_data.values_as_f32().collect()))
        .collect();
    Ok((size, channels))
}

fn take_channel(path: &Path, size: (u32, u32), chans: &mut Channels, name: &str) -> Result<Image<f32>> {
    let i = chans.iter().position(|(n, _)| n == name).ok_or_else(|| {
        let have: Vec<&str> = chans.iter().map(|(n, _)| n.as_str()).collect();
        Error::parse(path, format!("no channel {name:?} (channels: {})", have.join(", ")))
    })?;
    let (_, data) = chans.swap_remove(i);
    Image::from_vec(size.0, size.1, data).map_err(|e| Error::parse(path, e.to_string()))
}

/// Writes a single-channel f32 buffer (depth: use `"Z"` by OpenEXR convention, or any name) as
/// EXR, bit-exact.
pub fn write_exr_f32(path: impl AsRef<Path>, img: &Image<f32>, channel_name: &str) -> Result<()> {
    write_channels(path.as_ref(), img.size(), vec![(channel_name, img.data().to_vec())])
}

/// Reads channel `channel_name` of an EXR written by [`write_exr_f32`] (or any EXR) as f32.
pub fn read_exr_f32(path: impl AsRef<Path>, channel_name: &str) -> Result<Image<f32>> {
    let path = path.as_ref();
    let (size, mut chans) = read_channels(path)?;
    take_channel(path, size, &mut chans, channel_name)
}

/// Writes a linear RGB colour buffer as EXR channels `R`, `G`, `B` (f32, no transfer curve).
pub fn write_exr_rgb(path: impl AsRef<Path>, img: &Image<[f32; 3]>) -> Result<()> {
    let plane = |c: usize| img.data().iter().map(|p| p[c]).collect::<Vec<f32>>();
    write_channels(path.as_ref(), img.size(), vec![("R", plane(0)), ("G", plane(1)), ("B", plane(2))])
}

/// Reads channels `R`, `G`, `B` of an EXR as linear RGB.
pub fn read_exr_rgb(path: impl AsRef<Path>) -> Result<Image<[f32; 3]>> {
    let path = path.as_ref();
    let (size, mut chans) = read_channels(path)?;
    let r = take_channel(path, size, &mut chans, "R")?;
    let g = take_channel(path, size, &mut chans, "G")?;
    let b = take_channel(path, size, &mut chans, "B")?;
    let px = r.data().iter().zip(g.data()).zip(b.data()).map(|((&r, &g), &b)| [r, g, b]).collect();
    Image::from_vec(size.0, size.1, px)
}

/// Writes a motion buffer (seed 000 Sec. 3.1: motion `v` in pixels and the target-view depth)
/// as EXR channels `vx`, `vy`, `depth`.
pub fn write_exr_motion(path: impl AsRef<Path>, img: &Image<Motion>) -> Result<()> {
    let d = img.data();
    write_channels(
        path.as_ref(),
        img.size(),
        vec![
            ("vx", d.iter().map(|m| m.v.x).collect()),
            ("vy", d.iter().map(|m| m.v.y).collect()),
            ("depth", d.iter().map(|m| m.depth).collect()),
        ],
    )
}

/// Reads a motion buffer written by [`write_exr_motion`] (channels `vx`, `vy`, `depth`).
pub fn read_exr_motion(path: impl AsRef<Path>) -> Result<Image<Motion>> {
    let path = path.as_ref();
    let (size, mut chans) = read_channels(path)?;
    let vx = take_channel(path, size, &mut chans, "vx")?;
    let vy = take_channel(path, size, &mut chans, "vy")?;
    let depth = take_channel(path, size, &mut chans, "depth")?;
    let px = vx
        .data()
        .iter()
        .zip(vy.data())
        .zip(depth.data())
        .map(|((&x, &y), &d)| Motion { v: glam::Vec2::new(x, y), depth: d })
        .collect();
    Image::from_vec(size.0, size.1, px)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;

    /// A fresh temp dir, removed when it drops (also when the test fails).
    fn scratch() -> tempfile::TempDir {
        tempfile::Builder::new().prefix("zwarp-viz-test-").tempdir().unwrap()
    }

    #[test]
    fn png_round_trip() {
        let dir = scratch();
        let tmp = |name: &str| dir.path().join(name);
        let img = Image::from_fn(7, 5, |x, y| [(x * 30) as u8, (y * 50) as u8, (x * y) as u8]);
        let p = tmp("rgb.png");
        write_png(&p, &img).unwrap();
        assert_eq!(read_png(&p).unwrap(), img);
        let g = Image::from_fn(3, 4, |x, y| (x * 80 + y) as u8);
        let pg = tmp("gray.png");
        write_png_gray(&pg, &g).unwrap();
        assert_eq!(read_png(&pg).unwrap(), g.map(|&v| [v, v, v]));
    }

    #[test]
    fn exr_round_trips_are_bit_exact() {
        let dir = scratch();
        let tmp = |name: &str| dir.path().join(name);
        let depth = Image::from_fn(9, 6, |x, y| 0.9 + (x as f32 * 0.013 + y as f32 * 0.0007).sin() * 0.05);
        let p = tmp("depth.exr");
        write_exr_f32(&p, &depth, "Z").unwrap();
        assert_eq!(read_exr_f32(&p, "Z").unwrap(), depth);
        let e = read_exr_f32(&p, "depth").unwrap_err().to_string();
        assert!(e.contains("depth.exr") && e.contains("no channel \"depth\"") && e.contains("Z"), "{e}");

        let rgb = Image::from_fn(4, 3, |x, y| [x as f32 * 0.25, y as f32 * 1.5, -0.125]);
        let pr = tmp("rgb.exr");
        write_exr_rgb(&pr, &rgb).unwrap();
        assert_eq!(read_exr_rgb(&pr).unwrap(), rgb);

        let motion = Image::from_fn(5, 4, |x, y| Motion {
            v: Vec2::new(x as f32 - 2.5, y as f32 * 0.75),
            depth: if x == 0 { 1.0 } else { 0.95 + y as f32 * 0.001 },
        });
        let pm = tmp("motion.exr");
        write_exr_motion(&pm, &motion).unwrap();
        assert_eq!(read_exr_motion(&pm).unwrap(), motion);
        let (_, chans) = read_channels(&pm).unwrap();
        let mut names: Vec<String> = chans.into_iter().map(|(n, _)| n).collect();
        names.sort();
        assert_eq!(names, vec!["depth", "vx", "vy"]);
    }

    #[test]
    fn errors_name_the_file() {
        let dir = scratch();
        let tmp = |name: &str| dir.path().join(name);
        let missing = tmp("does-not-exist.exr");
        let e = read_exr_f32(&missing, "Z").unwrap_err();
        assert!(e.to_string().contains("does-not-exist.exr"), "{e}");
        let e = read_png(tmp("nope.png")).unwrap_err();
        assert!(matches!(e, Error::Io { .. }), "{e}");
        // Garbage content is a parse error with the path.
        let bad = tmp("garbage.png");
        std::fs::write(&bad, b"not a png").unwrap();
        let e = read_png(&bad).unwrap_err();
        assert!(matches!(e, Error::Parse { .. }) && e.to_string().contains("garbage.png"), "{e}");
        let bad_exr = tmp("garbage.exr");
        std::fs::write(&bad_exr, b"not an exr").unwrap();
        let e = read_exr_rgb(&bad_exr).unwrap_err();
        assert!(e.to_string().contains("garbage.exr"), "{e}");
        // Unwritable directory.
        let dir = tmp("no-such-dir").join("x.png");
        let e = write_png(&dir, &Image::new(2, 2, [0u8; 3])).unwrap_err();
        assert!(e.to_string().contains("x.png"), "{e}");
        // Zero-size images and bad channel names are rejected before touching the disk.
        assert!(write_png(tmp("z.png"), &Image::new(0, 2, [0u8; 3])).is_err());
        assert!(write_exr_f32(tmp("z.exr"), &Image::new(3, 0, 0.0), "Z").is_err());
        assert!(write_exr_f32(tmp("e.exr"), &Image::new(3, 1, 0.0), "").unwrap_err().to_string().contains("channel"));
    }
}
