//! The engine file formats read back by readers flatbake did not write:
//! the KTX2 lightmap by the `ktx2` crate (header, data format descriptor
//! and every texel within the half-float bound), compressed EXRs by
//! `image` bit for bit and with the same bytes on every run, and, for
//! every `--engine` preset, every file it writes, each within the
//! documented error of its encoding (README "Using the lightmap in an
//! engine").
// Channel loops index the decoded texel and the reference at once.
#![allow(clippy::needless_range_loop)]

mod common;
use common::*;

use std::collections::BTreeMap;
use std::path::Path;

use flatbake_core::bake::{Settings, bake};
use flatbake_core::level::{Cell, Level};
use flatbake_core::output::ktx2::{HALF_MAX, half_error_bound};
use flatbake_core::output::{
    Encoded, ExrCompression, OutputKind, OutputOptions, encode_exr_rgb, encode_exr_rgb32f,
    encode_exr_rgba, encode_exr_rgba32f, encode_images, padded_hdr_pixels,
};
use flatbake_core::quality::Quality;

fn quiet(_: &str) {}

/// A bright room (light above 1 near the lamp, deep shadow behind a
/// pillar) in a margin of void.
fn level() -> Level {
    let rows = [
        "                        ",
        "  ####################  ",
        "  #..................#  ",
        "  #.......##.........L  ",
        "  #.......##.........L  ",
        "  #..................#  ",
        "  #.....#............#  ",
        "  ####################  ",
        "                        ",
    ];
    ascii(&rows, &[('#', wall(0.6)), ('L', light(20.0, 0.5))])
}

fn baked() -> (Level, flatbake_core::output::Lightmap) {
    let lvl = level();
    let b = bake(&lvl, &Settings::new(Quality::Draft), &quiet).expect("bake");
    (lvl, b.lightmap)
}

fn file(files: &[Encoded], kind: OutputKind) -> &[u8] {
    &files.iter().find(|f| f.kind == kind).expect("output").bytes
}

fn coverage(lvl: &Level) -> Vec<f32> {
    lvl.cells
        .iter()
        .map(|c| if *c == Cell::Floor { 1.0 } else { 0.0 })
        .collect()
}

/// RGBA texels of a KTX2 file read with the `ktx2` crate, after checking
/// that it is one level of `R16G16B16A16_SFLOAT` with the data format
/// descriptor that format has.
fn read_ktx2(bytes: &[u8], width: u32, height: u32) -> Vec<[f32; 4]> {
    let r = ktx2::Reader::new(bytes).expect("the ktx2 crate reads the file");
    let h = r.header();
    assert_eq!(h.format, Some(ktx2::Format::R16G16B16A16_SFLOAT));
    assert_eq!(h.type_size, 2);
    assert_eq!((h.pixel_width, h.pixel_height), (width, height));
    assert_eq!(
        (h.pixel_depth, h.layer_count, h.face_count, h.level_count),
        (0, 0, 1, 1)
    );
    assert_eq!(h.supercompression_scheme, None);
    assert_eq!((h.index.kvd_byte_length, h.index.sgd_byte_length), (0, 0));
    // The level: right after the DFD, aligned to the 8-byte texel.
    let offset = u64::from_le_bytes(bytes[80..88].try_into().expect("8 bytes"));
    assert_eq!(offset % 8, 0);
    let dfd_end = (h.index.dfd_byte_offset + h.index.dfd_byte_length) as u64;
    assert!(
        offset >= dfd_end && offset < dfd_end + 8,
        "level at {offset}"
    );
    let dfd_total = u32::from_le_bytes(
        bytes[h.index.dfd_byte_offset as usize..][..4]
            .try_into()
            .expect("4 bytes"),
    );
    assert_eq!(dfd_total, h.index.dfd_byte_length);

    let blocks: Vec<_> = r.dfd_blocks().collect();
    assert_eq!(blocks.len(), 1);
    assert_eq!(blocks[0].header, ktx2::DfdHeader::BASIC);
    let basic = ktx2::DfdBlockBasic::parse(blocks[0].data).expect("basic DFD block");
    assert_eq!(basic.header.color_model, Some(ktx2::ColorModel::RGBSDA));
    assert_eq!(
        basic.header.color_primaries,
        Some(ktx2::ColorPrimaries::BT709)
    );
    assert_eq!(
        basic.header.transfer_function,
        Some(ktx2::TransferFunction::Linear)
    );
    assert_eq!(basic.header.flags, ktx2::DataFormatFlags::STRAIGHT_ALPHA);
    assert!(
        basic
            .header
            .texel_block_dimensions
            .iter()
            .all(|d| d.get() == 1)
    );
    assert_eq!(basic.header.bytes_planes, [8, 0, 0, 0, 0, 0, 0, 0]);
    let samples: Vec<_> = basic.sample_information().collect();
    assert_eq!(samples.len(), 4);
    for (i, (s, channel)) in samples.iter().zip([0u8, 1, 2, 15]).enumerate() {
        assert_eq!(s.bit_offset, 16 * i as u16);
        assert_eq!(s.bit_length.get(), 16);
        assert_eq!(s.channel_type, channel);
        assert_eq!(
            s.channel_type_qualifiers,
            ktx2::ChannelTypeQualifiers::SIGNED | ktx2::ChannelTypeQualifiers::FLOAT
        );
        assert_eq!(s.sample_positions, [0; 4]);
        assert_eq!((s.lower, s.upper), ((-1f32).to_bits(), 1f32.to_bits()));
    }

    let levels: Vec<_> = r.levels().collect();
    assert_eq!(levels.len(), 1);
    let data = levels[0].data;
    assert_eq!(data.len(), 8 * (width * height) as usize);
    assert_eq!(levels[0].uncompressed_byte_length, data.len() as u64);
    data.chunks_exact(8)
        .map(|t| [0, 1, 2, 3].map(|k| half::f16::from_le_bytes([t[2 * k], t[2 * k + 1]]).to_f32()))
        .collect()
}

/// The largest error of `got` against `want` relative to the half-float
/// bound, failing if any texel is past it.
fn check_halves(got: &[[f32; 4]], want: &[[f32; 3]]) -> f64 {
    let mut worst = 0f64;
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        for k in 0..3 {
            let w = w[k].min(HALF_MAX);
            let err = (g[k] - w).abs();
            assert!(
                err <= half_error_bound(w),
                "texel {i} channel {k}: {} for {w}",
                g[k]
            );
            if w > 0.0 {
                worst = worst.max(err as f64 / w as f64);
            }
        }
    }
    worst
}

#[test]
fn ktx2_reads_back_in_the_ktx2_crate_within_the_half_bound() {
    let (lvl, map) = baked();
    let (w, h) = (lvl.width as u32, lvl.height as u32);
    for padding in [0u32, 8] {
        let opts = OutputOptions {
            ktx2: true,
            padding,
            ..OutputOptions::default()
        };
        let files = encode_images(&lvl, &map, &opts).expect("encode");
        let texels = read_ktx2(file(&files, OutputKind::Ktx2), w, h);
        let want = padded_hdr_pixels(&lvl, &map, padding).expect("pad");
        assert!(want.iter().any(|p| p[0] > 1.0), "the test wants HDR values");
        let worst = check_halves(&texels, &want);
        assert!(worst > 0.0 && worst <= 2f64.powi(-11));
        // Alpha: the coverage when padded, else opaque everywhere.
        for (t, c) in texels.iter().zip(coverage(&lvl)) {
            assert_eq!(t[3], if padding > 0 { c } else { 1.0 });
        }
        // The same values as the EXR beside it, which holds them exactly.
        let exr = encode_images(
            &lvl,
            &map,
            &OutputOptions {
                hdr: true,
                ..opts.clone()
            },
        )
        .expect("encode");
        let exr = image::load_from_memory_with_format(
            file(&exr, OutputKind::Hdr),
            image::ImageFormat::OpenExr,
        )
        .expect("EXR")
        .into_rgb32f();
        let exr: Vec<[f32; 3]> = exr.pixels().map(|p| p.0).collect();
        check_halves(&texels, &exr);
    }
}

/// The `compression` attribute of an EXR header (0 none, 3 ZIP, 4 PIZ).
fn exr_compression_code(bytes: &[u8]) -> u8 {
    let key = b"compression\0compression\0\x01\0\0\0";
    let at = bytes
        .windows(key.len())
        .position(|w| w == key)
        .expect("a compression attribute");
    bytes[at + key.len()]
}

/// Values a lightmap can hold and some it should not lose either: 0,
/// f32 subnormals, tiny, ordinary, huge.
fn awkward(n: usize) -> Vec<[f32; 4]> {
    let mut x = 0x9E37_79B9u32;
    (0..n)
        .map(|i| {
            [0, 1, 2, 3].map(|k| {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                match (i + k) % 7 {
                    0 => 0.0,
                    1 => f32::from_bits(x % 0x0080_0000), // subnormal
                    2 => f32::from_bits(x % 0x7F00_0000), // anything finite, positive
                    3 => (x % 1000) as f32 / 1000.0,
                    _ => 1.0 + (x % 65536) as f32 / 4096.0,
                }
            })
        })
        .collect()
}

#[test]
fn compressed_exr_is_lossless_and_the_same_every_run() {
    let (lvl, map) = baked();
    let cov = coverage(&lvl);
    for compression in [ExrCompression::Zip, ExrCompression::Piz] {
        for padding in [0u32, 8] {
            let opts = OutputOptions {
                hdr: true,
                padding,
                exr_compression: compression,
                ..OutputOptions::default()
            };
            let a = encode_images(&lvl, &map, &opts).expect("encode");
            let b = encode_images(&lvl, &map, &opts).expect("encode");
            let bytes = file(&a, OutputKind::Hdr);
            assert_eq!(bytes, file(&b, OutputKind::Hdr), "{compression:?}");
            let code = exr_compression_code(bytes);
            assert_eq!(
                code,
                if compression == ExrCompression::Zip {
                    3
                } else {
                    4
                }
            );
            let img = image::load_from_memory_with_format(bytes, image::ImageFormat::OpenExr)
                .expect("image reads the compressed EXR")
                .into_rgba32f();
            let want = padded_hdr_pixels(&lvl, &map, padding).expect("pad");
            for ((p, w), c) in img.pixels().zip(&want).zip(&cov) {
                for k in 0..3 {
                    assert_eq!(p.0[k].to_bits(), w[k].to_bits());
                }
                assert_eq!(p.0[3], if padding > 0 { *c } else { 1.0 });
            }
        }
        // Awkward values survive bit for bit, and the encoder is a
        // function of the pixels.
        let (w, h) = (37, 23);
        let px = awkward(w * h);
        let bytes = encode_exr_rgba(w, h, &px, compression).expect("encode");
        assert_eq!(
            bytes,
            encode_exr_rgba(w, h, &px, compression).expect("again")
        );
        let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::OpenExr)
            .expect("decode")
            .into_rgba32f();
        for (p, want) in img.pixels().zip(&px) {
            assert_eq!(p.0.map(f32::to_bits), want.map(f32::to_bits));
        }
        let rgb: Vec<[f32; 3]> = px.iter().map(|p| [p[0], p[1], p[2]]).collect();
        let img = image::load_from_memory_with_format(
            &encode_exr_rgb(w, h, &rgb, compression).expect("encode"),
            image::ImageFormat::OpenExr,
        )
        .expect("decode")
        .into_rgb32f();
        for (p, want) in img.pixels().zip(&rgb) {
            assert_eq!(p.0.map(f32::to_bits), want.map(f32::to_bits));
        }
    }
    // No compression is the hand-written encoder, byte for byte.
    let px = awkward(12);
    let rgb: Vec<[f32; 3]> = px.iter().map(|p| [p[0], p[1], p[2]]).collect();
    assert_eq!(
        encode_exr_rgba(4, 3, &px, ExrCompression::None).expect("none"),
        encode_exr_rgba32f(4, 3, &px).expect("own")
    );
    assert_eq!(
        encode_exr_rgb(4, 3, &rgb, ExrCompression::None).expect("none"),
        encode_exr_rgb32f(4, 3, &rgb).expect("own")
    );
}

#[test]
fn another_process_and_thread_count_write_the_same_compressed_bytes() {
    let dir = tempfile::tempdir().expect("temp");
    let level = Path::new(env!("CARGO_MANIFEST_DIR")).join("levels/colour_bleed.png");
    let mut runs = Vec::new();
    for (k, jobs) in ["1", "2", "2"].into_iter().enumerate() {
        let out = dir.path().join(format!("run{k}"));
        let o = flatbake(&[
            "bake",
            s(&level),
            "-o",
            s(&out),
            "--quality",
            "draft",
            "--hdr",
            "--layers",
            "--exr-compression",
            "zip",
            "--jobs",
            jobs,
            "--quiet",
        ]);
        assert_exit(&o, 0);
        let mut exrs = BTreeMap::new();
        for e in std::fs::read_dir(&out).expect("out") {
            let p = e.expect("entry").path();
            if p.extension().is_some_and(|x| x == "exr") {
                let bytes = std::fs::read(&p).expect("read");
                assert_eq!(exr_compression_code(&bytes), 3, "{}", p.display());
                exrs.insert(p.file_name().expect("name").to_owned(), bytes);
            }
        }
        assert!(exrs.len() >= 2, "lightmap and at least one layer");
        runs.push(exrs);
    }
    assert_eq!(runs[0], runs[1]);
    assert_eq!(runs[1], runs[2]);
}

/// sRGB code (0 to 1) to linear light.
fn srgb_to_linear(s: f64) -> f64 {
    if s <= 0.04045 {
        s / 12.92
    } else {
        ((s + 0.055) / 1.055).powf(2.4)
    }
}

/// Half a code step of a `bits`-bit sRGB PNG in linear light: the curve's
/// steepest slope (2.4 / 1.055, at 1) times half a step.
fn srgb_bound(bits: u32) -> f64 {
    2.4 / 1.055 * 0.5 / ((1u64 << bits) - 1) as f64 + 1e-9
}

/// The largest round-trip error per format over every preset.
type Worst = BTreeMap<&'static str, f64>;

fn note(worst: &mut Worst, format: &'static str, err: f64) {
    let e = worst.entry(format).or_insert(0.0);
    *e = e.max(err);
}

/// Checks every file a bake in `out` wrote against the reference values
/// `want` (linear, padded) and coverage `cov` (and a layer EXR against its
/// uncompressed copy in `reference`), each with a reader flatbake did not
/// write; returns how many image files it checked.
fn check_outputs(
    out: &Path,
    reference: &Path,
    name: &str,
    want: &[[f32; 3]],
    cov: &[f32],
    size: (u32, u32),
    worst: &mut Worst,
) -> usize {
    let report: serde_json::Value = serde_json::from_slice(
        &std::fs::read(out.join(format!("{name}.report.json"))).expect("report"),
    )
    .expect("report JSON");
    let exposure = report["exposure"].as_f64().expect("exposure");
    let mut checked = 0;
    for f in report["outputs"].as_array().expect("outputs") {
        let f = f.as_str().expect("name");
        let bytes = std::fs::read(out.join(f)).expect("listed output exists");
        let suffix = &f[name.len() + 1..];
        let decoded = |fmt: image::ImageFormat| {
            let img = image::load_from_memory_with_format(&bytes, fmt)
                .unwrap_or_else(|e| panic!("{f}: {e}"));
            assert_eq!((img.width(), img.height()), size, "{f}");
            img
        };
        if !suffix.ends_with(".json") {
            checked += 1;
        }
        match suffix {
            "lightmap.exr" => {
                let img = decoded(image::ImageFormat::OpenExr).into_rgba32f();
                for ((p, w), c) in img.pixels().zip(want).zip(cov) {
                    assert_eq!([p.0[0], p.0[1], p.0[2]], *w, "{f}");
                    assert_eq!(p.0[3], *c, "{f}");
                }
                note(worst, "EXR", 0.0);
            }
            "lightmap.ktx2" => {
                let texels = read_ktx2(&bytes, size.0, size.1);
                note(worst, "KTX2 (relative)", check_halves(&texels, want));
                for (t, c) in texels.iter().zip(cov) {
                    assert_eq!(t[3], *c, "{f}");
                }
            }
            "lightmap.png" => {
                let img = decoded(image::ImageFormat::Png);
                let bits = if img.color() == image::ColorType::Rgba16 {
                    16
                } else {
                    8
                };
                let img = img.into_rgba16();
                for ((p, w), c) in img.pixels().zip(want).zip(cov) {
                    for k in 0..3 {
                        let got = srgb_to_linear(p.0[k] as f64 / 65535.0);
                        let v = (w[k] as f64 * exposure).clamp(0.0, 1.0);
                        let err = (got - v).abs();
                        assert!(
                            err <= srgb_bound(bits),
                            "{}: {f} ({bits} bits): {got} for {v}",
                            out.display()
                        );
                        note(worst, if bits == 16 { "PNG 16" } else { "PNG 8" }, err);
                    }
                    assert_eq!(p.0[3] as f32 / 65535.0, *c, "{f}");
                }
            }
            "lit.png" => {
                decoded(image::ImageFormat::Png);
            }
            "lightmap.rgbm.png" => {
                let img = decoded(image::ImageFormat::Png).into_rgba8();
                for (p, w) in img.pixels().zip(want) {
                    let m = p.0[3] as f64 / 255.0 * 6.0;
                    for k in 0..3 {
                        let got = p.0[k] as f64 / 255.0 * m;
                        let v = (w[k] as f64).min(6.0);
                        let err = (got - v).abs();
                        assert!(err <= 0.5 * m / 255.0 + 1e-6, "{f}: {got} for {v}");
                        note(worst, "RGBM (of the multiplier a*6)", err / m.max(1e-30));
                    }
                }
            }
            "lightmap.rgbm-unity.png" => {
                let img = decoded(image::ImageFormat::Png).into_rgba8();
                for (p, w) in img.pixels().zip(want) {
                    let a = p.0[3] as f64 / 255.0;
                    let brightest = w.iter().fold(0f64, |m, &c| m.max(c as f64));
                    for k in 0..3 {
                        let got = (p.0[k] as f64 / 255.0 * a * 5.0).powf(2.2);
                        let v = (w[k] as f64).min(5f64.powf(2.2));
                        let g = v.powf(1.0 / 2.2);
                        let bound = (g + 5.0 * a / 510.0).powf(2.2) - g.powf(2.2);
                        let err = (got - v).abs();
                        assert!(err <= bound + 1e-6, "{f}: {got} for {v}");
                        if brightest >= 0.01 {
                            note(
                                worst,
                                "Unity RGBM (of the brightest channel, from 0.01)",
                                err / brightest,
                            );
                        }
                    }
                }
            }
            s if s.starts_with("layer-") && s.ends_with(".exr") => {
                let img = decoded(image::ImageFormat::OpenExr).into_rgba32f();
                let exact = image::open(reference.join(f))
                    .expect("the reference layer")
                    .into_rgba32f();
                for ((p, c), q) in img.pixels().zip(cov).zip(exact.pixels()) {
                    assert_eq!(p.0[3], *c, "{f}");
                    assert_eq!(p.0, q.0, "{f}");
                }
                note(worst, "EXR", 0.0);
            }
            s if s.starts_with("layer-") && s.ends_with(".png") => {
                let img = decoded(image::ImageFormat::Png).into_rgba16();
                for (p, c) in img.pixels().zip(cov) {
                    assert_eq!(p.0[3] as f32 / 65535.0, *c, "{f}");
                }
            }
            "report.json" | "layers.json" => {
                serde_json::from_slice::<serde_json::Value>(&bytes).expect("JSON");
            }
            other => panic!("{f}: no check for the output {other}"),
        }
    }
    checked
}

#[test]
fn every_file_a_preset_writes_decodes_within_its_error() {
    let dir = tempfile::tempdir().expect("temp");
    let level = Path::new(env!("CARGO_MANIFEST_DIR")).join("levels/colour_bleed.png");
    let name = "colour_bleed";
    let bake_into = |out: &Path, extra: &[&str]| {
        let mut args = vec![
            "bake",
            s(&level),
            "-o",
            s(out),
            "--quality",
            "draft",
            "--quiet",
        ];
        args.extend_from_slice(extra);
        assert_exit(&flatbake(&args), 0);
    };
    // The reference of each bake: the uncompressed EXRs of flatbake's own
    // encoder, padded as every preset pads (tests/padding.rs pins them to
    // the padded pixels), from the same bake (`--layers` bakes the
    // responses, which changes draft's light slightly).
    let reference = |layers: bool| {
        let out = dir.path().join(format!("reference-{layers}"));
        let mut args = vec!["--hdr", "--padding", "8"];
        if layers {
            args.push("--layers");
        }
        bake_into(&out, &args);
        let img = image::open(out.join(format!("{name}.lightmap.exr")))
            .expect("reference EXR")
            .into_rgba32f();
        let want: Vec<[f32; 3]> = img.pixels().map(|p| [p.0[0], p.0[1], p.0[2]]).collect();
        let cov: Vec<f32> = img.pixels().map(|p| p.0[3]).collect();
        assert!(cov.contains(&1.0) && cov.contains(&0.0));
        (out, img.dimensions(), want, cov)
    };
    let references = [reference(false), reference(true)];

    let mut worst = Worst::new();
    for (engine, extra, files) in [
        // The presets alone, and with the other outputs beside them.
        ("godot", vec![], 3),
        ("unity", vec![], 4),
        ("bevy", vec![], 4),
        ("generic", vec![], 3),
        ("godot", vec!["--rgbm", "--layers"], 6),
        ("bevy", vec!["--depth", "16", "--rgbm-unity"], 5),
    ] {
        let out = dir.path().join(format!("{engine}{}", extra.join("")));
        let mut args = vec!["--engine", engine];
        args.extend(extra.iter().copied());
        bake_into(&out, &args);
        let (ref_dir, size, want, cov) = &references[usize::from(extra.contains(&"--layers"))];
        let n = check_outputs(&out, ref_dir, name, want, cov, *size, &mut worst);
        assert!(n >= files, "{engine} {extra:?}: {n} image files checked");
    }
    for f in ["EXR", "KTX2 (relative)", "PNG 8", "PNG 16"] {
        assert!(worst.contains_key(f), "no {f} checked");
    }
    eprintln!("largest round-trip error per format: {worst:#?}");
}

#[test]
fn relight_writes_ktx2_and_compressed_exr_too() {
    let dir = tempfile::tempdir().expect("temp");
    let level = Path::new(env!("CARGO_MANIFEST_DIR")).join("levels/colour_bleed.png");
    let bake_dir = dir.path().join("bake");
    assert_exit(
        &flatbake(&[
            "bake",
            s(&level),
            "-o",
            s(&bake_dir),
            "--quality",
            "draft",
            "--cache",
            "--quiet",
        ]),
        0,
    );
    let relit = dir.path().join("relit");
    assert_exit(
        &flatbake(&[
            "relight",
            s(&bake_dir.join("colour_bleed.flatbake")),
            "-o",
            s(&relit),
            "--layers",
            "--ktx2",
            "--exr-compression",
            "piz",
            "--padding",
            "8",
            "--quiet",
        ]),
        0,
    );
    let exr = std::fs::read(relit.join("colour_bleed.lightmap.exr")).expect("EXR");
    assert_eq!(exr_compression_code(&exr), 4);
    let img = image::load_from_memory_with_format(&exr, image::ImageFormat::OpenExr)
        .expect("EXR")
        .into_rgba32f();
    let want: Vec<[f32; 3]> = img.pixels().map(|p| [p.0[0], p.0[1], p.0[2]]).collect();
    let ktx2 = std::fs::read(relit.join("colour_bleed.lightmap.ktx2")).expect("KTX2");
    let texels = read_ktx2(&ktx2, img.width(), img.height());
    check_halves(&texels, &want);
    for (t, p) in texels.iter().zip(img.pixels()) {
        assert_eq!(t[3], p.0[3]);
    }
    let layers = std::fs::read_dir(&relit)
        .expect("relit")
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".layer-"))
        .filter(|e| e.file_name().to_string_lossy().ends_with(".exr"))
        .map(|e| exr_compression_code(&std::fs::read(e.path()).expect("layer")))
        .collect::<Vec<_>>();
    assert!(!layers.is_empty() && layers.iter().all(|&c| c == 4));
}

#[test]
fn the_moments_of_a_directional_bake_go_into_signed_ktx2_files_with_the_lightmap() {
    let lvl = level();
    let mut s = Settings::new(Quality::Draft);
    s.directional = true;
    let b = bake(&lvl, &s, &quiet).expect("bake");
    let dir = b.directional.as_ref().expect("asked for moments");
    let opts = OutputOptions {
        ktx2: true,
        ..OutputOptions::default()
    };
    let files =
        flatbake_core::output::directional::encode_directional(&lvl, &b.lightmap, dir, None, &opts)
            .expect("encodes");
    // Without the KTX2 lightmap, no KTX2 moments.
    let plain = flatbake_core::output::directional::encode_directional(
        &lvl,
        &b.lightmap,
        dir,
        None,
        &OutputOptions::default(),
    )
    .expect("encodes");
    assert!(plain.iter().all(|f| !f.kind.suffix().ends_with(".ktx2")));
    let cover = coverage(&lvl);
    let (w, h) = (lvl.width as u32, lvl.height as u32);
    let mut negatives = 0;
    for (kind, m) in [
        (OutputKind::DirectionalCosKtx2, &dir.cos),
        (OutputKind::DirectionalSinKtx2, &dir.sin),
    ] {
        let texels = read_ktx2(file(&files, kind.clone()), w, h);
        for (i, t) in texels.iter().enumerate() {
            assert_eq!(t[3], cover[i], "{kind:?} alpha at {i}");
            for c in 0..3 {
                let want = if cover[i] > 0.0 { m[i][c] } else { 0.0 };
                assert!(want.abs() < HALF_MAX);
                assert!(
                    (t[c] - want).abs() <= half_error_bound(want),
                    "{kind:?} texel {i} channel {c}: {} for {want}",
                    t[c]
                );
                negatives += usize::from(want < 0.0 && t[c] < 0.0);
            }
        }
    }
    // The light comes from the right (+x) and from all around the pillar:
    // moments of both signs, and the negative ones kept.
    assert!(negatives > 0);
}

/// Below one texel per pixel a texel's coverage is the share of its
/// painted pixels that are floor, in the EXR's `A`, the KTX2's alpha and
/// the PNG's alpha, while a texel with any floor is floor: its light is
/// the floor's, not padding.
#[test]
fn coverage_below_density_one_is_the_floor_share_of_each_texel() {
    use flatbake_core::bake::texels::{Density, Walls};
    let lvl = level();
    let (pw, ph) = (lvl.width, lvl.height);
    for m in [2usize, 3] {
        let t = draft_texels(&lvl, Density::Down(m as u32), Walls::default());
        let (tl, map) = (&t.level, &t.baked.lightmap);
        let (tw, th) = (tl.width, tl.height);
        assert_eq!((tw, th), (pw.div_ceil(m), ph.div_ceil(m)));
        // The floor's share of each texel, counted on the painted level.
        let share: Vec<f64> = (0..tw * th)
            .map(|i| {
                let (tx, ty) = (i % tw, i / tw);
                let (mut floor, mut all) = (0, 0);
                for y in ty * m..((ty + 1) * m).min(ph) {
                    for x in tx * m..((tx + 1) * m).min(pw) {
                        all += 1;
                        floor += usize::from(lvl.cells[y * pw + x] == Cell::Floor);
                    }
                }
                floor as f64 / all as f64
            })
            .collect();
        let partial = share.iter().filter(|&&f| f > 0.0 && f < 1.0).count();
        assert!(partial > 4, "1/{m}: the level wants texels part floor");
        let (files, exr, ktx) = exr_and_ktx2(tl, map, 2);
        let png = image::load_from_memory(file(&files, OutputKind::Lightmap))
            .expect("png")
            .into_rgba8();
        for i in 0..tw * th {
            let f = share[i];
            let (x, y) = ((i % tw) as u32, (i / tw) as u32);
            assert!(
                (exr.get_pixel(x, y).0[3] as f64 - f).abs() <= 1e-7,
                "1/{m} EXR A at {i}"
            );
            assert!(
                (ktx[i][3] as f64 - f).abs() <= f * 2f64.powi(-11),
                "1/{m} KTX2 A at {i}"
            );
            assert_eq!(
                png.get_pixel(x, y).0[3],
                (f * 255.0).round() as u8,
                "1/{m} PNG A at {i}"
            );
            // Any floor makes the texel floor: its light, never padding.
            assert_eq!(tl.cells[i] == Cell::Floor, f > 0.0, "1/{m} cell at {i}");
            if f > 0.0 {
                let p = exr.get_pixel(x, y).0;
                assert_eq!([p[0], p[1], p[2]], map.rgb[i], "1/{m} light at {i}");
            }
        }
    }
}

/// `lvl` baked at `draft` at `density` with `walls`.
fn draft_texels(
    lvl: &Level,
    density: flatbake_core::bake::texels::Density,
    walls: flatbake_core::bake::texels::Walls,
) -> flatbake_core::bake::texels::TexelBake {
    use flatbake_core::bake::texels::{TexelOptions, bake_texels};
    bake_texels(
        lvl,
        &Settings::new(Quality::Draft),
        &TexelOptions {
            density,
            walls,
            ..TexelOptions::default()
        },
        &quiet,
        &|_| {},
    )
    .expect("bake")
}

/// The lightmap's outputs with the EXR and the KTX2 at `padding`: the
/// files, the EXR as read by the image crate, the KTX2's texels.
fn exr_and_ktx2(
    tl: &Level,
    map: &flatbake_core::output::Lightmap,
    padding: u32,
) -> (Vec<Encoded>, image::Rgba32FImage, Vec<[f32; 4]>) {
    let opts = OutputOptions {
        hdr: true,
        ktx2: true,
        padding,
        ..OutputOptions::default()
    };
    let files = encode_images(tl, map, &opts).expect("encode");
    let exr = image::load_from_memory_with_format(
        file(&files, OutputKind::Hdr),
        image::ImageFormat::OpenExr,
    )
    .expect("EXR")
    .into_rgba32f();
    let ktx = read_ktx2(
        file(&files, OutputKind::Ktx2),
        tl.width as u32,
        tl.height as u32,
    );
    (files, exr, ktx)
}

/// `--walls` reaches the EXR and the KTX2 as it reaches the PNG: unpadded,
/// every solid texel holds what the walls mode says (the face's radiosity,
/// the emitter's emission, 0); padded, texels within the width hold the
/// padding and the wall-face texels beyond it keep the walls' values.
#[test]
fn walls_reach_the_exr_and_the_ktx2() {
    use flatbake_core::bake::texels::{Density, Walls};
    let lvl = level();
    let emission = 20.0f32;
    for walls in [Walls::Lit, Walls::Glow, Walls::Dark] {
        for (density, padding) in [(1u32, 0u32), (4, 0), (4, 1)] {
            let t = draft_texels(&lvl, Density::Up(density), walls);
            let (tl, map) = (&t.level, &t.baked.lightmap);
            let (tw, th) = (tl.width, tl.height);
            let (_, exr, ktx) = exr_and_ktx2(tl, map, padding);
            let exr: Vec<[f32; 3]> = exr.pixels().map(|p| [p.0[0], p.0[1], p.0[2]]).collect();
            check_halves(&ktx, &exr);
            let near_floor = |i: usize| {
                let (x, y) = (i % tw, i / tw);
                let p = padding as usize;
                (y.saturating_sub(p)..=(y + p).min(th - 1)).any(|yy| {
                    (x.saturating_sub(p)..=(x + p).min(tw - 1))
                        .any(|xx| tl.cells[yy * tw + xx] == Cell::Floor)
                })
            };
            let (mut lit, mut glowing, mut kept) = (0, 0, 0);
            for i in 0..tw * th {
                let Cell::Solid(mat) = tl.cells[i] else {
                    continue;
                };
                if padding > 0 && near_floor(i) {
                    continue; // the padding's, checked in tests/padding.rs
                }
                kept += usize::from(padding > 0);
                let v = exr[i];
                assert_eq!(v, map.rgb[i], "{walls:?} density {density} texel {i}");
                let emitter = tl.materials[mat as usize].emission[0] > 0.0;
                match walls {
                    Walls::Dark => assert_eq!(v, [0.0; 3]),
                    Walls::Glow if emitter => {
                        glowing += usize::from(v == [emission; 3]);
                    }
                    Walls::Glow => assert_eq!(v, [0.0; 3]),
                    Walls::Lit => lit += usize::from(!emitter && v[0] > 0.0),
                }
            }
            let what = format!("{walls:?} density {density} padding {padding}");
            if padding > 0 {
                assert!(kept > 0, "{what}: no wall texel beyond the padding");
            }
            match walls {
                Walls::Glow => assert!(glowing > 0, "{what}: no glowing texel"),
                Walls::Lit => assert!(lit > 0, "{what}: no lit wall texel"),
                Walls::Dark => {}
            }
        }
    }
}
