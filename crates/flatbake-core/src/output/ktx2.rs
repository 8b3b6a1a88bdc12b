//! KTX2: the HDR lightmap as an uncompressed RGBA 16-bit float texture
//! (`VK_FORMAT_R16G16B16A16_SFLOAT`), the container Bevy's lightmaps ship
//! in, written by hand after the KTX 2.0 specification so that the bytes
//! depend only on the pixels (no writer name, no timestamps).
//!
//! Layout of the file (all integers little-endian):
//!
//! | bytes | what |
//! |---|---|
//! | 0..12 | the identifier `«KTX 20»\r\n\x1A\n` |
//! | 12..48 | `vkFormat` 97, `typeSize` 2, width, height, depth 0, layers 0, faces 1, levels 1, supercompression 0 |
//! | 48..80 | index: DFD at 104 (92 bytes), no key/value data, no supercompression data |
//! | 80..104 | the one level: offset 200, length and uncompressed length `8 * width * height` |
//! | 104..196 | the Data Format Descriptor: one basic block, RGBSDA model, BT.709 primaries, linear transfer, straight alpha, 8 bytes a texel, four 16-bit signed float samples R, G, B, A with the range -1..1 as floats |
//! | 196..200 | zero padding: the level starts at a multiple of 8 (the texel size) |
//! | 200.. | texels, rows top to bottom (KTX2's default orientation `rd`), R, G, B, A halves each |
//!
//! Each value is rounded to the nearest half float (ties to even, the
//! [`half`] crate's conversion) after clamping to `[0, 65504]` (the largest
//! finite half; `[-65504, 65504]` for the signed moments of a directional
//! bake, [`encode_ktx2_rgba16f_signed`]), so the round trip of a value `v` is within
//! [`half_error_bound`]`(v)`: `2^-11 v` where the result is a normal half,
//! `2^-25` below `2^-14`, where halves are subnormal.

use half::f16;

/// `VK_FORMAT_R16G16B16A16_SFLOAT`.
pub const VK_FORMAT_R16G16B16A16_SFLOAT: u32 = 97;

/// The KTX2 file identifier.
pub const IDENTIFIER: [u8; 12] = [
    0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A,
];

/// Header (48 bytes) + index (32) + one level index entry (24).
const DFD_OFFSET: u32 = 104;
/// `dfdTotalSize` (4) + block header (8) + basic header (16) + 4 samples (16 each).
const DFD_LENGTH: u32 = 4 + 8 + 16 + 4 * 16;
/// Bytes per texel: four halves.
const TEXEL_BYTES: u64 = 8;

/// The largest finite half float; larger values are written as it.
pub const HALF_MAX: f32 = 65504.0;

/// The largest difference between `v` (finite, `0 <= v <= HALF_MAX`) and
/// the half float the KTX2 file holds for it: half a unit in the last place
/// of the nearest half, at most `2^-11 v` for normal halves and `2^-25`
/// (half the smallest subnormal) below.
pub fn half_error_bound(v: f32) -> f32 {
    (v.abs() * 2f32.powi(-11)).max(2f32.powi(-25))
}

/// The half float bits written for a linear value: clamped to
/// `[0, HALF_MAX]` (non-finite and negative values are 0), rounded to
/// nearest, ties to even.
pub fn to_half(v: f32) -> u16 {
    let v = if v.is_finite() && v > 0.0 {
        v.min(HALF_MAX)
    } else {
        0.0
    };
    f16::from_f32(v).to_bits()
}

/// The half float bits written for a signed value (a circular moment):
/// clamped to `[-HALF_MAX, HALF_MAX]` (NaN is 0), rounded to nearest, ties
/// to even.
pub fn to_half_signed(v: f32) -> u16 {
    let v = if v.is_nan() {
        0.0
    } else {
        v.clamp(-HALF_MAX, HALF_MAX)
    };
    f16::from_f32(v).to_bits()
}

/// Bytes of a KTX2 file holding `rgba` (row-major, `width * height`, top
/// row first) as one level of `R16G16B16A16_SFLOAT` texels (see the module
/// documentation for the layout and the rounding).
pub fn encode_ktx2_rgba16f(
    width: usize,
    height: usize,
    rgba: &[[f32; 4]],
) -> Result<Vec<u8>, String> {
    encode(width, height, rgba, to_half)
}

/// [`encode_ktx2_rgba16f`] for values of either sign (the moments of a
/// directional bake): negatives are kept ([`to_half_signed`]).
pub fn encode_ktx2_rgba16f_signed(
    width: usize,
    height: usize,
    rgba: &[[f32; 4]],
) -> Result<Vec<u8>, String> {
    encode(width, height, rgba, to_half_signed)
}

fn encode(
    width: usize,
    height: usize,
    rgba: &[[f32; 4]],
    half: fn(f32) -> u16,
) -> Result<Vec<u8>, String> {
    if rgba.len() != width * height {
        return Err(format!(
            "{} pixels given for a {width}x{height} image",
            rgba.len()
        ));
    }
    let (w, h) = match (u32::try_from(width), u32::try_from(height)) {
        (Ok(w), Ok(h)) if w > 0 && h > 0 => (w, h),
        _ => return Err(format!("a KTX2 texture cannot be {width}x{height} pixels")),
    };
    let level_offset = (DFD_OFFSET + DFD_LENGTH).next_multiple_of(TEXEL_BYTES as u32) as u64;
    let level_length = TEXEL_BYTES * w as u64 * h as u64;
    let mut out = Vec::with_capacity((level_offset + level_length) as usize);
    let u32s = |out: &mut Vec<u8>, v: &[u32]| {
        for x in v {
            out.extend_from_slice(&x.to_le_bytes());
        }
    };
    let u64s = |out: &mut Vec<u8>, v: &[u64]| {
        for x in v {
            out.extend_from_slice(&x.to_le_bytes());
        }
    };
    out.extend_from_slice(&IDENTIFIER);
    // vkFormat, typeSize, pixelWidth, pixelHeight, pixelDepth, layerCount,
    // faceCount, levelCount, supercompressionScheme.
    u32s(
        &mut out,
        &[VK_FORMAT_R16G16B16A16_SFLOAT, 2, w, h, 0, 0, 1, 1, 0],
    );
    // dfdByteOffset, dfdByteLength, kvdByteOffset, kvdByteLength.
    u32s(&mut out, &[DFD_OFFSET, DFD_LENGTH, 0, 0]);
    // sgdByteOffset, sgdByteLength.
    u64s(&mut out, &[0, 0]);
    // Level 0: byteOffset, byteLength, uncompressedByteLength.
    u64s(&mut out, &[level_offset, level_length, level_length]);
    debug_assert_eq!(out.len(), DFD_OFFSET as usize);
    out.extend_from_slice(&dfd());
    out.resize(level_offset as usize, 0);
    for p in rgba {
        for &c in p {
            out.extend_from_slice(&half(c).to_le_bytes());
        }
    }
    Ok(out)
}

/// The Data Format Descriptor of `R16G16B16A16_SFLOAT`, linear, BT.709
/// primaries, straight alpha (as `VkFormat` to DFD conversion gives it).
fn dfd() -> Vec<u8> {
    const MODEL_RGBSDA: u32 = 1;
    const PRIMARIES_BT709: u32 = 1;
    const TRANSFER_LINEAR: u32 = 1;
    const SIGNED_FLOAT: u32 = 0x4 | 0x8; // qualifier bits of channelType
    const BLOCK_SIZE: u32 = 8 + 16 + 4 * 16;
    let mut d = Vec::with_capacity(DFD_LENGTH as usize);
    let mut word = |v: u32| d.extend_from_slice(&v.to_le_bytes());
    word(DFD_LENGTH); // dfdTotalSize
    word(0); // vendorId 0 (Khronos), descriptorType 0 (basic)
    word(2 | (BLOCK_SIZE << 16)); // versionNumber 2, descriptorBlockSize
    word(MODEL_RGBSDA | (PRIMARIES_BT709 << 8) | (TRANSFER_LINEAR << 16)); // flags 0: straight alpha
    word(0); // texelBlockDimension 1x1x1x1, each stored minus one
    word(TEXEL_BYTES as u32); // bytesPlane0 = 8, planes 1 to 3 empty
    word(0); // bytesPlane4..7
    // Samples R, G, B, A (channel ids 0, 1, 2 and 15): 16 bits each at
    // consecutive offsets, signed float, position 0, range -1.0..1.0.
    for (i, channel) in [0u32, 1, 2, 15].into_iter().enumerate() {
        word((16 * i as u32) | (15 << 16) | ((channel | (SIGNED_FLOAT << 4)) << 24));
        word(0); // samplePosition0..3
        word((-1f32).to_bits()); // sampleLower
        word(1f32.to_bits()); // sampleUpper
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halves_round_to_nearest_within_the_bound() {
        for &v in &[
            0.0f32, 1e-9, 3e-6, 6.1e-5, 0.1, 1.0, 1.0004, 123.456, 65504.0,
        ] {
            let back = f16::from_bits(to_half(v)).to_f32();
            assert!((back - v).abs() <= half_error_bound(v), "{v} -> {back}");
        }
        assert_eq!(to_half(1e9), f16::MAX.to_bits());
        assert_eq!(to_half(f32::NAN), 0);
        assert_eq!(to_half(-2.0), 0);
        // The bound is tight: halfway between 1 and the next half rounds
        // to even (1), an error of exactly 2^-11.
        let mid = 1.0 + 2f32.powi(-11);
        assert_eq!(f16::from_bits(to_half(mid)).to_f32(), 1.0);
    }

    #[test]
    fn level_data_is_aligned_and_sized() {
        let b = encode_ktx2_rgba16f(3, 2, &[[0.5, 1.0, 2.0, 1.0]; 6]).expect("encode");
        assert_eq!(&b[..12], &IDENTIFIER);
        assert_eq!(b.len(), 200 + 6 * 8);
        let off = u64::from_le_bytes(b[80..88].try_into().expect("8 bytes"));
        assert_eq!(off % 8, 0);
        assert!(encode_ktx2_rgba16f(3, 2, &[[0.0; 4]; 5]).is_err());
        assert!(encode_ktx2_rgba16f(0, 0, &[]).is_err());
    }
}
