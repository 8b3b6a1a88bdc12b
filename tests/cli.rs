//! The command line as a user meets it: baking a folder, what lands in the
//! output folder, the report's fields (docs/transport.md#report), the palette legend,
//! the batch going on past a bad level, and the documented exit codes.

mod common;
use common::*;

#[test]
fn baking_a_folder_writes_every_output_and_a_complete_report() {
    let dir = tempfile::tempdir().expect("temp dir");
    let levels = dir.path().join("levels");
    std::fs::create_dir(&levels).expect("mkdir");
    write_room(&levels, "a", false);
    write_room(&levels, "b", false);
    let o = flatbake_in(&["bake", "levels", "-o", "out", "--hdr"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    for name in ["a", "b"] {
        for suffix in ["lightmap.png", "lit.png", "lightmap.exr", "report.json"] {
            let p = dir.path().join("out").join(format!("{name}.{suffix}"));
            assert!(p.exists(), "{} was not written", p.display());
        }
        let text = std::fs::read_to_string(dir.path().join(format!("out/{name}.report.json")))
            .expect("report");
        let r: serde_json::Value = serde_json::from_str(&text).expect("report is JSON");
        assert_eq!(r["level"], name);
        assert_eq!(r["size"], serde_json::json!([24, 16]));
        assert_eq!(r["quality"], "normal");
        assert_eq!(r["kernel"], "flatland");
        assert!(r["falloff"].is_null());
        for k in ["edges", "patches", "floor_pixels"] {
            assert!(r["counts"][k].as_u64().is_some_and(|n| n > 0), "counts.{k}");
        }
        for k in [
            "load",
            "geometry",
            "form_factors",
            "solve",
            "gather",
            "write",
            "total",
        ] {
            assert!(
                r["timings"][k].as_f64().is_some_and(|t| t >= 0.0),
                "timings.{k}"
            );
        }
        // Light of one colour on grey walls: one solve, scaled to the
        // other two channels.
        assert_eq!(r["solves"], 1);
        assert!(
            r["skipped"]
                .as_array()
                .expect("skipped")
                .iter()
                .any(|s| s["effect"] == "channel solves"
                    && s["reason"].as_str().is_some_and(|t| t.contains("scaled"))),
            "{}",
            r["skipped"]
        );
        let e = &r["energy"];
        let (em, ab, es) = (
            e["emitted"].as_f64().unwrap(),
            e["absorbed"].as_f64().unwrap(),
            e["escaped"].as_f64().unwrap(),
        );
        assert!(
            em > 0.0 && ((ab + es) / em - 1.0).abs() < 1e-4,
            "energy {em} vs {ab} + {es}"
        );
        assert!(r["skipped"].is_array() && r["warnings"].is_array());
    }
    // Not quiet: one plain line per level, and a table for the batch.
    let err = stderr(&o);
    assert!(
        err.contains("baked levels/a.png") && err.contains("(normal quality)"),
        "{err}"
    );
    assert!(
        err.contains("levels/b.png") && err.contains("status"),
        "{err}"
    );
}

#[test]
fn one_bad_level_does_not_stop_the_batch_and_fails_the_exit_status() {
    let dir = tempfile::tempdir().expect("temp dir");
    write_room(dir.path(), "good", false);
    std::fs::write(dir.path().join("broken.png"), b"not a png at all").expect("write");
    let o = flatbake_in(&["bake", ".", "-o", "out", "--quiet"], dir.path());
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(dir.path().join("out/good.lightmap.png").exists());
    assert!(!dir.path().join("out/broken.lightmap.png").exists());
    let err = stderr(&o);
    assert!(err.contains("broken.png"), "the bad level is named: {err}");
    assert!(
        !err.contains("good.png"),
        "--quiet prints only errors: {err}"
    );
}

#[test]
fn quiet_success_prints_nothing_and_exits_zero() {
    let dir = tempfile::tempdir().expect("temp dir");
    write_room(dir.path(), "room", false);
    let o = flatbake_in(&["bake", "room.png", "-o", "out", "--quiet"], dir.path());
    assert_eq!(o.status.code(), Some(0));
    assert!(o.stderr.is_empty() && o.stdout.is_empty(), "{}", stderr(&o));
}

#[test]
fn bad_flags_exit_with_status_two() {
    let dir = tempfile::tempdir().expect("temp dir");
    write_room(dir.path(), "room", false);
    for args in [
        &["bake", "room.png", "--quality", "ultra"][..],
        &["bake", "room.png", "--falloff", "-3"],
        &["bake", "room.png", "--exposure", "0"],
        &["bake", "room.png", "--jobs", "0"],
        &["bake", "room.png", "--depth", "12"],
    ] {
        let o = flatbake_in(args, dir.path());
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(!stderr(&o).is_empty(), "{args:?} says why");
    }
}

#[test]
fn palette_legend_is_drawn_by_flatbake() {
    let dir = tempfile::tempdir().expect("temp dir");
    let o = flatbake_in(&["palette", "--legend", "legend.png"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(dir.path().join("legend.png"))
        .expect("legend is an image")
        .to_rgba8();
    assert!(img.width() > 100 && img.height() > 50);
    // Not blank: several distinct colours (swatches and text).
    let mut colours: Vec<[u8; 4]> = img.pixels().map(|p| p.0).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(colours.len() > 8, "legend has {} colours", colours.len());
    // Without --legend it prints the palette as text.
    let o = flatbake_in(&["palette"], dir.path());
    assert!(o.status.success());
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("wall") && text.contains("emitter") && text.contains("floor"),
        "{text}"
    );
}

#[test]
fn output_does_not_depend_on_the_thread_count() {
    let dir = tempfile::tempdir().expect("temp dir");
    write_room(dir.path(), "room", false);
    for jobs in ["1", "2"] {
        let out = format!("out{jobs}");
        let o = flatbake_in(
            &[
                "bake", "room.png", "-o", &out, "--hdr", "--quiet", "--jobs", jobs,
            ],
            dir.path(),
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }
    for f in ["room.lightmap.png", "room.lit.png", "room.lightmap.exr"] {
        let a = std::fs::read(dir.path().join("out1").join(f)).expect("read");
        let b = std::fs::read(dir.path().join("out2").join(f)).expect("read");
        assert!(a == b, "{f} differs between --jobs 1 and --jobs 2");
    }
}

#[test]
fn sweep_writes_the_csv_the_table_and_the_plot() {
    let dir = tempfile::tempdir().expect("temp dir");
    write_room(dir.path(), "room", false);
    let o = flatbake_in(&["sweep", "room.png", "-o", "sweep"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = std::fs::read_to_string(dir.path().join("sweep/accuracy.csv")).expect("csv");
    let mut lines = csv.lines();
    assert!(
        lines
            .next()
            .expect("header")
            .starts_with("level,quality,seconds,rel_rmse,max_err")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    for q in ["draft", "normal", "high", "reference"] {
        assert!(
            rows.iter().any(|r| r[0] == "room" && r[1] == q),
            "no {q} row in\n{csv}"
        );
    }
    let err = |q: &str| -> f64 {
        rows.iter().find(|r| r[1] == q).expect("row")[3]
            .parse()
            .expect("number")
    };
    assert_eq!(err("reference"), 0.0);
    assert!(
        err("draft") >= err("normal") && err("normal") >= err("high"),
        "{csv}"
    );
    let md = std::fs::read_to_string(dir.path().join("sweep/accuracy.md")).expect("md");
    assert!(md.contains("| room |") && md.contains("## room"), "{md}");
    let png = image::open(dir.path().join("sweep/accuracy.png")).expect("plot is an image");
    assert!(png.width() >= 640 && png.height() >= 400);
}

#[test]
fn palette_bounces_and_the_flag_switch_off_the_bounce_and_say_so() {
    let dir = tempfile::tempdir().expect("temp dir");
    write_room(dir.path(), "room", false);
    let report = |out: &str| -> serde_json::Value {
        let text =
            std::fs::read_to_string(dir.path().join(out).join("room.report.json")).expect("report");
        serde_json::from_str(&text).expect("JSON")
    };
    // The flag: direct light only, no solve, reported and summarised.
    let o = flatbake_in(
        &["bake", "room.png", "-o", "flag", "--bounces", "0"],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let r = report("flag");
    assert_eq!(r["solves"], 0);
    assert_eq!(r["bounces"], 0);
    assert!(
        r["skipped"]
            .as_array()
            .unwrap()
            .iter()
            .any(|s| s["effect"] == "bounce"),
        "{r}"
    );
    assert!(stderr(&o).contains("bounces = 0"), "{}", stderr(&o));
    // The palette's [bake] bounces does the same.
    let pal = std::fs::read_to_string(dir.path().join("room.palette.toml")).expect("palette");
    std::fs::write(
        dir.path().join("room.palette.toml"),
        format!("[bake]\nbounces = 0\n\n{pal}"),
    )
    .expect("write");
    let o = flatbake_in(&["bake", "room.png", "-o", "palette"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(report("palette")["solves"], 0);
    let a = std::fs::read(dir.path().join("flag/room.lightmap.png")).expect("read");
    let b = std::fs::read(dir.path().join("palette/room.lightmap.png")).expect("read");
    assert!(a == b, "flag and palette give the same lightmap");
}
