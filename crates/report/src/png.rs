//! The size of a PNG image from its header (the report embeds PNG bytes as they are and
//! needs only their size to place labels over them).

/// The eight bytes every PNG file starts with.
const SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a];

/// Bytes up to the end of the header's height field: signature, chunk length, `IHDR`,
/// width, height.
const HEADER_LEN: usize = 24;

/// Bytes that are not a usable PNG image.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PngError {
    #[error("not a PNG image (the first bytes are not the PNG signature and header)")]
    NotPng,
    #[error("the PNG image is empty ({width} x {height} pixels)")]
    Empty { width: u32, height: u32 },
}

/// Width and height of an image (pixels).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PngSize {
    pub width: u32,
    pub height: u32,
}

impl PngSize {
    /// Reads the size from the `IHDR` chunk, which a PNG file must start with.
    pub fn read(png: &[u8]) -> Result<PngSize, PngError> {
        if png.len() < HEADER_LEN || png[..8] != SIGNATURE || &png[12..16] != b"IHDR" {
            return Err(PngError::NotPng);
        }
        let field =
            |at: usize| u32::from_be_bytes([png[at], png[at + 1], png[at + 2], png[at + 3]]);
        let (width, height) = (field(16), field(20));
        if width == 0 || height == 0 {
            return Err(PngError::Empty { width, height });
        }
        Ok(PngSize { width, height })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(width: u32, height: u32) -> Vec<u8> {
        let mut bytes = SIGNATURE.to_vec();
        bytes.extend(13u32.to_be_bytes());
        bytes.extend(b"IHDR");
        bytes.extend(width.to_be_bytes());
        bytes.extend(height.to_be_bytes());
        bytes
    }

    #[test]
    fn reads_the_size_and_rejects_other_bytes() {
        assert_eq!(
            PngSize::read(&header(640, 480)),
            Ok(PngSize {
                width: 640,
                height: 480
            })
        );
        assert_eq!(
            PngSize::read(b"GIF89a....................."),
            Err(PngError::NotPng)
        );
        assert_eq!(
            PngSize::read(&header(640, 480)[..20]),
            Err(PngError::NotPng)
        );
        assert_eq!(
            PngSize::read(&header(0, 480)),
            Err(PngError::Empty {
                width: 0,
                height: 480
            })
        );
    }
}
