//! A level's palette as a designer meets it on the command line: a palette
//! file adds to the built-in palette (`builtin = false` starts empty),
//! `flatbake palette LEVEL` shows what the level gets and where each colour
//! comes from, `flatbake palette --toml` writes a file to start from, and the
//! anti-aliasing advice is safe to follow word for word.

mod common;
use common::*;

use std::path::{Path, PathBuf};

/// Paints `rows` as `dir/NAME.png`: each character is a colour of `key`
/// (any other character is the floor colour `floor`).
fn paint(
    dir: &Path,
    name: &str,
    rows: &[&str],
    key: &[(char, [u8; 3])],
    floor: [u8; 3],
) -> PathBuf {
    let (w, h) = (rows[0].len() as u32, rows.len() as u32);
    let img = image::RgbaImage::from_fn(w, h, |x, y| {
        let c = rows[y as usize].as_bytes()[x as usize] as char;
        let rgb = key
            .iter()
            .find(|(k, _)| *k == c)
            .map_or(floor, |(_, rgb)| *rgb);
        image::Rgba([rgb[0], rgb[1], rgb[2], 255])
    });
    let path = dir.join(format!("{name}.png"));
    img.save(&path).expect("write level");
    path
}

/// The level's report.
fn report(out: &Path, name: &str) -> serde_json::Value {
    let text = std::fs::read_to_string(out.join(format!("{name}.report.json"))).expect("report");
    serde_json::from_str(&text).expect("report is JSON")
}

/// The report's warnings.
fn warnings(r: &serde_json::Value) -> Vec<String> {
    r["warnings"]
        .as_array()
        .expect("warnings")
        .iter()
        .filter_map(|w| w.as_str().map(str::to_string))
        .collect()
}

/// The lightmap's sRGB pixel at `(x, y)`.
fn light(out: &Path, name: &str, x: u32, y: u32) -> [u8; 3] {
    let img = image::open(out.join(format!("{name}.lightmap.png")))
        .expect("lightmap")
        .to_rgb8();
    img.get_pixel(x, y).0
}

const WALL: [u8; 3] = [0x5a, 0x5a, 0x5a];

/// A corridor walled in #5a5a5a with a red, a green and a blue lamp (the
/// built-in colours) set into its top wall.
const CORRIDOR: &[&str] = &[
    "##R#######G#######B##",
    "#...................#",
    "#...................#",
    "#...................#",
    "#####################",
];

fn corridor(dir: &Path) -> PathBuf {
    paint(
        dir,
        "corridor",
        CORRIDOR,
        &[
            ('#', WALL),
            ('R', [255, 0, 0]),
            ('G', [0, 255, 0]),
            ('B', [0, 0, 255]),
        ],
        [0xb4, 0xaa, 0x96],
    )
}

const CORRIDOR_WALL: &str = "[[wall]]\ncolor = \"#5a5a5a\"\nreflectance = 0.6\n";

/// A palette that lists only the corridor's wall keeps the built-in red,
/// green and blue lamps: each lights the floor below it in its colour.
#[test]
fn a_palette_listing_only_its_wall_keeps_the_builtin_lamps() {
    let dir = tempfile::tempdir().unwrap();
    corridor(dir.path());
    std::fs::write(dir.path().join("corridor.palette.toml"), CORRIDOR_WALL).unwrap();
    let o = flatbake_in(&["bake", "corridor.png", "-o", "out"], dir.path());
    assert_exit(&o, EXIT_OK);
    let out = dir.path().join("out");
    let r = report(&out, "corridor");
    assert!(r["energy"]["emitted"].as_f64().unwrap() > 0.0, "{r}");
    // Below each lamp its own channel is the brightest.
    for (x, channel) in [(2, 0), (10, 1), (18, 2)] {
        let p = light(&out, "corridor", x, 1);
        let others = (0..3)
            .filter(|&c| c != channel)
            .map(|c| p[c])
            .max()
            .unwrap();
        assert!(
            p[channel] > 0 && p[channel] > others,
            "below lamp {channel}: {p:?}"
        );
    }
    // The wall is the file's (reflectance 0.6), not the floor.
    assert_eq!(r["counts"]["floor_pixels"].as_u64(), Some(19 * 3), "{r}");
}

/// `builtin = false` at the top of the file starts from an empty palette:
/// the same lamps are then floor, and `palette` says so.
#[test]
fn builtin_false_starts_from_an_empty_palette() {
    let dir = tempfile::tempdir().unwrap();
    corridor(dir.path());
    std::fs::write(
        dir.path().join("corridor.palette.toml"),
        format!("builtin = false\n\n{CORRIDOR_WALL}"),
    )
    .unwrap();
    let o = flatbake_in(&["bake", "corridor.png", "-o", "out"], dir.path());
    assert_exit(&o, EXIT_OK);
    let r = report(&dir.path().join("out"), "corridor");
    assert_eq!(r["energy"]["emitted"].as_f64(), Some(0.0), "{r}");
    assert_eq!(
        r["counts"]["floor_pixels"].as_u64(),
        Some(19 * 3 + 3),
        "{r}"
    );
    let o = flatbake_in(&["palette", "corridor.png"], dir.path());
    assert_exit(&o, EXIT_OK);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("builtin = false"), "{text}");
    assert!(!text.contains("#ff0000"), "{text}");
    // Anything but true or false is an error naming file and line.
    std::fs::write(
        dir.path().join("corridor.palette.toml"),
        format!("builtin = \"no\"\n{CORRIDOR_WALL}"),
    )
    .unwrap();
    let o = flatbake_in(&["bake", "corridor.png", "-o", "out"], dir.path());
    assert_exit(&o, EXIT_FAILED);
    assert_says(
        &o,
        &["corridor.palette.toml:1:", "builtin must be true or false"],
    );
}

/// `palette LEVEL` lists what the level gets: each colour with its source
/// (the file and line, or built-in), the light groups and `[bake]`.
#[test]
fn palette_of_a_level_shows_each_colours_source_groups_and_bake() {
    let dir = tempfile::tempdir().unwrap();
    corridor(dir.path());
    std::fs::write(
        dir.path().join("corridor.palette.toml"),
        "[bake]\ntolerance = 5\nfalloff = 30\n\n[[wall]]\ncolour = \"#5a5a5a\"\nreflectance = 0.6\n\n\
         [[emitter]]\ncolor = \"#ff0000\"\nemission = [3, 0, 0]\ngroup = \"alarm\"\n\n\
         [[emitter]]\ncolor = \"#fffadc\"\nemission = 2\ngroup = \"alarm\"\n",
    )
    .unwrap();
    let o = flatbake_in(&["palette", "corridor.png"], dir.path());
    assert_exit(&o, EXIT_OK);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    let line_of = |colour: &str| {
        text.lines()
            .find(|l| l.trim_start().starts_with(colour))
            .unwrap_or_else(|| panic!("no {colour} in\n{text}"))
            .to_string()
    };
    assert!(text.contains("palette of corridor.png"), "{text}");
    assert!(text.contains("added to the built-in palette"), "{text}");
    assert!(
        line_of("#5a5a5a").ends_with("corridor.palette.toml:6"),
        "{text}"
    );
    let red = line_of("#ff0000");
    assert!(
        red.contains("corridor.palette.toml:10") && red.contains("replaces built-in red light"),
        "{red}"
    );
    let green = line_of("#00ff00");
    assert!(
        green.contains("green light") && green.ends_with("built-in"),
        "{green}"
    );
    assert!(text.contains("alarm: #ff0000, #fffadc"), "{text}");
    assert!(
        text.contains("tolerance = 5") && text.contains("falloff = 30"),
        "{text}"
    );
    assert!(text.contains("not set: bounces, exposure"), "{text}");

    // --palette FILE wins over the lookup, as for bake.
    std::fs::write(dir.path().join("other.toml"), CORRIDOR_WALL).unwrap();
    let o = flatbake_in(
        &["palette", "corridor.png", "--palette", "other.toml"],
        dir.path(),
    );
    assert_exit(&o, EXIT_OK);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        text.contains("other.toml:2") && !text.contains("alarm"),
        "{text}"
    );
    assert!(text.contains("[bake]: nothing set"), "{text}");

    // A level that does not exist is named, not shown with the built-in palette.
    let o = flatbake_in(&["palette", "corridr.png"], dir.path());
    assert_exit(&o, EXIT_FAILED);
    assert_says(&o, &["corridr.png", "file not found"]);
    assert!(o.stdout.is_empty());
}

/// `palette --toml` writes the built-in palette as a commented TOML file:
/// baking with it as the level's palette gives the same bytes as baking
/// with the built-in palette, and it is written only to a new .toml file.
#[test]
fn palette_toml_is_a_starting_file_that_bakes_like_the_builtin_palette() {
    let dir = tempfile::tempdir().unwrap();
    let o = flatbake_in(&["palette", "--toml"], dir.path());
    assert_exit(&o, EXIT_OK);
    let printed = String::from_utf8(o.stdout.clone()).unwrap();
    assert!(printed.starts_with("# "), "commented: {printed}");
    let o = flatbake_in(&["palette", "--toml", "start.toml"], dir.path());
    assert_exit(&o, EXIT_OK);
    let written = std::fs::read_to_string(dir.path().join("start.toml")).unwrap();
    assert_eq!(written, printed);

    // A room of built-in colours only: stone walls, a white and a torch lamp.
    let rows = [
        "####W#####",
        "#........#",
        "#..##....T",
        "#........#",
        "##########",
    ];
    let key = [
        ('#', [0, 0, 0]),
        ('W', [255, 255, 255]),
        ('T', [255, 0x80, 0]),
    ];
    paint(dir.path(), "room", &rows, &key, [0x90, 0x90, 0x90]);
    let o = flatbake_in(&["bake", "room.png", "-o", "builtin"], dir.path());
    assert_exit(&o, EXIT_OK);
    std::fs::copy(
        dir.path().join("start.toml"),
        dir.path().join("room.palette.toml"),
    )
    .unwrap();
    let o = flatbake_in(&["bake", "room.png", "-o", "file"], dir.path());
    assert_exit(&o, EXIT_OK);
    let a = std::fs::read(dir.path().join("builtin/room.lightmap.png")).unwrap();
    let b = std::fs::read(dir.path().join("file/room.lightmap.png")).unwrap();
    assert!(a == b, "the written palette bakes like the built-in one");
    assert!(report(&dir.path().join("file"), "room")["energy"]["emitted"].as_f64() > Some(0.0));

    // The level's palette file is shown as TOML too, and never overwritten.
    let o = flatbake_in(
        &["palette", "room.png", "--toml", "room.palette.toml"],
        dir.path(),
    );
    assert_exit(&o, EXIT_FAILED);
    assert_says(&o, &["room.palette.toml", "already exists"]);
    assert_eq!(
        std::fs::read_to_string(dir.path().join("room.palette.toml")).unwrap(),
        written
    );
    // `--toml room.png` would name the level as the output: refused, the image kept.
    let before = std::fs::read(dir.path().join("room.png")).unwrap();
    let o = flatbake_in(&["palette", "--toml", "room.png"], dir.path());
    assert_exit(&o, EXIT_FAILED);
    assert_says(&o, &["room.png", ".toml"]);
    assert_eq!(std::fs::read(dir.path().join("room.png")).unwrap(), before);
}

/// `colour` and `color` both name an entry's colour.
#[test]
fn colour_and_color_are_both_accepted() {
    let dir = tempfile::tempdir().unwrap();
    corridor(dir.path());
    for key in ["color", "colour"] {
        std::fs::write(
            dir.path().join("corridor.palette.toml"),
            format!("[[wall]]\n{key} = \"#5a5a5a\"\nreflectance = 0.6\n"),
        )
        .unwrap();
        let out = format!("out-{key}");
        let o = flatbake_in(&["bake", "corridor.png", "-o", &out], dir.path());
        assert_exit(&o, EXIT_OK);
        let r = report(&dir.path().join(&out), "corridor");
        assert_eq!(
            r["counts"]["floor_pixels"].as_u64(),
            Some(19 * 3),
            "{key}: {r}"
        );
    }
    std::fs::write(
        dir.path().join("corridor.palette.toml"),
        "[[wall]]\ncolor = \"#5a5a5a\"\ncolour = \"#5a5a5a\"\nreflectance = 0.6\n",
    )
    .unwrap();
    let o = flatbake_in(&["bake", "corridor.png", "-o", "out"], dir.path());
    assert_exit(&o, EXIT_FAILED);
    assert_says(
        &o,
        &[
            "corridor.palette.toml:3:",
            "both `color` (line 2) and `colour`",
        ],
    );
}

/// The near-miss warning's advice: the tolerance and the palette file it
/// names, read back from the warning.
fn advice(w: &str) -> (u8, String) {
    let at = w
        .find("tolerance = ")
        .unwrap_or_else(|| panic!("no tolerance advice: {w}"));
    let rest = &w[at + "tolerance = ".len()..];
    let digits: String = rest.chars().take_while(|c| c.is_ascii_digit()).collect();
    let rest = rest[digits.len()..]
        .strip_prefix("` in ")
        .unwrap_or_else(|| panic!("no file after the tolerance: {w}"));
    let file = rest.split_whitespace().next().unwrap().to_string();
    (digits.parse().unwrap(), file)
}

/// A soft-brushed level with the built-in palette: stone walls whose edges
/// are anti-aliased into the floor, lit by a white and a red lamp. The
/// warning names the level's palette file; writing just what it says into
/// that file snaps the fringe and keeps the lamps and the floor.
#[test]
fn soft_brush_advice_followed_word_for_word_keeps_the_lights() {
    let dir = tempfile::tempdir().unwrap();
    let rows = [
        "######W#######R#####",
        "#abcab.abcabca.bcab#",
        "#c................a#",
        "#b.......cba......b#",
        "#a.......###......c#",
        "#c.......abc......a#",
        "#b................b#",
        "#acbacbacbacbacbacb#",
        "####################",
    ];
    let key = [
        ('#', [0, 0, 0]),
        ('W', [255, 255, 255]),
        ('R', [255, 0, 0]),
        ('a', [9, 8, 8]),
        ('b', [16, 10, 5]),
        ('c', [23, 7, 1]),
    ];
    paint(dir.path(), "brushed", &rows, &key, [0x9a, 0x8a, 0x7a]);
    let o = flatbake_in(&["bake", "brushed.png", "-o", "out"], dir.path());
    assert_exit(&o, EXIT_OK);
    let r = report(&dir.path().join("out"), "brushed");
    let ws = warnings(&r);
    let w = ws
        .iter()
        .find(|w| w.contains("anti-aliasing"))
        .unwrap_or_else(|| panic!("{ws:?}"));
    assert!(
        w.contains("wall #000000 (stone)") && w.contains("up to 23 steps"),
        "{w}"
    );
    let (tolerance, file) = advice(w);
    assert_eq!(
        (tolerance, file.as_str()),
        (23, "brushed.palette.toml"),
        "{w}"
    );
    let floor_before = r["counts"]["floor_pixels"].as_u64().unwrap();

    std::fs::write(
        dir.path().join(&file),
        format!("[bake]\ntolerance = {tolerance}\n"),
    )
    .unwrap();
    let o = flatbake_in(&["bake", "brushed.png", "-o", "out"], dir.path());
    assert_exit(&o, EXIT_OK);
    let r = report(&dir.path().join("out"), "brushed");
    assert!(
        !warnings(&r)
            .iter()
            .any(|w| w.contains("anti-aliasing") || w.contains("no floor")),
        "{r}"
    );
    assert!(
        r["energy"]["emitted"].as_f64().unwrap() > 0.0,
        "the lamps still shine: {r}"
    );
    // The fringe (and only it) became wall; the floor is lit.
    let fringe = rows
        .iter()
        .flat_map(|r| r.chars())
        .filter(|c| "abc".contains(*c))
        .count() as u64;
    assert_eq!(
        r["counts"]["floor_pixels"].as_u64(),
        Some(floor_before - fringe),
        "{r}"
    );
    let p = light(&dir.path().join("out"), "brushed", 6, 3);
    assert!(p.iter().all(|&c| c > 0), "lit floor: {p:?}");
}

/// A whole floor painted #787878, close to the palette's wall #5a5a5a, is
/// a colour of its own, never a near miss. Real fringe pixels along the
/// wall still are, and the tolerance suggested for them stops short of the
/// floor colour: following it keeps every floor pixel of #787878.
#[test]
fn a_flat_floor_close_to_a_wall_is_not_anti_aliasing() {
    let dir = tempfile::tempdir().unwrap();
    let mut rows: Vec<String> = vec!["#".repeat(90)];
    for _ in 0..84 {
        rows.push(format!("#{}#", ".".repeat(88)));
    }
    rows.push("#".repeat(90));
    rows[0].replace_range(40..44, "LLLL");
    let rows: Vec<&str> = rows.iter().map(String::as_str).collect();
    let palette = "[[wall]]\ncolor = \"#5a5a5a\"\nreflectance = 0.6\n";
    paint(
        dir.path(),
        "grey",
        &rows,
        &[('#', WALL), ('L', [255, 255, 255])],
        [0x78; 3],
    );
    std::fs::write(dir.path().join("grey.palette.toml"), palette).unwrap();
    let o = flatbake_in(&["bake", "grey.png", "-o", "out"], dir.path());
    assert_exit(&o, EXIT_OK);
    let r = report(&dir.path().join("out"), "grey");
    assert!(
        !warnings(&r).iter().any(|w| w.contains("anti-aliasing")),
        "{r}"
    );
    assert_eq!(r["counts"]["floor_pixels"].as_u64(), Some(88 * 84));

    // Now a soft edge along the left wall: #5e5e5e, #6a6a6a and #7a7a7a, the
    // last one 32 steps from the wall, further than the floor colour (30).
    let mut soft: Vec<String> = rows.iter().map(|r| r.to_string()).collect();
    for (y, row) in soft.iter_mut().enumerate().skip(10).take(30) {
        row.replace_range(1..2, ["a", "b", "c"][y % 3]);
    }
    let soft: Vec<&str> = soft.iter().map(String::as_str).collect();
    let key = [
        ('#', WALL),
        ('L', [255, 255, 255]),
        ('a', [0x5e; 3]),
        ('b', [0x6a; 3]),
        ('c', [0x7a; 3]),
    ];
    paint(dir.path(), "grey", &soft, &key, [0x78; 3]);
    let o = flatbake_in(&["bake", "grey.png", "-o", "out"], dir.path());
    assert_exit(&o, EXIT_OK);
    let r = report(&dir.path().join("out"), "grey");
    let ws = warnings(&r);
    let w = ws
        .iter()
        .find(|w| w.contains("anti-aliasing"))
        .unwrap_or_else(|| panic!("{ws:?}"));
    assert!(
        w.contains("30 pixels in 3 colours") && w.contains("up to 32 steps"),
        "{w}"
    );
    assert!(w.contains("#787878, painted as an area of its own"), "{w}");
    let (tolerance, file) = advice(w);
    assert_eq!((tolerance, file.as_str()), (29, "grey.palette.toml"), "{w}");
    std::fs::write(
        dir.path().join(&file),
        format!("{palette}\n[bake]\ntolerance = {tolerance}\n"),
    )
    .unwrap();
    let o = flatbake_in(&["bake", "grey.png", "-o", "out"], dir.path());
    assert_exit(&o, EXIT_OK);
    let r = report(&dir.path().join("out"), "grey");
    // The 20 fringe pixels within 29 steps snapped; the floor and the 10
    // pixels of #7a7a7a stayed floor.
    assert_eq!(
        r["counts"]["floor_pixels"].as_u64(),
        Some(88 * 84 - 20),
        "{r}"
    );
    assert!(!warnings(&r).iter().any(|w| w.contains("no floor")), "{r}");
}
