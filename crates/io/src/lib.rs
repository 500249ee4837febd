//! # isolux-io
//!
//! Image files in and out:
//! - [`write_png`]: 8-bit sRGB after exposure and a documented [`Tonemap`];
//! - [`write_exr`]: linear 32-bit float RGB, plus AOV channels
//!   (`albedo.R/G/B`, `normal.X/Y/Z`, `depth.Z`) when the image has them;
//! - [`read_rgb_image`]: Radiance `.hdr` or OpenEXR `.exr` (first RGB(A)
//!   layer) as linear RGB, for environment maps.
//!
//! Every writer goes through [`atomic_write`]: the file is written to a
//! temporary file in the destination directory and renamed into place only
//! when complete, so a failure never leaves a half-written image.
#![warn(missing_docs)]

use isolux_core::color::srgb_encode;
use isolux_core::Image;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// I/O errors, each naming the file.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// File system error.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// Encoding or decoding error.
    #[error("{path}: {message}")]
    Format {
        /// File.
        path: PathBuf,
        /// Cause.
        message: String,
    },
}

fn format_err(path: &Path, message: impl std::fmt::Display) -> IoError {
    IoError::Format {
        path: path.to_path_buf(),
        message: message.to_string(),
    }
}

/// Output formats recognized by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputFormat {
    /// `.png`
    Png,
    /// `.exr`
    Exr,
}

impl OutputFormat {
    /// From a path's extension (case-insensitive).
    pub fn from_path(path: &Path) -> Option<Self> {
        match path.extension()?.to_str()?.to_ascii_lowercase().as_str() {
            "png" => Some(Self::Png),
            "exr" => Some(Self::Exr),
            _ => None,
        }
    }
}

/// Tone mapping applied before sRGB encoding for 8-bit output. Exposure
/// scales linear values by `2^exposure` first.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Tonemap {
    /// Clip each channel to `[0, 1]` (faithful for values <= 1; the default,
    /// so a reflectance of 0.5 under unit light encodes as sRGB(0.5)).
    #[default]
    Clamp,
    /// Luminance Reinhard: `L' = L / (1 + L)`, colour scaled by `L'/L`,
    /// then clipped; compresses highlights without shifting hue.
    Reinhard,
}

impl Tonemap {
    /// Maps one linear pixel (after exposure) to display-linear `[0, 1]`.
    pub fn apply(self, c: [f64; 3]) -> [f64; 3] {
        match self {
            Tonemap::Clamp => c.map(|v| v.clamp(0.0, 1.0)),
            Tonemap::Reinhard => {
                let l = 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
                if !(l > 0.0) {
                    return [0.0; 3];
                }
                let s = (l / (1.0 + l)) / l;
                c.map(|v| (v * s).clamp(0.0, 1.0))
            }
        }
    }
}

/// Checks, before any long work, that `path` can be written the way
/// [`atomic_write`] will write it: its directory exists and takes a new
/// file (one is created there and removed at once), and `path` itself is
/// not a directory. Commands call it first, so that a typo in `-o` fails
/// in a second instead of after the render.
pub fn check_output(path: &Path) -> Result<(), IoError> {
    let dir = output_dir(path);
    let fail = |message: String| {
        Err(IoError::Format {
            path: path.to_path_buf(),
            message,
        })
    };
    if !dir.is_dir() {
        return fail(format!(
            "cannot write here: the directory {} does not exist",
            dir.display()
        ));
    }
    if path.is_dir() {
        return fail("is a directory; give a file name".into());
    }
    if let Err(e) = tempfile::Builder::new()
        .prefix(".isolux-")
        .suffix(".tmp")
        .tempfile_in(&dir)
    {
        return fail(format!(
            "cannot create a file in {}: {}",
            dir.display(),
            std::io::Error::from(e.kind())
        ));
    }
    Ok(())
}

/// The directory a file is written into (`.` for a bare file name).
fn output_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Writes via a temporary file in the same directory, then renames.
pub fn atomic_write(
    path: &Path,
    write: impl FnOnce(&mut std::fs::File) -> Result<(), IoError>,
) -> Result<(), IoError> {
    let io = |source| IoError::Io {
        path: path.to_path_buf(),
        source,
    };
    let dir = output_dir(path);
    let mut tmp = tempfile::Builder::new()
        .prefix(".isolux-")
        .suffix(".tmp")
        .tempfile_in(&dir)
        .map_err(io)?;
    write(tmp.as_file_mut())?;
    tmp.as_file_mut().sync_all().map_err(io)?;
    // Temporary files are created private (0600); an image is not. Keep the
    // permissions of a file being replaced, else use the usual 0644.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(path)
            .map(|m| m.permissions().mode() & 0o7777)
            .unwrap_or(0o644);
        std::fs::set_permissions(tmp.path(), std::fs::Permissions::from_mode(mode)).map_err(io)?;
    }
    tmp.persist(path).map_err(|e| io(e.error))?;
    Ok(())
}

/// 8-bit sRGB bytes of an image after exposure and tone mapping.
pub fn to_srgb8(image: &Image, exposure: f64, tonemap: Tonemap) -> Vec<u8> {
    let k = 2f64.powf(exposure);
    let mut out = Vec::with_capacity(image.rgb.len() * 3);
    for p in &image.rgb {
        let c = tonemap.apply([p[0] as f64 * k, p[1] as f64 * k, p[2] as f64 * k]);
        for v in c {
            out.push((srgb_encode(v) * 255.0 + 0.5).floor().clamp(0.0, 255.0) as u8);
        }
    }
    out
}

/// Writes an 8-bit sRGB PNG.
pub fn write_png(
    path: &Path,
    image: &Image,
    exposure: f64,
    tonemap: Tonemap,
) -> Result<(), IoError> {
    let bytes = to_srgb8(image, exposure, tonemap);
    atomic_write(path, |f| {
        let mut w = BufWriter::new(f);
        image::write_buffer_with_format(
            &mut w,
            &bytes,
            image.width,
            image.height,
            image::ExtendedColorType::Rgb8,
            image::ImageFormat::Png,
        )
        .map_err(|e| format_err(path, e))?;
        w.flush().map_err(|source| IoError::Io {
            path: path.to_path_buf(),
            source,
        })
    })
}

/// How every OpenEXR file Isolux writes is encoded: exr's fast lossless
/// compression, with its blocks in increasing order. (exr's own
/// `FAST_LOSSLESS` leaves the order unspecified, and its parallel
/// compressor then writes each block as soon as it is compressed: the same
/// image gave files of different bytes from run to run, which broke
/// comparing renders by checksum. The sorted order costs a buffer of the
/// compressed blocks while writing, a few MB at 1080p.)
pub const EXR_ENCODING: exr::prelude::Encoding = exr::prelude::Encoding {
    line_order: exr::prelude::LineOrder::Increasing,
    ..exr::prelude::Encoding::FAST_LOSSLESS
};

/// Writes linear float RGB (and AOVs, if present) to OpenEXR.
pub fn write_exr(path: &Path, image: &Image) -> Result<(), IoError> {
    use exr::prelude::*;
    let plane = |k: usize| -> Vec<f32> { image.rgb.iter().map(|p| p[k]).collect() };
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    list.push(AnyChannel::new("R", FlatSamples::F32(plane(0))));
    list.push(AnyChannel::new("G", FlatSamples::F32(plane(1))));
    list.push(AnyChannel::new("B", FlatSamples::F32(plane(2))));
    if let Some(aov) = &image.aov {
        for (k, c) in ["R", "G", "B"].iter().enumerate() {
            let v: Vec<f32> = aov.albedo.iter().map(|p| p[k]).collect();
            list.push(AnyChannel::new(
                format!("albedo.{c}").as_str(),
                FlatSamples::F32(v),
            ));
        }
        for (k, c) in ["X", "Y", "Z"].iter().enumerate() {
            let v: Vec<f32> = aov.normal.iter().map(|p| p[k]).collect();
            list.push(AnyChannel::new(
                format!("normal.{c}").as_str(),
                FlatSamples::F32(v),
            ));
        }
        list.push(AnyChannel::new(
            "depth.Z",
            FlatSamples::F32(aov.depth.clone()),
        ));
    }
    let layer = Layer::new(
        (image.width as usize, image.height as usize),
        LayerAttributes::default(),
        EXR_ENCODING,
        AnyChannels::sort(list),
    );
    let img = exr::image::Image::from_layer(layer);
    atomic_write(path, |f| {
        img.write()
            .to_buffered(BufWriter::new(f))
            .map_err(|e| format_err(path, e))
    })
}

/// Writes `.png` or `.exr` by extension.
pub fn write_image(
    path: &Path,
    image: &Image,
    exposure: f64,
    tonemap: Tonemap,
) -> Result<(), IoError> {
    match OutputFormat::from_path(path) {
        Some(OutputFormat::Png) => write_png(path, image, exposure, tonemap),
        Some(OutputFormat::Exr) => write_exr(path, image),
        None => Err(format_err(
            path,
            "unknown output format: use a .png or .exr file name",
        )),
    }
}

/// A linear RGB raster read from a file (row 0 at the top).
#[derive(Clone, Debug)]
pub struct RgbImage {
    /// Width.
    pub width: usize,
    /// Height.
    pub height: usize,
    /// Row-major pixels.
    pub pixels: Vec<[f32; 3]>,
}

/// Reads a Radiance `.hdr` or OpenEXR `.exr` file as linear RGB.
pub fn read_rgb_image(path: &Path) -> Result<RgbImage, IoError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    if !path.exists() {
        return Err(IoError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::NotFound, "file not found"),
        });
    }
    match ext.as_deref() {
        Some("exr") => {
            let img = exr::prelude::read_first_rgba_layer_from_file(
                path,
                |res, _| RgbImage {
                    width: res.width(),
                    height: res.height(),
                    pixels: vec![[0.0; 3]; res.width() * res.height()],
                },
                |img: &mut RgbImage, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                    let w = img.width;
                    img.pixels[pos.y() * w + pos.x()] = [r, g, b];
                },
            )
            .map_err(|e| format_err(path, e))?;
            Ok(img.layer_data.channel_data.pixels)
        }
        Some("hdr") => {
            let dynimg = image::ImageReader::open(path)
                .map_err(|source| IoError::Io {
                    path: path.to_path_buf(),
                    source,
                })?
                .with_guessed_format()
                .map_err(|source| IoError::Io {
                    path: path.to_path_buf(),
                    source,
                })?
                .decode()
                .map_err(|e| match &e {
                    // Std's words for it are "failed to fill whole buffer".
                    image::ImageError::IoError(io)
                        if io.kind() == std::io::ErrorKind::UnexpectedEof =>
                    {
                        format_err(path, "the file ends early (truncated?)")
                    }
                    _ => format_err(path, e),
                })?;
            let rgb = dynimg.to_rgb32f();
            let (w, h) = rgb.dimensions();
            Ok(RgbImage {
                width: w as usize,
                height: h as usize,
                pixels: rgb.pixels().map(|p| p.0).collect(),
            })
        }
        _ => Err(format_err(
            path,
            "unsupported image format: use .hdr or .exr",
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use isolux_core::Aovs;

    fn sample_image(aov: bool) -> Image {
        let (w, h) = (5u32, 3u32);
        let n = (w * h) as usize;
        Image {
            width: w,
            height: h,
            rgb: (0..n).map(|i| [i as f32, 0.5, 2.0]).collect(),
            aov: aov.then(|| Aovs {
                albedo: vec![[0.1, 0.2, 0.3]; n],
                normal: vec![[0.0, 1.0, 0.0]; n],
                depth: (0..n).map(|i| i as f32 * 0.25).collect(),
            }),
        }
    }

    #[test]
    fn exr_round_trip_rgb() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.exr");
        let img = sample_image(true);
        write_exr(&p, &img).unwrap();
        let back = read_rgb_image(&p).unwrap();
        assert_eq!((back.width, back.height), (5, 3));
        assert_eq!(back.pixels, img.rgb);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&p).unwrap().permissions().mode() & 0o777;
            assert_eq!(mode, 0o644, "images are world-readable");
        }
        // Only the final file remains: no temporary left behind.
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 1);
    }

    /// The same image gives the same bytes every time it is written: its
    /// blocks in increasing order (`EXR_ENCODING`), not in the order exr's
    /// threads finished compressing them. An image of many blocks whose
    /// compression takes varied time (noise beside flat areas), written
    /// eight times; with the order unspecified, the shallows example at 96
    /// x 54 gave two different files in ten renders on 2 cores.
    #[test]
    fn exr_files_are_the_same_bytes_every_time() {
        let (width, height) = (640u32, 384u32);
        let mut state = 1u64;
        let rgb = (0..width * height)
            .map(|i| {
                if (i % width) < width / 2 {
                    return [0.25, 0.5, 1.0];
                }
                let mut next = || {
                    state = state
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    (state >> 40) as f32 / (1u64 << 24) as f32
                };
                [next(), next(), next()]
            })
            .collect();
        let img = Image {
            width,
            height,
            rgb,
            aov: None,
        };
        let dir = tempfile::tempdir().unwrap();
        let first = dir.path().join("0.exr");
        write_exr(&first, &img).unwrap();
        let meta = exr::meta::MetaData::read_from_file(&first, false).unwrap();
        assert_eq!(
            meta.headers[0].line_order,
            exr::meta::attribute::LineOrder::Increasing
        );
        let bytes = std::fs::read(&first).unwrap();
        for k in 1..8 {
            let p = dir.path().join(format!("{k}.exr"));
            write_exr(&p, &img).unwrap();
            assert!(std::fs::read(&p).unwrap() == bytes, "write {k} differs");
        }
        assert_eq!(read_rgb_image(&first).unwrap().pixels, img.rgb);
    }

    #[test]
    fn png_encodes_srgb() {
        let img = Image {
            width: 1,
            height: 1,
            rgb: vec![[0.5, 0.0, 4.0]],
            aov: None,
        };
        let b = to_srgb8(&img, 0.0, Tonemap::Clamp);
        assert_eq!(b, vec![188, 0, 255]); // sRGB(0.5) = 0.7354 -> 188
        let b = to_srgb8(&img, -1.0, Tonemap::Clamp);
        assert_eq!(b[0], 137); // 0.25 -> 0.5371
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.png");
        write_png(&p, &img, 0.0, Tonemap::Reinhard).unwrap();
        assert!(std::fs::metadata(&p).unwrap().len() > 0);
    }

    #[test]
    fn failed_write_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("y.png");
        let r = atomic_write(&p, |_| Err(format_err(&p, "boom")));
        assert!(r.is_err());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn output_checks_fail_before_the_work_and_leave_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let ok = dir.path().join("out.png");
        check_output(&ok).unwrap();
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        let missing = dir.path().join("no/such/dir/out.png");
        let e = check_output(&missing).unwrap_err().to_string();
        assert!(
            e.contains("does not exist") && e.contains("no/such/dir"),
            "{e}"
        );
        let e = check_output(dir.path()).unwrap_err().to_string();
        assert!(e.contains("is a directory"), "{e}");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let ro = dir.path().join("ro");
            std::fs::create_dir(&ro).unwrap();
            std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
            // Root may write anyway; the check must then agree with a write.
            let r = check_output(&ro.join("out.png"));
            let writable = std::fs::File::create(ro.join("probe")).is_ok();
            assert_eq!(r.is_ok(), writable, "{r:?}");
            if let Err(e) = r {
                assert!(e.to_string().contains("cannot create a file"), "{e}");
            }
        }
    }

    #[test]
    fn missing_and_unknown_files_are_clear_errors() {
        let e = read_rgb_image(Path::new("/nonexistent/sky.hdr")).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/sky.hdr"));
        let e = write_image(
            Path::new("out.jpg"),
            &sample_image(false),
            0.0,
            Tonemap::Clamp,
        )
        .unwrap_err();
        assert!(e.to_string().contains(".png or .exr"));
    }

    #[test]
    fn a_truncated_hdr_says_so() {
        // The example sky cut short: it read "failed to fill whole buffer".
        let sky = std::fs::read(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../examples/env/sky.hdr"
        ))
        .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let cut = dir.path().join("cut.hdr");
        std::fs::write(&cut, &sky[..sky.len() / 2]).unwrap();
        let e = read_rgb_image(&cut).unwrap_err().to_string();
        assert!(
            e.contains("cut.hdr") && e.contains("the file ends early (truncated?)"),
            "{e}"
        );
        assert!(read_rgb_image(Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../examples/env/sky.hdr"
        )))
        .is_ok());
    }
}
