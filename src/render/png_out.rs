//! Pictures as pixels: the image read back from the device, the colour bar drawn into it, and
//! PNG files written with the `png` crate.

use std::io::BufWriter;
use std::path::Path;

use crate::error::{Error, Result};
use crate::surface::colour::viridis;

/// An RGBA8 picture, rows from the top.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Four bytes per pixel, row after row.
    pub rgba: Vec<u8>,
}

impl Image {
    /// The pixel at column `x`, row `y` (from the top).
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        let i = 4 * (y as usize * self.width as usize + x as usize);
        [
            self.rgba[i],
            self.rgba[i + 1],
            self.rgba[i + 2],
            self.rgba[i + 3],
        ]
    }

    /// Set the pixel at column `x`, row `y`.
    pub fn set(&mut self, x: u32, y: u32, rgba: [u8; 4]) {
        let i = 4 * (y as usize * self.width as usize + x as usize);
        self.rgba[i..i + 4].copy_from_slice(&rgba);
    }
}

/// The colour bar's rectangle in a picture of `width` by `height`: columns `x0..x1`, rows
/// `y0..y1` (a strip at the right edge, over the middle 70% of the height).
pub fn legend_rect(width: u32, height: u32) -> [u32; 4] {
    let w = (width / 40).max(4);
    let x1 = width.saturating_sub(w);
    let x0 = x1.saturating_sub(w);
    [x0, x1, height * 3 / 20, height * 17 / 20]
}

/// Draw the colour bar: the displacement colour map from 0 at the bottom to the top of the
/// range at the top, framed in dark grey.
pub fn draw_legend(image: &mut Image) {
    let [x0, x1, y0, y1] = legend_rect(image.width, image.height);
    if x1 <= x0 + 2 || y1 <= y0 + 2 {
        return;
    }
    for y in y0..y1 {
        for x in x0..x1 {
            let frame = x == x0 || x + 1 == x1 || y == y0 || y + 1 == y1;
            let rgba = if frame {
                [60, 60, 60, 255]
            } else {
                let t = (y1 - 1 - y) as f64 / (y1 - y0 - 1) as f64;
                let c = viridis(t);
                [to_byte(c[0]), to_byte(c[1]), to_byte(c[2]), 255]
            };
            image.set(x, y, rgba);
        }
    }
}

/// A colour component in `[0, 1]` as a byte.
pub fn to_byte(c: f32) -> u8 {
    (c.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// Write `image` as an 8-bit RGBA PNG.
pub fn write_png(path: &Path, image: &Image) -> Result<()> {
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut encoder = png::Encoder::new(BufWriter::new(file), image.width, image.height);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Best);
    let fail = |e: png::EncodingError| {
        Error::io(
            path,
            std::io::Error::other(format!("encoding the picture: {e}")),
        )
    };
    let mut writer = encoder.write_header().map_err(fail)?;
    writer.write_image_data(&image.rgba).map_err(fail)?;
    writer.finish().map_err(fail)
}

/// Read an 8-bit RGB or RGBA PNG back (as RGBA), for tests and checks.
pub fn read_png(path: &Path) -> Result<Image> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let fail = |e: png::DecodingError| {
        Error::io(
            path,
            std::io::Error::other(format!("decoding the picture: {e}")),
        )
    };
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .map_err(fail)?;
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).map_err(fail)?;
    buf.truncate(info.buffer_size());
    let rgba = match (info.color_type, info.bit_depth) {
        (png::ColorType::Rgba, png::BitDepth::Eight) => buf,
        (png::ColorType::Rgb, png::BitDepth::Eight) => buf
            .chunks_exact(3)
            .flat_map(|c| [c[0], c[1], c[2], 255])
            .collect(),
        (c, d) => {
            return Err(Error::io(
                path,
                std::io::Error::other(format!("a {c:?} {d:?} PNG; expected 8-bit RGB or RGBA")),
            ))
        }
    };
    Ok(Image {
        width: info.width,
        height: info.height,
        rgba,
    })
}
