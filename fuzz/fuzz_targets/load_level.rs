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
