//! Image files: linear OpenEXR for renders, 8-bit PNG for display and heatmaps.
//!
//! Files are encoded in memory, then written with [`write_atomic`]: a temporary sibling
//! renamed over the target, so a failure (encoding or I/O) never leaves a half-written file
//! and never destroys an existing one. Errors name the target file.

use std::io::Cursor;
use std::path::Path;

use crate::atomic::write_atomic;
use crate::error::OutputError;
use crate::eval::image_error::{display_image, DisplayParams, Rgb8Image};
use crate::eval::render::{sphere_mask, Image};

fn encode_error(path: &Path, message: String) -> OutputError {
    OutputError::Encode {
        path: path.to_path_buf(),
        message,
    }
}

/// Encodes a render as OpenEXR bytes: linear RGB, 32-bit float, lossless compression.
fn encode_exr(image: &Image) -> Result<Vec<u8>, String> {
    use exr::prelude::{SpecificChannels, Vec2, WritableImage};
    image.check().map_err(|e| e.to_string())?;
    if image.width == 0 || image.height == 0 {
        return Err("empty image".into());
    }
    let (w, h) = (image.width as usize, image.height as usize);
    let data = &image.data;
    let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
        let i = 3 * (y * w + x);
        (data[i], data[i + 1], data[i + 2])
    });
    let mut bytes = Cursor::new(Vec::new());
    exr::prelude::Image::from_channels((w, h), channels)
        .write()
        // Blocks in increasing order: parallel compression writes them in completion
        // order, so the same image gave different bytes from run to run.
        .non_parallel()
        .to_buffered(&mut bytes)
        .map_err(|e| format!("cannot encode OpenEXR: {e}"))?;
    Ok(bytes.into_inner())
}

/// Writes a render as linear RGB 32-bit float OpenEXR (lossless compression; the mask is
/// not stored: off-sphere pixels are 0).
pub fn write_exr(path: impl AsRef<Path>, image: &Image) -> Result<(), OutputError> {
    let path = path.as_ref();
    let bytes = exr_bytes(path, image)?;
    write_atomic(path, |w| w.write_all(&bytes))
}

/// The bytes [`write_exr`] writes (`path` names the file in errors), for callers that
/// stage several outputs together ([`crate::atomic::OutputSet`]).
pub fn exr_bytes(path: &Path, image: &Image) -> Result<Vec<u8>, OutputError> {
    encode_exr(image).map_err(|m| encode_error(path, m))
}

/// The bytes [`write_png`] writes.
pub fn png_bytes(
    path: &Path,
    image: &Image,
    display: &DisplayParams,
) -> Result<Vec<u8>, OutputError> {
    let rgb = display_image(image, display).map_err(|e| encode_error(path, e.to_string()))?;
    rgb8_png_bytes(path, rgb.width, rgb.height, &rgb.data)
}

/// Reads an OpenEXR file's first RGB(A) layer as a render (channels converted to f32,
/// alpha ignored). The mask is the sphere mask of the image's size
/// ([`sphere_mask`]), since EXR files written by [`write_exr`] do not store it.
pub fn read_exr(path: impl AsRef<Path>) -> Result<Image, OutputError> {
    let path = path.as_ref();
    let decoded = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |size, _| {
            (
                size.width(),
                size.height(),
                vec![0.0f32; 3 * size.width() * size.height()],
            )
        },
        |pixels: &mut (usize, usize, Vec<f32>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let i = 3 * (pos.y() * pixels.0 + pos.x());
            pixels.2[i..i + 3].copy_from_slice(&[r, g, b]);
        },
    )
    .map_err(|e| match e {
        exr::error::Error::Io(source) => OutputError::Io {
            path: path.to_path_buf(),
            source,
        },
        other => encode_error(path, format!("cannot decode OpenEXR: {other}")),
    })?;
    let (w, h, data) = decoded.layer_data.channel_data.pixels;
    let too_big = || encode_error(path, format!("image too large: {w}x{h}"));
    let width = u32::try_from(w).map_err(|_| too_big())?;
    let height = u32::try_from(h).map_err(|_| too_big())?;
    Ok(Image {
        width,
        height,
        data,
        mask: sphere_mask(width, height),
    })
}

/// Writes a render as an 8-bit RGB PNG after the display mapping of `display`
/// (exposure and gamma, no extra sRGB curve).
pub fn write_png(
    path: impl AsRef<Path>,
    image: &Image,
    display: &DisplayParams,
) -> Result<(), OutputError> {
    let path = path.as_ref();
    let rgb = display_image(image, display).map_err(|e| encode_error(path, e.to_string()))?;
    write_png_rgb8(path, rgb.width, rgb.height, &rgb.data)
}

/// Writes an [`Rgb8Image`] (e.g. a heatmap) as PNG.
pub fn write_rgb8_image(path: impl AsRef<Path>, image: &Rgb8Image) -> Result<(), OutputError> {
    write_png_rgb8(path, image.width, image.height, &image.data)
}

/// Writes `width` x `height` interleaved 8-bit RGB (`3 * width * height` bytes, row 0 at
/// the top) as PNG.
pub(crate) fn write_png_rgb8(
    path: impl AsRef<Path>,
    width: u32,
    height: u32,
    data: &[u8],
) -> Result<(), OutputError> {
    let path = path.as_ref();
    let bytes = rgb8_png_bytes(path, width, height, data)?;
    write_atomic(path, |w| w.write_all(&bytes))
}

/// The bytes `write_png_rgb8` writes.
pub fn rgb8_png_bytes(
    path: &Path,
    width: u32,
    height: u32,
    data: &[u8],
) -> Result<Vec<u8>, OutputError> {
    let expected = 3 * width as usize * height as usize;
    if width == 0 || height == 0 || data.len() != expected {
        let message = format!(
            "{width}x{height} RGB image needs {expected} bytes, got {}",
            data.len()
        );
        return Err(encode_error(path, message));
    }
    let mut bytes = Vec::new();
    {
        use ::image::ImageEncoder;
        ::image::codecs::png::PngEncoder::new(&mut bytes)
            .write_image(data, width, height, ::image::ExtendedColorType::Rgb8)
            .map_err(|e| encode_error(path, format!("cannot encode PNG: {e}")))?;
    }
    Ok(bytes)
}

/// A tick label: decades as `1e-4` (`0.001` to `1000` written out), other values with at
/// most 4 significant digits and no float noise (`9.999999999999999e-5` is `1e-4`,
/// `0.30000000000000004` is `0.3`).
pub fn tick_label(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    if !v.is_finite() {
        return format!("{v}");
    }
    let e = v.abs().log10().floor() as i32;
    // Round to 4 significant digits first: 9.9999e-5 becomes 1.000e-4.
    let s = format!("{:.3e}", v);
    let (m, exp) = s.split_once('e').unwrap_or((&s, "0"));
    let exp: i32 = exp.parse().unwrap_or(e);
    let m = m.trim_end_matches('0').trim_end_matches('.');
    if (-3..=3).contains(&exp) {
        let decimals = (3 - exp).max(0) as usize;
        let t = format!("{:.*}", decimals, v);
        let t = if t.contains('.') {
            t.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            t
        };
        return t;
    }
    format!("{m}e{exp}")
}

/// What a heatmap's colour bar measures.
pub const HEATMAP_QUANTITY: &str = "per-pixel |error| after display mapping";

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::render::{render_sphere, RenderParams};

    fn test_image() -> Image {
        let f = |wi: [f64; 3], wo: [f64; 3]| {
            [0.1 + wi[0] * 0.3, 0.7 * wo[2] + 1e-7, 12.5 * wi[2] * wi[2]]
        };
        let mut img = render_sphere(
            &RenderParams::default()
                .with_size(37)
                .with_light(30.0, 200.0),
            &f,
        )
        .unwrap();
        // Values that must survive bit-exactly: subnormal, large, negative zero, odd mantissas.
        let on = img.mask.iter().position(|&m| m).unwrap();
        img.data[3 * on..3 * on + 3].copy_from_slice(&[1e-40, 3.4e38, -0.0]);
        img.data[3 * on + 3] = 0.1f32 + f32::EPSILON;
        img
    }

    fn no_temp_files(dir: &Path) -> bool {
        std::fs::read_dir(dir)
            .unwrap()
            .all(|e| !e.unwrap().file_name().to_string_lossy().contains(".tmp-"))
    }

    #[test]
    fn exr_round_trip_is_bit_exact() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("render.exr");
        let img = test_image();
        write_exr(&path, &img).unwrap();
        let back = read_exr(&path).unwrap();
        assert_eq!((back.width, back.height), (img.width, img.height));
        assert_eq!(back.mask, img.mask);
        assert_eq!(back.data.len(), img.data.len());
        for (a, b) in img.data.iter().zip(&back.data) {
            assert_eq!(a.to_bits(), b.to_bits());
        }
        assert!(no_temp_files(dir.path()));
    }

    #[test]
    fn exr_bytes_are_deterministic() {
        // Many blocks (16 lines each), so completion order would show if it leaked in.
        let (w, h) = (256u32, 512u32);
        let data: Vec<f32> = (0..3 * w * h)
            .map(|i| ((i * 7919) % 1013) as f32 / 97.0)
            .collect();
        let img = Image {
            width: w,
            height: h,
            data,
            mask: vec![true; (w * h) as usize],
        };
        let first = exr_bytes(Path::new("a.exr"), &img).unwrap();
        for _ in 0..4 {
            assert_eq!(exr_bytes(Path::new("a.exr"), &img).unwrap(), first);
        }
    }

    #[test]
    fn exr_non_square_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("wide.exr");
        let mut img = Image::black(5, 3);
        img.data
            .iter_mut()
            .enumerate()
            .for_each(|(i, v)| *v = i as f32 * 0.37);
        write_exr(&path, &img).unwrap();
        let back = read_exr(&path).unwrap();
        assert_eq!((back.width, back.height, back.data), (5, 3, img.data));
    }

    #[test]
    fn read_exr_errors_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("missing.exr");
        let err = read_exr(&missing).unwrap_err();
        assert!(err.to_string().contains("missing.exr"), "{err}");
        let junk = dir.path().join("junk.exr");
        std::fs::write(&junk, b"not an exr file at all").unwrap();
        let err = read_exr(&junk).unwrap_err();
        assert!(err.to_string().contains("junk.exr"), "{err}");
    }

    #[test]
    fn png_has_right_size_and_values() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("render.png");
        let img = test_image();
        let display = DisplayParams::default();
        write_png(&path, &img, &display).unwrap();
        let decoded = ::image::open(&path).unwrap().to_rgb8();
        assert_eq!(decoded.dimensions(), (37, 37));
        for (i, (&v, &byte)) in img.data.iter().zip(decoded.as_raw()).enumerate() {
            assert_eq!(byte, display.map_u8(f64::from(v)), "sample {i}");
        }
        assert!(no_temp_files(dir.path()));
    }

    #[test]
    fn png_rgb8_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("heat.png");
        let data: Vec<u8> = (0..4 * 3 * 3).map(|i| (i * 7) as u8).collect();
        write_rgb8_image(
            &path,
            &Rgb8Image {
                width: 4,
                height: 3,
                data: data.clone(),
            },
        )
        .unwrap();
        let decoded = ::image::open(&path).unwrap().to_rgb8();
        assert_eq!(decoded.dimensions(), (4, 3));
        assert_eq!(decoded.as_raw(), &data);
    }

    #[test]
    fn png_rgb8_rejects_wrong_length_and_keeps_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("old.png");
        std::fs::write(&path, b"old contents").unwrap();
        let err = write_png_rgb8(&path, 4, 4, &[0; 47]).unwrap_err();
        assert!(matches!(err, OutputError::Encode { .. }));
        assert!(err.to_string().contains("old.png"), "{err}");
        assert_eq!(std::fs::read(&path).unwrap(), b"old contents");
        assert!(no_temp_files(dir.path()));
    }

    #[test]
    fn missing_parent_directory_names_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no_such_dir").join("out.exr");
        let err = write_exr(&path, &test_image()).unwrap_err();
        assert!(matches!(err, OutputError::Io { .. }));
        assert!(err.to_string().contains("no_such_dir"), "{err}");
        assert!(err.to_string().contains("out.exr"), "{err}");
        let err = write_png(&path, &test_image(), &DisplayParams::default()).unwrap_err();
        assert!(err.to_string().contains("out.exr"), "{err}");
        assert!(!dir.path().join("no_such_dir").exists());
    }

    #[test]
    fn failed_encoding_keeps_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("target.exr");
        std::fs::write(&path, b"old").unwrap();
        let mut bad = test_image();
        bad.data.pop();
        let err = write_exr(&path, &bad).unwrap_err();
        assert!(matches!(err, OutputError::Encode { .. }));
        assert!(err.to_string().contains("target.exr"), "{err}");
        assert!(err.to_string().contains("malformed"), "{err}");
        let bad_display = DisplayParams::default().with_gamma(0.0);
        let err = write_png(&path, &test_image(), &bad_display).unwrap_err();
        assert!(err.to_string().contains("gamma"), "{err}");
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert!(no_temp_files(dir.path()));
    }

    #[test]
    fn failed_rename_keeps_target_and_removes_temp() {
        // The target is a non-empty directory: the final rename fails.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("occupied.exr");
        std::fs::create_dir(&path).unwrap();
        std::fs::write(path.join("keep"), b"x").unwrap();
        let err = write_exr(&path, &test_image()).unwrap_err();
        assert!(matches!(err, OutputError::Io { .. }));
        assert!(err.to_string().contains("occupied.exr"), "{err}");
        assert_eq!(std::fs::read(path.join("keep")).unwrap(), b"x");
        assert!(no_temp_files(dir.path()));
    }

    #[cfg(unix)]
    #[test]
    fn read_only_directory_keeps_old_file() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("ro");
        std::fs::create_dir(&sub).unwrap();
        let path = sub.join("render.png");
        std::fs::write(&path, b"old").unwrap();
        std::fs::set_permissions(&sub, std::fs::Permissions::from_mode(0o555)).unwrap();
        if std::fs::File::create(sub.join("probe")).is_ok() {
            // Running as root: permissions are not enforced, nothing to test.
            let _ = std::fs::remove_file(sub.join("probe"));
        } else {
            let err = write_png(&path, &test_image(), &DisplayParams::default()).unwrap_err();
            assert!(err.to_string().contains("render.png"), "{err}");
            assert_eq!(std::fs::read(&path).unwrap(), b"old");
        }
        std::fs::set_permissions(&sub, std::fs::Permissions::from_mode(0o755)).unwrap();
    }

    #[test]
    fn overwrites_existing_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("again.png");
        std::fs::write(&path, b"old").unwrap();
        write_png_rgb8(&path, 1, 1, &[1, 2, 3]).unwrap();
        assert_eq!(::image::open(&path).unwrap().to_rgb8().as_raw(), &[1, 2, 3]);
    }
}
