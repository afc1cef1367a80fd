//! Binary data arrays: value types, block headers, base64 and zlib-compressed blocks.

use std::borrow::Cow;

/// The numeric type of a binary data array (its `type` attribute).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Scalar {
    Int8,
    UInt8,
    Int16,
    UInt16,
    Int32,
    UInt32,
    Int64,
    UInt64,
    Float32,
    Float64,
}

impl Scalar {
    pub(super) fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "Int8" => Scalar::Int8,
            "UInt8" => Scalar::UInt8,
            "Int16" => Scalar::Int16,
            "UInt16" => Scalar::UInt16,
            "Int32" => Scalar::Int32,
            "UInt32" => Scalar::UInt32,
            "Int64" => Scalar::Int64,
            "UInt64" => Scalar::UInt64,
            "Float32" => Scalar::Float32,
            "Float64" => Scalar::Float64,
            _ => return None,
        })
    }

    /// Bytes per value.
    pub(super) fn size(self) -> usize {
        match self {
            Scalar::Int8 | Scalar::UInt8 => 1,
            Scalar::Int16 | Scalar::UInt16 => 2,
            Scalar::Int32 | Scalar::UInt32 | Scalar::Float32 => 4,
            Scalar::Int64 | Scalar::UInt64 | Scalar::Float64 => 8,
        }
    }

    /// The values packed in `bytes` (a whole number of them) in the given byte order.
    /// 64-bit integers beyond 2^53 are rounded.
    pub(super) fn values(self, bytes: &[u8], big_endian: bool) -> Vec<f64> {
        macro_rules! convert {
            ($t:ty) => {
                bytes
                    .chunks_exact(std::mem::size_of::<$t>())
                    .map(|chunk| {
                        let mut a = [0u8; std::mem::size_of::<$t>()];
                        a.copy_from_slice(chunk);
                        (if big_endian {
                            <$t>::from_be_bytes(a)
                        } else {
                            <$t>::from_le_bytes(a)
                        }) as f64
                    })
                    .collect()
            };
        }
        match self {
            Scalar::Int8 => convert!(i8),
            Scalar::UInt8 => convert!(u8),
            Scalar::Int16 => convert!(i16),
            Scalar::UInt16 => convert!(u16),
            Scalar::Int32 => convert!(i32),
            Scalar::UInt32 => convert!(u32),
            Scalar::Int64 => convert!(i64),
            Scalar::UInt64 => convert!(u64),
            Scalar::Float32 => convert!(f32),
            Scalar::Float64 => convert!(f64),
        }
    }
}

/// How binary data is laid out, from the `VTKFile` attributes `header_type` (UInt32 or
/// UInt64 block headers), `byte_order` (of headers and values) and `compressor`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Layout {
    pub(super) header_bytes: usize,
    pub(super) big_endian: bool,
    pub(super) zlib: bool,
}

/// Decodes base64 text without whitespace. VTK encodes a block header and its data
/// either as one base64 stream or as two, each padded with `=`; both decode to the same
/// bytes here because every padded 4-character group ends a stream and the next starts
/// afresh.
pub(super) fn base64_decode(chars: &[u8]) -> Result<Vec<u8>, String> {
    use base64::Engine as _;
    use base64::engine::{DecodePaddingMode, GeneralPurpose, GeneralPurposeConfig};
    const ENGINE: GeneralPurpose = GeneralPurpose::new(
        &base64::alphabet::STANDARD,
        GeneralPurposeConfig::new()
            .with_decode_allow_trailing_bits(true)
            .with_decode_padding_mode(DecodePaddingMode::RequireCanonical),
    );
    if !chars.len().is_multiple_of(4) {
        return Err(format!(
            "its base64 text has {} characters, not a multiple of 4 (truncated?)",
            chars.len()
        ));
    }
    let mut out = Vec::with_capacity(chars.len() / 4 * 3);
    let mut start = 0;
    for group in (0..chars.len()).step_by(4) {
        let end = group + 4;
        if chars[end - 1] == b'=' || end == chars.len() {
            ENGINE
                .decode_vec(&chars[start..end], &mut out)
                .map_err(|e| format!("invalid base64 in characters {start}..{end}: {e}"))?;
            start = end;
        }
    }
    Ok(out)
}

/// Like [`read_block`], and the block must fill `bytes` exactly.
pub(super) fn exact_block(bytes: &[u8], layout: Layout) -> Result<Cow<'_, [u8]>, String> {
    let (data, used) = read_block(bytes, layout)?;
    if used != bytes.len() {
        return Err(format!(
            "{} bytes follow the {used} bytes its header announces",
            bytes.len() - used
        ));
    }
    Ok(data)
}

/// Reads one binary block from the start of `bytes`: a header and the data it
/// announces. Uncompressed: the header is the data's byte count. Compressed (zlib): the
/// header is `[blocks, block size, last block size, compressed size of each block]`
/// (a last block size of 0 means a full block), followed by the compressed blocks.
/// Header words are `layout.header_bytes` wide in the file's byte order. Returns the
/// (uncompressed) data and the number of bytes of `bytes` used.
pub(super) fn read_block(bytes: &[u8], layout: Layout) -> Result<(Cow<'_, [u8]>, usize), String> {
    let h = layout.header_bytes;
    let kind = if h == 8 { "UInt64" } else { "UInt32" };
    let word = |k: usize| -> Result<u64, String> {
        let Some(b) = bytes.get(k * h..(k + 1) * h) else {
            return Err(format!(
                "truncated: {} bytes cannot hold header word {} ({kind})",
                bytes.len(),
                k + 1
            ));
        };
        let mut a = [0u8; 8];
        Ok(match (h, layout.big_endian) {
            (8, false) => {
                a.copy_from_slice(b);
                u64::from_le_bytes(a)
            }
            (8, true) => {
                a.copy_from_slice(b);
                u64::from_be_bytes(a)
            }
            (_, false) => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as u64,
            (_, true) => u32::from_be_bytes([b[0], b[1], b[2], b[3]]) as u64,
        })
    };
    if !layout.zlib {
        let n = word(0)?;
        let available = bytes.len() - h;
        return match usize::try_from(n).ok().filter(|&n| n <= available) {
            Some(n) => Ok((Cow::Borrowed(&bytes[h..h + n]), h + n)),
            None => Err(format!(
                "truncated: the header announces {n} bytes of data, {available} follow"
            )),
        };
    }
    let blocks = word(0)?;
    let block_size = word(1)?;
    let last_size = word(2)?;
    let header_len = usize::try_from(blocks)
        .ok()
        .and_then(|b| b.checked_add(3)?.checked_mul(h))
        .filter(|&len| len <= bytes.len())
        .ok_or_else(|| {
            format!(
                "truncated: the compression header announces {blocks} blocks, but {} bytes cannot hold their sizes",
                bytes.len()
            )
        })?;
    if last_size > block_size {
        return Err(format!(
            "corrupt compression header: last block size {last_size} exceeds block size {block_size}"
        ));
    }
    let blocks = blocks as usize;
    let mut data = Vec::new();
    let mut position = header_len;
    // One inflater for all blocks: setting one up costs more than a small block.
    let mut inflater = flate2::Decompress::new(true);
    for b in 0..blocks {
        let compressed = word(3 + b)?;
        let expected = if b + 1 == blocks && last_size != 0 {
            last_size
        } else {
            block_size
        };
        let available = bytes.len() - position;
        let compressed = usize::try_from(compressed)
            .ok()
            .filter(|&c| c <= available)
            .ok_or_else(|| {
                format!(
                    "truncated: compressed block {} of {blocks} needs {compressed} bytes, {available} follow",
                    b + 1
                )
            })?;
        inflate_block(
            &mut inflater,
            &bytes[position..position + compressed],
            expected,
            &mut data,
        )
        .map_err(|problem| format!("compressed block {} of {blocks} {problem}", b + 1))?;
        position += compressed;
    }
    Ok((Cow::Owned(data), position))
}

/// Appends the zlib stream `block` inflated to `out`, which must give exactly `expected`
/// bytes. Memory grows with the output actually produced, so a corrupt header claiming
/// a huge block allocates nothing. The error completes "compressed block k of n ...".
fn inflate_block(
    inflater: &mut flate2::Decompress,
    block: &[u8],
    expected: u64,
    out: &mut Vec<u8>,
) -> Result<(), String> {
    const CHUNK: u64 = 1 << 20;
    inflater.reset(true);
    let start = out.len();
    let mut input = block;
    loop {
        let produced = (out.len() - start) as u64;
        if produced > expected {
            return Err(format!(
                "decompresses to more than the {expected} bytes its header announces"
            ));
        }
        // Room for one byte more than expected, to notice a block that is too long.
        out.reserve((expected - produced + 1).min(CHUNK) as usize);
        let (in_before, out_before) = (inflater.total_in(), out.len());
        let status = inflater
            .decompress_vec(input, out, flate2::FlushDecompress::Finish)
            .map_err(|e| format!("is corrupt: {e}"))?;
        input = &input[(inflater.total_in() - in_before) as usize..];
        let produced = (out.len() - start) as u64;
        if status == flate2::Status::StreamEnd {
            return if produced == expected {
                Ok(())
            } else {
                Err(format!(
                    "decompresses to {produced} bytes, the header announces {expected}"
                ))
            };
        }
        if inflater.total_in() == in_before && out.len() == out_before {
            return Err(format!(
                "ends after {produced} of {expected} bytes: the stream is truncated or corrupt"
            ));
        }
    }
}
