//! Image files: PNG frames (png crate) and an animated GIF (gif crate) whose frames are
//! mapped onto a fixed 6×7×6 colour cube with ordered dithering, which is fast (no
//! per-frame palette search) and keeps the sphere shading smooth.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

/// Levels of the palette's colour cube per channel (R, G, B).
const LEVELS: [u32; 3] = [6, 7, 6];

/// 4×4 Bayer matrix, thresholds in sixteenths.
const BAYER: [[u8; 4]; 4] = [[0, 8, 2, 10], [12, 4, 14, 6], [3, 11, 1, 9], [15, 7, 13, 5]];

/// Writes RGBA pixels as an 8-bit RGB PNG.
pub fn write_png(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<(), String> {
    let file =
        File::create(path).map_err(|e| format!("cannot create `{}`: {e}", path.display()))?;
    let mut encoder = png::Encoder::new(BufWriter::new(file), width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Fast);
    let rgb: Vec<u8> = rgba
        .chunks_exact(4)
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect();
    encoder
        .write_header()
        .and_then(|mut w| w.write_image_data(&rgb))
        .map_err(|e| format!("cannot write `{}`: {e}", path.display()))
}

/// The colour cube palette as RGB triples.
fn palette() -> Vec<u8> {
    let mut out = Vec::with_capacity(256 * 3);
    for r in 0..LEVELS[0] {
        for g in 0..LEVELS[1] {
            for b in 0..LEVELS[2] {
                for (v, n) in [(r, LEVELS[0]), (g, LEVELS[1]), (b, LEVELS[2])] {
                    out.push((v * 255 / (n - 1)) as u8);
                }
            }
        }
    }
    out
}

/// Palette index of an RGBA pixel at `(x, y)`, with ordered dithering.
#[inline]
fn index_of(p: &[u8], x: usize, y: usize) -> u8 {
    let t = BAYER[y & 3][x & 3] as u32;
    let mut level = [0u32; 3];
    for c in 0..3 {
        let steps = LEVELS[c] - 1;
        // value in sixteenths of a palette step, plus the dither threshold
        let scaled = p[c] as u32 * steps * 16 / 255 + t;
        level[c] = (scaled / 16).min(steps);
    }
    ((level[0] * LEVELS[1] + level[1]) * LEVELS[2] + level[2]) as u8
}

/// An animated GIF being written frame by frame.
pub struct GifWriter {
    encoder: gif::Encoder<BufWriter<File>>,
    width: u16,
    height: u16,
    delay: u16,
}

impl GifWriter {
    /// Starts a looping GIF; `delay` is the time between frames in hundredths of a second.
    pub fn create(path: &Path, width: u32, height: u32, delay: u16) -> Result<Self, String> {
        let too_big = |_| format!("image too large for a GIF: {width}×{height}");
        let (w, h) = (
            u16::try_from(width).map_err(too_big)?,
            u16::try_from(height).map_err(too_big)?,
        );
        let file =
            File::create(path).map_err(|e| format!("cannot create `{}`: {e}", path.display()))?;
        let mut encoder = gif::Encoder::new(BufWriter::new(file), w, h, &palette())
            .map_err(|e| format!("cannot write `{}`: {e}", path.display()))?;
        encoder
            .set_repeat(gif::Repeat::Infinite)
            .map_err(|e| format!("cannot write `{}`: {e}", path.display()))?;
        Ok(Self {
            encoder,
            width: w,
            height: h,
            delay,
        })
    }

    /// Appends a frame of RGBA pixels (`width × height`).
    pub fn add_frame(&mut self, rgba: &[u8]) -> Result<(), String> {
        let width = self.width as usize;
        let indices: Vec<u8> = rgba
            .chunks_exact(4)
            .enumerate()
            .map(|(i, p)| index_of(p, i % width, i / width))
            .collect();
        let mut frame = gif::Frame::from_indexed_pixels(self.width, self.height, indices, None);
        frame.delay = self.delay;
        self.encoder
            .write_frame(&frame)
            .map_err(|e| format!("cannot write GIF frame: {e}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn palette_maps_primaries_and_greys_exactly() {
        let pal = palette();
        assert_eq!(pal.len(), 6 * 7 * 6 * 3);
        for rgb in [[0u8, 0, 0], [255, 255, 255], [255, 0, 0], [0, 0, 255]] {
            let i = index_of(&[rgb[0], rgb[1], rgb[2], 255], 0, 0) as usize;
            assert_eq!(&pal[i * 3..i * 3 + 3], &rgb);
        }
        // dithering keeps the mean: a flat mid grey averages back to itself
        let grey = [128u8, 128, 128, 255];
        let mean: f32 = (0..16)
            .map(|k| pal[index_of(&grey, k % 4, k / 4) as usize * 3] as f32)
            .sum::<f32>()
            / 16.0;
        assert!((mean - 128.0).abs() < 10.0, "{mean}");
    }
}
