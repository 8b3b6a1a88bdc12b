//! The game pipeline (README, "Using flatbake in a game"): light layers add up to the full lightmap,
//! relighting a cache equals a fresh bake with the new emission, caches of
//! another version, level or a damaged file are refused, unchanged batches
//! are skipped (and `--force` bakes), and watch mode bakes again after a
//! save and survives a broken level.

mod common;
use common::*;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use flatbake_core::bake::{self, Settings};
use flatbake_core::level::Level;
use flatbake_core::level::palette::Palette;
use flatbake_core::output::layers;
use flatbake_core::output::read_lightmap_exr;
use flatbake_core::quality::Quality;

/// Colours of the test level.
const WALL: [u8; 3] = [0x80, 0x80, 0x80];
const RED: [u8; 3] = [0xc0, 0x20, 0x20];
const LAMP: [u8; 3] = [0xff, 0xff, 0xff];
const TORCH: [u8; 3] = [0xff, 0xa0, 0x00];
const DARK: [u8; 3] = [0x00, 0xff, 0xff];
const FLOOR: [u8; 3] = [0xb0, 0xa0, 0x90];

/// A 48 x 32 room: grey border, a red (colour-reflecting) wall, a pillar
/// that casts shadows, and three emitters: a white lamp, an orange torch
/// and a cyan light that the palette leaves off.
fn level_pixels() -> image::RgbaImage {
    let (w, h) = (48u32, 32u32);
    image::RgbaImage::from_fn(w, h, |x, y| {
        let c = if x == 0 || y == 0 || x == w - 1 || y == h - 1 {
            if y == 0 && (10..16).contains(&x) {
                LAMP
            } else if x == w - 1 && (20..24).contains(&y) {
                TORCH
            } else if y == h - 1 && (30..34).contains(&x) {
                DARK
            } else if x == 0 {
                RED
            } else {
                WALL
            }
        } else if (20..24).contains(&x) && (10..18).contains(&y) {
            WALL
        } else {
            FLOOR
        };
        image::Rgba([c[0], c[1], c[2], 255])
    })
}

/// The palette text with the given emissions and an optional falloff.
fn palette_text(lamp: [f64; 3], torch: [f64; 3], dark: [f64; 3], falloff: Option<f64>) -> String {
    let f = |v: [f64; 3]| format!("[{:?}, {:?}, {:?}]", v[0], v[1], v[2]);
    let mut s = String::new();
    if let Some(d) = falloff {
        s += &format!("[bake]\nfalloff = {d:?}\n\n");
    }
    s += "[[wall]]\ncolor = \"#808080\"\nreflectance = 0.5\n\n";
    s += "[[wall]]\ncolor = \"#c02020\"\nreflectance = [0.7, 0.2, 0.1]\n\n";
    s += &format!(
        "[[emitter]]\ncolor = \"#ffffff\"\nemission = {}\nreflectance = 0.3\ngroup = \"lamps\"\n\n",
        f(lamp)
    );
    s += &format!(
        "[[emitter]]\ncolor = \"#ffa000\"\nemission = {}\nreflectance = 0.2\n\n",
        f(torch)
    );
    s += &format!("[[emitter]]\ncolor = \"#00ffff\"\nemission = {}\n", f(dark));
    s
}

const LAMP_E: [f64; 3] = [3.0, 3.0, 3.0];
const TORCH_E: [f64; 3] = [4.0, 2.0, 0.5];

fn default_palette() -> String {
    palette_text(LAMP_E, TORCH_E, [0.0; 3], None)
}

/// Writes `NAME.png` and `NAME.palette.toml` into `dir`; returns the image path.
fn write_level(dir: &Path, name: &str, palette: &str) -> PathBuf {
    let png = dir.join(format!("{name}.png"));
    level_pixels().save(&png).expect("write level png");
    std::fs::write(dir.join(format!("{name}.palette.toml")), palette).expect("write palette");
    png
}

fn resolved(palette: &str) -> Level {
    let pal = Palette::parse(palette, Path::new("test.palette.toml")).expect("palette parses");
    let img = level_pixels();
    let px: Vec<[u8; 4]> = img.pixels().map(|p| p.0).collect();
    Level::from_rgba(
        "room",
        img.width() as usize,
        img.height() as usize,
        &px,
        &pal,
    )
}

/// Largest absolute difference, and the largest value of `a`.
fn max_diff(a: &[[f32; 3]], b: &[[f32; 3]]) -> (f64, f64) {
    assert_eq!(a.len(), b.len());
    let mut d: f64 = 0.0;
    let mut m: f64 = 0.0;
    for (p, q) in a.iter().zip(b) {
        for c in 0..3 {
            d = d.max((p[c] as f64 - q[c] as f64).abs());
            m = m.max(p[c] as f64);
        }
    }
    (d, m)
}

fn settings(falloff: Option<f64>) -> Settings {
    let mut s = Settings::new(Quality::Normal);
    s.falloff = falloff;
    s.responses = true;
    s
}

#[test]
fn layers_sum_to_the_full_lightmap() {
    for falloff in [None, Some(12.0)] {
        let level = resolved(&palette_text(LAMP_E, TORCH_E, [0.0; 3], falloff));
        let baked = bake::bake(&level, &settings(falloff), &|_| {}).expect("bakes");
        let r = baked.responses.as_ref().expect("responses asked for");
        let groups = layers::groups(&level, r);
        let names: Vec<&str> = groups.iter().map(|g| g.name.as_str()).collect();
        assert_eq!(names, ["lamps", "ffa000", "00ffff"], "falloff {falloff:?}");
        let e = layers::palette_emission(&level, r);
        let mut sum = vec![[0f32; 3]; level.width * level.height];
        for g in &groups {
            let l = layers::layer(r, &e, g);
            for (s, v) in sum.iter_mut().zip(&l.rgb) {
                for c in 0..3 {
                    s[c] += v[c];
                }
            }
        }
        let (d, m) = max_diff(&baked.lightmap.rgb, &sum);
        eprintln!("layers, falloff {falloff:?}: max error {d:e} of max {m}");
        assert!(m > 0.1, "the level is lit");
        // Linear up to the solver tolerance (1e-6) and float rounding.
        assert!(
            d <= 1e-4 * m,
            "falloff {falloff:?}: layers differ by {d} (max {m})"
        );
        // The layered lightmap is the plain bake's, up to the positivity
        // limiter on patch slopes acting on each emitter's light alone.
        let mut plain = settings(falloff);
        plain.responses = false;
        let direct = bake::bake(&level, &plain, &|_| {}).expect("bakes");
        let (dp, _) = max_diff(&direct.lightmap.rgb, &baked.lightmap.rgb);
        eprintln!("layered vs plain bake, falloff {falloff:?}: max difference {dp:e}");
        assert!(
            dp <= 5e-3 * m,
            "layered bake differs from a plain one by {dp}"
        );
        // The lamp layer alone is not the whole picture: the torch adds light.
        let lamp = layers::layer(r, &e, &groups[0]);
        assert!(max_diff(&baked.lightmap.rgb, &lamp.rgb).0 > 0.01 * m);
    }
}

#[test]
fn bake_layers_writes_files_that_add_up() {
    let dir = tempfile::tempdir().expect("tempdir");
    let png = write_level(dir.path(), "room", &default_palette());
    let out = dir.path().join("out");
    let o = flatbake(&["bake", s(&png), "-o", s(&out), "--layers", "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let manifest: layers::Manifest = serde_json::from_slice(
        &std::fs::read(out.join("room.layers.json")).expect("manifest written"),
    )
    .expect("manifest parses");
    assert_eq!(manifest.groups.len(), 3);
    let report: flatbake_core::bake::report::Report =
        serde_json::from_slice(&std::fs::read(out.join("room.report.json")).expect("report"))
            .expect("report parses");
    for f in [
        "room.layers.json",
        "room.layer-lamps.exr",
        "room.report.json",
    ] {
        assert!(
            report.outputs.iter().any(|o| o == f),
            "{f} in {:?}",
            report.outputs
        );
    }
    assert_eq!(manifest.groups[0].name, "lamps");
    assert_eq!(manifest.groups[1].emitters[0].emission, TORCH_E);
    let (_, _, full) = read_lightmap_exr(&out.join(&manifest.lightmap_exr)).expect("full exr");
    let mut sum = vec![[0f32; 3]; full.len()];
    for g in &manifest.groups {
        assert!(out.join(&g.png).is_file(), "{} written", g.png);
        let (_, _, l) = read_lightmap_exr(&out.join(&g.exr)).expect("layer exr");
        for (s, v) in sum.iter_mut().zip(&l) {
            for c in 0..3 {
                s[c] += v[c];
            }
        }
    }
    let (d, m) = max_diff(&full, &sum);
    assert!(
        m > 0.1 && d <= 1e-4 * m,
        "layer files differ by {d} (max {m})"
    );
}

/// Relighting with new emission equals baking the level with that emission
/// in its palette — including an emitter the palette had switched off.
#[test]
fn relight_equals_a_fresh_bake_with_the_new_emission() {
    let new_lamp = [0.5, 1.0, 6.0];
    let new_dark = [0.0, 2.0, 2.0];
    for falloff in [None, Some(12.0)] {
        let level = resolved(&palette_text(LAMP_E, TORCH_E, [0.0; 3], falloff));
        let fresh_level = resolved(&palette_text(new_lamp, TORCH_E, new_dark, falloff));
        // Against a bake without responses, with the lattice off: a bake
        // decides where to interpolate from its own light, the unit
        // responses of a cache or its palette's emission (compared below).
        let mut exact_pixels = settings(falloff);
        exact_pixels.knobs.lattice = None;
        let baked = bake::bake(&level, &exact_pixels, &|_| {}).expect("bakes");
        let r = baked.responses.expect("responses");
        let relit_exact_pixels = r.combine(&[new_lamp, TORCH_E, new_dark]);
        let mut s = exact_pixels;
        s.responses = false;
        let fresh = bake::bake(&fresh_level, &s, &|_| {}).expect("bakes");
        let (d, m) = max_diff(&fresh.lightmap.rgb, &relit_exact_pixels);
        // Without falloff nothing is culled: equal up to the solver
        // tolerance. With falloff each bake culls pairs whose light is below
        // reach_bound x its brightest emission; the two bakes cull different
        // pairs, so allow ten such pairs per pixel (measured: about 1.3).
        let e_max = 6.0;
        let tol = match falloff {
            None => 1e-4 * m,
            Some(_) => 1e-4 * m + 10.0 * Quality::Normal.knobs().reach_bound * e_max,
        };
        eprintln!(
            "relight, falloff {falloff:?}: max error {d:e} of max {m}; culled pairs {}",
            fresh.report.counts.culled_pairs
        );
        assert!(m > 0.1, "the level is lit");
        assert!(
            d <= tol,
            "falloff {falloff:?}: relit differs by {d} (tol {tol}, max {m})"
        );
        // A relight is exactly what a layered bake with the new emission
        // writes: both are sums of per-emitter light, with falloff both
        // cull the same pairs, and both interpolate the same pixels (chosen
        // for unit emission, whatever the palette).
        let baked = bake::bake(&level, &settings(falloff), &|_| {}).expect("bakes");
        let r = baked.responses.expect("responses");
        let relit = r.combine(&[new_lamp, TORCH_E, new_dark]);
        let layered = bake::bake(&fresh_level, &settings(falloff), &|_| {}).expect("bakes");
        let (dl, _) = max_diff(&layered.lightmap.rgb, &relit);
        let tol_layered = 1e-5 * m;
        eprintln!("relight vs layered bake, falloff {falloff:?}: max error {dl:e}");
        assert!(
            dl <= tol_layered,
            "relit differs from a layered bake by {dl}"
        );
        // A bake without responses interpolates where its own light says
        // so: within the lattice's tolerance of the relight.
        let mut s = settings(falloff);
        s.responses = false;
        let plain = bake::bake(&fresh_level, &s, &|_| {}).expect("bakes");
        let (dp, _) = max_diff(&plain.lightmap.rgb, &relit);
        let lattice = Quality::Normal
            .knobs()
            .lattice
            .expect("normal interpolates");
        eprintln!("relight vs plain bake, falloff {falloff:?}: max error {dp:e}");
        assert!(
            dp <= tol + lattice * m,
            "relit differs from a plain bake by {dp}"
        );
        // And it is not simply the old lightmap.
        assert!(max_diff(&baked.lightmap.rgb, &relit).0 > 0.05 * m);
    }
}

/// The same through the command line and the cache file.
#[test]
fn relight_command_equals_bake_command() {
    let dir = tempfile::tempdir().expect("tempdir");
    let png = write_level(dir.path(), "room", &default_palette());
    let out = dir.path().join("out");
    let o = flatbake(&["bake", s(&png), "-o", s(&out), "--cache", "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let cache = out.join("room.flatbake");
    assert!(cache.is_file());

    let relit = dir.path().join("relit");
    let o = flatbake(&[
        "relight",
        s(&cache),
        "--emission",
        "#ffa000=1,5,9",
        "--emission",
        "#00FFFF=2",
        "--hdr",
        "--layers",
        "--level",
        s(&png),
        "-o",
        s(&relit),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(relit.join("room.lightmap.png").is_file());
    let report: flatbake_core::bake::report::Report =
        serde_json::from_slice(&std::fs::read(relit.join("room.report.json")).expect("report"))
            .expect("report parses");
    assert_eq!(report.solver, "relight");
    assert_eq!(report.timings.form_factors, 0.0);
    // The report on disk lists exactly the files the relight wrote, layers
    // included.
    let mut listed = report.outputs.clone();
    listed.sort();
    let mut on_disk: Vec<String> = std::fs::read_dir(&relit)
        .expect("relit folder")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    on_disk.sort();
    assert_eq!(listed, on_disk);
    assert!(
        listed.iter().any(|n| n.starts_with("room.layer-")),
        "{listed:?}"
    );

    let fresh_dir = tempfile::tempdir().expect("tempdir");
    let png2 = write_level(
        fresh_dir.path(),
        "room",
        &palette_text(LAMP_E, [1.0, 5.0, 9.0], [2.0; 3], None),
    );
    let fresh = fresh_dir.path().join("out");
    // (With `--layers`, as the cache was: both then interpolate the same
    // pixels, chosen for unit emission.)
    let o = flatbake(&[
        "bake",
        s(&png2),
        "-o",
        s(&fresh),
        "--hdr",
        "--layers",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, _, a) = read_lightmap_exr(&fresh.join("room.lightmap.exr")).expect("fresh exr");
    let (_, _, b) = read_lightmap_exr(&relit.join("room.lightmap.exr")).expect("relit exr");
    let (d, m) = max_diff(&a, &b);
    assert!(m > 0.1 && d <= 1e-4 * m, "relight differs by {d} (max {m})");
}

#[test]
fn relight_refuses_other_versions_levels_and_damaged_files() {
    let dir = tempfile::tempdir().expect("tempdir");
    let png = write_level(dir.path(), "room", &default_palette());
    let out = dir.path().join("out");
    let o = flatbake(&["bake", s(&png), "-o", s(&out), "--cache", "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let cache = out.join("room.flatbake");
    let bytes = std::fs::read(&cache).expect("cache");
    let relit = dir.path().join("relit");
    let relight = |file: &Path, extra: &[&str]| {
        let mut args = vec!["relight", s(file), "-o", s(&relit)];
        args.extend_from_slice(extra);
        flatbake(&args)
    };

    // A device is never read into memory.
    #[cfg(unix)]
    {
        let o = relight(Path::new("/dev/zero"), &[]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(
            stderr(&o).contains("is not a flatbake cache"),
            "{}",
            stderr(&o)
        );
    }
    // Emission a palette may not give, a relight may not either.
    let o = relight(&cache, &["--emission", "#ffa000=1e300"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("is too large"), "{}", stderr(&o));

    // Not a cache at all.
    let o = relight(&png, &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("is not a flatbake cache"),
        "{}",
        stderr(&o)
    );

    // Another flatbake version: same layout, other version string.
    let version = env!("CARGO_PKG_VERSION").as_bytes();
    let at = 16 + 8;
    assert_eq!(&bytes[at..at + version.len()], version);
    let mut other = bytes.clone();
    other[at] = if other[at] == b'9' { b'8' } else { b'9' };
    let f = dir.path().join("other-version.flatbake");
    std::fs::write(&f, &other).expect("write");
    let o = relight(&f, &[]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("was written by flatbake") && e.contains("bake the level again"),
        "{e}"
    );

    // Damaged payload, and a truncated file.
    let mut bad = bytes.clone();
    let n = bad.len();
    bad[n / 2] ^= 0x55;
    let f = dir.path().join("damaged.flatbake");
    std::fs::write(&f, &bad).expect("write");
    let o = relight(&f, &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("damaged"), "{}", stderr(&o));
    std::fs::write(&f, &bytes[..40]).expect("write");
    let o = relight(&f, &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("damaged"), "{}", stderr(&o));

    // Another level's image.
    let other_png = dir.path().join("other.png");
    let mut img = level_pixels();
    img.put_pixel(5, 5, image::Rgba([0x80, 0x80, 0x80, 255]));
    img.save(&other_png).expect("write");
    let o = relight(&cache, &["--level", s(&other_png)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("another level"), "{}", stderr(&o));

    // A colour that is not an emitter of this level is named.
    let o = relight(&cache, &["--emission", "#123456=1"]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(e.contains("#123456") && e.contains("#ffa000"), "{e}");
    let o = relight(&cache, &["--emission", "#c02020=1"]);
    assert!(stderr(&o).contains("is a wall"), "{}", stderr(&o));

    // The genuine cache still works.
    let o = relight(&cache, &["--emission", "#ffa000=1"]);
    assert!(o.status.success(), "{}", stderr(&o));

    // Never into the bake's own folder: its lightmap stays the bake's, and
    // the bake stays up to date.
    let before = std::fs::read(out.join("room.lightmap.png")).expect("lightmap");
    let o = flatbake(&[
        "relight",
        s(&cache),
        "--emission",
        "#ffa000=1",
        "-o",
        s(&out),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("holds the bake of room"),
        "{}",
        stderr(&o)
    );
    assert_eq!(
        std::fs::read(out.join("room.lightmap.png")).expect("lightmap"),
        before
    );
    // The default folder is its own (out/relit), beside the bake's.
    let o = std::process::Command::new(BIN)
        .args(["relight", s(&cache), "--emission", "#ffa000=1"])
        .current_dir(dir.path())
        .output()
        .expect("flatbake runs");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.path().join("out/relit/room.lightmap.png").is_file());
    assert_eq!(
        std::fs::read(out.join("room.lightmap.png")).expect("lightmap"),
        before
    );
}

#[test]
fn unchanged_batch_skips_and_force_or_a_palette_change_bakes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let png = write_level(dir.path(), "room", &default_palette());
    let out = dir.path().join("out");
    let bake = |extra: &[&str]| {
        let mut args = vec!["bake", s(&png), "-o", s(&out)];
        args.extend_from_slice(extra);
        let o = flatbake(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        stderr(&o)
    };
    let first = bake(&[]);
    assert!(first.contains("1 level baked"), "{first}");
    let lightmap = std::fs::read(out.join("room.lightmap.png")).expect("lightmap");

    let again = bake(&[]);
    assert!(
        again.contains("up to date: ") && again.contains("0 levels baked"),
        "{again}"
    );
    assert!(again.contains("1 up to date"), "{again}");

    let forced = bake(&["--force"]);
    assert!(forced.contains("1 level baked"), "{forced}");

    // Another setting is another bake.
    let other = bake(&["--exposure", "2"]);
    assert!(other.contains("1 level baked"), "{other}");
    let back = bake(&[]);
    assert!(back.contains("1 level baked"), "{back}");

    // An output that something else rewrote (a person, a relight, another
    // process) is not the bake's: baked again, and put back.
    let ours = std::fs::read(out.join("room.lightmap.png")).expect("lightmap");
    std::fs::copy(out.join("room.lit.png"), out.join("room.lightmap.png")).expect("overwrite");
    let rewritten = bake(&[]);
    assert!(rewritten.contains("1 level baked"), "{rewritten}");
    assert_eq!(
        std::fs::read(out.join("room.lightmap.png")).expect("lightmap"),
        ours
    );

    // A temporary file that a killed bake left behind is removed.
    let leftover = out.join(".flatbake-killed.tmp");
    std::fs::write(&leftover, b"half a lightmap").expect("leftover");
    let _ = bake(&[]);
    assert!(!leftover.exists(), "stale temporary file kept");

    // A missing output is baked again.
    std::fs::remove_file(out.join("room.lit.png")).expect("remove");
    let missing = bake(&[]);
    assert!(missing.contains("1 level baked"), "{missing}");
    assert!(out.join("room.lit.png").is_file());

    // A palette edit is baked again and changes the lightmap.
    std::fs::write(
        dir.path().join("room.palette.toml"),
        palette_text([1.0; 3], TORCH_E, [0.0; 3], None),
    )
    .expect("write palette");
    let edited = bake(&[]);
    assert!(edited.contains("1 level baked"), "{edited}");
    let relit = std::fs::read(out.join("room.lightmap.png")).expect("lightmap");
    assert_ne!(lightmap, relit, "the palette edit shows");

    // Same bytes written again (a touch): still up to date.
    std::fs::write(
        dir.path().join("room.palette.toml"),
        palette_text([1.0; 3], TORCH_E, [0.0; 3], None),
    )
    .expect("write palette");
    let touched = bake(&[]);
    assert!(touched.contains("1 up to date"), "{touched}");
}

/// Polls up to 20 s for `f` to hold.
fn eventually(what: &str, f: impl Fn() -> bool) {
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    while !f() {
        assert!(
            std::time::Instant::now() < deadline,
            "no {what} within 20 s"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The `watch` command end to end: first bake, then a bake after a save.
#[test]
fn watch_command_bakes_and_rebakes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let levels = dir.path().join("levels");
    std::fs::create_dir(&levels).expect("mkdir");
    write_level(&levels, "room", &default_palette());
    let out = dir.path().join("out");
    let mut child = Command::new(BIN)
        .args(["watch", s(&levels), "-o", s(&out), "-q", "draft"])
        .args(["--debounce", "100"])
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("start flatbake watch");
    let stamp = out.join("room.stamp.json");
    let result = std::panic::catch_unwind(|| {
        eventually("first bake", || stamp.is_file());
        let first = std::fs::read(&stamp).expect("stamp");
        // Watching starts before the first bake, so this save is seen.
        std::fs::write(
            levels.join("room.palette.toml"),
            palette_text([9.0; 3], TORCH_E, [0.0; 3], None),
        )
        .expect("write");
        eventually("bake after the save", || {
            std::fs::read(&stamp).is_ok_and(|now| now != first)
        });
    });
    // Stop the watcher this test started, whatever happened.
    let _ = child.kill();
    let _ = child.wait();
    if let Err(e) = result {
        std::panic::resume_unwind(e);
    }
}

/// Panics inside a level's bake while it reports its stages.
struct PanicsOn(&'static str);

impl flatbake_core::batch::Observer for PanicsOn {
    fn stage(&self, path: &Path, _stage: &str) {
        if path.file_stem().is_some_and(|s| s == self.0) {
            panic!("a test panic in {}", self.0);
        }
    }
}

/// A panic while one level bakes (a decoder's or a bug) is that level's
/// failure, naming its file; the other levels of the batch still bake.
#[test]
fn a_panic_in_one_level_fails_that_level_and_the_batch_goes_on() {
    use flatbake_core::batch::{self, BatchOptions, LevelOutcome};
    let dir = tempfile::tempdir().expect("tempdir");
    let good = write_level(dir.path(), "good", &default_palette());
    let bad = write_level(dir.path(), "bad", &default_palette());
    let opts = BatchOptions {
        out_dir: dir.path().join("out"),
        ..BatchOptions::default()
    };
    let outcomes = batch::run(&[bad.clone(), good.clone()], &opts, &PanicsOn("bad"));
    assert_eq!(outcomes.len(), 2);
    for o in &outcomes {
        match o {
            LevelOutcome::Failed { path, error } => {
                assert_eq!(path, &bad);
                let msg = error.to_string();
                assert!(
                    msg.contains("bad.png") && msg.contains("a test panic in bad"),
                    "{msg}"
                );
            }
            LevelOutcome::Baked { path, .. } => assert_eq!(path, &good),
            other => panic!("unexpected outcome {other:?}"),
        }
    }
    assert!(dir.path().join("out/good.lightmap.png").is_file());
    assert!(!dir.path().join("out/bad.lightmap.png").exists());
}

/// A bake into a folder that another process is writing waits for it (and
/// says so) instead of mixing the two processes' files.
#[cfg(unix)]
#[test]
fn a_second_bake_into_a_held_folder_waits() {
    let dir = tempfile::tempdir().expect("tempdir");
    let png = write_level(dir.path(), "room", &default_palette());
    let out = dir.path().join("out");
    let lock = flatbake_core::batch::FolderLock::acquire(&out, || panic!("nobody holds it yet"));
    assert!(lock.is_held());
    let child = std::process::Command::new(BIN)
        .args(["bake", s(&png), "-o", s(&out), "-q", "draft"])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("start flatbake");
    std::thread::sleep(std::time::Duration::from_millis(1500));
    assert!(
        !out.join("room.lightmap.png").exists(),
        "baked into a folder another process holds"
    );
    drop(lock);
    let o = child.wait_with_output().expect("flatbake ends");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("is being written by another flatbake; waiting"),
        "{}",
        stderr(&o)
    );
    assert!(out.join("room.lightmap.png").is_file());
}

/// The memory estimate's count of form-factor entries is the exact count
/// when every patch is sampled, and close to it from a sample of 64 patches
/// on a level of scattered obstacles; the falloff's reach is applied as the
/// form factors apply it.
#[test]
fn the_memory_estimate_counts_form_factor_entries_from_a_sample() {
    use flatbake_core::transport::{self, kernel::Reach};
    use flatbake_core::visibility::Structures;
    for (falloff, tolerance) in [(None, 0.25), (Some(6.0), 0.25)] {
        let (level, _) = flatbake_synth::bench_obstacles(192, 20, 4, 3)
            .level()
            .expect("the benchmark's palette parses");
        let knobs = Quality::Normal.knobs();
        let scene = bake::Scene::new(&level, &knobs, false);
        let falloff = falloff.map(transport::kernel::Falloff::new);
        let lens: Vec<f64> = scene.geometry.edges.iter().map(|e| e.len()).collect();
        let reach = Reach::new(
            &lens,
            &vec![1.0; lens.len()],
            falloff,
            0.5,
            knobs.reach_bound,
        );
        let structures = Structures::new(&scene.geometry);
        let (ff, _, _) = transport::form_factors(
            &structures,
            &scene.patches,
            knobs.quad,
            falloff,
            &reach,
            knobs.reach_bound,
        );
        // The merged rows' entries: those of S less the ones added to
        // make its pattern symmetric.
        let exact = ff.nnz() as u64 - ff.one_sided;
        let n = scene.patch_count();
        let estimate = |samples| {
            transport::estimate_entries(
                &structures,
                &scene.patches,
                knobs.quad,
                falloff,
                &reach,
                knobs.reach_bound,
                samples,
            )
        };
        assert_eq!(estimate(n), exact, "every patch sampled: the exact count");
        let sampled = estimate(64);
        let ratio = sampled as f64 / exact as f64;
        assert!(
            (1.0 - tolerance..=1.0 + tolerance).contains(&ratio),
            "{n} patches, 64 sampled: {sampled} vs {exact} ({ratio:.3})"
        );
    }
}

/// `Settings::keep_form_factors` decides only whether the form factors are
/// handed back: off (as a batch bakes), they are freed before the gather
/// and the lightmap and the report's entry count are the same.
#[test]
fn dropping_the_form_factors_changes_no_output() {
    let level = resolved(&default_palette());
    let kept = bake::bake(&level, &Settings::new(Quality::Normal), &|_| {}).expect("bakes");
    let ff = kept.form_factors.as_ref().expect("kept by default");
    assert!(ff.nnz() > 0);
    let mut settings = Settings::new(Quality::Normal);
    settings.keep_form_factors = false;
    let dropped = bake::bake(&level, &settings, &|_| {}).expect("bakes");
    assert!(dropped.form_factors.is_none());
    assert_eq!(dropped.lightmap.rgb, kept.lightmap.rgb);
    assert_eq!(dropped.radiosity, kept.radiosity);
    assert_eq!(
        dropped.report.counts.form_factor_entries,
        kept.report.counts.form_factor_entries
    );
    assert_eq!(dropped.report.counts.form_factor_entries, ff.nnz());
}

/// A bake whose estimate is above `Settings::max_memory` is refused before
/// its form factors, with the estimate; at the estimate itself it bakes,
/// and the report records the same estimate.
#[test]
fn max_memory_refuses_above_the_estimate_and_bakes_at_it() {
    let (level, _) = flatbake_synth::cornell(48).level().expect("palette");
    let mut settings = Settings::new(Quality::Draft);
    let baked = bake::bake(&level, &settings, &|_| {}).expect("no limit: bakes");
    let estimate = baked.report.counts.memory_estimate;
    assert!(estimate > 0);
    settings.max_memory = Some(estimate);
    let again = bake::bake(&level, &settings, &|_| {}).expect("at the estimate: bakes");
    assert_eq!(again.report.counts.memory_estimate, estimate);
    settings.max_memory = Some(estimate - 1);
    match bake::bake(&level, &settings, &|_| {}) {
        Err(bake::BakeError::TooMuchMemory { estimate: e, limit }) => {
            assert_eq!((e.bytes, limit), (estimate, estimate - 1));
        }
        Err(other) => panic!("refused for another reason: {other}"),
        Ok(_) => panic!("baked above its limit"),
    }
}

#[test]
fn a_bake_without_a_flag_removes_what_the_flag_wrote_and_nothing_else() {
    let dir = tempfile::tempdir().unwrap();
    let img = write_level(dir.path(), "room", &default_palette());
    let out = dir.path().join("out");
    let bake = |flags: &[&str]| {
        let mut args = vec!["bake", s(&img), "-o", s(&out)];
        args.extend_from_slice(flags);
        let o = flatbake(&args);
        assert_exit(&o, EXIT_OK);
        o
    };
    bake(&["--hdr", "--layers", "--occluders"]);
    let extras = [
        "room.lightmap.exr",
        "room.layers.json",
        "room.occluders.json",
        "room.occluders.svg",
        "room.occluders.tres",
    ];
    for f in extras {
        assert!(out.join(f).is_file(), "{f} written");
    }
    let layer_files: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|f| f.starts_with("room.layer-"))
        .collect();
    assert!(!layer_files.is_empty());
    // Files the stamp does not list stay, whatever their names.
    std::fs::write(out.join("room.notes.txt"), "mine").unwrap();
    std::fs::write(dir.path().join("outside.png"), "mine").unwrap();
    let mut stamp: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("room.stamp.json")).unwrap()).unwrap();
    for f in ["room.notes.txt", "../outside.png"] {
        stamp["outputs"].as_array_mut().unwrap().push(f.into());
        stamp["hashes"].as_array_mut().unwrap().push("0".into());
    }
    std::fs::write(out.join("room.stamp.json"), stamp.to_string()).unwrap();

    let o = bake(&[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("removed what this bake no longer writes"),
        "{err}"
    );
    for f in extras
        .iter()
        .copied()
        .chain(layer_files.iter().map(|f| f.as_str()))
    {
        assert!(!out.join(f).exists(), "{f} is stale and stays");
    }
    for f in [
        "room.lightmap.png",
        "room.lit.png",
        "room.report.json",
        "room.stamp.json",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    assert!(out.join("room.notes.txt").is_file());
    assert!(dir.path().join("outside.png").is_file());
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("room.report.json")).unwrap()).unwrap();
    let removed = report["removed"].as_array().expect("the report lists them");
    assert_eq!(removed.len(), extras.len() + layer_files.len());
    // The next bake with the same flags is up to date and removes nothing.
    let o = bake(&[]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("1 up to date"));
}
