//! LDtk projects as levels. The fixtures in `tests/fixtures/ldtk` were written
//! by the LDtk editor (its own sample projects, see the README there); tests
//! that need flatbake's level fields add them to a copy, as a designer would
//! in the editor, and count cells against the fixture's own `intGridCsv`.

mod common;

use std::path::{Path, PathBuf};

use common::{EXIT_FAILED, EXIT_OK, assert_exit, assert_says, flatbake, s, stderr};

use flatbake_core::MaterialKind;
use flatbake_core::batch::{self, BatchOptions, LevelOutcome};
use flatbake_core::level::{Cell, Level, LoadLimits, ldtk, load_level, palette::Palette};
use flatbake_core::quality::Quality;
use serde_json::{Value, json};

const FIXTURES: &str = "tests/fixtures/ldtk";
const SEPARATE: &str = "SeparateLevelFiles";
const ALL: &str = "Test_file_for_API_showing_all_features";

fn load(path: &Path) -> Result<Level, String> {
    load_level(path, &Palette::builtin(), LoadLimits::default()).map_err(|e| e.to_string())
}

fn read_json(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).expect("read fixture")).expect("fixture is JSON")
}

/// The level `id` of a project (or a level file's own object).
fn level_of<'a>(project: &'a mut Value, id: &str) -> &'a mut Value {
    project["levels"]
        .as_array_mut()
        .expect("levels")
        .iter_mut()
        .find(|l| l["identifier"] == id)
        .expect("the fixture has the level")
}

/// Adds string level fields to a level object, as the editor writes them.
fn add_fields(level: &mut Value, fields: &[(&str, &str)]) {
    let list = level["fieldInstances"]
        .as_array_mut()
        .expect("fieldInstances");
    for (k, v) in fields {
        list.push(json!({"__identifier": k, "__type": "String", "__value": v, "__tile": null, "defUid": 9000, "realEditorValues": []}));
    }
}

/// A copy of the all-features project in `dir` with `fields` added to
/// level `id`, and `edit` applied to the level.
fn all_features_with(
    dir: &Path,
    id: &str,
    fields: &[(&str, &str)],
    edit: impl FnOnce(&mut Value),
) -> PathBuf {
    let mut p = read_json(&Path::new(FIXTURES).join(format!("{ALL}.ldtk")));
    let level = level_of(&mut p, id);
    add_fields(level, fields);
    edit(level);
    let out = dir.join(format!("{ALL}.ldtk"));
    std::fs::write(&out, serde_json::to_vec_pretty(&p).unwrap()).unwrap();
    out
}

/// The IntGrid CSV of layer `layer` in a level object, with its width.
fn csv(level: &Value, layer: &str) -> (Vec<i64>, usize) {
    let l = level["layerInstances"]
        .as_array()
        .unwrap()
        .iter()
        .find(|l| l["__identifier"] == layer)
        .expect("layer");
    let values = l["intGridCsv"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_i64().unwrap())
        .collect();
    (values, l["__cWid"].as_u64().unwrap() as usize)
}

/// Each pixel's kind and emission, `None` for floor.
fn solids(level: &Level) -> Vec<Option<(MaterialKind, [f64; 3])>> {
    level
        .cells
        .iter()
        .map(|c| match c {
            Cell::Solid(i) => {
                let m = &level.materials[usize::from(*i)];
                Some((m.kind, m.emission))
            }
            _ => None,
        })
        .collect()
}

#[test]
fn every_level_of_a_project_with_separate_level_files_is_listed_and_loads_its_cells() {
    let project = Path::new(FIXTURES).join(format!("{SEPARATE}.ldtk"));
    let levels = batch::collect_levels(std::slice::from_ref(&project));
    let ids = ["World_Level_0", "World_Level_1", "World_Level_2"];
    assert_eq!(
        levels,
        ids.iter().map(|id| project.join(id)).collect::<Vec<_>>()
    );
    for (path, id) in levels.iter().zip(ids) {
        let level = load(path).expect("the level loads");
        assert_eq!(level.name, format!("{SEPARATE}.{id}"));
        assert_eq!((level.width, level.height), (240, 240), "15 cells of 16 px");
        let file = read_json(
            &Path::new(FIXTURES)
                .join(SEPARATE)
                .join(format!("{id}.ldtkl")),
        );
        let (values, cw) = csv(&file, "IntGrid");
        let kinds = solids(&level);
        for (i, v) in values.iter().enumerate() {
            let (cx, cy) = (i % cw, i / cw);
            for py in 0..16 {
                for px in 0..16 {
                    let k = kinds[(cy * 16 + py) * 240 + cx * 16 + px].map(|k| k.0);
                    let want = (*v == 1).then_some(MaterialKind::Wall);
                    assert_eq!(k, want, "{id}: cell ({cx}, {cy}) is value {v}");
                }
            }
        }
        let walls = kinds.iter().filter(|k| k.is_some()).count();
        assert_eq!(
            walls,
            values.iter().filter(|v| **v == 1).count() * 256,
            "{id}"
        );
        assert!(walls > 0);
    }
}

#[test]
fn entities_the_flatbake_field_names_are_emitters_of_their_shape() {
    let dir = tempfile::tempdir().unwrap();
    let path = all_features_with(
        dir.path(),
        "Everything",
        &[
            ("flatbake_layer", "IntGrid_with_rules"),
            (
                "flatbake",
                "RectRegion = emitter\nCircleRegion = emitter emission=2",
            ),
        ],
        |_| {},
    );
    let level = load(&path.join("Everything")).expect("loads");
    assert_eq!(level.name, format!("{ALL}.Everything"));
    assert_eq!((level.width, level.height), (43 * 16, 36 * 16));
    let kinds = solids(&level);
    let at = |x: usize, y: usize| kinds[y * level.width + x];
    let mut rect = 0;
    let mut disc = 0;
    for y in 0..level.height {
        for x in 0..level.width {
            // The fixture's RectRegion: 128 x 80 px from (368, 288), pivot (0, 0).
            let in_rect = (368..496).contains(&x) && (288..368).contains(&y);
            // Its CircleRegion, drawn as an ellipse: 112 x 112 px centred on (584, 440).
            let (dx, dy) = (x as f64 + 0.5 - 584.0, y as f64 + 0.5 - 440.0);
            let in_disc = dx * dx + dy * dy <= 56.0 * 56.0;
            let e = at(x, y)
                .filter(|k| k.0 == MaterialKind::Emitter)
                .map(|k| k.1);
            let want = if in_rect {
                rect += 1;
                Some([4.0; 3])
            } else if in_disc {
                disc += 1;
                Some([2.0; 3])
            } else {
                None
            };
            assert_eq!(e, want, "pixel ({x}, {y})");
        }
    }
    assert_eq!(rect, 128 * 80);
    assert!((disc as f64 - std::f64::consts::PI * 56.0 * 56.0).abs() < 2.0 * 56.0 * 4.0);
    // The walls are the IntGrid_with_rules cells (value 1 "walls").
    let mut p = read_json(&Path::new(FIXTURES).join(format!("{ALL}.ldtk")));
    let (values, _) = csv(level_of(&mut p, "Everything"), "IntGrid_with_rules");
    let walls = kinds
        .iter()
        .filter(|k| k.is_some_and(|k| k.0 == MaterialKind::Wall))
        .count();
    assert_eq!(walls, values.iter().filter(|v| **v == 1).count() * 256);
}

#[test]
fn an_entity_definition_tagged_light_is_an_emitter_and_its_tag_is_in_the_stamp() {
    let dir = tempfile::tempdir().unwrap();
    let path = all_features_with(
        dir.path(),
        "Everything",
        &[("flatbake_layer", "IntGrid_with_rules")],
        |_| {},
    );
    let emitters = |level: &Level| {
        solids(level)
            .iter()
            .filter(|k| k.is_some_and(|k| k.0 == MaterialKind::Emitter))
            .count()
    };
    let level = path.join("Everything");
    assert_eq!(emitters(&load(&level).expect("loads")), 0);
    let before = ldtk::level_inputs(&level).expect("inputs");
    // Tag the RectRegion definition only: the instances' `__tags` copies
    // stay as they were, as after a hand edit of the definition.
    let mut p = read_json(&path);
    let def = p["defs"]["entities"]
        .as_array_mut()
        .unwrap()
        .iter_mut()
        .find(|d| d["identifier"] == "RectRegion")
        .expect("the fixture defines RectRegion");
    def["tags"] = json!(["Light"]);
    std::fs::write(&path, serde_json::to_vec_pretty(&p).unwrap()).unwrap();
    // The fixture's RectRegion: 128 x 80 px.
    assert_eq!(emitters(&load(&level).expect("loads")), 128 * 80);
    assert_ne!(ldtk::level_inputs(&level).expect("inputs"), before);
}

#[test]
fn a_level_without_lights_is_told_how_to_add_one_in_ldtk() {
    let dir = tempfile::tempdir().unwrap();
    let path = all_features_with(
        dir.path(),
        "Everything",
        &[("flatbake_layer", "IntGrid_with_rules")],
        |_| {},
    );
    let out = dir.path().join("out");
    let run = flatbake(&["bake", s(&path.join("Everything")), "-o", s(&out)]);
    assert_exit(&run, EXIT_OK);
    assert_says(
        &run,
        &[
            "Everything",
            "no light",
            "tagged `light`",
            "level field `flatbake`",
        ],
    );
    // Not the advice for painted images.
    assert!(!stderr(&run).contains("palette"), "{}", stderr(&run));
}

#[test]
fn relight_checks_a_cache_against_its_own_level_of_the_project() {
    let dir = tempfile::tempdir().unwrap();
    let project = glowing_project(dir.path());
    let (one, other) = (project.join("World_Level_0"), project.join("World_Level_1"));
    let out = dir.path().join("out");
    let baked = flatbake(&["bake", s(&one), "--cache", "-o", s(&out)]);
    assert_exit(&baked, EXIT_OK);
    let cache = out.join(format!("{SEPARATE}.World_Level_0.flatbake"));
    let relit = dir.path().join("relit");
    let relight =
        |level: &Path| flatbake(&["relight", s(&cache), "--level", s(level), "-o", s(&relit)]);
    let same = relight(&one);
    assert_exit(&same, EXIT_OK);
    assert!(
        relit
            .join(format!("{SEPARATE}.World_Level_0.lightmap.png"))
            .is_file()
    );
    let wrong = relight(&other);
    assert_exit(&wrong, EXIT_FAILED);
    assert_says(&wrong, &["another level", "World_Level_1"]);
}

#[test]
fn a_light_entity_with_a_radius_is_a_disc_around_its_position() {
    let dir = tempfile::tempdir().unwrap();
    let path = all_features_with(
        dir.path(),
        "Everything",
        &[("flatbake_layer", "IntGrid_with_rules")],
        |level| {
            // The editor's CircleRegion instance renamed Light, with a
            // colour and a radius of 1.5 cells.
            for layer in level["layerInstances"].as_array_mut().unwrap() {
                for e in layer["entityInstances"].as_array_mut().unwrap() {
                    if e["__identifier"] == "CircleRegion" {
                        e["__identifier"] = json!("Light");
                        let f = e["fieldInstances"].as_array_mut().unwrap();
                        f.push(
                            json!({"__identifier": "radius", "__type": "Float", "__value": 1.5}),
                        );
                        f.push(json!({"__identifier": "colour", "__type": "Color", "__value": "#FF0000"}));
                    }
                }
            }
        },
    );
    let level = load(&path.join("Everything")).expect("loads");
    let kinds = solids(&level);
    let mut n = 0;
    for y in 0..level.height {
        for x in 0..level.width {
            let (dx, dy) = (x as f64 + 0.5 - 584.0, y as f64 + 0.5 - 440.0);
            let want = (dx * dx + dy * dy <= 24.0 * 24.0).then_some([4.0, 0.0, 0.0]);
            let e = kinds[y * level.width + x]
                .filter(|k| k.0 == MaterialKind::Emitter)
                .map(|k| k.1);
            assert_eq!(e, want, "pixel ({x}, {y})");
            n += usize::from(want.is_some());
        }
    }
    assert!(n > 1700 && n < 1900, "{n} pixels in a disc of radius 24");
}

#[test]
fn the_flatbake_field_maps_identifiers_and_value_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let path = all_features_with(
        dir.path(),
        "Everything",
        &[
            ("flatbake_layer", "IntGrid_without_rules"),
            (
                "flatbake",
                "# walls\nfirst = wall reflectance=0.25 # a comment\nsecond = floor albedo=0.2,0.3,0.4; 3 = emitter emission=2 colour=#ff0000",
            ),
        ],
        |_| {},
    );
    let level = load(&path.join("Everything")).expect("loads");
    let mut p = read_json(&Path::new(FIXTURES).join(format!("{ALL}.ldtk")));
    let (values, _) = csv(level_of(&mut p, "Everything"), "IntGrid_without_rules");
    let count = |v: i64| values.iter().filter(|x| **x == v).count() * 256;
    let mats = |kind| {
        level
            .cells
            .iter()
            .filter(|c| match c {
                Cell::Solid(i) => level.materials[usize::from(*i)].kind == kind,
                _ => false,
            })
            .count()
    };
    assert_eq!(mats(MaterialKind::Wall), count(1));
    assert_eq!(mats(MaterialKind::Emitter), count(3));
    let tinted = level
        .albedo
        .iter()
        .filter(|a| **a == [0.2, 0.3, 0.4])
        .count();
    assert_eq!(tinted, count(2));
    let wall = level
        .materials
        .iter()
        .find(|m| m.kind == MaterialKind::Wall)
        .unwrap();
    assert_eq!(wall.reflectance, [0.25; 3]);
    let lamp = level
        .materials
        .iter()
        .find(|m| m.kind == MaterialKind::Emitter)
        .unwrap();
    assert_eq!(lamp.emission, [2.0, 0.0, 0.0], "emission 2 tinted red");
}

#[test]
fn an_unknown_value_is_an_error_naming_project_level_layer_and_cell() {
    let dir = tempfile::tempdir().unwrap();
    let path = all_features_with(
        dir.path(),
        "Everything",
        &[("flatbake_layer", "IntGrid_without_rules")],
        |_| {},
    );
    let err = load(&path.join("Everything")).unwrap_err();
    let mut p = read_json(&Path::new(FIXTURES).join(format!("{ALL}.ldtk")));
    let (values, cw) = csv(level_of(&mut p, "Everything"), "IntGrid_without_rules");
    let first = values.iter().position(|v| *v != 0).unwrap();
    let cell = format!("cell ({}, {})", first % cw, first / cw);
    let ident = ["first", "second", "third_used_in_autoLayer"][values[first] as usize - 1];
    for word in [
        &format!("{ALL}.ldtk"),
        "\"Everything\"",
        "\"IntGrid_without_rules\"",
        &cell,
        ident,
        "flatbake",
    ] {
        assert!(err.contains(word), "{word:?} missing from: {err}");
    }
}

#[test]
fn several_intgrid_layers_and_no_choice_is_an_error_listing_them() {
    let err = load(&Path::new(FIXTURES).join(format!("{ALL}.ldtk/Everything"))).unwrap_err();
    for word in [
        "IntGrid_8px_grid",
        "IntGrid_without_rules",
        "IntGrid_with_rules",
        "flatbake_layer",
    ] {
        assert!(err.contains(word), "{word:?} missing from: {err}");
    }
    let err = load(&Path::new(FIXTURES).join(format!("{ALL}.ldtk/Nowhere"))).unwrap_err();
    assert!(
        err.contains("Nowhere") && err.contains("Autolayer"),
        "{err}"
    );
}

/// A copy of the separate-files project in `dir` whose levels say that
/// their walls glow (`walls = emitter`), so that each has light.
fn glowing_project(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir.join(SEPARATE)).unwrap();
    let src = Path::new(FIXTURES);
    std::fs::copy(
        src.join(format!("{SEPARATE}.ldtk")),
        dir.join(format!("{SEPARATE}.ldtk")),
    )
    .unwrap();
    for i in 0..3 {
        let rel = format!("{SEPARATE}/World_Level_{i}.ldtkl");
        let mut l = read_json(&src.join(&rel));
        add_fields(&mut l, &[("flatbake", "walls = emitter emission=2")]);
        std::fs::write(dir.join(&rel), serde_json::to_vec_pretty(&l).unwrap()).unwrap();
    }
    dir.join(format!("{SEPARATE}.ldtk"))
}

fn outcome_names(outcomes: &[LevelOutcome]) -> Vec<(String, &'static str)> {
    outcomes
        .iter()
        .map(|o| {
            let what = match o {
                LevelOutcome::Baked { .. } => "baked",
                LevelOutcome::UpToDate { .. } => "up to date",
                LevelOutcome::Failed { .. } => "failed",
            };
            (flatbake_core::output::names::level_name(o.path()), what)
        })
        .collect()
}

#[test]
fn a_batch_bakes_every_level_as_project_level_and_re_bakes_only_an_edited_one() {
    let dir = tempfile::tempdir().unwrap();
    let project = glowing_project(dir.path());
    let opts = BatchOptions {
        out_dir: dir.path().join("out"),
        quality: Quality::Draft,
        ..BatchOptions::default()
    };
    let names: Vec<String> = (0..3)
        .map(|i| format!("{SEPARATE}.World_Level_{i}"))
        .collect();
    let run = || batch::run(&[dir.path().to_path_buf()], &opts, &batch::Silent);
    let first = run();
    for o in &first {
        if let LevelOutcome::Failed { error, .. } = o {
            panic!("{error}");
        }
    }
    assert_eq!(
        outcome_names(&first),
        names
            .iter()
            .map(|n| (n.clone(), "baked"))
            .collect::<Vec<_>>()
    );
    for n in &names {
        assert!(
            dir.path()
                .join("out")
                .join(format!("{n}.lightmap.png"))
                .is_file(),
            "{n}"
        );
        assert!(
            dir.path()
                .join("out")
                .join(format!("{n}.stamp.json"))
                .is_file(),
            "{n}"
        );
    }
    assert!(
        outcome_names(&run())
            .iter()
            .all(|(_, w)| *w == "up to date"),
        "a second run bakes nothing"
    );
    // An edit the levels do not read (a level's background colour in the
    // project file) re-bakes nothing.
    let text = std::fs::read_to_string(&project).unwrap();
    std::fs::write(&project, text.replace("#4A4C7F", "#4A4C80")).unwrap();
    assert!(
        outcome_names(&run())
            .iter()
            .all(|(_, w)| *w == "up to date")
    );
    // A cell painted in level 1's own file re-bakes level 1 only.
    let file = dir.path().join(SEPARATE).join("World_Level_1.ldtkl");
    let mut l = read_json(&file);
    l["layerInstances"][0]["intGridCsv"][0] = json!(1);
    std::fs::write(&file, serde_json::to_vec_pretty(&l).unwrap()).unwrap();
    assert_eq!(
        outcome_names(&run()),
        vec![
            (names[0].clone(), "up to date"),
            (names[1].clone(), "baked"),
            (names[2].clone(), "up to date"),
        ]
    );
    // A level whose file is gone fails with its name; the others go on.
    std::fs::remove_file(&file).unwrap();
    let outcomes = batch::run(
        std::slice::from_ref(&project),
        &BatchOptions {
            force: true,
            ..opts.clone()
        },
        &batch::Silent,
    );
    assert_eq!(
        outcome_names(&outcomes),
        vec![
            (names[0].clone(), "baked"),
            (names[1].clone(), "failed"),
            (names[2].clone(), "baked"),
        ]
    );
    if let LevelOutcome::Failed { error, .. } = &outcomes[1] {
        let msg = error.to_string();
        assert!(msg.contains("World_Level_1.ldtkl"), "{msg}");
    }
}

#[test]
fn a_level_image_of_the_same_name_is_a_clash_not_an_overwrite() {
    let dir = tempfile::tempdir().unwrap();
    glowing_project(dir.path());
    let img = image::RgbaImage::from_pixel(8, 8, image::Rgba([0xb0, 0xa0, 0x90, 255]));
    img.save(dir.path().join(format!("{SEPARATE}.World_Level_2.png")))
        .unwrap();
    let opts = BatchOptions {
        out_dir: dir.path().join("out"),
        quality: Quality::Draft,
        ..BatchOptions::default()
    };
    let outcomes = batch::run(&[dir.path().to_path_buf()], &opts, &batch::Silent);
    let clashes: Vec<String> = outcomes
        .iter()
        .filter_map(|o| match o {
            LevelOutcome::Failed { error, .. } => Some(error.to_string()),
            _ => None,
        })
        .collect();
    assert_eq!(clashes.len(), 1, "{clashes:?}");
    assert!(clashes[0].contains("overwrite"), "{}", clashes[0]);
}

#[test]
fn a_broken_project_is_an_error_never_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let src = std::fs::read(Path::new(FIXTURES).join(format!("{ALL}.ldtk"))).unwrap();
    let path = dir.path().join("broken.ldtk");
    let try_all = |bytes: &[u8]| {
        std::fs::write(&path, bytes).unwrap();
        for level in batch::collect_levels(std::slice::from_ref(&path)) {
            let _ = load(&level);
            let _ = ldtk::level_inputs(&level);
        }
    };
    // Cut short at many places.
    for cut in (0..src.len()).step_by(src.len() / 97) {
        try_all(&src[..cut]);
        std::fs::write(&path, &src[..cut]).unwrap();
        let levels = batch::collect_levels(std::slice::from_ref(&path));
        if cut < src.len() / 2 {
            assert_eq!(levels, vec![path.clone()], "an unreadable project is kept");
            let err = load(&path).unwrap_err();
            assert!(
                err.contains("broken.ldtk") && err.contains("not an LDtk project"),
                "{err}"
            );
        }
    }
    // Numbers and shapes that make no level.
    let text = String::from_utf8(src.clone()).unwrap();
    for (from, to) in [
        ("\"__cWid\": 43", "\"__cWid\": -43"),
        ("\"__cWid\": 43", "\"__cWid\": 4300000000"),
        ("\"__cHei\": 36", "\"__cHei\": 0"),
        ("\"__gridSize\": 16", "\"__gridSize\": 0"),
        ("\"intGridCsv\": [", "\"intGridCsv\": [7,"),
        ("\"px\": [368,288]", "\"px\": [1e300,-1e300]"),
        ("\"width\": 128", "\"width\": -128"),
        ("\"layerInstances\": [", "\"layerInstances\": [{},"),
    ] {
        assert!(text.contains(from), "the fixture has {from}");
        let mut p: Value = serde_json::from_str(&text.replace(from, to)).unwrap_or(Value::Null);
        if let Some(level) = p["levels"].as_array_mut().and_then(|l| l.first_mut()) {
            add_fields(
                level,
                &[
                    ("flatbake_layer", "IntGrid_with_rules"),
                    ("flatbake", "RectRegion = emitter"),
                ],
            );
        }
        try_all(serde_json::to_string(&p).unwrap().as_bytes());
        try_all(text.replace(from, to).as_bytes());
    }
    // Wrong types for flatbake's fields.
    for (k, v) in [
        ("flatbake_tile_pixels", json!(0)),
        ("flatbake_tile_pixels", json!("eight")),
        ("flatbake_layer", json!(3)),
        ("flatbake", json!("walls = glass")),
        ("flatbake", json!("walls = wall reflectance=2")),
        ("flatbake", json!("walls")),
        ("flatbake", json!("RectRegion = emitter emission=nan")),
    ] {
        let mut p: Value = serde_json::from_str(&text).unwrap();
        let level = level_of(&mut p, "Everything");
        level["fieldInstances"]
            .as_array_mut()
            .unwrap()
            .push(json!({"__identifier": k, "__value": v}));
        if k != "flatbake_layer" {
            add_fields(level, &[("flatbake_layer", "IntGrid_with_rules")]);
        }
        std::fs::write(&path, serde_json::to_vec(&p).unwrap()).unwrap();
        let err = load(&path.join("Everything")).unwrap_err();
        assert!(
            err.contains(k) && err.contains("Everything"),
            "{k} = {v}: {err}"
        );
    }
}

/// Level fields `flatbake_falloff`, `flatbake_bounces` and
/// `flatbake_exposure` are that level's `[bake]` settings; a bad one names
/// the project, the level and the field.
#[test]
fn level_fields_carry_the_bake_settings() {
    let number = |level: &mut Value, k: &str, v: f64| {
        level["fieldInstances"].as_array_mut().unwrap().push(
            json!({"__identifier": k, "__type": "Float", "__value": v, "__tile": null, "defUid": 9001, "realEditorValues": []}),
        );
    };
    let dir = tempfile::tempdir().unwrap();
    let project = glowing_project(dir.path());
    let rel = format!("{SEPARATE}/World_Level_1.ldtkl");
    let mut l = read_json(&dir.path().join(&rel));
    number(&mut l, "flatbake_falloff", 9.0);
    number(&mut l, "flatbake_bounces", 2.0);
    number(&mut l, "flatbake_exposure", 0.5);
    std::fs::write(
        dir.path().join(&rel),
        serde_json::to_vec_pretty(&l).unwrap(),
    )
    .unwrap();
    let levels = flatbake_core::level::ldtk::project_levels(&project).unwrap();
    let one = levels
        .iter()
        .find(|p| p.to_string_lossy().ends_with("World_Level_1"))
        .unwrap();
    let opts = BatchOptions {
        out_dir: dir.path().join("out"),
        quality: Quality::Draft,
        ..BatchOptions::default()
    };
    let report = batch::bake_one(one, &opts, &batch::Silent).unwrap();
    assert_eq!(
        (report.falloff, report.bounces, report.exposure),
        (Some(9.0), Some(2), 0.5)
    );
    // The other levels keep the defaults.
    let zero = levels
        .iter()
        .find(|p| p.to_string_lossy().ends_with("World_Level_0"))
        .unwrap();
    let report = batch::bake_one(zero, &opts, &batch::Silent).unwrap();
    assert_eq!((report.falloff, report.bounces), (None, None));

    for f in l["fieldInstances"].as_array_mut().unwrap() {
        if f["__identifier"] == "flatbake_bounces" {
            f["__value"] = json!(2.5);
        }
    }
    std::fs::write(
        dir.path().join(&rel),
        serde_json::to_vec_pretty(&l).unwrap(),
    )
    .unwrap();
    let e = batch::bake_one(one, &opts, &batch::Silent)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(&*project.to_string_lossy())
            && e.contains("World_Level_1")
            && e.contains("field flatbake_bounces"),
        "{e}"
    );
}

#[test]
fn projects_of_ldtk_0_7_and_0_8_load_as_ldtk_upgrades_them() {
    let dir = Path::new(FIXTURES).join("legacy");
    let old = dir.join("AutoLayers_1_basic.0.7.1.ldtk");
    // The 0.7.1 file lists its set cells: every one is value index 0, "walls".
    let p = read_json(&old);
    let layer = p["levels"][0]["layerInstances"]
        .as_array()
        .unwrap()
        .iter()
        .find(|l| l["__type"] == "IntGrid")
        .expect("an IntGrid layer");
    let cells = layer["intGrid"]
        .as_array()
        .expect("the pre-0.8 intGrid list");
    let grid = layer["__gridSize"].as_u64().unwrap() as usize;
    let mut levels = Vec::new();
    for file in [old, dir.join("AutoLayers_1_basic.0.8.0.ldtk")] {
        let ids = ldtk::project_levels(&file).expect("the levels are listed");
        assert_eq!(ids.len(), 1, "{}", file.display());
        let level = load(&ids[0]).expect("an old project loads");
        let walls = solids(&level)
            .iter()
            .filter(|k| k.is_some_and(|k| k.0 == MaterialKind::Wall))
            .count();
        assert_eq!(walls, cells.len() * grid * grid, "{}", file.display());
        levels.push(level.cells);
    }
    // The two versions of the sample hold the same walls.
    assert!(levels[0] == levels[1]);
}

#[test]
fn a_project_too_old_to_read_is_an_error_naming_its_version() {
    let dir = tempfile::tempdir().unwrap();
    // The 0.7.1 sample with its levels in a shape no LDtk version wrote,
    // claiming to be from LDtk 0.3.0.
    let mut p = read_json(&Path::new(FIXTURES).join("legacy/AutoLayers_1_basic.0.7.1.ldtk"));
    p["jsonVersion"] = json!("0.3.0");
    p["levels"] = json!([{"identifier": 7}]);
    let file = dir.path().join("old.ldtk");
    std::fs::write(&file, serde_json::to_vec(&p).unwrap()).unwrap();
    let e = ldtk::project_levels(&file).unwrap_err().to_string();
    for words in ["old.ldtk", "LDtk 0.3.0", "0.4 and later", "save it again"] {
        assert!(e.contains(words), "{words:?} missing from: {e}");
    }
}
