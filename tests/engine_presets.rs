//! `--engine` presets: each writes the files its engine imports, and every
//! file decodes in a reader flatbake did not write (`image` for PNG and EXR).

mod common;
use common::*;

use flatbake_core::batch::BatchOptions;
use flatbake_core::output::{Depth, Engine, ExrCompression};

#[test]
fn presets_add_to_the_options_given() {
    for e in Engine::ALL {
        let o = BatchOptions::default().with_engine(e);
        assert!(o.hdr, "{e:?}");
        assert_eq!(o.padding, 8, "{e:?}");
        assert_eq!(o.rgbm_unity, e == Engine::Unity);
        assert_eq!(o.depth == Depth::Sixteen, e == Engine::Generic);
        assert_eq!(o.ktx2, e == Engine::Bevy);
        let zip = if e == Engine::Generic {
            ExrCompression::None
        } else {
            ExrCompression::Zip
        };
        assert_eq!(o.output_options(1.0).exr_compression, zip);
        // An explicit padding and extra outputs are kept.
        let given = BatchOptions {
            padding: 3,
            rgbm: true,
            ..BatchOptions::default()
        }
        .with_engine(e);
        assert_eq!(given.padding, 3);
        assert!(given.rgbm);
        // An EXR compression chosen beside a preset wins over the preset's.
        let chosen = BatchOptions {
            exr_compression: Some(ExrCompression::None),
            ..BatchOptions::default()
        }
        .with_engine(e);
        assert_eq!(
            chosen.output_options(1.0).exr_compression,
            ExrCompression::None
        );
    }
}

#[test]
fn new_format_options_are_spelled_in_the_stamp_only_when_set() {
    let plain = BatchOptions::default();
    let fp = plain.fingerprint();
    let ktx2 = BatchOptions {
        ktx2: true,
        ..BatchOptions::default()
    };
    let zip = BatchOptions {
        exr_compression: Some(ExrCompression::Zip),
        ..BatchOptions::default()
    };
    let none = BatchOptions {
        exr_compression: Some(ExrCompression::None),
        ..BatchOptions::default()
    };
    assert!(!fp.contains("ktx2") && !fp.contains("exr-"));
    assert_eq!(ktx2.fingerprint(), format!("{fp} ktx2"));
    assert_eq!(zip.fingerprint(), format!("{fp} exr-zip"));
    // Asking for the default changes no byte, so no stamp either.
    assert_eq!(none.fingerprint(), fp);
}

#[test]
fn every_preset_writes_files_that_decode() {
    let dir = tempfile::tempdir().expect("temp");
    for (e, extra) in [
        ("godot", vec![]),
        ("unity", vec!["lightmap.rgbm-unity.png"]),
        ("bevy", vec![]),
        ("generic", vec![]),
    ] {
        let out = dir.path().join(e);
        let o = flatbake(&[
            "bake",
            s(&fixture("rgba8_room_with_void.png")),
            "-o",
            s(&out),
            "--quality",
            "draft",
            "--engine",
            e,
            "--quiet",
        ]);
        assert_exit(&o, 0);
        let exr = std::fs::read(out.join("rgba8_room_with_void.lightmap.exr")).expect("exr");
        let img = image::load_from_memory_with_format(&exr, image::ImageFormat::OpenExr)
            .expect("EXR decodes")
            .into_rgba32f();
        assert!(img.pixels().any(|p| p.0[3] == 1.0) && img.pixels().any(|p| p.0[3] == 0.0));
        for suffix in ["lightmap.png"].into_iter().chain(extra) {
            let png =
                std::fs::read(out.join(format!("rgba8_room_with_void.{suffix}"))).expect("written");
            let img = image::load_from_memory(&png).expect("PNG decodes");
            let want16 = e == "generic" && suffix == "lightmap.png";
            assert_eq!(
                img.color() == image::ColorType::Rgba16,
                want16,
                "{e} {suffix}"
            );
        }
    }
}
