//! Palette parsing, lookup order and the built-in palette
//! (docs/transport.md#palette-and-materials). Every malformed palette must fail with the right line
//! and words, because designers fix palettes by reading those messages.

use std::collections::HashSet;
use std::path::Path;

use flatbake_core::level::material::MaterialKind;
use flatbake_core::level::palette::{ColorClass, Palette, PaletteError, PaletteOrigin, parse_hex};

fn parse(text: &str) -> Result<Palette, PaletteError> {
    Palette::parse(text, Path::new("levels/x.palette.toml"))
}

/// Parses `text`, expects an error on `line` whose message contains every
/// one of `words`.
#[track_caller]
fn fails(text: &str, line: usize, words: &[&str]) -> PaletteError {
    let err = match parse(text) {
        Ok(p) => panic!("expected an error, parsed {p:?}"),
        Err(e) => e,
    };
    let shown = err.to_string();
    assert_eq!(err.line, Some(line), "wrong line in {shown:?}");
    assert!(
        shown.starts_with(&format!("levels/x.palette.toml:{line}: ")),
        "{shown:?}"
    );
    for w in words {
        assert!(shown.contains(w), "{shown:?} does not contain {w:?}");
    }
    err
}

const GOOD: &str = r##"
# a full palette
[bake]
falloff = 40.0
bounces = 3
tolerance = 12
exposure = 1.5

[[wall]]
color = "#5a5a5a"
reflectance = 0.6
name = "stone"

[[emitter]]
color = "#FFFADC"
emission = [2.0, 2, 2.5]
reflectance = 0.5
group = "hall"

[[emitter]]
color = [255, 0, 0]
emission = 1

[[floor]]
color = "#b4aa96"
albedo = [0.5, 0.5, 0.5]
name = "sand"
"##;

#[test]
fn full_palette_parses_with_lines_and_settings() {
    let p = parse(GOOD).unwrap();
    assert_eq!(
        p.origin,
        PaletteOrigin::File("levels/x.palette.toml".into())
    );
    assert_eq!(p.settings.falloff, Some(40.0));
    assert_eq!(p.settings.bounces, Some(3));
    assert_eq!(p.settings.tolerance, Some(12));
    assert_eq!(p.settings.exposure, Some(1.5));
    // The file's three, then the built-in ones but red light, which the
    // file's #ff0000 replaces.
    let builtin = Palette::builtin();
    assert!(p.includes_builtin);
    assert_eq!(p.solids.len(), 3 + builtin.solids.len() - 1);
    let added: Vec<_> = builtin
        .solids
        .iter()
        .filter(|m| m.color != [255, 0, 0])
        .collect();
    assert_eq!(p.solids[3..].iter().collect::<Vec<_>>(), added);
    assert_eq!(p.solid_name(3), builtin.solid_name(0));
    let wall = &p.solids[0];
    assert_eq!(
        (wall.color, wall.kind, wall.reflectance, wall.line),
        ([0x5a; 3], MaterialKind::Wall, [0.6; 3], Some(10))
    );
    assert_eq!(p.solid_name(0), Some("stone"));
    let warm = &p.solids[1];
    assert_eq!(warm.color, [0xff, 0xfa, 0xdc]);
    assert_eq!(warm.kind, MaterialKind::Emitter);
    assert_eq!(warm.emission, [2.0, 2.0, 2.5]);
    assert_eq!(warm.reflectance, [0.5; 3]);
    assert_eq!(warm.group.as_deref(), Some("hall"));
    assert_eq!(warm.line, Some(15));
    let red = &p.solids[2];
    assert_eq!(
        (red.color, red.emission, red.reflectance),
        ([255, 0, 0], [1.0; 3], [0.0; 3])
    );
    assert_eq!(red.group, None);
    assert_eq!(p.solid_name(2), None);
    assert_eq!(p.floors.len(), 1);
    assert_eq!(p.floors[0].color, [0xb4, 0xaa, 0x96]);
    assert_eq!(p.floors[0].albedo, [0.5; 3]);
    assert_eq!(p.floors[0].line, Some(25));
    assert_eq!(p.floors[0].name.as_deref(), Some("sand"));
}

#[test]
fn empty_palette_is_all_floor() {
    let p = parse("# nothing here\nbuiltin = false\n").unwrap();
    assert!(p.solids.is_empty() && p.floors.is_empty() && !p.includes_builtin);
    assert_eq!(p.classify([0, 0, 0]), None);
    // Without `builtin = false` an empty file is the built-in palette.
    let p = parse("# nothing here\n").unwrap();
    let builtin = Palette::builtin();
    assert_eq!(
        (&p.solids, &p.floors, &p.solid_names),
        (&builtin.solids, &builtin.floors, &builtin.solid_names)
    );
    assert_eq!(p.source(ColorClass::Solid(0)), "built-in");
    let p = parse("builtin = true\n").unwrap();
    assert_eq!(p.solids, builtin.solids);
}

/// A file's entries are added to the built-in palette; an entry of any kind
/// replaces the built-in entry of its colour, and `builtin = false` leaves
/// every built-in entry out.
#[test]
fn a_file_extends_the_builtin_palette_colour_by_colour() {
    let text = "[[wall]]\ncolor = \"#5a5a5a\"\nreflectance = 0.6\n\n\
                [[wall]]\ncolor = \"#ffffff\"\nreflectance = 0.9\n\n\
                [[floor]]\ncolor = \"#000\"\nalbedo = 0.1\n";
    let p = parse(text).unwrap();
    let builtin = Palette::builtin();
    let kind = |p: &Palette, rgb: [u8; 3]| match p.classify(rgb) {
        Some(ColorClass::Solid(i)) => Some(p.solids[i].kind),
        _ => None,
    };
    // The file's wall, and the built-in lamps the file does not mention.
    assert_eq!(kind(&p, [0x5a; 3]), Some(MaterialKind::Wall));
    for lamp in [[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 0x80, 0]] {
        assert_eq!(kind(&p, lamp), Some(MaterialKind::Emitter), "{lamp:?}");
    }
    // White is now a wall, black a floor of albedo 0.1: one entry each.
    assert_eq!(kind(&p, [255; 3]), Some(MaterialKind::Wall));
    assert_eq!(p.classify([0; 3]), Some(ColorClass::Floor(0)));
    assert_eq!(p.solids.len(), 2 + builtin.solids.len() - 2);
    assert_eq!(p.source(ColorClass::Solid(1)), "levels/x.palette.toml:6");
    assert_eq!(p.source(ColorClass::Floor(0)), "levels/x.palette.toml:10");
    assert_eq!(p.source(ColorClass::Solid(2)), "built-in");
    // A duplicate within the file is still an error.
    fails(
        "[[wall]]\ncolor = \"#f00\"\nreflectance = 0.5\n[[emitter]]\ncolor = \"#ff0000\"\nemission = 1\n",
        5,
        &["duplicate colour"],
    );
    // builtin = false: only the file.
    let p = parse(&format!("builtin = false\n{text}")).unwrap();
    assert_eq!((p.solids.len(), p.floors.len()), (2, 1));
    assert_eq!(p.classify([255, 0, 0]), None);
    assert_eq!(p.source(ColorClass::Solid(0)), "levels/x.palette.toml:3");
    // Its spelling is checked, and where it stands.
    fails(
        "builtin = 0\n",
        1,
        &["builtin must be true or false", "found 0"],
    );
    fails(
        "[bake]\nbuiltin = false\n",
        2,
        &["`builtin` belongs at the top of the file"],
    );
}

/// `palette --toml`'s text parses back to the same palette: the built-in
/// one, and one with every kind of entry, odd numbers and odd names.
#[test]
fn palettes_round_trip_through_their_toml() {
    let strip = |p: &Palette| {
        let mut p = p.clone();
        p.solids.iter_mut().for_each(|m| m.line = None);
        p.floors.iter_mut().for_each(|f| f.line = None);
        p.solid_names.resize(p.solids.len(), None);
        (p.solids, p.floors, p.solid_names, p.settings)
    };
    let builtin = Palette::builtin();
    let text = builtin.to_toml();
    let back =
        Palette::parse(&text, Path::new("start.toml")).unwrap_or_else(|e| panic!("{e}\n{text}"));
    assert_eq!(strip(&back), strip(&builtin));
    assert!(!back.includes_builtin, "the file spells every entry out");
    assert!(
        text.lines().filter(|l| l.starts_with('#')).count() > 5,
        "commented:\n{text}"
    );

    let odd = parse(
        "[bake]\nfalloff = 1e300\nbounces = 7\ntolerance = 255\nexposure = 0.1\n\
         [[emitter]]\ncolour = \"#123456\"\nemission = [1e15, 0.30000000000000004, 0]\n\
         reflectance = 1e-300\ngroup = \"a \\\"quoted\\\" \\\\ group\"\nname = \"é\\ttab\"\n\
         [[floor]]\ncolor = [1, 2, 3]\nalbedo = [0, 0.5, 1]\nname = \"sand\"\n\
         [[wall]]\ncolor = \"#fff\"\nreflectance = 0.123456789012345678\n",
    )
    .unwrap();
    let text = odd.to_toml();
    let back =
        Palette::parse(&text, Path::new("odd.toml")).unwrap_or_else(|e| panic!("{e}\n{text}"));
    assert_eq!(strip(&back), strip(&odd), "{text}");
    assert_eq!(
        back.solids[0].group.as_deref(),
        Some("a \"quoted\" \\ group")
    );
}

#[test]
fn colour_spellings_accepted() {
    for (spelling, rgb) in [
        ("\"#aabbcc\"", [0xaa, 0xbb, 0xcc]),
        ("\"#AABBCC\"", [0xaa, 0xbb, 0xcc]),
        ("\"#AbC\"", [0xaa, 0xbb, 0xcc]),
        ("\"#000\"", [0, 0, 0]),
        ("[170, 187, 204]", [0xaa, 0xbb, 0xcc]),
        ("[0xaa, 0xbb, 0xcc]", [0xaa, 0xbb, 0xcc]),
        ("'#0f0'", [0, 255, 0]),
    ] {
        for key in ["color", "colour"] {
            let p = parse(&format!(
                "[[wall]]\n{key} = {spelling}\nreflectance = 0.5\n"
            ))
            .unwrap_or_else(|e| panic!("{key} = {spelling}: {e}"));
            assert_eq!(p.solids[0].color, rgb, "{key} = {spelling}");
        }
    }
    // Every kind of entry takes both spellings.
    for (entry, class) in [
        (
            "[[wall]]\ncolour = \"#0a0b0c\"\nreflectance = 0.5\n",
            ColorClass::Solid(0),
        ),
        (
            "[[emitter]]\ncolour = \"#0a0b0c\"\nemission = 1\n",
            ColorClass::Solid(0),
        ),
        (
            "[[floor]]\ncolour = \"#0a0b0c\"\nalbedo = 0.5\n",
            ColorClass::Floor(0),
        ),
    ] {
        let p = parse(entry).unwrap_or_else(|e| panic!("{entry}: {e}"));
        assert_eq!(p.classify([10, 11, 12]), Some(class), "{entry}");
    }
    // Both in one entry: say so, with both lines.
    fails(
        "[[wall]]\ncolour = \"#000\"\ncolor = \"#000\"\nreflectance = 0.5\n",
        3,
        &["both `colour` (line 2) and `color`"],
    );
    // Messages about the value name the spelling used.
    fails(
        "[[wall]]\ncolour = \"red\"\nreflectance = 0.5\n",
        2,
        &["colour \"red\" is not a colour"],
    );
}

#[test]
fn colour_spellings_rejected_with_the_spelling_named() {
    for (spelling, shown) in [
        ("\"#abcd\"", "\"#abcd\""),
        ("\"red\"", "\"red\""),
        ("\"#ggg\"", "\"#ggg\""),
        ("\"\"", "\"\""),
        ("[300, 0, 0]", "[300, 0, 0]"),
        ("[1.5, 0, 0]", "[1.5, 0, 0]"),
        ("[-1, 0, 0]", "[-1, 0, 0]"),
        ("[1, 2]", "[1, 2]"),
        ("[1, 2, 3, 4]", "[1, 2, 3, 4]"),
    ] {
        let text = format!("[[wall]]\nreflectance = 0.5\ncolor = {spelling}\n");
        fails(&text, 3, &["color", shown, "is not a colour"]);
    }
    fails(
        "[[wall]]\ncolor = 7\nreflectance = 0.5\n",
        2,
        &["color must be", "found integer"],
    );
}

#[test]
fn missing_hash_gets_a_hint() {
    fails(
        "[[wall]]\ncolor = \"ff0000\"\nreflectance = 0.5\n",
        2,
        &["did you mean \"#ff0000\""],
    );
}

#[test]
fn toml_syntax_error_names_its_line() {
    fails(
        "[[wall]]\ncolor = \"#000000\"\nreflectance = \n",
        3,
        &["invalid TOML"],
    );
    fails(
        "[[wall]]\ncolor = \"#000000\nreflectance = 0.5\n",
        2,
        &["invalid TOML"],
    );
    // A key given twice in one entry is a TOML error, found by the parser.
    fails(
        "\n[[wall]]\ncolor = \"#000000\"\ncolor = \"#111111\"\n",
        4,
        &["invalid TOML", "duplicate key"],
    );
}

#[test]
fn unknown_keys_are_reported_not_ignored() {
    fails(
        "[[wall]]\ncolr = \"#000000\"\nreflectance = 0.5\n",
        2,
        &["unknown key `colr` in [[wall]] (expected color (or colour), reflectance, name)"],
    );
    fails(
        "[[emitter]]\ncolor = \"#fff\"\nemission = 1\nalbedo = 0.5\n",
        4,
        &["unknown key `albedo` in [[emitter]]", "group"],
    );
    fails(
        "[[floor]]\ncolor = \"#fff\"\nalbedo = 0.5\nreflectance = 0.5\n",
        4,
        &["unknown key `reflectance` in [[floor]]"],
    );
    fails(
        "[[wall]]\ncolor = \"#fff\"\nemission = 1\nreflectance = 0.5\n",
        3,
        &["unknown key `emission` in [[wall]]"],
    );
    fails(
        "[bake]\nfalloff = 3\nfallof = 4\n",
        3,
        &[
            "unknown key `fallof` in [bake]",
            "falloff, bounces, tolerance, exposure",
        ],
    );
    fails(
        "\n\n[[walls]]\ncolor = \"#fff\"\n",
        3,
        &["unknown key `walls`", "[[wall]]"],
    );
    fails("x = 1\n", 1, &["unknown key `x`"]);
}

#[test]
fn tables_must_have_the_right_shape() {
    fails(
        "\n[wall]\ncolor = \"#000\"\nreflectance = 0.5\n",
        2,
        &["[[wall]]", "double brackets"],
    );
    fails("bake = 3\n", 1, &["`bake` must be a table"]);
    fails(
        "emitter = 3\n",
        1,
        &["`emitter` must be an array of tables"],
    );
}

#[test]
fn wrong_types_are_reported() {
    fails(
        "[[wall]]\ncolor = \"#000\"\nreflectance = \"high\"\n",
        3,
        &["reflectance must be a number or [r, g, b]", "found string"],
    );
    fails(
        "[[wall]]\ncolor = \"#000\"\nreflectance = [0.5, \"x\", 0.5]\n",
        3,
        &["reflectance must be", "string"],
    );
    fails(
        "[[wall]]\ncolor = \"#000\"\nreflectance = [0.5, 0.5]\n",
        3,
        &["reflectance [0.5, 0.5]", "three numbers"],
    );
    fails(
        "[[emitter]]\ncolor = \"#fff\"\nemission = true\n",
        3,
        &["emission must be", "found boolean"],
    );
    fails(
        "[[wall]]\ncolor = \"#000\"\nreflectance = 0.5\nname = 3\n",
        4,
        &["name must be a string"],
    );
    fails(
        "[[emitter]]\ncolor = \"#fff\"\nemission = 1\ngroup = 2\n",
        4,
        &["group must be a string"],
    );
    fails(
        "[bake]\nbounces = 2.5\n",
        2,
        &["bounces 2.5 must be a whole number"],
    );
    fails(
        "[bake]\nbounces = -1\n",
        2,
        &["bounces -1 must be a whole number >= 0"],
    );
    // A bounce count that would run for hours is refused, with the way out.
    fails(
        "[bake]\nbounces = 4294967295\n",
        2,
        &[
            "bounces 4294967295 is more than 1000",
            "leave bounces out for the full solve",
        ],
    );
    fails(
        "[bake]\ntolerance = 256\n",
        2,
        &["tolerance 256 is outside 0..=255"],
    );
    fails(
        "[bake]\ntolerance = \"8\"\n",
        2,
        &["tolerance must be a whole number", "string"],
    );
    fails("[bake]\nexposure = 0\n", 2, &["exposure 0 must be", "> 0"]);
    fails("[[wall]]\n\"#000\" = 1\n", 2, &["unknown key `#000`"]);
}

#[test]
fn numbers_out_of_range() {
    let e = fails(
        "[[wall]]\ncolor = \"#000\"\nreflectance = 1.5\n",
        3,
        &["reflectance 1.5 is outside 0..=1"],
    );
    assert_eq!(
        e.to_string(),
        "levels/x.palette.toml:3: reflectance 1.5 is outside 0..=1"
    );
    fails(
        "[[wall]]\ncolor = \"#000\"\nreflectance = [0.5,\n  -0.1, 0.5]\n",
        4,
        &["reflectance -0.1 is outside 0..=1"],
    );
    fails(
        "[[wall]]\ncolor = \"#000\"\nreflectance = nan\n",
        3,
        &["reflectance nan is outside 0..=1"],
    );
    fails(
        "[[floor]]\ncolor = \"#000\"\nalbedo = [0, 0, 2]\n",
        3,
        &["albedo 2 is outside 0..=1"],
    );
    fails(
        "[[emitter]]\ncolor = \"#fff\"\nemission = -1\n",
        3,
        &["emission -1 is negative"],
    );
    fails(
        "[[emitter]]\ncolor = \"#fff\"\nemission = [1, inf, 1]\n",
        3,
        &["emission inf is not a finite number"],
    );
    fails(
        "[[emitter]]\ncolor = \"#fff\"\nemission = nan\n",
        3,
        &["emission nan is not a finite number"],
    );
    fails(
        "[[emitter]]\ncolor = \"#fff\"\nemission = 1\nreflectance = 2\n",
        4,
        &["reflectance 2 is outside 0..=1"],
    );
    fails("[bake]\nfalloff = 0\n", 2, &["falloff 0 must be", "> 0"]);
    fails("[bake]\nfalloff = -5.0\n", 2, &["falloff -5.0 must be"]);
    fails(
        "[bake]\nfalloff = inf\n",
        2,
        &["falloff inf must be a finite number"],
    );
    fails(
        "[bake]\nfalloff = nan\n",
        2,
        &["falloff nan must be a finite number"],
    );
}

#[test]
fn missing_required_keys() {
    fails(
        "\n[[wall]]\nreflectance = 0.5\n",
        2,
        &["[[wall]] entry has no `color` (or `colour`)"],
    );
    fails(
        "[[wall]]\ncolor = \"#123456\"\n",
        2,
        &["[[wall]] \"#123456\" has no `reflectance`"],
    );
    fails(
        "[[emitter]]\ncolor = \"#123456\"\n",
        2,
        &["has no `emission`"],
    );
    fails("[[floor]]\ncolor = \"#123456\"\n", 2, &["has no `albedo`"]);
}

#[test]
fn empty_group_names_are_rejected() {
    fails(
        "[[emitter]]\ncolor = \"#fff\"\nemission = 1\ngroup = \"\"\n",
        4,
        &["group name is empty"],
    );
    fails(
        "[[emitter]]\ncolor = \"#fff\"\nemission = 1\ngroup = \"  \"\n",
        4,
        &["group name is empty"],
    );
}

#[test]
fn duplicate_colours_across_tables_name_both_lines() {
    let text = "[[wall]]\ncolor = \"#abc\"\nreflectance = 0.5\n\n[[emitter]]\ncolor = \"#AABBCC\"\nemission = 1\n";
    fails(
        text,
        6,
        &[
            "duplicate colour",
            "\"#AABBCC\"",
            "\"#abc\"",
            "line 2",
            "line 6",
            "[[wall]]",
        ],
    );
    let text = "[[floor]]\ncolor = [0, 0, 0]\nalbedo = 0.5\n[[wall]]\ncolor = \"#000000\"\nreflectance = 0.5\n";
    fails(text, 5, &["duplicate colour", "line 2", "[[floor]]"]);
    // Reported at the later entry even when tables interleave in the file.
    let text = "[[emitter]]\ncolor = \"#fff\"\nemission = 1\n[[wall]]\ncolor = \"#111\"\nreflectance = 0.5\n\
                [[emitter]]\ncolor = \"#111111\"\nemission = 1\n";
    fails(text, 8, &["duplicate colour", "line 5"]);
}

#[test]
fn first_problem_in_the_file_is_reported() {
    // The floor entry comes first in the file, though "floor" sorts after "emitter".
    let text =
        "[[floor]]\ncolor = \"#123\"\nalbedo = 3\n[[emitter]]\ncolor = \"#fff\"\nemission = -1\n";
    fails(text, 3, &["albedo 3"]);
}

#[test]
fn inline_tables_work_too() {
    let p = parse("wall = [{ color = \"#101010\", reflectance = 0.25 }]\n").unwrap();
    assert_eq!(p.solids[0].color, [16, 16, 16]);
    assert_eq!(p.solids[0].line, Some(1));
    fails(
        "wall = [{ color = \"#101010\", reflectance = 0.25 },\n  { color = \"#101010\", reflectance = 0.5 }]\n",
        2,
        &["duplicate colour"],
    );
}

#[test]
fn crlf_line_endings_count_lines() {
    fails(
        "[[wall]]\r\ncolor = \"#000\"\r\nreflectance = 1.5\r\n",
        3,
        &["reflectance 1.5"],
    );
}

#[test]
fn hex_parser() {
    assert_eq!(parse_hex("#fff"), Some([255, 255, 255]));
    assert_eq!(parse_hex("#12aB9f"), Some([0x12, 0xab, 0x9f]));
    for bad in [
        "fff", "#ff", "#ffff", "#fffffff", "#+12345", "#ééé", "# fff",
    ] {
        assert_eq!(parse_hex(bad), None, "{bad}");
    }
}

#[test]
fn classify_and_nearest() {
    let p = parse(GOOD).unwrap();
    assert_eq!(p.classify([0x5a; 3]), Some(ColorClass::Solid(0)));
    assert_eq!(p.classify([0xb4, 0xaa, 0x96]), Some(ColorClass::Floor(0)));
    assert_eq!(p.classify([1, 2, 3]), None);
    assert_eq!(
        p.nearest([0x60, 0x5a, 0x50], 10),
        Some((ColorClass::Solid(0), 10))
    );
    assert_eq!(p.nearest([0x60, 0x5a, 0x50], 9), None);
    assert_eq!(
        p.nearest([0xb0, 0xb0, 0x90], 40),
        Some((ColorClass::Floor(0), 6))
    );
    assert_eq!(p.describe(ColorClass::Solid(0)), "wall #5a5a5a (stone)");
    assert_eq!(p.describe(ColorClass::Solid(2)), "emitter #ff0000");
}

#[test]
fn unreadable_palette_file_names_it() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.toml");
    let e = Palette::load(&missing).unwrap_err();
    assert!(
        e.to_string().contains("nope.toml") && e.to_string().contains("not found"),
        "{e}"
    );
    let binary = dir.path().join("bin.toml");
    std::fs::write(&binary, [0xff, 0xfe, 0x00, 0x80]).unwrap();
    let e = Palette::load(&binary).unwrap_err();
    assert!(e.to_string().contains("not UTF-8"), "{e}");
}

const WALL_A: &str = "[[wall]]\ncolor = \"#0a0a0a\"\nreflectance = 0.1\n";
const WALL_B: &str = "[[wall]]\ncolor = \"#0b0b0b\"\nreflectance = 0.2\n";
const WALL_C: &str = "[[wall]]\ncolor = \"#0c0c0c\"\nreflectance = 0.3\n";

#[test]
fn lookup_order_explicit_then_named_then_folder_then_builtin() {
    let dir = tempfile::tempdir().unwrap();
    let level = dir.path().join("cave.png");
    let named = dir.path().join("cave.palette.toml");
    let folder = dir.path().join("palette.toml");
    let explicit = dir.path().join("elsewhere.toml");
    std::fs::write(&explicit, WALL_A).unwrap();
    std::fs::write(&named, WALL_B).unwrap();
    std::fs::write(&folder, WALL_C).unwrap();

    let first_wall = |p: &Palette| p.solids[0].color[0];
    let p = Palette::resolve_for_level(&level, Some(&explicit)).unwrap();
    assert_eq!(
        (first_wall(&p), &p.origin),
        (0x0a, &PaletteOrigin::File(explicit.clone()))
    );
    let p = Palette::resolve_for_level(&level, None).unwrap();
    assert_eq!(
        (first_wall(&p), &p.origin),
        (0x0b, &PaletteOrigin::File(named.clone()))
    );
    // Another level in the same folder has no NAME.palette.toml: folder palette.
    let p = Palette::resolve_for_level(&dir.path().join("other.png"), None).unwrap();
    assert_eq!(first_wall(&p), 0x0c);
    std::fs::remove_file(&named).unwrap();
    let p = Palette::resolve_for_level(&level, None).unwrap();
    assert_eq!(
        (first_wall(&p), &p.origin),
        (0x0c, &PaletteOrigin::File(folder.clone()))
    );
    std::fs::remove_file(&folder).unwrap();
    let p = Palette::resolve_for_level(&level, None).unwrap();
    assert_eq!(p, Palette::builtin());
    // An explicit palette that does not exist is an error, never a fallback.
    assert!(Palette::resolve_for_level(&level, Some(&dir.path().join("missing.toml"))).is_err());
}

#[test]
fn broken_named_palette_is_an_error_not_skipped() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("cave.palette.toml"),
        "[[wall]]\ncolor = \"#000\"\nreflectance = 9\n",
    )
    .unwrap();
    std::fs::write(dir.path().join("palette.toml"), WALL_C).unwrap();
    let e = Palette::resolve_for_level(&dir.path().join("cave.png"), None).unwrap_err();
    assert!(
        e.to_string().contains("cave.palette.toml:3: reflectance 9"),
        "{e}"
    );
}

#[test]
fn candidate_paths_for_bare_file_names() {
    let [named, folder] = Palette::candidate_paths(Path::new("map.v2.png"));
    assert_eq!(named, Path::new("./map.v2.palette.toml"));
    assert_eq!(folder, Path::new("./palette.toml"));
}

#[test]
fn builtin_palette_is_valid_and_has_no_duplicates() {
    let p = Palette::builtin();
    assert_eq!(p.origin, PaletteOrigin::BuiltIn);
    let mut seen = HashSet::new();
    for (i, m) in p.solids.iter().enumerate() {
        assert!(seen.insert(m.color), "duplicate {}", m.hex());
        assert!(
            m.reflectance.iter().all(|r| (0.0..=1.0).contains(r)),
            "{}",
            m.hex()
        );
        assert!(
            m.emission.iter().all(|e| e.is_finite() && *e >= 0.0),
            "{}",
            m.hex()
        );
        assert_eq!(m.emits(), m.kind == MaterialKind::Emitter, "{}", m.hex());
        assert!(
            p.solid_name(i).is_some(),
            "builtin entries are documented by name"
        );
    }
    for f in &p.floors {
        assert!(seen.insert(f.color));
    }
    let walls = p
        .solids
        .iter()
        .filter(|m| m.kind == MaterialKind::Wall)
        .count();
    assert!(walls >= 3 && p.solids.len() - walls >= 3);
    // Pure white is a light, never a wall.
    assert_eq!(
        p.classify([255; 3]).map(|c| p.describe(c)),
        Some("emitter #ffffff (white light)".into())
    );
    assert_eq!(p.solids[0].color, [0, 0, 0]);
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    /// Fragments that make palette files both valid and subtly broken.
    const PIECES: &[&str] = &[
        "[[wall]]\n",
        "[[emitter]]\n",
        "[[floor]]\n",
        "[bake]\n",
        "[wall]\n",
        "color = \"#abc\"\n",
        "color = \"#aabbcc\"\n",
        "color = [1, 2, 3]\n",
        "color = \"#zz\"\n",
        "reflectance = 0.5\n",
        "reflectance = [0.1, 2, 0]\n",
        "emission = inf\n",
        "emission = 3\n",
        "albedo = 0.2\n",
        "group = \"\"\n",
        "name = \"é\"\n",
        "falloff = -1\n",
        "tolerance = 9\n",
        "colour = 1\n",
        "= =\n",
        "\"\n",
        "é",
        "\r\n",
        "# comment\n",
        "x = [\n",
        "]\n",
    ];

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        /// Whatever the text, parsing answers without panicking, and an
        /// error points at a line that exists.
        #[test]
        fn parse_never_panics_and_lines_exist(picks in prop::collection::vec(0..PIECES.len(), 0..24)) {
            let text: String = picks.iter().map(|&i| PIECES[i]).collect();
            match parse(&text) {
                Ok(p) => {
                    let mut seen = HashSet::new();
                    prop_assert!(p.solids.iter().map(|m| m.color).chain(p.floors.iter().map(|f| f.color)).all(|c| seen.insert(c)));
                }
                Err(e) => {
                    let lines = text.split('\n').count();
                    prop_assert!(matches!(e.line, Some(l) if l >= 1 && l <= lines), "{e} for {text:?}");
                }
            }
        }

        /// Every 8-bit colour survives the "#rrggbb" spelling and the
        /// three-digit form doubles its digits.
        #[test]
        fn hex_round_trips(r: u8, g: u8, b: u8) {
            prop_assert_eq!(parse_hex(&format!("#{r:02x}{g:02X}{b:02x}")), Some([r, g, b]));
            let (r, g, b) = (r >> 4, g >> 4, b >> 4);
            prop_assert_eq!(parse_hex(&format!("#{r:x}{g:x}{b:x}")), Some([r * 17, g * 17, b * 17]));
        }
    }
}
