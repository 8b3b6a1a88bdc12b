//! Flags as a newcomer types them: `--falloff none`, negative numbers,
//! `--quiet` on every subcommand that bakes, the `--help` examples (run as
//! written), and batches past one machine (`--shard K/N`, `batch.json`).

mod common;
use common::*;

use std::collections::{BTreeMap, BTreeSet};
use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

const PALETTE: &str = "[[wall]]\ncolor = \"#5a5a5a\"\nreflectance = 0.6\n\n\
                       [[emitter]]\ncolor = \"#fffadc\"\nemission = [2.0, 1.8, 1.5]\n";

/// A closed room `w` x 16 with a lamp strip at `lamp` in its top wall and a
/// wall stub in the middle, and its palette (plus `extra` palette text).
fn write_room(dir: &Path, name: &str, w: u32, lamp: u32, extra: &str) -> PathBuf {
    let h = 16u32;
    let img = image::RgbaImage::from_fn(w, h, |x, y| {
        if y == 0 && (lamp..lamp + 4).contains(&x) {
            image::Rgba([0xff, 0xfa, 0xdc, 255])
        } else if x == 0 || y == 0 || x == w - 1 || y == h - 1 || (x == w / 2 && y > 6) {
            image::Rgba([0x5a, 0x5a, 0x5a, 255])
        } else {
            image::Rgba([0xb4, 0xaa, 0x96, 255])
        }
    });
    let png = dir.join(format!("{name}.png"));
    img.save(&png).expect("write level");
    std::fs::write(
        dir.join(format!("{name}.palette.toml")),
        format!("{extra}{PALETTE}"),
    )
    .expect("write palette");
    png
}

fn json(path: &Path) -> Value {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_slice(&bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn read(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The names of the files in `dir`.
fn files(dir: &Path) -> BTreeSet<String> {
    std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect()
}

// --- --falloff none --------------------------------------------------------

/// `--falloff none` (and `off`) switches off the falloff a palette asks
/// for: the report says `null` and the lightmap is exactly that of the same
/// level whose palette has no falloff.
#[test]
fn falloff_none_switches_off_the_palettes_falloff() {
    let dir = tempfile::tempdir().unwrap();
    let (with, without) = (dir.path().join("with"), dir.path().join("without"));
    std::fs::create_dir_all(&with).unwrap();
    std::fs::create_dir_all(&without).unwrap();
    let lvl = write_room(&with, "hall", 40, 6, "[bake]\nfalloff = 6.0\n\n");
    let plain = write_room(&without, "hall", 40, 6, "");

    let o = flatbake_mixed(&[&"bake", &plain, &"-o", &dir.path().join("plain")]);
    assert_exit(&o, EXIT_OK);
    let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &dir.path().join("palette")]);
    assert_exit(&o, EXIT_OK);
    assert_eq!(
        json(&dir.path().join("palette/hall.report.json"))["falloff"],
        6.0
    );
    let reference = read(&dir.path().join("plain/hall.lightmap.png"));
    assert_ne!(
        read(&dir.path().join("palette/hall.lightmap.png")),
        reference,
        "the palette's falloff changes the light"
    );
    for word in ["none", "off"] {
        let out = dir.path().join(word);
        let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &out, &"--falloff", &word]);
        assert_exit(&o, EXIT_OK);
        assert_eq!(json(&out.join("hall.report.json"))["falloff"], Value::Null);
        assert_eq!(read(&out.join("hall.lightmap.png")), reference, "{word}");
    }
}

/// `0`, negative and nan stay usage errors, and the message says how to
/// switch falloff off (a negative number included: it reaches the check
/// instead of clap's advice to write `-- -3`).
#[test]
fn falloff_zero_negative_or_nan_says_how_to_switch_it_off() {
    let dir = tempfile::tempdir().unwrap();
    let lvl = write_room(dir.path(), "room", 24, 8, "");
    for value in ["0", "-3", "nan", "forty"] {
        let o = flatbake_mixed(&[
            &"bake",
            &lvl,
            &"-o",
            &dir.path().join("out"),
            &"--falloff",
            &value,
        ]);
        assert_exit(&o, EXIT_USAGE);
        assert_says(
            &o,
            &["--falloff", "positive number of pixels", "--falloff none"],
        );
        assert!(!stderr(&o).contains("-- "), "{value}: {}", stderr(&o));
    }
    assert!(!dir.path().join("out").exists());
}

// --- negative numbers --------------------------------------------------------

/// A negative number given to a numeric flag is refused with the flag's
/// range, never with clap's tip to write `-- -1` (which would turn the
/// number into a level path).
#[test]
fn negative_numbers_get_the_flags_range_not_a_hint_to_make_them_paths() {
    let dir = tempfile::tempdir().unwrap();
    let lvl = write_room(dir.path(), "room", 24, 8, "");
    let out = dir.path().join("out");
    let level = lvl.to_str().unwrap();
    let o_dir = out.to_str().unwrap();
    let folder = dir.path().to_str().unwrap();
    for (args, words) in [
        (
            vec!["bake", level, "-o", o_dir, "--bounces", "-1"],
            &["--bounces takes 0 to 1000", "not -1"][..],
        ),
        (
            vec!["bake", level, "-o", o_dir, "--jobs", "-1"],
            &["--jobs takes 1 to 512"],
        ),
        (
            vec!["bake", level, "-o", o_dir, "-j", "-4"],
            &["--jobs takes 1 to 512", "not -4"],
        ),
        (
            vec!["bake", level, "-o", o_dir, "--exposure", "-1"],
            &["--exposure must be a positive number"],
        ),
        (
            vec!["bake", level, "-o", o_dir, "--max-pixels", "-1"],
            &["--max-pixels takes", "not -1"],
        ),
        (
            vec!["bake", level, "-o", o_dir, "--depth", "-8"],
            &["8 or 16", "not -8"],
        ),
        (
            vec!["watch", folder, "-o", o_dir, "--debounce", "-5"],
            &["--debounce takes", "milliseconds", "not -5"],
        ),
        (
            vec!["watch", folder, "-o", o_dir, "--jobs", "-2"],
            &["--jobs takes 1 to 512"],
        ),
        (
            vec!["sweep", level, "-o", o_dir, "--jobs", "-1"],
            &["--jobs takes 1 to 512"],
        ),
    ] {
        let o = flatbake(&args);
        assert_exit(&o, EXIT_USAGE);
        assert_says(&o, words);
        assert!(!stderr(&o).contains("-- -"), "{args:?}: {}", stderr(&o));
        assert!(!out.exists(), "{args:?} wrote outputs");
    }
}

// --- --quiet -----------------------------------------------------------------

/// `sweep --quiet` writes its tables and plot and prints nothing.
#[test]
fn sweep_accepts_quiet_and_prints_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let lvl = write_room(dir.path(), "room", 16, 4, "");
    let out = dir.path().join("sweep");
    let o = flatbake_mixed(&[&"sweep", &lvl, &"-o", &out, &"--quiet"]);
    assert_exit(&o, EXIT_OK);
    assert!(o.stderr.is_empty() && o.stdout.is_empty(), "{}", stderr(&o));
    for f in ["accuracy.csv", "accuracy.md", "accuracy.png"] {
        assert!(out.join(f).is_file(), "{f}");
    }
}

/// `watch --quiet` bakes the folder and prints nothing while all is well.
#[test]
fn watch_accepts_quiet_and_prints_nothing_while_all_is_well() {
    let dir = tempfile::tempdir().unwrap();
    let levels = dir.path().join("levels");
    std::fs::create_dir_all(&levels).unwrap();
    write_room(&levels, "room", 24, 8, "");
    let out = dir.path().join("out");
    let mut child = Command::new(BIN)
        .args([
            "watch",
            s(&levels),
            "-o",
            s(&out),
            "--quiet",
            "--quality",
            "draft",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let stamp = out.join("room.stamp.json");
    while !stamp.is_file() && start.elapsed() < Duration::from_secs(60) {
        if let Some(status) = child.try_wait().unwrap() {
            let o = child.wait_with_output().unwrap();
            panic!("watch ended with {status}: {}", stderr(&o));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    // Still watching after its first bake: stop it as Ctrl-C would.
    let running = child.try_wait().unwrap().is_none();
    child.kill().unwrap();
    let o = child.wait_with_output().unwrap();
    assert!(stamp.is_file(), "no bake within 60 s: {}", stderr(&o));
    assert!(running, "watch stopped by itself: {}", stderr(&o));
    assert!(o.stderr.is_empty() && o.stdout.is_empty(), "{}", stderr(&o));
}

// --- --help examples ---------------------------------------------------------

/// Splits an example command like a shell: words, and double-quoted words.
fn shell_words(line: &str) -> Vec<String> {
    let (mut words, mut word, mut quoted, mut any) = (Vec::new(), String::new(), false, false);
    for c in line.chars() {
        match c {
            '"' => {
                quoted = !quoted;
                any = true;
            }
            c if c.is_whitespace() && !quoted => {
                if any {
                    words.push(std::mem::take(&mut word));
                    any = false;
                }
            }
            c => {
                word.push(c);
                any = true;
            }
        }
    }
    if any {
        words.push(word);
    }
    words
}

/// The example commands at the end of `flatbake SUB --help`, as argument
/// lists without the program name and the trailing `# comment`.
fn help_examples(sub: &str) -> Vec<Vec<String>> {
    let o = flatbake(&[sub, "--help"]);
    assert_exit(&o, EXIT_OK);
    let help = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        help.contains("Examples:"),
        "{sub} --help has no examples:\n{help}"
    );
    let examples: Vec<Vec<String>> = help
        .lines()
        .filter_map(|l| l.strip_prefix("  flatbake "))
        .map(|l| shell_words(l.split(" # ").next().unwrap_or(l)))
        .collect();
    assert!(!examples.is_empty(), "{sub}:\n{help}");
    for e in &examples {
        assert!(!e.is_empty(), "{sub}: an empty example");
    }
    examples
}

/// A small stand-in for the sample level `dungeon` (the real one takes
/// half a minute to sweep): a room of its stone wall with one of its
/// torches and one of its crystals, and its real palette.
fn write_dungeon_standin(levels: &Path) {
    let (w, h) = (40u32, 24u32);
    let img = image::RgbaImage::from_fn(w, h, |x, y| {
        let c = if y == 0 && (6..10).contains(&x) {
            [0xff, 0x9a, 0x2a]
        } else if y == h - 1 && (28..31).contains(&x) {
            [0x60, 0xd8, 0xff]
        } else if x == 0 || y == 0 || x == w - 1 || y == h - 1 || (x == 20 && y < 14) {
            [0x4a, 0x46, 0x52]
        } else {
            [0x8a, 0x80, 0x70]
        };
        image::Rgba([c[0], c[1], c[2], 255])
    });
    img.save(levels.join("dungeon.png")).unwrap();
    let samples = Path::new(env!("CARGO_MANIFEST_DIR")).join("levels");
    std::fs::copy(
        samples.join("dungeon.palette.toml"),
        levels.join("dungeon.palette.toml"),
    )
    .unwrap();
}

/// Every example of every subcommand's `--help` runs as written, in a
/// folder whose `levels/` holds a small room and a small `dungeon` with the
/// sample dungeon's palette: the bakes, the relights of the cache a bake
/// example wrote, the palette, the sweep; the watch is stopped once it
/// says it is watching.
#[test]
fn every_help_example_runs_as_written() {
    let dir = tempfile::tempdir().unwrap();
    let levels = dir.path().join("levels");
    std::fs::create_dir_all(&levels).unwrap();
    write_room(&levels, "room", 24, 8, "");
    write_dungeon_standin(&levels);
    let mut ran = 0;
    for sub in ["bake", "relight", "palette", "sweep", "watch"] {
        for args in help_examples(sub) {
            if sub == "watch" {
                run_watch_until_watching(&args, dir.path());
            } else {
                let o = flatbake_in(&args, dir.path());
                assert_exit(&o, EXIT_OK);
            }
            ran += 1;
        }
    }
    assert!(ran >= 5, "{ran} examples");
    // What the examples promise is there.
    assert!(dir.path().join("game/dungeon.flatbake").is_file());
    assert!(dir.path().join("game/night/dungeon.lightmap.png").is_file());
    assert!(dir.path().join("legend.png").is_file());
    assert!(dir.path().join("sweep/accuracy.png").is_file());
}

/// Runs a watch example until it says it is watching (after its first
/// bake), then stops it.
fn run_watch_until_watching(args: &[String], cwd: &Path) {
    let mut child = Command::new(BIN)
        .args(args)
        .current_dir(cwd)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = child.stderr.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(stderr)
            .lines()
            .map_while(Result::ok)
        {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let start = Instant::now();
    let mut said = Vec::new();
    let watching = loop {
        match rx.recv_timeout(Duration::from_millis(200)) {
            Ok(line) if line.contains("watching ") => break true,
            Ok(line) => said.push(line),
            Err(_) if start.elapsed() > Duration::from_secs(60) => break false,
            Err(_) => {
                if child.try_wait().unwrap().is_some() {
                    break false;
                }
            }
        }
    };
    let _ = child.kill();
    let _ = child.wait();
    assert!(watching, "{args:?} never watched: {said:?}");
}

// --- batches past one machine ------------------------------------------------

/// Six rooms of different sizes and lamps (one with falloff) and one file
/// that is not an image, in `dir/levels`.
fn write_batch(dir: &Path) {
    let levels = dir.join("levels");
    std::fs::create_dir_all(&levels).unwrap();
    for (i, name) in ["atrium", "bunker", "crypt", "depot", "engine", "forge"]
        .iter()
        .enumerate()
    {
        let i = i as u32;
        let extra = if i == 2 {
            "[bake]\nfalloff = 10.0\n\n"
        } else {
            ""
        };
        write_room(&levels, name, 20 + 3 * i, 2 + i, extra);
    }
    std::fs::write(levels.join("garbled.png"), b"not a png at all").unwrap();
}

/// A report without its timings (the only part that may differ).
fn report_sans_timings(path: &Path) -> Value {
    let mut r = json(path);
    r.as_object_mut().unwrap().remove("timings");
    r
}

/// A stamp without the hash of the report (whose timings differ).
fn stamp_sans_report_hash(path: &Path) -> Value {
    let mut st = json(path);
    let outputs: Vec<String> = st["outputs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect();
    let hashes = st["hashes"].as_array_mut().unwrap();
    for (i, o) in outputs.iter().enumerate() {
        if o.ends_with(".report.json") {
            hashes[i] = Value::Null;
        }
    }
    st
}

/// The levels of a batch summary by name, without their times.
fn summary_levels(path: &Path) -> BTreeMap<String, Value> {
    let s = json(path);
    s["levels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| {
            let mut l = l.clone();
            l.as_object_mut().unwrap().remove("seconds");
            (l["level"].as_str().unwrap().to_string(), l)
        })
        .collect()
}

/// Checks that every level file of `full` is in `other` with the same
/// content (images byte for byte, reports apart from timings, stamps apart
/// from the report's hash).
fn assert_same_outputs(full: &Path, other: &Path, names: &BTreeSet<String>) {
    for name in names {
        let (a, b) = (full.join(name), other.join(name));
        if name.ends_with(".report.json") {
            assert_eq!(report_sans_timings(&a), report_sans_timings(&b), "{name}");
        } else if name.ends_with(".stamp.json") {
            assert_eq!(
                stamp_sans_report_hash(&a),
                stamp_sans_report_hash(&b),
                "{name}"
            );
        } else {
            assert!(
                read(&a) == read(&b),
                "{name} differs in {}",
                other.display()
            );
        }
    }
}

/// Three shards, each into its own folder and all three at once into one
/// shared folder, bake exactly what one full run bakes: no level twice,
/// none missing (the unreadable one fails in exactly one shard), the same
/// bytes, and each shard's `batch-K-of-3.json` beside the others.
#[test]
fn three_shards_partition_the_levels_and_add_up_to_the_full_run() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    write_batch(root);
    let o = flatbake_in(
        &["bake", "levels", "-o", "full", "--quality", "draft"],
        root,
    );
    assert_exit(&o, EXIT_FAILED);
    let full = root.join("full");
    let full_levels = summary_levels(&full.join("batch.json"));
    assert_eq!(full_levels.len(), 7);
    let level_files: BTreeSet<String> = files(&full)
        .into_iter()
        .filter(|f| f != "batch.json")
        .collect();

    // Each shard into its own folder, one after the other.
    let mut seen: BTreeMap<String, u32> = BTreeMap::new();
    let mut union_files = BTreeSet::new();
    let mut failing_shards = 0;
    let mut nonempty = 0;
    for k in 1..=3u32 {
        let out = format!("own-{k}");
        let shard = format!("{k}/3");
        let o = flatbake_in(
            &[
                "bake",
                "levels",
                "-o",
                &out,
                "--quality",
                "draft",
                "--shard",
                &shard,
            ],
            root,
        );
        let code = o.status.code().unwrap();
        assert!(code == 0 || code == 1, "{}", stderr(&o));
        failing_shards += usize::from(code == 1);
        let own = root.join(&out);
        let summary_name = format!("batch-{k}-of-3.json");
        let summary = json(&own.join(&summary_name));
        assert_eq!(summary["shard"]["index"], k);
        assert_eq!(summary["shard"]["count"], 3);
        let levels = summary_levels(&own.join(&summary_name));
        nonempty += usize::from(!levels.is_empty());
        for (name, entry) in &levels {
            *seen.entry(name.clone()).or_default() += 1;
            assert_eq!(entry, &full_levels[name], "{name} in shard {k}");
        }
        let produced: BTreeSet<String> = files(&own)
            .into_iter()
            .filter(|f| *f != summary_name)
            .collect();
        // A shard writes only its own levels' files.
        for f in &produced {
            let level = f.split('.').next().unwrap();
            assert!(levels.contains_key(level), "shard {k} wrote {f}");
        }
        assert_same_outputs(&full, &own, &produced);
        union_files.extend(produced);
    }
    assert_eq!(
        seen.keys().collect::<Vec<_>>(),
        full_levels.keys().collect::<Vec<_>>(),
        "every level in some shard"
    );
    assert!(
        seen.values().all(|&n| n == 1),
        "a level in two shards: {seen:?}"
    );
    assert_eq!(union_files, level_files);
    assert_eq!(failing_shards, 1, "the unreadable level fails in one shard");
    assert!(nonempty >= 2, "the shards split the batch");

    // All three at once into one folder: they take turns and keep each
    // other's files and summaries.
    let children: Vec<_> = (1..=3)
        .map(|k| {
            Command::new(BIN)
                .args(["bake", "levels", "-o", "shared", "--quality", "draft"])
                .args(["--shard", &format!("{k}/3")])
                .current_dir(root)
                .stdout(Stdio::null())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for c in children {
        let o = c.wait_with_output().unwrap();
        assert!(matches!(o.status.code(), Some(0 | 1)), "{}", stderr(&o));
    }
    let shared = root.join("shared");
    let mut expected = level_files.clone();
    for k in 1..=3 {
        let name = format!("batch-{k}-of-3.json");
        assert_eq!(
            summary_levels(&shared.join(&name)),
            summary_levels(&root.join(format!("own-{k}")).join(&name))
        );
        expected.insert(name);
    }
    assert_eq!(files(&shared), expected);
    assert_same_outputs(&full, &shared, &level_files);
}

/// `--shard` takes K/N with 1 <= K <= N, and says so.
#[test]
fn bad_shards_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let lvl = write_room(dir.path(), "room", 24, 8, "");
    let out = dir.path().join("out");
    for (shard, words) in [
        ("0/3", &["0/3", "K from 1 to N", "1 to 3"][..]),
        ("4/3", &["4/3", "1 to 3"]),
        ("a/b", &["a/b", "K/N", "2/3"]),
        ("1/0", &["1/0", "N at least 1"]),
        ("2", &["K/N"]),
    ] {
        let o = flatbake_mixed(&[&"bake", &lvl, &"-o", &out, &"--shard", &shard]);
        assert_exit(&o, EXIT_USAGE);
        assert_says(&o, words);
        assert!(!out.exists(), "{shard} wrote outputs");
    }
}

/// Every run writes `batch.json`: each level with its status, time,
/// warnings (those of its report) and outputs (the files it has in the
/// folder), the failure's reason; a second run lists the levels as up to
/// date with the same outputs.
#[test]
fn every_bake_writes_a_batch_summary() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    write_batch(root);
    let o = flatbake_in(&["bake", "levels", "-o", "out"], root);
    assert_exit(&o, EXIT_FAILED);
    let out = root.join("out");
    let first = json(&out.join("batch.json"));
    assert_eq!(first["flatbake"], env!("CARGO_PKG_VERSION"));
    assert_eq!(first["quality"], "normal");
    assert_eq!(first["shard"], Value::Null);
    assert_eq!(first["counts"]["levels"], 7);
    assert_eq!(first["counts"]["baked"], 6);
    assert_eq!(first["counts"]["failed"], 1);
    let levels = first["levels"].as_array().unwrap();
    let names: Vec<&str> = levels
        .iter()
        .map(|l| l["level"].as_str().unwrap())
        .collect();
    let mut sorted = names.clone();
    sorted.sort();
    assert_eq!(names, sorted, "in the batch's (sorted) order");
    for l in levels {
        let name = l["level"].as_str().unwrap();
        if name == "garbled" {
            assert_eq!(l["status"], "failed");
            assert!(l["error"].as_str().unwrap().contains("garbled.png"), "{l}");
            assert_eq!(l["outputs"], serde_json::json!([]));
            continue;
        }
        assert_eq!(l["status"], "baked", "{l}");
        let report = json(&out.join(format!("{name}.report.json")));
        assert_eq!(l["seconds"], report["timings"]["total"]);
        assert_eq!(l["warnings"], report["warnings"]);
        let outputs: Vec<String> = l["outputs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap().to_string())
            .collect();
        assert!(outputs.contains(&format!("{name}.stamp.json")));
        assert!(outputs.contains(&format!("{name}.lightmap.png")));
        for f in &outputs {
            assert!(out.join(f).is_file(), "{f}");
        }
        assert_eq!(l["error"], Value::Null);
    }

    let o = flatbake_in(&["bake", "levels", "-o", "out"], root);
    assert_exit(&o, EXIT_FAILED);
    let second = json(&out.join("batch.json"));
    assert_eq!(second["counts"]["up_to_date"], 6);
    assert_eq!(second["counts"]["baked"], 0);
    for (a, b) in levels.iter().zip(second["levels"].as_array().unwrap()) {
        assert_eq!(a["level"], b["level"]);
        if a["status"] == "baked" {
            assert_eq!(b["status"], "up_to_date");
            assert_eq!(b["seconds"], Value::Null);
            assert_eq!(a["outputs"], b["outputs"]);
            assert_eq!(a["warnings"], b["warnings"]);
        }
    }
    assert!(!out.join("batch-1-of-1.json").exists());
}
