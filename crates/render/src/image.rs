//! The rendered picture and its PNG encoding.

use crate::RenderError;

/// An RGBA picture, 8 bits per channel, sRGB, straight (not premultiplied) alpha, rows
/// from the top.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    width: u32,
    height: u32,
    rgba: Vec<u8>,
}

impl Image {
    /// A picture of `width` × `height` pixels (both at least one) filled with `colour`.
    pub(crate) fn filled(width: u32, height: u32, colour: [u8; 4]) -> Image {
        Image {
            width,
            height,
            rgba: colour.repeat(width as usize * height as usize),
        }
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    /// All pixels, four bytes each, row by row.
    pub fn rgba(&self) -> &[u8] {
        &self.rgba
    }

    pub(crate) fn rgba_mut(&mut self) -> &mut [u8] {
        &mut self.rgba
    }

    /// The pixel in column `x`, row `y` (from the top); `None` outside the picture.
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 4]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let start = 4 * (y as usize * self.width as usize + x as usize);
        self.rgba[start..start + 4].try_into().ok()
    }
}

/// The picture as a PNG file's bytes (RGBA, 8 bits).
pub fn encode_png(image: &Image) -> Result<Vec<u8>, RenderError> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, image.width, image.height);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder
        .write_header()
        .map_err(|e| RenderError::Png(e.to_string()))?;
    writer
        .write_image_data(&image.rgba)
        .map_err(|e| RenderError::Png(e.to_string()))?;
    writer
        .finish()
        .map_err(|e| RenderError::Png(e.to_string()))?;
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_round_trips_the_pixels() {
        let mut image = Image::filled(3, 2, [10, 20, 30, 255]);
        image.rgba_mut()[4..8].copy_from_slice(&[200, 100, 0, 128]);
        let bytes = encode_png(&image).unwrap();
        let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes))
            .read_info()
            .unwrap();
        let mut pixels = vec![0; decoder.output_buffer_size().unwrap()];
        let info = decoder.next_frame(&mut pixels).unwrap();
        assert_eq!((info.width, info.height), (3, 2));
        assert_eq!(pixels, image.rgba());
    }
}
