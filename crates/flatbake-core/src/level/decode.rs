//! Reading a level image: the format from its content, the declared size
//! checked against [`LoadLimits`] before any pixel is decoded, and every
//! failure named as an [`ImageProblem`].

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::Path;

use image::{ImageError, ImageFormat, ImageReader, RgbaImage};

use crate::level::{ImageProblem, LevelError, LoadLimits};

/// Decodes a level image to 8-bit RGBA.
///
/// The format comes from the file's content (a PNG named `.jpg` loads); the
/// declared size is checked against `limits` before decoding, so a tiny file
/// that claims to be 100000 x 100000 fails at once without allocating.
/// 16-bit, grey, grey + alpha and paletted images are converted; 16-bit
/// values round to the nearest 8-bit value, so a colour saved as 16-bit
/// still matches its palette entry.
pub fn read_image(path: &Path, limits: LoadLimits) -> Result<RgbaImage, LevelError> {
    let fail = |problem: ImageProblem| LevelError::Image {
        path: path.to_path_buf(),
        problem,
    };
    let io_fail = |e: std::io::Error| {
        fail(match e.kind() {
            std::io::ErrorKind::NotFound => ImageProblem::NotFound,
            std::io::ErrorKind::PermissionDenied => ImageProblem::PermissionDenied,
            _ => ImageProblem::Read(e),
        })
    };

    let meta = std::fs::metadata(path).map_err(io_fail)?;
    if meta.is_dir() {
        return Err(fail(ImageProblem::Folder));
    }
    if meta.len() == 0 {
        return Err(fail(ImageProblem::Empty));
    }

    let mut head = Vec::with_capacity(32);
    File::open(path)
        .and_then(|f| f.take(32).read_to_end(&mut head))
        .map_err(io_fail)?;
    let by_extension = ImageFormat::from_path(path).ok();
    let format = match image::guess_format(&head) {
        Ok(f) => f,
        // TGA has no signature to recognise; trust its extension.
        Err(_) if by_extension == Some(ImageFormat::Tga) => ImageFormat::Tga,
        Err(_) => return Err(fail(not_an_image(&head, by_extension))),
    };
    if !format.reading_enabled() {
        return Err(fail(ImageProblem::FormatNotBuilt {
            format: format_name(format),
        }));
    }

    let open = || {
        File::open(path)
            .map(|f| ImageReader::with_format(BufReader::new(f), format))
            .map_err(io_fail)
    };
    // PNG's size sits at a fixed place in the first chunk; reading it there
    // refuses an oversized PNG even when the rest of the file is missing,
    // which the decoder would otherwise report first.
    let (w, h) = match png_dimensions(&head) {
        Some(d) => d,
        None => open()?
            .into_dimensions()
            .map_err(|e| fail(decode_message(e, format)))?,
    };
    let pixels = w as u64 * h as u64;
    if pixels == 0 {
        return Err(fail(ImageProblem::NoPixels {
            width: w,
            height: h,
        }));
    }
    if pixels > limits.max_pixels {
        return Err(fail(ImageProblem::TooLarge {
            width: w,
            height: h,
            limit: limits.max_pixels,
        }));
    }

    if format == ImageFormat::Png
        && let Some(detail) = png_palette_problem(path)
    {
        return Err(fail(ImageProblem::Corrupt {
            format: format_name(format),
            detail,
        }));
    }
    let mut reader = open()?;
    let mut decode_limits = image::Limits::default();
    // The declared size passed the check above; hold the decoder to it, and
    // give it room for a 16-bit RGBA buffer plus scratch space.
    decode_limits.max_image_width = Some(w);
    decode_limits.max_image_height = Some(h);
    decode_limits.max_alloc = Some((pixels * 16).max(512 << 20));
    reader.limits(decode_limits);
    let img = reader
        .decode()
        .map_err(|e| fail(decode_message(e, format)))?;
    Ok(img.into_rgba8())
}

/// A palette chunk the `png` decoder cannot take: its length is not a whole
/// number of 3-byte colours, or more than 256 of them (the decoder panics on
/// some of these, with a tRNS chunk). Walks the chunk headers before the
/// image data; `None` when the palette is fine, absent, or the file cannot
/// be walked (the decoder then says what is wrong).
fn png_palette_problem(path: &Path) -> Option<String> {
    use std::io::{Seek, SeekFrom};
    let mut f = BufReader::new(File::open(path).ok()?);
    f.seek(SeekFrom::Start(8)).ok()?;
    loop {
        let mut header = [0u8; 8];
        f.read_exact(&mut header).ok()?;
        let len = u32::from_be_bytes([header[0], header[1], header[2], header[3]]);
        match &header[4..8] {
            b"PLTE" if len == 0 || len % 3 != 0 || len > 768 => {
                return Some(format!(
                    "its PLTE (palette) chunk is {len} bytes, not 1 to 256 colours of 3 bytes"
                ));
            }
            b"PLTE" | b"IDAT" | b"IEND" => return None,
            _ => {}
        }
        // The chunk's data and CRC.
        f.seek(SeekFrom::Current(i64::from(len) + 4)).ok()?;
    }
}

/// Width and height from a PNG signature followed by its IHDR chunk.
fn png_dimensions(head: &[u8]) -> Option<(u32, u32)> {
    if head.len() < 24 || &head[..8] != b"\x89PNG\r\n\x1a\n" || &head[12..16] != b"IHDR" {
        return None;
    }
    let be = |i: usize| u32::from_be_bytes([head[i], head[i + 1], head[i + 2], head[i + 3]]);
    Some((be(16), be(20)))
}

fn format_name(f: ImageFormat) -> String {
    f.extensions_str()
        .first()
        .map(|e| e.to_uppercase())
        .unwrap_or_else(|| format!("{f:?}"))
}

/// Why a file that is not a recognisable image was refused, with a glimpse
/// of what it is instead (text is shown, binary as hex).
fn not_an_image(head: &[u8], by_extension: Option<ImageFormat>) -> ImageProblem {
    let named = by_extension.map(format_name);
    let start = &head[..head.len().min(16)];
    let looks_like_text = start
        .iter()
        .all(|&b| b == b'\t' || b == b'\n' || b == b'\r' || (0x20..0x7f).contains(&b));
    let glimpse = if looks_like_text {
        let text: String = String::from_utf8_lossy(start)
            .chars()
            .map(|c| if c.is_control() { ' ' } else { c })
            .collect();
        format!("it starts with the text {:?}", text.trim())
    } else {
        let hex: Vec<String> = start.iter().take(8).map(|b| format!("{b:02x}")).collect();
        format!("it starts with the bytes {}", hex.join(" "))
    };
    ImageProblem::NotAnImage { named, glimpse }
}

/// What a decoding failure means; truncation is by far the most common cause.
fn decode_message(e: ImageError, format: ImageFormat) -> ImageProblem {
    let format = format_name(format);
    match e {
        ImageError::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            ImageProblem::Truncated {
                format,
                detail: None,
            }
        }
        ImageError::IoError(io) => ImageProblem::Read(io),
        ImageError::Decoding(d) => {
            let detail = d.to_string();
            let lower = detail.to_lowercase();
            if lower.contains("eof") || lower.contains("end of") || lower.contains("truncat") {
                ImageProblem::Truncated {
                    format,
                    detail: Some(detail),
                }
            } else {
                ImageProblem::Corrupt { format, detail }
            }
        }
        ImageError::Limits(l) => ImageProblem::DecodeLimit {
            detail: l.to_string(),
        },
        ImageError::Unsupported(u) => ImageProblem::Unsupported {
            format,
            detail: u.to_string(),
        },
        other => ImageProblem::Decode {
            format,
            detail: other.to_string(),
        },
    }
}

/// The lossy format a level image is stored in, if it is: JPEG, or WebP
/// whose image data is lossy (a `VP8 ` chunk rather than `VP8L`). Such
/// images rarely hold exactly the colours that were painted. `None` for
/// every other format and when the file cannot be read (loading reports
/// that).
pub fn lossy_format(path: &Path) -> Option<&'static str> {
    let mut f = File::open(path).ok()?;
    let mut head = [0u8; 16];
    f.read_exact(&mut head).ok()?;
    match image::guess_format(&head).ok()? {
        ImageFormat::Jpeg => Some("JPEG"),
        ImageFormat::WebP => webp_is_lossy(&mut f).then_some("WebP"),
        _ => None,
    }
}

/// Walks the RIFF chunks of a WebP file (positioned after its 12-byte
/// header and the first chunk's fourcc) to the image data: lossy `VP8 `
/// or lossless `VP8L`.
fn webp_is_lossy(f: &mut File) -> bool {
    use std::io::{Seek, SeekFrom};
    if f.seek(SeekFrom::Start(12)).is_err() {
        return false;
    }
    // A few chunks (VP8X, ICCP, ANIM, ALPH, ...) may come before the data.
    for _ in 0..64 {
        let mut chunk = [0u8; 8];
        if f.read_exact(&mut chunk).is_err() {
            return false;
        }
        match &chunk[..4] {
            b"VP8 " => return true,
            b"VP8L" => return false,
            _ => {}
        }
        let size = u32::from_le_bytes([chunk[4], chunk[5], chunk[6], chunk[7]]) as i64;
        // Chunks are padded to an even size.
        if f.seek(SeekFrom::Current(size + (size & 1))).is_err() {
            return false;
        }
    }
    false
}
