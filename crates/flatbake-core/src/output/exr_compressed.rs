//! Compressed OpenEXR (`--exr-compression zip|piz`) through the `exr`
//! crate, with bytes that depend only on the pixels.
//!
//! The `exr` crate compresses blocks in parallel and, when it does, writes
//! them in the order they finish; written with `non_parallel()` it
//! compresses one block after the other and writes them in increasing `y`
//! (`LineOrder::Increasing`), and ZIP (deflate, `miniz_oxide`) and PIZ
//! (wavelet and Huffman) are deterministic functions of their input, so the
//! same pixels give the same bytes on every run, machine and thread count.
//! Both compressions are lossless: the values read back are the written
//! `f32`s bit for bit. The uncompressed default stays our own encoder
//! ([`super::exr`]), whose bytes the reference tests pin.

use std::io::Cursor;

use exr::prelude::*;

/// How the EXR outputs (lightmap and layers) are compressed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ExrCompression {
    /// No compression: flatbake's own encoder, the default.
    #[default]
    None,
    /// ZIP, deflate over blocks of 16 scan lines (OpenEXR's `ZIP_COMPRESSION`):
    /// what Godot, Unity and Blender import; smallest for smooth light.
    Zip,
    /// PIZ, wavelet and Huffman over blocks of 32 scan lines.
    Piz,
}

impl ExrCompression {
    /// The name on the command line and in the stamp.
    pub fn name(self) -> &'static str {
        match self {
            ExrCompression::None => "none",
            ExrCompression::Zip => "zip",
            ExrCompression::Piz => "piz",
        }
    }
}

/// Bytes of a single-part, scan-line OpenEXR file holding `channels` (name
/// and row-major values, `width * height` each) as 32-bit floats,
/// compressed with `compression` (not [`ExrCompression::None`], which is
/// [`super::exr`]'s encoder), written single-threaded in increasing line
/// order.
pub fn encode_exr_f32_compressed(
    width: usize,
    height: usize,
    channels: Vec<(&str, Vec<f32>)>,
    compression: ExrCompression,
) -> std::result::Result<Vec<u8>, String> {
    if width == 0 || height == 0 || i32::try_from(width.max(height)).is_err() {
        return Err(format!("an EXR image cannot be {width}x{height} pixels"));
    }
    if let Some((name, v)) = channels.iter().find(|(_, v)| v.len() != width * height) {
        return Err(format!(
            "{} values of channel {name} given for a {width}x{height} image",
            v.len()
        ));
    }
    let compression = match compression {
        ExrCompression::None => {
            return Err("an uncompressed EXR is written by flatbake's own encoder".into());
        }
        ExrCompression::Zip => Compression::ZIP16,
        ExrCompression::Piz => Compression::PIZ,
    };
    let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = channels
        .into_iter()
        .map(|(name, v)| AnyChannel {
            name: Text::from(name),
            sample_data: FlatSamples::F32(v),
            // As flatbake's own encoder writes it (pLinear 0); only lossy
            // compressions read it.
            quantize_linearly: false,
            sampling: Vec2(1, 1),
        })
        .collect();
    let layer = Layer::new(
        (width, height),
        LayerAttributes::default(),
        Encoding {
            compression,
            blocks: Blocks::ScanLines,
            line_order: LineOrder::Increasing,
        },
        AnyChannels::sort(list),
    );
    let mut bytes = Vec::new();
    Image::from_layer(layer)
        .write()
        .non_parallel()
        .to_buffered(Cursor::new(&mut bytes))
        .map_err(|e| format!("the EXR encoder failed ({e})"))?;
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_mismatched_sizes_and_no_compression() {
        let v = vec![0.0f32; 6];
        assert!(
            encode_exr_f32_compressed(3, 2, vec![("R", v.clone())], ExrCompression::Zip).is_ok()
        );
        assert!(
            encode_exr_f32_compressed(3, 3, vec![("R", v.clone())], ExrCompression::Zip).is_err()
        );
        assert!(encode_exr_f32_compressed(3, 2, vec![("R", v)], ExrCompression::None).is_err());
        assert!(encode_exr_f32_compressed(0, 2, vec![], ExrCompression::Zip).is_err());
    }
}
