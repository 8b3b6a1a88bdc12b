//! Tiled maps as levels: the fixtures in `tests/fixtures/tiled` were written
//! by Tiled 1.8.2 itself (`tiled --export-map tmx room.tmj room.tmx` and
//! `tiled --export-tileset tsx room.tsj room.tsx`, with
//! `QT_QPA_PLATFORM=offscreen`); their tileset image does not exist on
//! purpose, since only tile properties are read.

use std::path::Path;

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
