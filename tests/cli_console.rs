//! What a level designer sees on the console: results that look like
//! success but are not (white is light, lossy colours, clipping) named as
//! warnings with their cause, `--strict` for CI, one plain line per level,
//! the batch's summary table, `--exposure auto`, no progress drawing when
//! piped, and watch's timed lines. Every test runs the binary on real files.

mod common;
use common::*;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::time::{Duration, Instant};

/// A closed room of grey wall (`#5a5a5a`) with a lamp strip in its top wall,
/// a pillar and a warm floor, plus its palette with the lamp at `emission`.
fn write_room(dir: &Path, name: &str, emission: f64) -> PathBuf {
    let (w, h) = (24u32, 16u32);
    let img = image::RgbaImage::from_fn(w, h, |x, y| {
        if y == 0 && (8..14).contains(&x) {
            image::Rgba([255, 250, 220, 255])
        } else if x == 0 || y == 0 || x == w - 1 || y == h - 1 || (x == 12 && y > 6) {
            image::Rgba([90, 90, 90, 255])
        } else {
            image::Rgba([180, 170, 150, 255])
        }
    });
    let png = dir.join(format!("{name}.png"));
    img.save(&png).expect("write level");
    std::fs::write(
        dir.join(format!("{name}.palette.toml")),
        format!(
            "[[wall]]\ncolor = \"#5a5a5a\"\nreflectance = 0.6\n\n[[emitter]]\ncolor = \"#fffadc\"\nemission = {emission}\n"
        ),
    )
    .expect("write palette");
    png
}

/// A sketch the way one draws on paper: black strokes on a white
/// background, no palette file (white is a built-in emitter).
fn write_white_sketch(dir: &Path, name: &str) -> PathBuf {
    let (w, h) = (32u32, 24u32);
    let img = image::RgbImage::from_fn(w, h, |x, y| {
        let stroke = x == 4 || x == 27 || y == 3 || y == 20 || (x == 16 && y < 14);
        if stroke {
            image::Rgb([0, 0, 0])
        } else {
            image::Rgb([255, 255, 255])
        }
    });
    let png = dir.join(format!("{name}.png"));
    img.save(&png).expect("write sketch");
    png
}

fn report(out: &Path, name: &str) -> serde_json::Value {
    let text = std::fs::read_to_string(out.join(format!("{name}.report.json"))).expect("report");
    serde_json::from_str(&text).expect("report is JSON")
}

/// The line flatbake prints for a baked level.
fn baked_line<'a>(err: &'a str, level: &str) -> &'a str {
    err.lines()
        .find(|l| l.starts_with("baked ") && l.contains(level))
        .unwrap_or_else(|| panic!("no line for {level}:\n{err}"))
}

#[test]
fn a_sketch_on_white_warns_that_white_is_light() {
    let dir = tempfile::tempdir().expect("temp dir");
    let png = write_white_sketch(dir.path(), "sketch");
    let out = dir.path().join("out");
    let o = flatbake(&["bake", s(&png), "-o", s(&out), "-q", "draft"]);
    // Still a bake (not an error) without --strict, but a loud one.
    assert_exit(&o, EXIT_OK);
    assert_says(
        &o,
        &[
            "warning: ",
            "sketch.png",
            "looks wrong (no floor)",
            "white (#ffffff)",
            "white is light",
        ],
    );
    let r = report(&out, "sketch");
    let kinds: Vec<&str> = r["problems"]
        .as_array()
        .expect("problems")
        .iter()
        .map(|p| p["kind"].as_str().expect("kind"))
        .collect();
    assert!(kinds.contains(&"no floor"), "{r}");
    assert!(
        r["warnings"]
            .as_array()
            .expect("warnings")
            .iter()
            .any(|w| w.as_str().is_some_and(|w| w.contains("white is light"))),
        "{r}"
    );
}

#[test]
fn strict_turns_warnings_into_exit_1_also_when_up_to_date() {
    let dir = tempfile::tempdir().expect("temp dir");
    let png = write_white_sketch(dir.path(), "sketch");
    let out = dir.path().join("out");
    let bake = |extra: &[&str]| {
        let mut args = vec!["bake", s(&png), "-o", s(&out), "-q", "draft"];
        args.extend_from_slice(extra);
        flatbake(&args)
    };
    let o = bake(&["--strict"]);
    assert_exit(&o, EXIT_FAILED);
    assert_says(&o, &["--strict", "white is light"]);
    // Nothing changed: up to date, but its warnings still fail CI ...
    let o = bake(&["--strict"]);
    assert_exit(&o, EXIT_FAILED);
    assert_says(&o, &["up to date", "--strict"]);
    // ... and quiet does not hide them, since they are failures.
    let o = bake(&["--strict", "--quiet"]);
    assert_exit(&o, EXIT_FAILED);
    assert_says(&o, &["white is light"]);
    // Without --strict the same level passes.
    assert_exit(&bake(&[]), EXIT_OK);
    // A level without warnings passes --strict.
    let room = write_room(dir.path(), "room", 0.5);
    let o = flatbake(&["bake", s(&room), "-o", s(&out), "-q", "draft", "--strict"]);
    assert_exit(&o, EXIT_OK);
}

#[test]
fn a_jpeg_level_is_warned_about_its_lossy_colours() {
    let dir = tempfile::tempdir().expect("temp dir");
    let png = write_room(dir.path(), "room", 0.5);
    let img = image::open(&png).expect("read back").to_rgb8();
    let jpg = dir.path().join("room.jpg");
    img.save(&jpg).expect("write JPEG");
    std::fs::remove_file(&png).expect("remove the PNG");
    let out = dir.path().join("out");
    let o = flatbake(&["bake", s(&jpg), "-o", s(&out), "-q", "draft"]);
    assert_exit(&o, EXIT_OK);
    assert_says(&o, &["warning: ", "room.jpg", "JPEG", "lossy", "PNG"]);
    // The PNG of the same level says nothing of the kind.
    let png = write_room(dir.path(), "clean", 0.5);
    let o = flatbake(&["bake", s(&png), "-o", s(&out), "-q", "draft"]);
    assert_exit(&o, EXIT_OK);
    assert!(!stderr(&o).contains("lossy"), "{}", stderr(&o));
}

#[test]
fn a_batch_ends_with_a_table_of_every_level() {
    let dir = tempfile::tempdir().expect("temp dir");
    let levels = dir.path().join("levels");
    std::fs::create_dir(&levels).expect("mkdir");
    write_room(&levels, "alpha", 0.5);
    write_room(&levels, "beta", 0.5);
    write_white_sketch(&levels, "gamma");
    std::fs::write(levels.join("broken.png"), b"not a png").expect("write");
    let o = flatbake_in(&["bake", "levels", "-o", "out", "-q", "draft"], dir.path());
    assert_exit(&o, EXIT_FAILED);
    let err = stderr(&o);
    let header = err
        .lines()
        .position(|l| {
            ["level", "size", "time", "warnings", "clipped", "status"]
                .iter()
                .all(|w| l.contains(w))
        })
        .unwrap_or_else(|| panic!("no summary table:\n{err}"));
    let table: Vec<&str> = err.lines().skip(header + 1).take(4).collect();
    let row = |name: &str| {
        *table
            .iter()
            .find(|l| l.starts_with(&format!("levels/{name}.")))
            .unwrap_or_else(|| panic!("no row for {name}:\n{err}"))
    };
    assert!(row("alpha").contains("24x16") && row("alpha").ends_with("ok"));
    assert!(row("beta").contains("24x16"));
    assert!(row("gamma").contains("no floor"), "{err}");
    assert!(row("broken").ends_with("failed"), "{err}");
    // One baked level that is fine: no table, just its line.
    let o = flatbake_in(
        &["bake", "levels/alpha.png", "-o", "one", "-q", "draft"],
        dir.path(),
    );
    assert_exit(&o, EXIT_OK);
    assert!(!stderr(&o).contains("status"), "{}", stderr(&o));
}

#[test]
fn exposure_auto_fixes_a_clipped_level_and_says_what_it_chose() {
    let dir = tempfile::tempdir().expect("temp dir");
    // A lamp far too bright for exposure 1.
    let png = write_room(dir.path(), "hot", 40.0);
    let out = dir.path().join("fixed");
    let o = flatbake(&["bake", s(&png), "-o", s(&out), "-q", "draft"]);
    assert_exit(&o, EXIT_OK);
    assert_says(&o, &["looks wrong (clipped)", "--exposure auto"]);
    let before = report(&out, "hot");
    let clipped = before["clipped"].as_f64().expect("clipped");
    assert!(clipped > 0.1, "the level is clipped: {before}");
    assert_eq!(before["exposure"], 1.0);

    let auto = dir.path().join("auto");
    let o = flatbake(&[
        "bake",
        s(&png),
        "-o",
        s(&auto),
        "-q",
        "draft",
        "--exposure",
        "auto",
    ]);
    assert_exit(&o, EXIT_OK);
    let after = report(&auto, "hot");
    let chosen = after["exposure"].as_f64().expect("exposure");
    assert_eq!(after["exposure_auto"], true);
    assert!(chosen > 0.0 && chosen < 1.0, "darker than 1: {after}");
    assert!(
        after["clipped"].as_f64().expect("clipped") <= 0.02,
        "at most about 1 % clipped: {after}"
    );
    assert!(after["problems"].as_array().is_some_and(|p| p.is_empty()));
    let err = stderr(&o);
    let line = baked_line(&err, "hot.png");
    assert!(
        line.contains(&format!("exposure {chosen} (auto)")),
        "{line}"
    );
    // The lightmap really is darker.
    let lum = |p: &Path| -> u64 {
        let img = image::open(p).expect("lightmap").to_rgb8();
        img.pixels()
            .map(|p| p.0.iter().map(|&c| c as u64).sum::<u64>())
            .sum()
    };
    assert!(lum(&auto.join("hot.lightmap.png")) < lum(&out.join("hot.lightmap.png")));
    // A word flatbake does not know is refused with the choices.
    let o = flatbake(&["bake", s(&png), "--exposure", "bright"]);
    assert_exit(&o, EXIT_USAGE);
    assert_says(&o, &["auto"]);
}

#[test]
fn the_level_line_is_plain_and_verbose_keeps_the_detail() {
    let dir = tempfile::tempdir().expect("temp dir");
    let levels = Path::new(env!("CARGO_MANIFEST_DIR")).join("levels");
    // A sample level whose gather merges distant bounce light.
    let cornell = levels.join("cornell.png");
    let o = flatbake(&[
        "bake",
        s(&cornell),
        "-o",
        s(dir.path()),
        "-q",
        "draft",
        "--exposure",
        "auto",
    ]);
    assert_exit(&o, EXIT_OK);
    let err = stderr(&o);
    let line = baked_line(&err, "cornell.png");
    for jargon in ["patch", "pieces", "solve", "edge-point", "e-"] {
        assert!(!line.contains(jargon), "{jargon:?} in {line:?}");
    }
    for plain in [
        "draft quality",
        "no warnings",
        "of the floor clipped",
        "left out",
    ] {
        assert!(line.contains(plain), "{plain:?} not in {line:?}");
    }
    // The technical account is one flag away.
    let o = flatbake(&[
        "bake",
        s(&cornell),
        "-o",
        s(dir.path()),
        "-q",
        "draft",
        "--exposure",
        "auto",
        "--force",
        "--verbose",
    ]);
    assert_exit(&o, EXIT_OK);
    assert_says(&o, &["patch pieces", "solve", "form factors"]);
}

#[test]
fn piped_output_has_no_progress_drawing() {
    let dir = tempfile::tempdir().expect("temp dir");
    write_room(dir.path(), "a", 0.5);
    write_room(dir.path(), "b", 0.5);
    let o = flatbake_in(&["bake", ".", "-o", "out"], dir.path());
    assert_exit(&o, EXIT_OK);
    let err = stderr(&o);
    assert!(!err.contains('\x1b') && !err.contains('\r'), "{err:?}");
    assert!(err.lines().count() >= 2, "{err}");
}

#[test]
fn watch_lines_carry_the_time_and_show_warnings() {
    let dir = tempfile::tempdir().expect("temp dir");
    let levels = dir.path().join("levels");
    std::fs::create_dir(&levels).expect("mkdir");
    write_room(&levels, "room", 0.5);
    write_white_sketch(&levels, "sketch");
    let mut child = std::process::Command::new(BIN)
        .args(["watch", "levels", "-o", "out", "-q", "draft"])
        .current_dir(dir.path())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("watch starts");
    let err = child.stderr.take().expect("stderr");
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(err).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    // Everything up to "watching" (the first bake of both levels).
    let deadline = Instant::now() + Duration::from_secs(60);
    let mut lines = Vec::new();
    while !lines.iter().any(|l: &String| l.contains("watching")) {
        let left = deadline.saturating_duration_since(Instant::now());
        match rx.recv_timeout(left) {
            Ok(l) => lines.push(l),
            Err(_) => break,
        }
    }
    let _ = child.kill();
    let _ = child.wait();
    let all = lines.join("\n");
    assert!(all.contains("watching"), "watch did not start:\n{all}");
    let timed = |l: &str| {
        let b = l.as_bytes();
        b.len() > 9
            && [0, 1, 3, 4, 6, 7].iter().all(|&i| b[i].is_ascii_digit())
            && b[2] == b':'
            && b[5] == b':'
            && b[8] == b' '
    };
    for l in &lines {
        assert!(timed(l), "no time at the start of {l:?}");
    }
    assert!(
        lines
            .iter()
            .any(|l| l.contains("warning: ") && l.contains("white is light")),
        "{all}"
    );
    assert!(
        lines
            .iter()
            .any(|l| l.contains("baked ") && l.contains("room.png"))
    );
}
