//! Outputs (docs/transport.md#tone-mapping-and-outputs): every file is decoded back and compared with
//! values computed here independently; atomic writes are checked by making
//! writes fail and looking at what is left on disk.

use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use flatbake_core::bake::report::Report;
use flatbake_core::level::material::{Material, MaterialKind};
use flatbake_core::level::{Cell, Level};
use flatbake_core::output::{
    Depth, Lightmap, OutputError, OutputOptions, RGBM_RANGE, ensure_output_dir, read_lightmap_exr,
    rgbm_decode, rgbm_encode, write_file_atomic, write_level_outputs,
};
use image::{ColorType, DynamicImage};

/// sRGB encoding written out here so the tests do not trust the library's.
fn srgb(v: f64) -> f64 {
    let v = if v.is_finite() {
        v.clamp(0.0, 1.0)
    } else {
        0.0
    };
    if v <= 0.0031308 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}
fn srgb8(v: f64) -> u8 {
    (srgb(v) * 255.0).round() as u8
}
fn srgb16(v: f64) -> u16 {
    (srgb(v) * 65535.0).round() as u16
}

fn emitter() -> Material {
    Material {
        color: [255, 255, 255],
        kind: MaterialKind::Emitter,
        reflectance: [0.5; 3],
        emission: [1.0; 3],
        group: None,
        line: None,
    }
}

/// A level from rows: `.` floor, `#` solid, ` ` void. Floor albedo varies per
/// pixel and per channel so that mixing channels or pixels up shows.
fn level(name: &str, rows: &[&str]) -> Level {
    let h = rows.len();
    let w = rows[0].len();
    let mut cells = vec![];
    let mut albedo = vec![];
    for (y, r) in rows.iter().enumerate() {
        for (x, ch) in r.chars().enumerate() {
            let c = match ch {
                '.' => Cell::Floor,
                '#' => Cell::Solid(0),
                _ => Cell::Void,
            };
            cells.push(c);
            let i = (y * w + x) as f32;
            albedo.push(if c == Cell::Floor {
                [0.8, 0.5 - 0.01 * i, 0.25]
            } else {
                [0.0; 3]
            });
        }
    }
    Level {
        name: name.into(),
        width: w,
        height: h,
        cells,
        albedo,
        materials: vec![emitter()],
        warnings: vec![],
        lossy_format: None,
        origin: Default::default(),
        floor_fraction: None,
    }
}

/// A lightmap whose values differ per pixel and channel, some above 1.
fn lightmap(lvl: &Level) -> Lightmap {
    let rgb = (0..lvl.width * lvl.height)
        .map(|i| {
            let i = i as f32;
            if lvl.cells[i as usize] == Cell::Void {
                [0.0; 3]
            } else {
                [0.05 + 0.09 * i, 0.3 + 0.4 * i, 0.013 * i]
            }
        })
        .collect();
    Lightmap {
        width: lvl.width,
        height: lvl.height,
        rgb,
    }
}

fn report_for(lvl: &Level) -> Report {
    Report {
        level: lvl.name.clone(),
        size: [lvl.width, lvl.height],
        quality: "normal".into(),
        kernel: "flatland".into(),
        solves: 3,
        residual: 1e-9,
        ..Report::default()
    }
}

fn opts(exposure: f64, depth: Depth, hdr: bool, rgbm: bool) -> OutputOptions {
    OutputOptions {
        exposure,
        depth,
        hdr,
        rgbm,
        ..OutputOptions::default()
    }
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().expect("temporary folder")
}

fn open(path: &Path) -> DynamicImage {
    image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn rgba8(path: &Path) -> Vec<[u8; 4]> {
    let img = open(path);
    assert_eq!(img.color(), ColorType::Rgba8, "{}", path.display());
    img.to_rgba8().pixels().map(|p| p.0).collect()
}

/// Files in `dir` whose names are not in `expected`: leftovers.
fn leftovers(dir: &Path, expected: &[&str]) -> Vec<String> {
    fs::read_dir(dir)
        .expect("read dir")
        .map(|e| {
            e.expect("dir entry")
                .file_name()
                .to_string_lossy()
                .into_owned()
        })
        .filter(|n| !expected.contains(&n.as_str()))
        .collect()
}

const ROWS: &[&str] = &["#..", ". #", "..."];

#[test]
fn lightmap_png_is_srgb_of_light_times_exposure_with_transparent_void() {
    let lvl = level("m", ROWS);
    let map = lightmap(&lvl);
    let dir = tmp();
    let paths = write_level_outputs(
        dir.path(),
        &lvl,
        &map,
        &report_for(&lvl),
        &opts(0.5, Depth::Eight, false, false),
    )
    .expect("write");
    assert_eq!(paths[0], dir.path().join("m.lightmap.png"));
    let px = rgba8(&paths[0]);
    for (i, p) in px.iter().enumerate() {
        if lvl.cells[i] == Cell::Void {
            assert_eq!(*p, [0, 0, 0, 0], "void pixel {i}");
            continue;
        }
        // Solid pixels hold their own value too (emitters glow).
        let want = map.rgb[i].map(|v| srgb8(v as f64 * 0.5));
        assert_eq!(p[..3], want, "pixel {i}");
        assert_eq!(p[3], 255, "pixel {i} must be opaque");
    }
}

#[test]
fn depth_sixteen_writes_a_16_bit_png_with_finer_values() {
    let mut lvl = level("d", &["...."]);
    lvl.albedo = vec![[1.0; 3]; 4];
    // Two values closer together than one 8-bit step.
    let map = Lightmap {
        width: 4,
        height: 1,
        rgb: vec![[0.5; 3], [0.501; 3], [0.02; 3], [0.0201; 3]],
    };
    let dir = tmp();
    let p16 = write_level_outputs(
        dir.path(),
        &lvl,
        &map,
        &report_for(&lvl),
        &opts(1.0, Depth::Sixteen, false, false),
    )
    .expect("write");
    for path in &p16[..2] {
        let img = open(path);
        assert_eq!(img.color(), ColorType::Rgba16, "{}", path.display());
        let px: Vec<[u16; 4]> = img.to_rgba16().pixels().map(|p| p.0).collect();
        for (i, p) in px.iter().enumerate() {
            assert_eq!(
                p[..3],
                map.rgb[i].map(|v| srgb16(v as f64)),
                "{} pixel {i}",
                path.display()
            );
            assert_eq!(p[3], u16::MAX);
        }
        assert_ne!(px[0][0], px[1][0], "16 bits separate 0.5 and 0.501");
        assert_ne!(px[2][0], px[3][0], "16 bits separate 0.02 and 0.0201");
    }
    let dir8 = tmp();
    let p8 = write_level_outputs(
        dir8.path(),
        &lvl,
        &map,
        &report_for(&lvl),
        &OutputOptions::default(),
    )
    .expect("write");
    let px = rgba8(&p8[0]);
    assert_eq!(px[0], px[1], "8 bits cannot separate 0.5 and 0.501");
}

#[test]
fn lit_is_albedo_times_light_on_floor_and_the_lightmap_on_solids() {
    let lvl = level("lit", ROWS);
    let map = lightmap(&lvl);
    let dir = tmp();
    let exposure = 0.7;
    let paths = write_level_outputs(
        dir.path(),
        &lvl,
        &map,
        &report_for(&lvl),
        &opts(exposure, Depth::Eight, false, false),
    )
    .expect("write");
    assert_eq!(paths[1], dir.path().join("lit.lit.png"));
    let px = rgba8(&paths[1]);
    for (i, p) in px.iter().enumerate() {
        let want = match lvl.cells[i] {
            Cell::Void => [0, 0, 0, 0],
            Cell::Floor => {
                let c = [0, 1, 2]
                    .map(|k| srgb8(lvl.albedo[i][k] as f64 * map.rgb[i][k] as f64 * exposure));
                [c[0], c[1], c[2], 255]
            }
            Cell::Solid(_) => {
                let c = map.rgb[i].map(|v| srgb8(v as f64 * exposure));
                [c[0], c[1], c[2], 255]
            }
        };
        assert_eq!(*p, want, "pixel {i} ({:?})", lvl.cells[i]);
    }
}

#[test]
fn exr_reads_back_exact_floats_unscaled_by_exposure_with_walls_as_the_png_and_void_zero() {
    let lvl = level("h", ROWS);
    let mut map = lightmap(&lvl);
    map.rgb[1] = [37.25, 1.0e-7, 3.333_333_3]; // HDR, tiny, not a short binary fraction
    let dir = tmp();
    let paths = write_level_outputs(
        dir.path(),
        &lvl,
        &map,
        &report_for(&lvl),
        &opts(4.0, Depth::Eight, true, false),
    )
    .expect("write");
    let exr = dir.path().join("h.lightmap.exr");
    assert!(paths.contains(&exr), "{paths:?}");
    let (w, h, px) = read_lightmap_exr(&exr).expect("read exr");
    assert_eq!((w, h), (3, 3));
    for (i, p) in px.iter().enumerate() {
        // Solid pixels hold what the lightmap holds there (the PNG's
        // rule, what `--walls` put there); void 0.
        let want = if lvl.cells[i] == Cell::Void {
            [0.0; 3]
        } else {
            map.rgb[i]
        };
        assert_eq!(*p, want, "pixel {i} ({:?})", lvl.cells[i]);
    }
    assert!(
        (0..px.len()).any(|i| matches!(lvl.cells[i], Cell::Solid(_)) && px[i] != [0.0; 3]),
        "the level wants a lit wall pixel"
    );
}

#[test]
fn exposure_scales_the_pngs_but_not_the_exr() {
    let lvl = level("x", ROWS);
    let map = lightmap(&lvl);
    let (a, b) = (tmp(), tmp());
    write_level_outputs(
        a.path(),
        &lvl,
        &map,
        &report_for(&lvl),
        &opts(1.0, Depth::Eight, true, true),
    )
    .expect("write");
    write_level_outputs(
        b.path(),
        &lvl,
        &map,
        &report_for(&lvl),
        &opts(0.25, Depth::Eight, true, true),
    )
    .expect("write");
    for name in ["x.lightmap.exr", "x.lightmap.rgbm.png"] {
        let (fa, fb) = (
            fs::read(a.path().join(name)).expect("read"),
            fs::read(b.path().join(name)).expect("read"),
        );
        assert_eq!(fa, fb, "{name} must not depend on exposure");
    }
    let (la, lb) = (
        rgba8(&a.path().join("x.lightmap.png")),
        rgba8(&b.path().join("x.lightmap.png")),
    );
    assert_ne!(la, lb);
    // Pixel 1 is floor with value [0.14, 0.7, 0.013].
    assert_eq!(lb[1][..3], map.rgb[1].map(|v| srgb8(v as f64 * 0.25)));
}

#[test]
fn output_bytes_are_the_same_on_every_run() {
    // Large enough for several PNG rows and EXR lines of real size.
    let rows: Vec<String> = (0..70)
        .map(|y| {
            (0..130)
                .map(|x| if (x * 7 + y * 3) % 11 == 0 { '#' } else { '.' })
                .collect()
        })
        .collect();
    let rows: Vec<&str> = rows.iter().map(String::as_str).collect();
    let lvl = level("big", &rows);
    let map = lightmap(&lvl);
    let (a, b) = (tmp(), tmp());
    for d in [&a, &b] {
        write_level_outputs(
            d.path(),
            &lvl,
            &map,
            &report_for(&lvl),
            &opts(1.0, Depth::Sixteen, true, true),
        )
        .expect("write");
    }
    for name in [
        "big.lightmap.png",
        "big.lit.png",
        "big.lightmap.exr",
        "big.lightmap.rgbm.png",
    ] {
        let (fa, fb) = (
            fs::read(a.path().join(name)).expect("read"),
            fs::read(b.path().join(name)).expect("read"),
        );
        assert!(fa == fb, "{name} differs between two identical writes");
    }
    let (w, h, px) = read_lightmap_exr(&a.path().join("big.lightmap.exr")).expect("read exr");
    assert_eq!((w, h), (130, 70));
    let i = 69 * 130 + 128;
    assert_eq!(lvl.cells[i], Cell::Floor);
    assert_eq!(px[i], map.rgb[i]);
}

/// Log-spaced values between `lo` and `hi`.
fn log_range(lo: f32, hi: f32, n: usize) -> impl Iterator<Item = f32> {
    (0..n).map(move |k| lo * (hi / lo).powf(k as f32 / (n - 1) as f32))
}

#[test]
fn rgbm_round_trip_is_within_a_few_percent_from_1e_3_to_6() {
    for v in log_range(1e-3, RGBM_RANGE, 400) {
        for hue in [
            [1.0, 1.0, 1.0],
            [1.0, 0.5, 0.1],
            [0.02, 1.0, 0.3],
            [0.0, 0.0, 1.0],
        ] {
            let rgb: [f32; 3] = [0, 1, 2].map(|k| v * hue[k]);
            let enc = rgbm_encode(rgb);
            let dec = rgbm_decode(enc);
            // Every channel is within half an 8-bit step of this pixel's scale.
            let step = enc[3] as f32 / 255.0 * RGBM_RANGE / 255.0;
            for k in 0..3 {
                let err = (dec[k] - rgb[k]).abs();
                assert!(
                    err <= 0.5 * step * 1.0001 + 1e-9,
                    "{rgb:?} -> {enc:?} -> {dec:?}: channel {k} off by {err}"
                );
            }
            // The brightest channel keeps its relative precision.
            let rel = (dec[0].max(dec[1]).max(dec[2]) - v).abs() / v;
            assert!(rel < 0.05, "{rgb:?} -> {dec:?}: {:.2}% off", rel * 100.0);
            if v > 0.025 {
                assert!(
                    rel < 0.005,
                    "{rgb:?} -> {dec:?}: {:.3}% off above 0.025",
                    rel * 100.0
                );
            }
        }
    }
}

#[test]
fn rgbm_alpha_is_m_rounded_up_and_extremes_are_safe() {
    // max 3.0: M = 0.5 exactly -> a = 128 after rounding 127.5 up.
    let p = rgbm_encode([3.0, 1.5, 0.0]);
    assert_eq!(p[3], 128);
    assert_eq!(p[0], 255 - 1, "3.0 / (128/255 * 6) = 0.996 -> 254");
    assert_eq!(rgbm_encode([0.0; 3]), [0, 0, 0, 1]);
    assert_eq!(rgbm_decode([0, 0, 0, 1]), [0.0; 3]);
    assert_eq!(rgbm_encode([RGBM_RANGE; 3]), [255; 4]);
    // Above the range clamps to it rather than wrapping.
    assert_eq!(
        rgbm_decode(rgbm_encode([100.0, 6.0, 0.0])),
        [RGBM_RANGE, RGBM_RANGE, 0.0]
    );
    // Poisoned inputs encode as 0 in that channel only.
    assert_eq!(rgbm_encode([f32::NAN, -2.0, f32::INFINITY]), [0, 0, 0, 1]);
    let p = rgbm_encode([f32::NAN, 1.0, f32::NEG_INFINITY]);
    assert_eq!((p[0], p[2]), (0, 0));
    assert!((rgbm_decode(p)[1] - 1.0).abs() < 0.01);
}

#[test]
fn rgbm_png_decodes_to_the_hdr_lightmap() {
    let lvl = level("r", ROWS);
    let mut map = lightmap(&lvl);
    map.rgb[2] = [5.0, 0.01, 2.5];
    let dir = tmp();
    write_level_outputs(
        dir.path(),
        &lvl,
        &map,
        &report_for(&lvl),
        &opts(3.0, Depth::Sixteen, false, true),
    )
    .expect("write");
    let px = rgba8(&dir.path().join("r.lightmap.rgbm.png"));
    for (i, p) in px.iter().enumerate() {
        let dec = rgbm_decode(*p);
        // The EXR's values: walls as the lightmap holds them, void 0.
        let want = if lvl.cells[i] == Cell::Void {
            [0.0; 3]
        } else {
            map.rgb[i]
        };
        for k in 0..3 {
            assert!(
                (dec[k] - want[k]).abs() <= 0.5 * p[3] as f32 / 255.0 * RGBM_RANGE / 255.0 + 1e-6,
                "pixel {i}"
            );
        }
    }
    assert!(
        !dir.path().join("r.lightmap.exr").exists(),
        "no EXR without hdr"
    );
}

#[test]
fn report_json_parses_back_and_lists_the_outputs_written() {
    let lvl = level("rep", ROWS);
    let map = lightmap(&lvl);
    let dir = tmp();
    let mut rep = report_for(&lvl);
    rep.warnings.push("a warning".into());
    rep.timings.total = 1.5;
    let paths = write_level_outputs(
        dir.path(),
        &lvl,
        &map,
        &rep,
        &opts(1.0, Depth::Eight, true, true),
    )
    .expect("write");
    let names = [
        "rep.lightmap.png",
        "rep.lit.png",
        "rep.lightmap.exr",
        "rep.lightmap.rgbm.png",
        "rep.report.json",
    ];
    assert_eq!(paths, names.map(|n| dir.path().join(n)));
    let text = fs::read_to_string(dir.path().join("rep.report.json")).expect("read report");
    assert!(
        text.contains("\n  \"level\": \"rep\""),
        "pretty-printed: {text}"
    );
    let back: Report = serde_json::from_str(&text).expect("report parses back");
    assert_eq!(back.outputs, names.map(String::from));
    assert_eq!(back.warnings, rep.warnings);
    assert_eq!(
        (back.level.as_str(), back.size, back.solves),
        ("rep", [3, 3], 3)
    );
    assert!(back.timings.write >= 0.0 && back.timings.total >= 1.5);
    assert!(
        leftovers(dir.path(), &names).is_empty(),
        "no temporary files left"
    );
}

#[test]
fn writing_twice_replaces_the_content() {
    let lvl = level("twice", ROWS);
    let map = lightmap(&lvl);
    let dir = tmp();
    write_level_outputs(
        dir.path(),
        &lvl,
        &map,
        &report_for(&lvl),
        &opts(1.0, Depth::Eight, false, false),
    )
    .expect("write");
    let first = rgba8(&dir.path().join("twice.lightmap.png"));
    write_level_outputs(
        dir.path(),
        &lvl,
        &map,
        &report_for(&lvl),
        &opts(0.1, Depth::Eight, false, false),
    )
    .expect("write");
    let second = rgba8(&dir.path().join("twice.lightmap.png"));
    assert_ne!(first, second);
    assert_eq!(second[1][..3], map.rgb[1].map(|v| srgb8(v as f64 * 0.1)));
    let names = ["twice.lightmap.png", "twice.lit.png", "twice.report.json"];
    assert!(leftovers(dir.path(), &names).is_empty());
}

#[test]
fn nan_inf_and_negative_light_do_not_poison_the_outputs() {
    let lvl = level("nan", &["...", "#.."]);
    let map = Lightmap {
        width: 3,
        height: 2,
        rgb: vec![
            [f32::NAN, 0.5, 0.5],
            [f32::INFINITY, f32::NEG_INFINITY, -0.3],
            [1e30, 2.0, 0.25],
            [f32::NAN, f32::NAN, f32::NAN],
            [-1e-9, 0.0, 0.5],
            [0.5, 0.5, 0.5],
        ],
    };
    let dir = tmp();
    write_level_outputs(
        dir.path(),
        &lvl,
        &map,
        &report_for(&lvl),
        &opts(1.0, Depth::Eight, true, true),
    )
    .expect("write");
    let px = rgba8(&dir.path().join("nan.lightmap.png"));
    assert_eq!(
        px[0],
        [0, srgb8(0.5), srgb8(0.5), 255],
        "NaN is 0, other channels unharmed"
    );
    assert_eq!(px[1], [0, 0, 0, 255], "inf and negative are 0");
    assert_eq!(px[2], [255, 255, srgb8(0.25), 255], "large values clamp");
    assert_eq!(
        px[3],
        [0, 0, 0, 255],
        "a NaN solid pixel is black, not garbage"
    );
    assert_eq!(
        px[5],
        [srgb8(0.5); 3].into_iter().chain([255]).collect::<Vec<_>>()[..]
    );
    let lit = rgba8(&dir.path().join("nan.lit.png"));
    assert_eq!(lit[1], [0, 0, 0, 255]);
    let (_, _, hdr) = read_lightmap_exr(&dir.path().join("nan.lightmap.exr")).expect("read exr");
    assert_eq!(hdr[0], [0.0, 0.5, 0.5]);
    assert_eq!(hdr[1], [0.0, 0.0, 0.0]);
    assert_eq!(hdr[2], [1e30, 2.0, 0.25], "the EXR keeps large values");
    assert_eq!(hdr[4], [0.0, 0.0, 0.5]);
    assert!(hdr.iter().flatten().all(|v| v.is_finite() && *v >= 0.0));
    let rgbm = rgba8(&dir.path().join("nan.lightmap.rgbm.png"));
    assert_eq!(rgbm[1], [0, 0, 0, 1]);
}

/// True when permission bits are not enforced for us (running as root).
fn permissions_ignored(dir: &Path) -> bool {
    fs::write(dir.join("probe"), b"x").is_ok()
}

#[cfg(unix)]
#[test]
fn unwritable_folder_keeps_the_previous_file_and_names_the_path() {
    use std::os::unix::fs::PermissionsExt;
    let lvl = level("ro", ROWS);
    let map = lightmap(&lvl);
    let dir = tmp();
    let out = dir.path().join("out");
    fs::create_dir(&out).expect("mkdir");
    write_level_outputs(
        &out,
        &lvl,
        &map,
        &report_for(&lvl),
        &OutputOptions::default(),
    )
    .expect("first write");
    let before = fs::read(out.join("ro.lightmap.png")).expect("read");
    fs::set_permissions(&out, fs::Permissions::from_mode(0o555)).expect("chmod");
    if permissions_ignored(&out) {
        fs::set_permissions(&out, fs::Permissions::from_mode(0o755)).expect("chmod back");
        eprintln!(
            "note: permission bits are not enforced here (root?); skipping the read-only folder check"
        );
        return;
    }
    let res = write_level_outputs(
        &out,
        &lvl,
        &map,
        &report_for(&lvl),
        &opts(0.2, Depth::Eight, false, false),
    );
    fs::set_permissions(&out, fs::Permissions::from_mode(0o755)).expect("chmod back");
    let err = res.expect_err("writing into a read-only folder must fail");
    let msg = err.to_string();
    let path = out.join("ro.lightmap.png");
    assert_eq!(
        msg,
        format!("cannot write {}: permission denied", path.display())
    );
    assert_eq!(
        fs::read(&path).expect("read"),
        before,
        "previous output intact"
    );
    assert!(leftovers(&out, &["ro.lightmap.png", "ro.lit.png", "ro.report.json"]).is_empty());
}

#[test]
fn a_failed_encode_touches_nothing_on_disk() {
    let lvl = level("enc", ROWS);
    let map = lightmap(&lvl);
    let dir = tmp();
    write_level_outputs(
        dir.path(),
        &lvl,
        &map,
        &report_for(&lvl),
        &OutputOptions::default(),
    )
    .expect("write");
    let names = ["enc.lightmap.png", "enc.lit.png", "enc.report.json"];
    let before: Vec<Vec<u8>> = names
        .iter()
        .map(|n| fs::read(dir.path().join(n)).expect("read"))
        .collect();
    let wrong = Lightmap {
        width: 2,
        height: 3,
        rgb: vec![[1.0; 3]; 6],
    };
    let err = write_level_outputs(
        dir.path(),
        &lvl,
        &wrong,
        &report_for(&lvl),
        &OutputOptions::default(),
    )
    .expect_err("size mismatch");
    assert!(
        err.to_string().contains("level enc") && err.to_string().contains("2x3"),
        "{err}"
    );
    let after: Vec<Vec<u8>> = names
        .iter()
        .map(|n| fs::read(dir.path().join(n)).expect("read"))
        .collect();
    assert_eq!(before, after);
    assert!(leftovers(dir.path(), &names).is_empty());
}

#[test]
fn an_empty_level_is_an_error_not_a_panic() {
    let lvl = Level {
        name: "empty".into(),
        width: 0,
        height: 0,
        cells: vec![],
        albedo: vec![],
        materials: vec![],
        warnings: vec![],
        lossy_format: None,
        origin: Default::default(),
        floor_fraction: None,
    };
    let map = Lightmap {
        width: 0,
        height: 0,
        rgb: vec![],
    };
    let dir = tmp();
    let err = write_level_outputs(
        dir.path(),
        &lvl,
        &map,
        &report_for(&lvl),
        &OutputOptions::default(),
    )
    .expect_err("nothing to write");
    assert!(err.to_string().contains("0x0"), "{err}");
    assert!(leftovers(dir.path(), &[]).is_empty());
}

#[test]
fn a_failed_rename_leaves_no_temporary_file_and_names_the_path() {
    let lvl = level("busy", ROWS);
    let map = lightmap(&lvl);
    let dir = tmp();
    // A folder where the lit image should go: the rename onto it fails, even
    // for root.
    let blocker = dir.path().join("busy.lit.png");
    fs::create_dir(&blocker).expect("mkdir");
    fs::write(blocker.join("keep"), b"x").expect("write");
    let err = write_level_outputs(
        dir.path(),
        &lvl,
        &map,
        &report_for(&lvl),
        &OutputOptions::default(),
    )
    .expect_err("rename onto a folder must fail");
    assert_eq!(err.path(), Some(blocker.as_path()));
    assert!(
        err.to_string()
            .starts_with(&format!("cannot write {}: ", blocker.display())),
        "{err}"
    );
    assert!(blocker.join("keep").exists());
    // The report comes last, so it is not written for a failed set.
    assert!(!dir.path().join("busy.report.json").exists());
    assert!(leftovers(dir.path(), &["busy.lightmap.png", "busy.lit.png"]).is_empty());
}

#[test]
fn an_output_folder_that_is_a_file_fails_clearly() {
    let lvl = level("f", ROWS);
    let map = lightmap(&lvl);
    let dir = tmp();
    let file = dir.path().join("out");
    fs::write(&file, b"not a folder").expect("write");
    let err = write_level_outputs(
        &file,
        &lvl,
        &map,
        &report_for(&lvl),
        &OutputOptions::default(),
    )
    .expect_err("file");
    assert_eq!(
        err.to_string(),
        format!("output folder {} is a file, not a folder", file.display())
    );
    let below = file.join("x");
    let err = write_level_outputs(
        &below,
        &lvl,
        &map,
        &report_for(&lvl),
        &OutputOptions::default(),
    )
    .expect_err("file");
    assert_eq!(
        err.to_string(),
        format!(
            "output folder {} cannot be created: {} is a file, not a folder",
            below.display(),
            file.display()
        )
    );
    let err = ensure_output_dir(&below).expect_err("cannot create below a file");
    assert!(err.to_string().contains("is a file, not a folder"), "{err}");
    let err = ensure_output_dir(&file).expect_err("a file is not a folder");
    assert!(err.to_string().contains("is a file, not a folder"), "{err}");
    // A single file write below a file names that file's path.
    let err = write_file_atomic(&file.join("a.png"), b"x").expect_err("below a file");
    assert!(
        err.to_string().contains(&file.display().to_string()),
        "{err}"
    );
    assert_eq!(fs::read(&file).expect("read"), b"not a folder");
}

#[test]
fn a_missing_folder_is_named_and_ensure_output_dir_creates_it() {
    let lvl = level("m", ROWS);
    let map = lightmap(&lvl);
    let dir = tmp();
    let out = dir.path().join("out").join("x");
    let err = write_level_outputs(
        &out,
        &lvl,
        &map,
        &report_for(&lvl),
        &OutputOptions::default(),
    )
    .expect_err("missing");
    assert_eq!(
        err.to_string(),
        format!("output folder {} does not exist", out.display())
    );
    assert!(!out.exists(), "writing does not create folders");
    ensure_output_dir(&out).expect("create");
    ensure_output_dir(&out).expect("existing folder is fine");
    write_level_outputs(
        &out,
        &lvl,
        &map,
        &report_for(&lvl),
        &OutputOptions::default(),
    )
    .expect("write");
    assert!(out.join("m.lightmap.png").is_file());
}

#[test]
fn a_full_disk_says_the_disk_is_full() {
    let path = PathBuf::from("out/x/level.lightmap.png");
    let err = OutputError::from_io(&path, io::Error::from_raw_os_error(28));
    if cfg!(unix) {
        assert_eq!(
            err.to_string(),
            "cannot write out/x/level.lightmap.png: the disk is full"
        );
        assert!(err.is_disk_full());
    }
    let err = OutputError::from_io(&path, io::Error::from(io::ErrorKind::StorageFull));
    assert_eq!(
        err.to_string(),
        "cannot write out/x/level.lightmap.png: the disk is full"
    );
    assert!(err.is_disk_full());
    let err = OutputError::from_io(&path, io::Error::from(io::ErrorKind::PermissionDenied));
    assert_eq!(
        err.to_string(),
        "cannot write out/x/level.lightmap.png: permission denied"
    );
    assert!(!err.is_disk_full());
    assert_eq!(err.path(), Some(path.as_path()));
}

#[cfg(unix)]
#[test]
fn output_files_get_the_usual_permissions_not_owner_only() {
    use std::os::unix::fs::PermissionsExt;
    let lvl = level("perm", ROWS);
    let map = lightmap(&lvl);
    let dir = tmp();
    write_level_outputs(
        dir.path(),
        &lvl,
        &map,
        &report_for(&lvl),
        &OutputOptions::default(),
    )
    .expect("write");
    // A file created the ordinary way shows what the umask allows.
    let plain = dir.path().join("plain");
    fs::File::create(&plain).expect("create");
    let want = fs::metadata(&plain).expect("stat").permissions().mode() & 0o777;
    for n in ["perm.lightmap.png", "perm.lit.png", "perm.report.json"] {
        let mode = fs::metadata(dir.path().join(n))
            .expect("stat")
            .permissions()
            .mode()
            & 0o777;
        assert_eq!(mode, want, "{n}: {mode:o} vs {want:o}");
    }
}
