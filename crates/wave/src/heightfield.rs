//! Heightfields: micron-scale surface heights on a periodic texel grid.
//!
//! Texel (column `c`, row `r`) holds the height (um) at
//! `s = ((c + 1/2) w, (r + 1/2) w)` um, `w` the texel size: x along
//! columns, y along rows. The field tiles the plane periodically.
//!
//! # Files
//! | format | how heights are read |
//! |---|---|
//! | `.exr` | a channel named `Y`, `H` or `height`, else the luminance of `R`, `G`, `B`, else the first channel; half or float; heights in um; the texel size from the header attribute `isolux.texel_um` when present |
//! | `.png` | 16-bit grey: `value / 65535` (so 0..1), times the vertical scale |
//! | `.raw`, `.f32`, `.bin` | little-endian f32, row-major, width and height given |
//!
//! Every height is multiplied by the vertical scale (default 1). Memory: 4
//! bytes per texel here, 12 more for the Gabor kernels' slopes and heights
//! ([`crate::GaborSurface`]): 8192 x 8192 costs about 1.1 GiB in all.

use std::path::{Path, PathBuf};

/// Errors loading or writing heightfields, each naming the file.
#[derive(Debug, thiserror::Error)]
pub enum HeightfieldError {
    /// The file could not be read or decoded.
    #[error("{path}: {msg}")]
    File {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        msg: String,
    },
    /// A parameter is out of range.
    #[error("{0}")]
    Invalid(String),
}

fn file_err(path: &Path, msg: impl std::fmt::Display) -> HeightfieldError {
    HeightfieldError::File {
        path: path.to_path_buf(),
        msg: msg.to_string(),
    }
}

/// Largest number of texels accepted (8192 x 8192 times 4).
pub const MAX_TEXELS: usize = 1 << 28;

/// A periodic heightfield.
#[derive(Clone, Debug, PartialEq)]
pub struct Heightfield {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Texel size (um).
    pub texel_um: f64,
    /// Row-major heights (um).
    pub heights: Vec<f32>,
}

/// How to read a heightfield file.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadOptions {
    /// Texel size (um); overrides the file's own. Default: the EXR header's
    /// `isolux.texel_um`, else 1 um.
    pub texel_um: Option<f64>,
    /// Vertical scale applied to every height (default 1).
    pub vertical_scale: f64,
    /// Width and height of a raw f32 file.
    pub raw_size: Option<(usize, usize)>,
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self {
            texel_um: None,
            vertical_scale: 1.0,
            raw_size: None,
        }
    }
}

/// The EXR header attribute holding the texel size (um).
pub const TEXEL_ATTRIBUTE: &str = "isolux.texel_um";

impl Heightfield {
    /// A field from heights, checked: positive sizes, finite heights,
    /// positive finite texel size.
    pub fn new(
        width: usize,
        height: usize,
        texel_um: f64,
        heights: Vec<f32>,
    ) -> Result<Self, HeightfieldError> {
        if width == 0 || height == 0 {
            return Err(HeightfieldError::Invalid(format!(
                "heightfield size {width} x {height} is empty"
            )));
        }
        if width.saturating_mul(height) > MAX_TEXELS {
            return Err(HeightfieldError::Invalid(format!(
                "heightfield size {width} x {height} exceeds {MAX_TEXELS} texels"
            )));
        }
        if heights.len() != width * height {
            return Err(HeightfieldError::Invalid(format!(
                "{} heights for a {width} x {height} field",
                heights.len()
            )));
        }
        check_texel(texel_um)?;
        if let Some(i) = heights.iter().position(|h| !h.is_finite()) {
            return Err(HeightfieldError::Invalid(format!(
                "height at column {}, row {} is {} (heights must be finite)",
                i % width,
                i / width,
                heights[i]
            )));
        }
        Ok(Self {
            width,
            height,
            texel_um,
            heights,
        })
    }

    /// Height (um) of texel `(c, r)`, wrapped periodically.
    pub fn at(&self, c: i64, r: i64) -> f32 {
        let c = c.rem_euclid(self.width as i64) as usize;
        let r = r.rem_euclid(self.height as i64) as usize;
        self.heights[r * self.width + c]
    }

    /// Height (um) at a point `s` (um), bilinear between texel centres,
    /// periodic.
    pub fn bilinear(&self, s: [f64; 2]) -> f64 {
        let x = s[0] / self.texel_um - 0.5;
        let y = s[1] / self.texel_um - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (c, r) = (x0 as i64, y0 as i64);
        let h = |dc, dr| self.at(c + dc, r + dr) as f64;
        (h(0, 0) * (1.0 - fx) + h(1, 0) * fx) * (1.0 - fy)
            + (h(0, 1) * (1.0 - fx) + h(1, 1) * fx) * fy
    }

    /// Root-mean-square height about the mean (um).
    pub fn rms(&self) -> f64 {
        let n = self.heights.len() as f64;
        let mean = self.heights.iter().map(|&h| h as f64).sum::<f64>() / n;
        (self
            .heights
            .iter()
            .map(|&h| (h as f64 - mean).powi(2))
            .sum::<f64>()
            / n)
            .sqrt()
    }

    /// Reads a heightfield file (see the module docs).
    pub fn load(path: &Path, opts: &LoadOptions) -> Result<Self, HeightfieldError> {
        if !(opts.vertical_scale.is_finite()) {
            return Err(HeightfieldError::Invalid(format!(
                "vertical scale {} is not finite",
                opts.vertical_scale
            )));
        }
        if let Some(t) = opts.texel_um {
            check_texel(t)?;
        }
        if !path.exists() {
            return Err(file_err(path, "file not found"));
        }
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        let (w, h, mut data, file_texel) = match ext.as_deref() {
            Some("exr") => read_exr(path)?,
            Some("png") => read_png(path)?,
            Some("raw" | "f32" | "bin") => {
                let Some((w, h)) = opts.raw_size else {
                    return Err(file_err(
                        path,
                        "a raw f32 heightfield needs its width and height",
                    ));
                };
                read_raw(path, w, h)?
            }
            _ => {
                return Err(file_err(
                    path,
                    "unknown heightfield format: use .exr, 16-bit .png or raw .f32",
                ))
            }
        };
        if opts.vertical_scale != 1.0 {
            let s = opts.vertical_scale as f32;
            data.iter_mut().for_each(|v| *v *= s);
        }
        let texel = opts.texel_um.or(file_texel).unwrap_or(1.0);
        Self::new(w, h, texel, data).map_err(|e| file_err(path, e))
    }

    /// Writes the field as a one-channel (`Y`) float EXR with the texel
    /// size in the header, atomically.
    pub fn write_exr(&self, path: &Path) -> Result<(), HeightfieldError> {
        use exr::prelude::*;
        let channels = AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new(
            "Y",
            FlatSamples::F32(self.heights.clone()),
        )]));
        let mut attrs = LayerAttributes::named("heightfield");
        attrs.other.insert(
            Text::from(TEXEL_ATTRIBUTE),
            AttributeValue::F32(self.texel_um as f32),
        );
        let layer = Layer::new(
            (self.width, self.height),
            attrs,
            isolux_io::EXR_ENCODING,
            channels,
        );
        let img = exr::image::Image::from_layer(layer);
        isolux_io::atomic_write(path, |f| {
            img.write()
                .to_buffered(std::io::BufWriter::new(f))
                .map_err(|e| isolux_io::IoError::Format {
                    path: path.to_path_buf(),
                    message: e.to_string(),
                })
        })
        .map_err(|e| HeightfieldError::Invalid(e.to_string()))
    }
}

fn check_texel(t: f64) -> Result<(), HeightfieldError> {
    if !(t > 0.0) || !t.is_finite() {
        return Err(HeightfieldError::Invalid(format!(
            "texel size {t} um must be positive and finite"
        )));
    }
    Ok(())
}

type Raw = (usize, usize, Vec<f32>, Option<f64>);

fn read_exr(path: &Path) -> Result<Raw, HeightfieldError> {
    use exr::prelude::*;
    let img = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| file_err(path, e))?;
    let layer = &img.layer_data;
    let (w, h) = (layer.size.width(), layer.size.height());
    let chans = &layer.channel_data.list;
    let find = |name: &str| chans.iter().find(|c| c.name.eq_case_insensitive(name));
    let to_vec =
        |c: &AnyChannel<FlatSamples>| -> Vec<f32> { c.sample_data.values_as_f32().collect() };
    let data = if let Some(c) = find("Y").or_else(|| find("H")).or_else(|| find("height")) {
        to_vec(c)
    } else if let (Some(r), Some(g), Some(b)) = (find("R"), find("G"), find("B")) {
        let (r, g, b) = (to_vec(r), to_vec(g), to_vec(b));
        (0..w * h)
            .map(|i| 0.2126 * r[i] + 0.7152 * g[i] + 0.0722 * b[i])
            .collect()
    } else if let Some(c) = chans.first() {
        to_vec(c)
    } else {
        return Err(file_err(path, "the EXR file has no channels"));
    };
    let texel = layer
        .attributes
        .other
        .get(&Text::from(TEXEL_ATTRIBUTE))
        .and_then(|v| match v {
            AttributeValue::F32(x) => Some(*x as f64),
            AttributeValue::F64(x) => Some(*x),
            _ => None,
        });
    Ok((w, h, data, texel))
}

fn read_png(path: &Path) -> Result<Raw, HeightfieldError> {
    let img = image::ImageReader::open(path)
        .map_err(|e| file_err(path, e))?
        .with_guessed_format()
        .map_err(|e| file_err(path, e))?
        .decode()
        .map_err(|e| file_err(path, e))?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let data = match img {
        image::DynamicImage::ImageLuma16(g) => {
            g.pixels().map(|p| p.0[0] as f32 / 65535.0).collect()
        }
        image::DynamicImage::ImageLumaA16(g) => {
            g.pixels().map(|p| p.0[0] as f32 / 65535.0).collect()
        }
        other => {
            return Err(file_err(
                path,
                format!(
                    "a PNG heightfield must be 16-bit greyscale, this one is {:?}",
                    other.color()
                ),
            ))
        }
    };
    Ok((w, h, data, None))
}

fn read_raw(path: &Path, w: usize, h: usize) -> Result<Raw, HeightfieldError> {
    if w == 0 || h == 0 || w.saturating_mul(h) > MAX_TEXELS {
        return Err(file_err(path, format!("invalid raw size {w} x {h}")));
    }
    let bytes = std::fs::read(path).map_err(|e| file_err(path, e))?;
    if bytes.len() != w * h * 4 {
        return Err(file_err(
            path,
            format!(
                "{} bytes, but {w} x {h} f32 heights need {}",
                bytes.len(),
                w * h * 4
            ),
        ));
    }
    let data = bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    Ok((w, h, data, None))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field() -> Heightfield {
        let (w, h) = (7, 5);
        let d = (0..w * h).map(|i| (i as f32 * 0.37).sin()).collect();
        Heightfield::new(w, h, 0.5, d).unwrap()
    }

    #[test]
    fn exr_round_trip_keeps_texel_size() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("h.exr");
        let f = field();
        f.write_exr(&p).unwrap();
        let back = Heightfield::load(&p, &LoadOptions::default()).unwrap();
        assert_eq!(back, f);
        let scaled = Heightfield::load(
            &p,
            &LoadOptions {
                texel_um: Some(2.0),
                vertical_scale: 2.0,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(scaled.texel_um, 2.0);
        assert_eq!(scaled.heights[3], 2.0 * f.heights[3]);
    }

    #[test]
    fn png16_and_raw() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("h.png");
        let img = image::ImageBuffer::<image::Luma<u16>, _>::from_fn(4, 3, |x, y| {
            image::Luma([(x * 1000 + y * 20000) as u16])
        });
        img.save(&p).unwrap();
        let f = Heightfield::load(
            &p,
            &LoadOptions {
                vertical_scale: 0.5,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!((f.width, f.height, f.texel_um), (4, 3, 1.0));
        assert!((f.heights[4 + 1] as f64 - 21000.0 / 65535.0 * 0.5).abs() < 1e-6);
        // 8-bit PNGs are refused.
        let p8 = dir.path().join("h8.png");
        image::GrayImage::new(2, 2).save(&p8).unwrap();
        let e = Heightfield::load(&p8, &LoadOptions::default()).unwrap_err();
        assert!(e.to_string().contains("16-bit"), "{e}");
        // Raw f32.
        let pr = dir.path().join("h.f32");
        let vals: Vec<u8> = (0..6).flat_map(|i| (i as f32).to_le_bytes()).collect();
        std::fs::write(&pr, &vals).unwrap();
        let opts = LoadOptions {
            raw_size: Some((3, 2)),
            ..Default::default()
        };
        let f = Heightfield::load(&pr, &opts).unwrap();
        assert_eq!(f.heights, vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
        let bad = LoadOptions {
            raw_size: Some((4, 2)),
            ..Default::default()
        };
        let e = Heightfield::load(&pr, &bad).unwrap_err().to_string();
        assert!(e.contains("h.f32") && e.contains("24 bytes"), "{e}");
    }

    #[test]
    fn bad_input_is_a_clear_error() {
        let e = Heightfield::new(2, 1, 1.0, vec![0.0, f32::NAN]).unwrap_err();
        assert!(e.to_string().contains("column 1, row 0"), "{e}");
        assert!(Heightfield::new(1, 1, 0.0, vec![0.0]).is_err());
        assert!(Heightfield::new(1, 1, f64::NAN, vec![0.0]).is_err());
        let e = Heightfield::load(Path::new("/nope/h.exr"), &LoadOptions::default()).unwrap_err();
        assert!(e.to_string().contains("/nope/h.exr"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("corrupt.exr");
        std::fs::write(&p, b"not an exr").unwrap();
        let e = Heightfield::load(&p, &LoadOptions::default()).unwrap_err();
        assert!(e.to_string().contains("corrupt.exr"), "{e}");
    }

    #[test]
    fn bilinear_hits_texel_centres_and_wraps() {
        let f = field();
        let w = f.texel_um;
        assert!((f.bilinear([2.5 * w, 1.5 * w]) - f.at(2, 1) as f64).abs() < 1e-6);
        assert!((f.bilinear([(2.5 + 7.0) * w, (1.5 - 5.0) * w]) - f.at(2, 1) as f64).abs() < 1e-5);
        let mid = f.bilinear([3.0 * w, 1.5 * w]);
        assert!((mid - 0.5 * (f.at(2, 1) + f.at(3, 1)) as f64).abs() < 1e-6);
    }
}
