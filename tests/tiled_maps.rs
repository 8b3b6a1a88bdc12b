//! Tiled maps as levels: the fixtures in `tests/fixtures/tiled` were written
//! by Tiled 1.8.2 itself (`tiled --export-map tmx room.tmj room.tmx`, the
//! same for `grouped.tmj`, and
//! `tiled --export-tileset tsx room.tsj room.tsx`, with
//! `QT_QPA_PLATFORM=offscreen`); their tileset image does not exist on
//! purpose, since only tile properties are read.

mod common;

use std::path::Path;

use common::{EXIT_OK, assert_exit, assert_says, flatbake, s, stderr, write_room};

use flatbake_core::MaterialKind;
use flatbake_core::level::tiled_map::load_tiled;
use flatbake_core::level::{Cell, LoadLimits};

#[test]
fn the_exported_room_has_its_walls_and_its_light_object() {
    let path = Path::new("tests/fixtures/tiled/room.tmx");
    let level = load_tiled(path, LoadLimits::default()).expect("the map loads");
    assert_eq!((level.width, level.height), (64, 48));
    let kind = |c: Cell| match c {
        Cell::Solid(i) => Some(level.materials[usize::from(i)].kind),
        _ => None,
    };
    let walls = level
        .cells
        .iter()
        .filter(|&&c| kind(c) == Some(MaterialKind::Wall))
        .count();
    let emitters: Vec<(usize, usize)> = (0..level.cells.len())
        .filter(|&i| kind(level.cells[i]) == Some(MaterialKind::Emitter))
        .map(|i| (i % level.width, i / level.width))
        .collect();
    assert_eq!(walls, 1600, "25 wall tiles of 8 x 8 px");
    assert_eq!(emitters.len(), 64, "one 8 x 8 px light rectangle");
    assert!(
        emitters
            .iter()
            .all(|&(x, y)| (16..24).contains(&x) && (16..24).contains(&y))
    );
}

#[test]
fn an_unknown_material_names_the_map_layer_and_tile() {
    let dir = tempfile::tempdir().unwrap();
    let src = Path::new("tests/fixtures/tiled");
    std::fs::copy(src.join("room.tmx"), dir.path().join("room.tmx")).unwrap();
    let tsx = std::fs::read_to_string(src.join("room.tsx")).unwrap();
    assert!(
        tsx.contains("value=\"wall\""),
        "the fixture's tileset has a wall tile"
    );
    std::fs::write(
        dir.path().join("room.tsx"),
        tsx.replacen("value=\"wall\"", "value=\"glass\"", 1),
    )
    .unwrap();
    let err = load_tiled(&dir.path().join("room.tmx"), LoadLimits::default())
        .unwrap_err()
        .to_string();
    for word in ["room.tmx", "walls", "glass"] {
        assert!(err.contains(word), "{word:?} missing from: {err}");
    }
}

/// `grouped.tmx` (written by Tiled 1.8.2 from `grouped.tmj`): the walls
/// layer and an object layer inside group layers; a tile object of the
/// emitter tile standing on (40, 32), a plain rectangle with `flatbake =
/// wall`, and a rectangle with neither class nor property.
#[test]
fn layers_in_groups_and_tile_objects_standing_on_their_position() {
    let path = Path::new("tests/fixtures/tiled/grouped.tmx");
    let level = load_tiled(path, LoadLimits::default()).expect("the map loads");
    let at = |x: usize, y: usize| match level.cell(x, y) {
        Cell::Solid(i) => Some(&level.materials[usize::from(i)]),
        _ => None,
    };
    let mut emitters = 0;
    let mut crate_walls = 0;
    for y in 0..level.height {
        for x in 0..level.width {
            let (tx, ty) = (x / 8, y / 8);
            let wall_tile = tx == 0 || ty == 0 || tx == 7 || ty == 5 || (tx, ty) == (4, 3);
            let lamp = (40..48).contains(&x) && (24..32).contains(&y);
            let crate_px = (8..12).contains(&x) && (8..12).contains(&y);
            match at(x, y) {
                Some(m) if m.kind == MaterialKind::Emitter => {
                    assert!(lamp, "emitter at ({x}, {y})");
                    assert_eq!(m.emission, [4.0, 3.4, 2.4], "the tile's own emission");
                    emitters += 1;
                }
                Some(m) => {
                    assert!(wall_tile || crate_px, "wall at ({x}, {y})");
                    assert_eq!(m.kind, MaterialKind::Wall);
                    crate_walls += usize::from(crate_px);
                }
                None => assert!(!wall_tile && !lamp && !crate_px, "floor at ({x}, {y})"),
            }
        }
    }
    assert_eq!(emitters, 64, "one tile object of 8 x 8 px");
    assert_eq!(crate_walls, 16, "a 4 x 4 px crate");
}

/// A folder with an image and a map bakes both from the command line; a
/// second run finds both up to date; editing the map's tileset re-bakes
/// the map alone.
#[test]
fn a_folder_with_an_image_and_a_map_bakes_both_and_a_tileset_edit_re_bakes_the_map() {
    let dir = tempfile::tempdir().unwrap();
    let levels = dir.path().join("levels");
    std::fs::create_dir(&levels).unwrap();
    write_room(&levels, "painted", false);
    for f in ["room.tmx", "room.tsx"] {
        std::fs::copy(Path::new("tests/fixtures/tiled").join(f), levels.join(f)).unwrap();
    }
    let out = dir.path().join("out");
    let bake = || {
        let o = flatbake(&["bake", s(&levels), "-o", s(&out), "--quality", "draft"]);
        assert_exit(&o, EXIT_OK);
        format!(
            "{}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        )
    };
    let said = |text: &str, what: &str, file: &str| {
        text.lines()
            .any(|l| l.contains(what) && l.contains(&*levels.join(file).to_string_lossy()))
    };
    let first = bake();
    for f in ["painted.png", "room.tmx"] {
        assert!(said(&first, "baked", f), "{f} not baked:\n{first}");
    }
    assert!(out.join("room.lightmap.png").is_file());
    assert!(out.join("painted.lightmap.png").is_file());
    let second = bake();
    for f in ["painted.png", "room.tmx"] {
        assert!(said(&second, "up to date", f), "{f}:\n{second}");
    }
    let tsx = std::fs::read_to_string(levels.join("room.tsx")).unwrap();
    assert!(tsx.contains("value=\"0.6\""), "the wall tile's reflectance");
    std::fs::write(
        levels.join("room.tsx"),
        tsx.replace("value=\"0.6\"", "value=\"0.3\""),
    )
    .unwrap();
    let third = bake();
    assert!(said(&third, "up to date", "painted.png"), "{third}");
    assert!(said(&third, "baked", "room.tmx"), "{third}");
}

/// Map properties `flatbake_falloff`, `flatbake_bounces` and
/// `flatbake_exposure` are the map's `[bake]` settings: they reach the
/// bake, a command-line flag still wins, and a bad value names the map and
/// the property.
#[test]
fn map_properties_carry_the_bake_settings() {
    use flatbake_core::batch::{self, BatchOptions};
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy("tests/fixtures/tiled/room.tsx", dir.path().join("room.tsx")).unwrap();
    let tmx = std::fs::read_to_string("tests/fixtures/tiled/room.tmx").unwrap();
    let with = |props: &str| {
        let (head, rest) = tmx.split_once('\n').unwrap();
        let (map, rest) = rest.split_once('\n').unwrap();
        let text = format!("{head}\n{map}\n <properties>\n{props} </properties>\n{rest}");
        let path = dir.path().join("room.tmx");
        std::fs::write(&path, text).unwrap();
        path
    };
    let path = with(
        "  <property name=\"flatbake_falloff\" type=\"float\" value=\"12.5\"/>\n  \
         <property name=\"flatbake_bounces\" type=\"int\" value=\"1\"/>\n  \
         <property name=\"flatbake_exposure\" type=\"float\" value=\"0.25\"/>\n",
    );
    let s = flatbake_core::level::map_settings(&path).unwrap();
    assert_eq!(
        (s.falloff, s.bounces, s.exposure),
        (Some(12.5), Some(1), Some(0.25))
    );
    let mut opts = BatchOptions {
        out_dir: dir.path().join("out"),
        quality: flatbake_core::quality::Quality::Draft,
        ..BatchOptions::default()
    };
    let report = batch::bake_one(&path, &opts, &batch::Silent).unwrap();
    assert_eq!(
        (report.falloff, report.bounces, report.exposure),
        (Some(12.5), Some(1), 0.25)
    );
    opts.falloff = Some(Some(30.0));
    opts.force = true;
    let report = batch::bake_one(&path, &opts, &batch::Silent).unwrap();
    assert_eq!(report.falloff, Some(30.0), "the flag beats the map");

    let path = with("  <property name=\"flatbake_falloff\" type=\"float\" value=\"-3\"/>\n");
    let e = batch::bake_one(&path, &opts, &batch::Silent)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("room.tmx") && e.contains("map property flatbake_falloff") && e.contains("-3"),
        "{e}"
    );
    let path = with("  <property name=\"flatbake_bounces\" type=\"string\" value=\"lots\"/>\n");
    let e = flatbake_core::level::map_settings(&path)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("flatbake_bounces") && e.contains("not a number"),
        "{e}"
    );
}

#[test]
fn a_map_without_lights_is_told_how_to_add_one_in_tiled() {
    let dir = tempfile::tempdir().unwrap();
    let src = Path::new("tests/fixtures/tiled");
    std::fs::copy(src.join("room.tsx"), dir.path().join("room.tsx")).unwrap();
    let tmx = std::fs::read_to_string(src.join("room.tmx")).unwrap();
    let (head, rest) = tmx
        .split_once(" <objectgroup")
        .expect("the fixture has lights");
    let tail = rest.split_once("</objectgroup>\n").expect("closed").1;
    let map = dir.path().join("room.tmx");
    std::fs::write(&map, format!("{head}{tail}")).unwrap();
    let out = dir.path().join("out");
    let run = flatbake(&["bake", s(&map), "-o", s(&out)]);
    assert_exit(&run, EXIT_OK);
    assert_says(
        &run,
        &[
            "room.tmx",
            "no light",
            "class `light`",
            "`flatbake` = `emitter`",
        ],
    );
    // Not the advice for painted images.
    assert!(!stderr(&run).contains("palette"), "{}", stderr(&run));
}
