//! Bad input through the command line (docs/robustness.md, "Bad input"): every broken file, palette
//! or output folder gets a clear message naming it, good levels in the same
//! batch still bake, earlier good outputs survive, and the exit status says
//! something failed (0 baked, 1 a level failed, 2 a bad command line).
//!
//! The library-level details (every palette message word for word, every
//! image variant's pixels) are in `tests/palette.rs` and
//! `tests/level_loading.rs`; these tests check what a user of the binary sees.

mod common;
use common::*;

use std::path::{Path, PathBuf};
use std::process::Command;

/// Copies a fixture into `dir` under `name`.
fn copy(dir: &Path, fixture_name: &str, name: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::copy(fixture(fixture_name), &p).unwrap();
    p
}

const PALETTE: &str = r##"[[wall]]
color = "#808080"
reflectance = 0.5

[[emitter]]
color = "#ffffff"
emission = 1.0
reflectance = 0.2
"##;

/// Paints rows (`#` wall grey, `L` white light, `.` dark floor) as `NAME.png`,
/// with `palette` beside it as `NAME.palette.toml` when given.
fn paint(dir: &Path, name: &str, rows: &[&str], palette: Option<&str>) -> PathBuf {
    let (w, h) = (rows[0].len() as u32, rows.len() as u32);
    let img = image::RgbaImage::from_fn(w, h, |x, y| {
        image::Rgba(match rows[y as usize].as_bytes()[x as usize] {
            b'#' => [0x80, 0x80, 0x80, 255],
            b'L' => [255, 255, 255, 255],
            b'a' => [0x86, 0x7c, 0x80, 255], // anti-aliased wall grey
            // Dark, but no built-in palette colour (#202020 is soot, a wall).
            _ => [0x50, 0x44, 0x38, 255],
        })
    });
    let path = dir.join(format!("{name}.png"));
    img.save(&path).unwrap();
    if let Some(p) = palette {
        std::fs::write(dir.join(format!("{name}.palette.toml")), p).unwrap();
    }
    path
}

const ROOM: &[&str] = &[
    "##########",
    "#........#",
    "#...L....#",
    "#........#",
    "##########",
];

fn report(out: &Path, name: &str) -> serde_json::Value {
    let p = out.join(format!("{name}.report.json"));
    serde_json::from_slice(&std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display())))
        .unwrap()
}

// ---------------------------------------------------------------------------
// Level files

#[test]
fn truncated_empty_and_non_image_files_are_named_with_their_problem() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    for (fix, words) in [
        (
            "truncated_room.png",
            vec!["truncated_room.png", "truncated"],
        ),
        (
            "empty_should_fail.png",
            vec!["empty_should_fail.png", "empty (0 bytes)"],
        ),
        (
            "text_named_should_fail.png",
            vec![
                "text_named_should_fail.png",
                "not an image",
                "This is a text",
            ],
        ),
    ] {
        let o = flatbake_mixed(&[&"bake", &fixture(fix), &"-o", &out]);
        assert_exit(&o, EXIT_FAILED);
        assert_says(&o, &words);
        assert_says(&o, &["0 levels baked", "1 failed"]);
    }
    // Binary junk under an image name; a missing file.
    let junk = dir.path().join("junk.png");
    std::fs::write(&junk, [0u8, 1, 2, 3, 0xff, 0xfe, 7, 9, 11, 13]).unwrap();
    let o = flatbake_mixed(&[&"bake", &junk, &"-o", &out]);
    assert_exit(&o, EXIT_FAILED);
    assert_says(&o, &["junk.png", "not an image", "00 01 02 03"]);
    let o = flatbake_mixed(&[&"bake", &dir.path().join("nowhere.png"), &"-o", &out]);
    assert_exit(&o, EXIT_FAILED);
    assert_says(&o, &["nowhere.png", "file not found"]);
    // Nothing but the batch summary, which names the failure.
    let left: Vec<String> = std::fs::read_dir(&out)
        .map(|rd| {
            rd.map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    assert!(left.iter().all(|f| f == "batch.json"), "{left:?}");
}

/// The format comes from the content: a PNG named `.jpg` or `.bmp` bakes.
#[test]
fn wrong_extension_loads_by_content() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let jpg = fixture("png_content_named.jpg");
    let bmp = copy(dir.path(), "rgb8_room.png", "room_named.bmp");
    let o = flatbake_mixed(&[&"bake", &jpg, &bmp, &"-o", &out]);
    assert_exit(&o, EXIT_OK);
    for name in ["png_content_named", "room_named"] {
        assert!(out.join(format!("{name}.lightmap.png")).is_file(), "{name}");
    }
}

#[test]
fn enormous_declared_size_is_refused_with_the_limit_and_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    for (fix, dims) in [
        (
            "huge_header_100000x100000_should_fail_fast.png",
            "100000 x 100000",
        ),
        ("huge_header_with_idat_should_fail_fast.png", ""),
        (
            "huge_header_16000x16000_should_fail_fast.qoi",
            "16000 x 16000",
        ),
    ] {
        let o = flatbake_mixed(&[&"bake", &fixture(fix), &"-o", &out]);
        assert_exit(&o, EXIT_FAILED);
        assert_says(
            &o,
            &[
                fix,
                dims,
                "more than the limit of 67108864 pixels",
                "--max-pixels",
            ],
        );
    }
}

/// `--max-pixels` is the flag the message names: lowering it refuses a real
/// level, raising it back to the level's size lets it bake.
#[test]
fn max_pixels_flag_raises_and_lowers_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let lvl = paint(dir.path(), "room", ROOM, Some(PALETTE));
    let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &out, &"--max-pixels", &"49"]);
    assert_exit(&o, EXIT_FAILED);
    assert_says(
        &o,
        &[
            "10 x 5 = 50 pixels",
            "limit of 49 pixels",
            "--max-pixels 50",
        ],
    );
    let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &out, &"--max-pixels", &"50"]);
    assert_exit(&o, EXIT_OK);
    let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &out, &"--max-pixels", &"lots"]);
    assert_exit(&o, EXIT_USAGE);
}

/// 16-bit, grey, grey + alpha, paletted and alpha images all bake, and the
/// lightmap has the level's size.
#[test]
fn sixteen_bit_grey_paletted_and_alpha_images_bake() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let names = [
        "rgb8_room",
        "rgb16_room",
        "gray8_room",
        "gray16_room",
        "graya8_room_with_void",
        "paletted8_room_with_trns_void",
        "paletted2_room_with_trns_void",
        "rgba8_room_with_void",
    ];
    let paths: Vec<PathBuf> = names.iter().map(|n| fixture(&format!("{n}.png"))).collect();
    let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&"bake"];
    for p in &paths {
        args.push(p);
    }
    args.push(&"-o");
    args.push(&out);
    let o = flatbake(&args);
    assert_exit(&o, EXIT_OK);
    assert_says(&o, &["8 levels baked", "0 failed"]);
    for (n, p) in names.iter().zip(&paths) {
        let (w, h) = image::image_dimensions(p).unwrap();
        let lm = image::open(out.join(format!("{n}.lightmap.png"))).unwrap();
        assert_eq!((lm.width(), lm.height()), (w, h), "{n}");
        if n.contains("void") {
            // Void pixels are transparent in the lightmap.
            assert!(lm.to_rgba8().pixels().any(|p| p[3] == 0), "{n}");
        }
    }
}

// ---------------------------------------------------------------------------
// Palettes

/// Each broken palette, given with `--palette` or found beside the level,
/// fails the level with `FILE:LINE: problem`.
#[test]
fn palette_errors_name_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let cases: &[(&str, &str, usize, &[&str])] = &[
        (
            "syntax",
            "[[wall]]\ncolor = \"#808080\"\nreflectance = 0.5 0.5\n",
            3,
            &["invalid TOML"],
        ),
        (
            "unknown_key",
            "[[wall]]\ncolor = \"#808080\"\nreflectivity = 0.5\n",
            3,
            &["unknown key `reflectivity`"],
        ),
        (
            "wrong_type",
            "[[wall]]\ncolor = \"#808080\"\nreflectance = \"high\"\n",
            3,
            &["reflectance must be", "found string"],
        ),
        (
            "reflectance_high",
            "[[wall]]\ncolor = \"#808080\"\nreflectance = 1.5\n",
            3,
            &["reflectance 1.5 is outside 0..=1"],
        ),
        (
            "reflectance_low",
            "[[wall]]\ncolor = \"#808080\"\nreflectance = [0.5, -0.1, 0.5]\n",
            3,
            &["reflectance -0.1 is outside 0..=1"],
        ),
        (
            "emission_negative",
            "[[emitter]]\ncolor = \"#fff\"\nemission = -2\n",
            3,
            &["emission -2 is negative"],
        ),
        (
            "emission_nan",
            "[[emitter]]\ncolor = \"#fff\"\nemission = nan\n",
            3,
            &["emission nan is not a finite number"],
        ),
        (
            "emission_inf",
            "[[emitter]]\ncolor = \"#fff\"\n\nemission = [1, 1, inf]\n",
            4,
            &["emission inf is not a finite number"],
        ),
        (
            "emission_too_large",
            "[[emitter]]\ncolor = \"#fff\"\nemission = [1, 1e39, 1]\n",
            3,
            &["emission 1e39 is too large", "at most 1e15"],
        ),
        (
            "duplicate",
            "[[wall]]\ncolor = \"#808080\"\nreflectance = 0.5\n\n[[emitter]]\ncolor = [128, 128, 128]\nemission = 1\n",
            6,
            &["duplicate colour", "[128, 128, 128]", "line 2"],
        ),
        (
            "duplicate_short_spelling",
            "[[wall]]\ncolor = \"#fff\"\nreflectance = 0.5\n[[wall]]\ncolor = \"#FFFFFF\"\nreflectance = 0.2\n",
            5,
            &["duplicate colour", "\"#fff\"", "line 2"],
        ),
        (
            "bad_spelling",
            "[[wall]]\nreflectance = 0.5\ncolor = \"#ABCD\"\n",
            3,
            &["\"#ABCD\"", "is not a colour"],
        ),
        (
            "bad_rgb_array",
            "[[wall]]\nreflectance = 0.5\ncolor = [256, 0, 0]\n",
            3,
            &["[256, 0, 0]", "is not a colour"],
        ),
    ];
    let lvl = paint(dir.path(), "room", ROOM, None);
    for (name, text, line, words) in cases {
        let pal = dir.path().join(format!("{name}.toml"));
        std::fs::write(&pal, text).unwrap();
        let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &out, &"--palette", &pal]);
        assert_exit(&o, EXIT_FAILED);
        let at = format!("{}:{line}: ", pal.display());
        assert_says(&o, &[&at]);
        assert_says(&o, words);
        // `flatbake palette --palette` shows the same message.
        let o = flatbake_mixed(&[&"palette", &"--palette", &pal]);
        assert_exit(&o, EXIT_FAILED);
        assert_says(&o, &[&at]);
        assert_says(&o, words);
    }
    // A broken palette found beside the level is an error, not skipped.
    let beside = paint(
        dir.path(),
        "beside",
        ROOM,
        Some("[[wall]]\ncolor = \"#808080\"\nreflectance = 2\n"),
    );
    let o = flatbake_mixed(&[&"bake", &beside, &"-o", &out]);
    assert_exit(&o, EXIT_FAILED);
    assert_says(
        &o,
        &["beside.palette.toml:3: ", "reflectance 2 is outside 0..=1"],
    );
    assert!(!out.join("beside.lightmap.png").exists());
}

/// `#ABC` and `[r, g, b]` spellings are accepted and mean the full colour.
#[test]
fn short_hex_and_rgb_array_spellings_bake() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let pal = "[[wall]]\ncolor = [128, 128, 128]\nreflectance = 0.5\n\n[[emitter]]\ncolor = \"#FFF\"\nemission = 1.0\n";
    let lvl = paint(dir.path(), "spelled", ROOM, Some(pal));
    let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &out]);
    assert_exit(&o, EXIT_OK);
    let r = report(&out, "spelled");
    assert!(r["energy"]["emitted"].as_f64().unwrap() > 0.0, "{r}");
    assert_eq!(r["counts"]["edges"].as_u64(), Some(8), "{r}");
}

/// Anti-aliased pixels near the wall colour: a warning that counts them and
/// says where, on the terminal and in the report; `tolerance` snaps them.
#[test]
fn anti_aliased_pixels_are_counted_and_located() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let rows = [
        "##########",
        "#a.......#",
        "#...L....#",
        "#.......a#",
        "##########",
    ];
    let lvl = paint(dir.path(), "soft", &rows, Some(PALETTE));
    let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &out]);
    assert_exit(&o, EXIT_OK);
    let r = report(&out, "soft");
    let warnings: Vec<&str> = r["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|w| w.as_str())
        .collect();
    let w = warnings
        .iter()
        .find(|w| w.contains("anti-aliasing"))
        .unwrap_or_else(|| panic!("{warnings:?}"));
    for words in [
        "2 pixels",
        "#867c80",
        "at (1, 1)",
        "x 1..=8, y 1..=3",
        "tolerance = 6",
    ] {
        assert!(w.contains(words), "{w:?} lacks {words:?}");
    }
    assert_says(&o, &["warning", "soft.png", "2 pixels", "anti-aliasing"]);
    // --quiet prints only errors.
    let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &out, &"--quiet"]);
    assert_exit(&o, EXIT_OK);
    assert!(stderr(&o).is_empty(), "{}", stderr(&o));
    // With a tolerance they snap to the wall: two more solid pixels' edges.
    let snapped = format!("[bake]\ntolerance = 6\n\n{PALETTE}");
    std::fs::write(dir.path().join("soft.palette.toml"), snapped).unwrap();
    let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &out]);
    assert_exit(&o, EXIT_OK);
    let r2 = report(&out, "soft");
    assert!(
        !r2["warnings"].to_string().contains("anti-aliasing"),
        "{r2}"
    );
    assert!(r2["counts"]["edges"].as_u64() > r["counts"]["edges"].as_u64());
}

// ---------------------------------------------------------------------------
// Output folders and disks

#[test]
fn output_folder_that_is_a_file_or_under_a_file_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let lvl = paint(dir.path(), "room", ROOM, Some(PALETTE));
    let file = dir.path().join("not_a_folder");
    std::fs::write(&file, "x").unwrap();
    let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &file]);
    assert_exit(&o, EXIT_FAILED);
    assert_says(&o, &["not_a_folder is a file, not a folder"]);
    let under = file.join("out");
    let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &under]);
    assert_exit(&o, EXIT_FAILED);
    assert_says(
        &o,
        &["cannot be created", "not_a_folder is a file, not a folder"],
    );
    assert_eq!(std::fs::read(&file).unwrap(), b"x", "the file is untouched");
}

/// A missing output folder is created, parents included.
#[test]
fn missing_output_folder_is_created() {
    let dir = tempfile::tempdir().unwrap();
    let lvl = paint(dir.path(), "room", ROOM, Some(PALETTE));
    let out = dir.path().join("a/b/c");
    let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &out]);
    assert_exit(&o, EXIT_OK);
    assert!(out.join("room.lightmap.png").is_file());
}

/// A scratch tmpfs mount (needs root, as in CI here); `None` where mounting
/// is not allowed, and the caller says the test was skipped.
struct Mount(PathBuf);

impl Mount {
    fn tmpfs(at: &Path, options: &str) -> Option<Mount> {
        std::fs::create_dir_all(at).ok()?;
        let ok = Command::new("mount")
            .args(["-t", "tmpfs", "-o", options, "tmpfs"])
            .arg(at)
            .stderr(std::process::Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        ok.then(|| Mount(at.to_path_buf()))
    }
}

impl Drop for Mount {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.0).status();
    }
}

fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect();
    v.sort();
    v
}

/// A read-only output folder: the message says so and the earlier outputs
/// are untouched.
#[test]
fn read_only_output_folder_keeps_earlier_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let lvl = paint(dir.path(), "room", ROOM, Some(PALETTE));
    let mnt = dir.path().join("ro");
    let Some(m) = Mount::tmpfs(&mnt, "size=1m") else {
        eprintln!("skipped: cannot mount a tmpfs here (needs root)");
        return;
    };
    let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &mnt]);
    assert_exit(&o, EXIT_OK);
    let before = snapshot(&mnt);
    let st = Command::new("mount")
        .args(["-o", "remount,ro"])
        .arg(&m.0)
        .status()
        .unwrap();
    assert!(st.success());
    let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &mnt, &"--exposure", &"3"]);
    assert_exit(&o, EXIT_FAILED);
    assert_says(&o, &["room.lightmap.png", "read-only"]);
    assert_eq!(snapshot(&mnt), before);
}

/// A full disk: the message says the disk is full, the earlier outputs of
/// that level are intact (atomic writes) and no temporary file is left.
#[test]
fn full_disk_says_so_and_earlier_outputs_survive() {
    let dir = tempfile::tempdir().unwrap();
    let lvl = paint(dir.path(), "room", ROOM, Some(PALETTE));
    let big = dir.path().join("big.png");
    flatbake_synth::cornell(96).to_image().save(&big).unwrap();
    let mnt = dir.path().join("small");
    let Some(_m) = Mount::tmpfs(&mnt, "size=256k") else {
        eprintln!("skipped: cannot mount a tmpfs here (needs root)");
        return;
    };
    let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &mnt]);
    assert_exit(&o, EXIT_OK);
    let before = snapshot(&mnt);
    // Fill the disk.
    {
        use std::io::Write;
        let mut f = std::fs::File::create(mnt.join("filler")).unwrap();
        let chunk = vec![7u8; 4096];
        while f.write_all(&chunk).is_ok() {}
        let _ = f.sync_all();
    }
    let o = flatbake_mixed(&[&"bake", &lvl, &big, &"-o", &mnt, &"--exposure", &"2"]);
    assert_exit(&o, EXIT_FAILED);
    assert_says(&o, &["the disk is full", "0 levels baked", "2 failed"]);
    let mut after = snapshot(&mnt);
    after.retain(|(n, _)| n != "filler");
    assert_eq!(
        after, before,
        "earlier outputs changed or temporary files left"
    );
    // Every output is staged before any is replaced: the earlier set is
    // whole, still up to date for its own settings, and the new settings
    // bake once there is room.
    std::fs::remove_file(mnt.join("filler")).unwrap();
    let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &mnt]);
    assert_exit(&o, EXIT_OK);
    assert_says(&o, &["1 up to date"]);
    let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &mnt, &"--exposure", &"2"]);
    assert_exit(&o, EXIT_OK);
    assert_says(&o, &["1 level baked"]);
}

// ---------------------------------------------------------------------------
// A batch of good and bad levels

#[test]
fn batch_bakes_every_good_level_and_names_every_bad_one() {
    let dir = tempfile::tempdir().unwrap();
    let levels = dir.path().join("levels");
    std::fs::create_dir(&levels).unwrap();
    let out = dir.path().join("out");
    flatbake_synth::cornell(48).save(&levels).unwrap();
    paint(&levels, "good_room", ROOM, Some(PALETTE));
    copy(&levels, "rgb16_room.png", "good_16bit.png");
    copy(&levels, "truncated_room.png", "bad_truncated.png");
    copy(&levels, "empty_should_fail.png", "bad_empty.png");
    copy(&levels, "text_named_should_fail.png", "bad_text.png");
    copy(
        &levels,
        "huge_header_100000x100000_should_fail_fast.png",
        "bad_huge.png",
    );
    paint(
        &levels,
        "bad_palette",
        ROOM,
        Some("[[wall]]\ncolor = \"#808080\"\nreflectance = 0.5\nshine = 1\n"),
    );
    // A closed mirror room with a light: no finite answer.
    paint(
        &levels,
        "bad_mirror",
        ROOM,
        Some(
            "[[wall]]\ncolor = \"#808080\"\nreflectance = 1\n\n[[emitter]]\ncolor = \"#ffffff\"\nemission = 1\nreflectance = 1\n",
        ),
    );
    let o = flatbake_mixed(&[&"bake", &levels, &"-o", &out, &"--jobs", &"2"]);
    assert_exit(&o, EXIT_FAILED);
    assert_says(&o, &["3 levels baked", "6 failed"]);
    for good in ["cornell", "good_room", "good_16bit"] {
        for suffix in ["lightmap.png", "lit.png", "report.json"] {
            assert!(
                out.join(format!("{good}.{suffix}")).is_file(),
                "{good}.{suffix} missing; stderr: {}",
                stderr(&o)
            );
        }
    }
    let e = stderr(&o);
    for (bad, reason) in [
        ("bad_truncated.png", "truncated"),
        ("bad_empty.png", "empty"),
        ("bad_text.png", "not an image"),
        ("bad_huge.png", "--max-pixels"),
        ("bad_palette.palette.toml:4", "unknown key `shine`"),
        ("bad_mirror.png", "reflectance 1"),
    ] {
        let line = e
            .lines()
            .find(|l| l.contains(bad))
            .unwrap_or_else(|| panic!("{bad} not named:\n{e}"));
        assert!(line.starts_with("error: "), "{line}");
        assert!(line.contains(reason), "{line:?} lacks {reason:?}");
        let stem = bad.split('.').next().unwrap();
        assert!(!out.join(format!("{stem}.lightmap.png")).exists());
    }
    // Every good level's outputs were written whatever failed around them.
    let o2 = flatbake_mixed(&[&"bake", &levels.join("good_room.png"), &"-o", &out]);
    assert_exit(&o2, EXIT_OK);
}

#[test]
fn bad_flag_values_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let lvl = paint(dir.path(), "room", ROOM, Some(PALETTE));
    for (flag, value, words) in [
        ("--falloff", "0", "--falloff must be a positive number"),
        ("--falloff", "nan", "--falloff must be a positive number"),
        ("--exposure", "-1", "--exposure must be a positive number"),
        ("--jobs", "0", "--jobs takes 1 to 512 worker threads, not 0"),
        ("--jobs", "100000", "--jobs takes 1 to 512 worker threads"),
        ("--bounces", "1001", "--bounces takes 0 to 1000"),
        ("--bounces", "4294967295", "not 4294967295"),
    ] {
        let arg = format!("{flag}={value}");
        let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &dir.path().join("out"), &arg]);
        assert_exit(&o, EXIT_USAGE);
        assert_says(&o, &[words]);
    }
}

/// Regression: two levels with the same name in one batch (`a/room.png`
/// and `b/room.png`) both wrote `out/room.*`, and the later silently
/// replaced the earlier. The first is baked, the second refused by name.
#[test]
fn same_level_name_twice_in_a_batch_is_refused_not_overwritten() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    std::fs::create_dir_all(&a).unwrap();
    std::fs::create_dir_all(&b).unwrap();
    let first = paint(&a, "room", ROOM, Some(PALETTE));
    let second = paint(&b, "room", &["####", "#L.#", "####"], Some(PALETTE));
    let out = dir.path().join("out");
    let o = flatbake_mixed(&[&"bake", &first, &second, &first, &"-o", &out]);
    assert_exit(&o, EXIT_FAILED);
    assert_says(&o, &["2 levels baked", "1 failed"]);
    let e = stderr(&o);
    let line = e
        .lines()
        .find(|l| l.starts_with("error: "))
        .unwrap_or_else(|| panic!("{e}"));
    let second_s = second.display().to_string();
    let first_s = first.display().to_string();
    assert!(line.contains(&second_s), "{line}");
    assert!(line.contains(&first_s), "{line}");
    assert!(line.contains("would overwrite"), "{line}");
    // The outputs are the first level's (10 x 5), not the second's (4 x 3).
    let lm = image::open(out.join("room.lightmap.png")).unwrap();
    assert_eq!((lm.width(), lm.height()), (10, 5));
}

#[test]
fn a_folder_without_levels_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    std::fs::write(empty.join("notes.txt"), "no levels here").unwrap();
    let o = flatbake_mixed(&[&"bake", &empty, &"-o", &dir.path().join("out")]);
    assert_exit(&o, EXIT_FAILED);
    assert_says(&o, &["empty", "holds no level images"]);
}

/// A malformed PNG that makes the decoder panic (a 4-byte PLTE with a tRNS
/// chunk, valid CRCs) is that level's failure, named, and the level after it
/// still bakes: the process neither aborts nor exits 101.
#[test]
fn a_png_that_panics_the_decoder_fails_alone() {
    let dir = tempfile::tempdir().unwrap();
    let levels = dir.path().join("levels");
    std::fs::create_dir(&levels).unwrap();
    let out = dir.path().join("out");
    copy(&levels, "png_plte_trns_panic.png", "a_bad.png");
    paint(&levels, "b_good", ROOM, Some(PALETTE));
    let o = flatbake_mixed(&[&"bake", &levels, &"-o", &out, &"--jobs", &"1"]);
    assert!(out.join("b_good.lightmap.png").is_file(), "{}", stderr(&o));
    match o.status.code() {
        // The decoder refused or panicked: named, and the batch failed.
        Some(1) => assert_says(&o, &["a_bad.png", "1 failed"]),
        // A decoder that reads it: baked like any other level.
        Some(0) => assert!(out.join("a_bad.lightmap.png").is_file()),
        other => panic!("exit {other:?}: {}", stderr(&o)),
    }
}

/// A level symlink that points nowhere is named as a failure, not dropped.
#[cfg(unix)]
#[test]
fn a_dangling_level_symlink_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let levels = dir.path().join("levels");
    std::fs::create_dir(&levels).unwrap();
    paint(&levels, "good", ROOM, Some(PALETTE));
    std::os::unix::fs::symlink(levels.join("gone.png"), levels.join("ghost.png")).unwrap();
    let out = dir.path().join("out");
    let o = flatbake_mixed(&[&"bake", &levels, &"-o", &out]);
    assert_exit(&o, EXIT_FAILED);
    assert_says(
        &o,
        &["ghost.png", "file not found", "1 level baked", "1 failed"],
    );
}

/// A field of isolated one-pixel pillars, `n` x `n`, lit at a few points:
/// every pillar's four edges see most of the others, so its form factors
/// grow with the square of the pillar count.
fn pillar_field(n: usize) -> Vec<String> {
    (0..n)
        .map(|y| {
            (0..n)
                .map(|x| match (x % 2, y % 2) {
                    _ if x % 40 == 20 && y % 40 == 20 => 'L',
                    (1, 1) => '#',
                    _ => '.',
                })
                .collect()
        })
        .collect()
}

/// Regression: a 640x640 level of isolated one-pixel pillars (~400,000
/// edges) grew to the machine's whole memory and was killed with the batch.
/// A level whose estimated peak memory is above `--max-memory` is refused
/// after tracing, naming the estimate and the flag; the batch goes on, and
/// the estimate is in every report.
#[test]
fn a_level_over_the_memory_limit_is_refused_with_its_estimate() {
    let dir = tempfile::tempdir().unwrap();
    let small = paint(dir.path(), "room", ROOM, Some(PALETTE));
    let rows = pillar_field(240);
    let field = paint(dir.path(), "pillars", &refs(&rows), Some(PALETTE));
    let out = dir.path().join("out");
    let o = flatbake_mixed(&[
        &"bake",
        &small,
        &field,
        &"-o",
        &out,
        &"--max-memory",
        &"300M",
    ]);
    assert_exit(&o, EXIT_FAILED);
    assert_says(
        &o,
        &[
            "pillars.png: needs an estimated",
            "of memory at its peak",
            "more than the 300 MB allowed",
            "raise the limit with --max-memory",
        ],
    );
    assert!(!out.join("pillars.lightmap.png").exists());
    assert!(out.join("room.lightmap.png").exists(), "the batch went on");
    let estimate = report(&out, "room")["counts"]["memory_estimate"]
        .as_u64()
        .expect("the report records the estimate");
    assert!(estimate > 0 && estimate < 300_000_000, "{estimate}");

    // The flag's suggested value is above the estimate, in whole gigabytes.
    let err = stderr(&o);
    let suggested = err
        .split("--max-memory ")
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .expect("a suggested --max-memory value");
    assert!(suggested.ends_with('G'), "{suggested}");

    for (value, words) in [
        ("12X", "unknown unit"),
        ("-1G", "not a usable memory size"),
        ("lots", "not a memory size"),
        ("0", "not a usable memory size"),
    ] {
        let arg = format!("--max-memory={value}");
        let o = flatbake_mixed(&[&"bake", &small, &"-o", &out, &arg]);
        assert_exit(&o, EXIT_USAGE);
        assert_says(&o, &[words]);
    }
}

/// The PNG whose palette chunk makes the decoder panic (4 bytes of PLTE and a
/// tRNS chunk) is refused before decoding with what is wrong in it, not as a
/// caught internal error.
#[test]
fn a_png_palette_of_a_partial_colour_is_named_before_decoding() {
    let dir = tempfile::tempdir().unwrap();
    copy(dir.path(), "png_plte_trns_panic.png", "bad.png");
    let o = flatbake_mixed(&[
        &"bake",
        &dir.path().join("bad.png"),
        &"-o",
        &dir.path().join("out"),
    ]);
    assert_exit(&o, EXIT_FAILED);
    assert_says(
        &o,
        &[
            "bad.png",
            "PNG file is corrupt",
            "PLTE (palette) chunk is 4 bytes",
        ],
    );
    assert!(!stderr(&o).contains("internal error"), "{}", stderr(&o));
}
