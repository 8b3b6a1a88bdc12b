//! Level + palette loading from arbitrary bytes, then geometry and a draft
//! bake of whatever loads. Input: `palette text` NUL `image bytes`.
#![no_main]

use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;

use flatbake_core::level::{LoadLimits, load_level};
use flatbake_core::level::palette::Palette;

fuzz_target!(|data: &[u8]| {
    let (pal_bytes, img) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (&data[..0], data),
    };
    let dir = std::env::temp_dir().join(format!("flatbake-fuzz-{}", std::process::id()));
    let _ = std::fs::create_dir_all(&dir);
    let pal_path = dir.join("level.palette.toml");
    let palette = match std::str::from_utf8(pal_bytes) {
        Ok(text) if !text.is_empty() => match Palette::parse(text, &pal_path) {
            Ok(p) => p,
            Err(e) => {
                // Every palette error names the file.
                assert!(e.to_string().starts_with(&pal_path.display().to_string()));
                return;
            }
        },
        _ => Palette::builtin(),
    };
    if has_partial_palette_entry(img) {
        return;
    }
    let path = dir.join("level.png");
    if std::fs::write(&path, img).is_err() {
        return;
    }
    let limits = LoadLimits {
        max_pixels: 64 * 64,
    };
    let level = match load_level(&path, &palette, limits) {
        Ok(l) => l,
        Err(e) => {
            assert!(e.to_string().contains("level.png"), "{e}");
            return;
        }
    };
    assert_eq!(level.cells.len(), level.width * level.height);
    common::bake_and_check(&level, palette.settings.falloff, false);
});

/// A PNG whose `PLTE` length is not a multiple of 3 panics inside the `png`
/// crate (a slice out of range while it expands the palette). The batch
/// contains that panic as the level's failure (tested in
/// `tests/mutation.rs`); a fuzz target cannot catch it, so such inputs are
/// skipped to let the fuzzer look for other faults.
fn has_partial_palette_entry(img: &[u8]) -> bool {
    let mut i = 8;
    while let Some(head) = img.get(i..i + 8) {
        let len = u32::from_be_bytes([head[0], head[1], head[2], head[3]]) as usize;
        if &head[4..8] == b"PLTE" && len % 3 != 0 {
            return true;
        }
        i = i.saturating_add(12).saturating_add(len);
    }
    false
}
