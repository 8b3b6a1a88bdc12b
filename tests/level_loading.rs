//! Level loading (docs/transport.md, units and pixels, and the palette): every image flavour a paint program
//! saves loads to the same level, bad files fail with words that name the
//! file and the problem, oversized images are refused before decoding, and
//! anti-aliased wall edges are reported or snapped.
//!
//! The images under `tests/fixtures/input/` are written by [`fixtures`] with
//! a tiny hand-rolled PNG writer (stored deflate, so the bytes never depend
//! on a compressor version). `fixtures_match_their_generator` checks them;
//! `FLATBAKE_REGENERATE_FIXTURES=1 cargo test --release --test level_loading`
//! rewrites them.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use flatbake_core::level::material::{MaterialKind, srgb_to_linear};
use flatbake_core::level::palette::Palette;
use flatbake_core::level::{
    Cell, Level, LevelError, LoadLimits, NEAR_MISS_DISTANCE, load_level, read_image,
};

// ---------------------------------------------------------------- PNG writer

fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    out.extend_from_slice(&(data.len() as u32).to_be_bytes());
    let mut body = kind.to_vec();
    body.extend_from_slice(data);
    out.extend_from_slice(&body);
    out.extend_from_slice(&crc32(&body).to_be_bytes());
}

/// zlib stream of stored (uncompressed) deflate blocks.
fn zlib_stored(data: &[u8]) -> Vec<u8> {
    let mut out = vec![0x78, 0x01];
    let blocks: Vec<&[u8]> = if data.is_empty() {
        vec![&[]]
    } else {
        data.chunks(65535).collect()
    };
    for (i, block) in blocks.iter().enumerate() {
        out.push((i + 1 == blocks.len()) as u8);
        let len = block.len() as u16;
        out.extend_from_slice(&len.to_le_bytes());
        out.extend_from_slice(&(!len).to_le_bytes());
        out.extend_from_slice(block);
    }
    let (mut a, mut b) = (1u32, 0u32);
    for &x in data {
        a = (a + x as u32) % 65521;
        b = (b + a) % 65521;
    }
    out.extend_from_slice(&((b << 16) | a).to_be_bytes());
    out
}

fn ihdr(w: u32, h: u32, depth: u8, color_type: u8) -> Vec<u8> {
    let mut d = Vec::new();
    d.extend_from_slice(&w.to_be_bytes());
    d.extend_from_slice(&h.to_be_bytes());
    d.extend_from_slice(&[depth, color_type, 0, 0, 0]);
    d
}

/// A PNG from samples: `rows[y]` holds `w * channels` samples of `depth`
/// bits each (packed for depths below 8, big-endian for 16).
fn png(
    w: u32,
    depth: u8,
    color_type: u8,
    rows: &[Vec<u16>],
    extra: &[(&[u8; 4], Vec<u8>)],
) -> Vec<u8> {
    let mut raw = Vec::new();
    for row in rows {
        raw.push(0); // filter: none
        match depth {
            16 => row
                .iter()
                .for_each(|s| raw.extend_from_slice(&s.to_be_bytes())),
            8 => raw.extend(row.iter().map(|&s| s as u8)),
            d => {
                let per_byte = 8 / d as usize;
                for group in row.chunks(per_byte) {
                    let mut byte = 0u8;
                    for (k, &s) in group.iter().enumerate() {
                        byte |= (s as u8) << (8 - d as usize * (k + 1));
                    }
                    raw.push(byte);
                }
            }
        }
    }
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    chunk(
        &mut out,
        b"IHDR",
        &ihdr(w, rows.len() as u32, depth, color_type),
    );
    for (kind, data) in extra {
        chunk(&mut out, kind, data);
    }
    chunk(&mut out, b"IDAT", &zlib_stored(&raw));
    chunk(&mut out, b"IEND", &[]);
    out
}

// ---------------------------------------------------------------- fixtures

const K: [u8; 3] = [0, 0, 0]; // built-in stone wall
const L: [u8; 3] = [255, 255, 255]; // built-in white light
const F: [u8; 3] = [128, 128, 128]; // floor (not in the built-in palette)

/// The reference room: walls around, a light on the left wall, floor inside.
const ROOM: [[[u8; 3]; 6]; 5] = [
    [K, K, K, K, K, K],
    [K, F, F, F, F, K],
    [L, F, F, F, F, K],
    [K, F, F, F, F, K],
    [K, K, K, K, K, K],
];
/// Pixels of the RGBA and grey+alpha variants that are fully transparent.
const VOID: [(usize, usize); 2] = [(5, 0), (4, 1)];

fn room_rows(f: impl Fn(usize, usize, [u8; 3]) -> Vec<u16>) -> Vec<Vec<u16>> {
    ROOM.iter()
        .enumerate()
        .map(|(y, row)| {
            row.iter()
                .enumerate()
                .flat_map(|(x, &c)| f(x, y, c))
                .collect()
        })
        .collect()
}

fn grey_of(c: [u8; 3]) -> u16 {
    c[0] as u16
}

fn fixtures() -> Vec<(&'static str, Vec<u8>)> {
    let w = ROOM[0].len() as u32;
    let wide = |c: [u8; 3]| c.map(|v| v as u16 * 257).to_vec();
    let alpha = |x, y| {
        if VOID.contains(&(x, y)) {
            0u16
        } else if x == 1 && y == 1 {
            128
        } else {
            255
        }
    };
    let rgb8 = png(
        w,
        8,
        2,
        &room_rows(|_, _, c| c.map(u16::from).to_vec()),
        &[],
    );
    let mut truncated = rgb8.clone();
    truncated.truncate(rgb8.len() * 2 / 3);

    // Paletted: index 3 is transparent through tRNS; 2 bits per pixel.
    let plte = [K, L, F, [1, 2, 3]].concat();
    let index = |x, y, c| {
        if VOID.contains(&(x, y)) {
            3
        } else {
            [K, L, F].iter().position(|&p| p == c).unwrap_or(0) as u16
        }
    };
    let paletted = |depth| {
        png(
            w,
            depth,
            3,
            &room_rows(|x, y, c| vec![index(x, y, c)]),
            &[(b"PLTE", plte.clone()), (b"tRNS", vec![255, 255, 255, 0])],
        )
    };

    // A file that claims 100000 x 100000 pixels and holds none of them.
    let mut huge = b"\x89PNG\r\n\x1a\n".to_vec();
    chunk(&mut huge, b"IHDR", &ihdr(100_000, 100_000, 8, 6));
    chunk(&mut huge, b"IEND", &[]);
    // The same with a first IDAT chunk, as an image cut short after a few
    // rows would be: the decoder could start on it.
    let mut huge_idat = b"\x89PNG\r\n\x1a\n".to_vec();
    chunk(&mut huge_idat, b"IHDR", &ihdr(100_000, 100_000, 8, 6));
    chunk(&mut huge_idat, b"IDAT", &zlib_stored(&[0; 64]));
    // QOI: a 14-byte header, decoded through the generic dimension probe.
    let mut huge_qoi = b"qoif".to_vec();
    huge_qoi.extend_from_slice(&16_000u32.to_be_bytes());
    huge_qoi.extend_from_slice(&16_000u32.to_be_bytes());
    huge_qoi.extend_from_slice(&[4, 0]);
    huge_qoi.extend_from_slice(&[0; 8]);

    // 16-bit RGB: every 8-bit value v stored as v * 257 (exact) in red and
    // as an off-grid value in green, to check the 16 -> 8 bit rounding.
    let ramp = vec![
        (0..256u16)
            .flat_map(|v| [v * 257, (v * 257).saturating_add(100), 0])
            .collect::<Vec<u16>>(),
    ];

    vec![
        ("rgb8_room.png", rgb8.clone()),
        (
            "rgba8_room_with_void.png",
            png(
                w,
                8,
                6,
                &room_rows(|x, y, c| [c.map(u16::from).to_vec(), vec![alpha(x, y)]].concat()),
                &[],
            ),
        ),
        (
            "rgb16_room.png",
            png(w, 16, 2, &room_rows(|_, _, c| wide(c)), &[]),
        ),
        (
            "rgb16_ramp_should_round_to_8_bit.png",
            png(256, 16, 2, &ramp, &[]),
        ),
        (
            "gray8_room.png",
            png(w, 8, 0, &room_rows(|_, _, c| vec![grey_of(c)]), &[]),
        ),
        (
            "gray16_room.png",
            png(w, 16, 0, &room_rows(|_, _, c| vec![grey_of(c) * 257]), &[]),
        ),
        (
            "graya8_room_with_void.png",
            png(
                w,
                8,
                4,
                &room_rows(|x, y, c| vec![grey_of(c), alpha(x, y)]),
                &[],
            ),
        ),
        ("paletted8_room_with_trns_void.png", paletted(8)),
        ("paletted2_room_with_trns_void.png", paletted(2)),
        ("png_content_named.jpg", rgb8),
        ("truncated_room.png", truncated),
        ("empty_should_fail.png", Vec::new()),
        (
            "text_named_should_fail.png",
            b"This is a text file, not a level.\n".to_vec(),
        ),
        ("huge_header_100000x100000_should_fail_fast.png", huge),
        ("huge_header_with_idat_should_fail_fast.png", huge_idat),
        ("huge_header_16000x16000_should_fail_fast.qoi", huge_qoi),
    ]
}

fn fixture_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/input")
}

fn fixture(name: &str) -> PathBuf {
    let path = fixture_dir().join(name);
    assert!(
        path.exists(),
        "{} is missing; run with FLATBAKE_REGENERATE_FIXTURES=1",
        path.display()
    );
    path
}

#[test]
fn fixtures_match_their_generator() {
    let regenerate = std::env::var_os("FLATBAKE_REGENERATE_FIXTURES").is_some();
    if regenerate {
        std::fs::create_dir_all(fixture_dir()).unwrap();
    }
    for (name, bytes) in fixtures() {
        let path = fixture_dir().join(name);
        if regenerate {
            std::fs::write(&path, &bytes).unwrap();
        } else {
            let on_disk =
                std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert!(
                on_disk == bytes,
                "{name} differs from its generator; run with FLATBAKE_REGENERATE_FIXTURES=1"
            );
        }
    }
}

// ---------------------------------------------------------------- helpers

fn load(name: &str) -> Result<Level, LevelError> {
    load_level(&fixture(name), &Palette::builtin(), LoadLimits::default())
}

#[track_caller]
fn load_err(path: &Path, limits: LoadLimits) -> String {
    match load_level(path, &Palette::builtin(), limits) {
        Ok(l) => panic!(
            "{} loaded as a {}x{} level",
            path.display(),
            l.width,
            l.height
        ),
        Err(e) => {
            let s = e.to_string();
            eprintln!("{s}");
            assert!(
                s.starts_with(&path.display().to_string()),
                "message does not name the file: {s}"
            );
            s
        }
    }
}

/// The room as the built-in palette should read it.
#[track_caller]
fn assert_is_room(level: &Level, with_void: bool) {
    assert_eq!((level.width, level.height), (6, 5));
    let stone = level
        .materials
        .iter()
        .position(|m| m.color == K)
        .expect("stone used") as u16;
    let light = level
        .materials
        .iter()
        .position(|m| m.color == L)
        .expect("light used") as u16;
    assert_eq!(level.materials.len(), 2);
    // Palette order: stone comes before the white light in the built-in palette.
    assert!(stone < light);
    assert_eq!(level.materials[light as usize].kind, MaterialKind::Emitter);
    let grey = srgb_to_linear(128) as f32;
    for (y, row) in ROOM.iter().enumerate() {
        for (x, &color) in row.iter().enumerate() {
            let want = if with_void && VOID.contains(&(x, y)) {
                Cell::Void
            } else {
                match color {
                    K => Cell::Solid(stone),
                    L => Cell::Solid(light),
                    _ => Cell::Floor,
                }
            };
            assert_eq!(level.cell(x, y), want, "pixel ({x}, {y})");
            let a = level.albedo[y * 6 + x];
            let want_albedo = if want == Cell::Floor {
                [grey; 3]
            } else {
                [0.0; 3]
            };
            assert_eq!(a, want_albedo, "albedo at ({x}, {y})");
        }
    }
    assert!(level.warnings.is_empty(), "{:?}", level.warnings);
}

// ---------------------------------------------------------------- formats

#[test]
fn rgb8_loads() {
    let level = load("rgb8_room.png").unwrap();
    assert_eq!(level.name, "rgb8_room");
    assert_is_room(&level, false);
}

#[test]
fn rgba8_alpha_zero_is_void_and_partial_alpha_is_opaque() {
    let level = load("rgba8_room_with_void.png").unwrap();
    // (5, 0) is a black wall pixel with alpha 0: void, not wall.
    assert_is_room(&level, true);
    assert_eq!(
        level.cell(1, 1),
        Cell::Floor,
        "alpha 128 counts as opaque floor"
    );
}

#[test]
fn rgb16_loads_with_palette_colours_matching() {
    assert_is_room(&load("rgb16_room.png").unwrap(), false);
}

#[test]
fn rgb16_values_round_to_nearest_8_bit() {
    let img = read_image(
        &fixture("rgb16_ramp_should_round_to_8_bit.png"),
        LoadLimits::default(),
    )
    .unwrap();
    for (v, px) in img.pixels().enumerate() {
        let exact = v as u8;
        let off = ((v as u32 * 257 + 100).min(65535) as f64 / 257.0).round() as u8;
        assert_eq!(px.0, [exact, off, 0, 255], "16-bit value {}", v * 257);
    }
}

#[test]
fn grey_and_grey_alpha_load() {
    assert_is_room(&load("gray8_room.png").unwrap(), false);
    assert_is_room(&load("gray16_room.png").unwrap(), false);
    assert_is_room(&load("graya8_room_with_void.png").unwrap(), true);
}

#[test]
fn paletted_pngs_load_with_trns_void() {
    assert_is_room(&load("paletted8_room_with_trns_void.png").unwrap(), true);
    assert_is_room(&load("paletted2_room_with_trns_void.png").unwrap(), true);
}

#[test]
fn format_comes_from_content_not_extension() {
    let level = load("png_content_named.jpg").unwrap();
    assert_eq!(level.name, "png_content_named");
    assert_is_room(&level, false);
}

// ---------------------------------------------------------------- bad files

#[test]
fn missing_file() {
    let path = fixture_dir().join("no_such_level.png");
    let msg = load_err(&path, LoadLimits::default());
    assert!(msg.contains("file not found"), "{msg}");
}

#[test]
fn folder_instead_of_file() {
    let msg = load_err(&fixture_dir(), LoadLimits::default());
    assert!(msg.contains("is a folder"), "{msg}");
}

#[test]
fn empty_file() {
    let msg = load_err(&fixture("empty_should_fail.png"), LoadLimits::default());
    assert!(msg.contains("empty"), "{msg}");
}

#[test]
fn text_file_named_png() {
    let msg = load_err(
        &fixture("text_named_should_fail.png"),
        LoadLimits::default(),
    );
    assert!(msg.contains("not an image"), "{msg}");
    assert!(msg.contains("PNG"), "{msg}");
    assert!(
        msg.contains("This is a text"),
        "shows what the file starts with: {msg}"
    );
}

#[test]
fn binary_junk_with_unknown_extension() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("level.dat");
    std::fs::write(&path, [0u8, 1, 2, 3, 250, 251, 252, 253, 9, 9]).unwrap();
    let msg = load_err(&path, LoadLimits::default());
    assert!(
        msg.contains("not an image") && msg.contains("00 01 02 03"),
        "{msg}"
    );
}

#[test]
fn truncated_file() {
    let msg = load_err(&fixture("truncated_room.png"), LoadLimits::default());
    assert!(msg.contains("truncated"), "{msg}");
}

#[test]
fn truncated_inside_the_header() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("stub.png");
    std::fs::write(
        &path,
        &std::fs::read(fixture("rgb8_room.png")).unwrap()[..20],
    )
    .unwrap();
    let msg = load_err(&path, LoadLimits::default());
    assert!(msg.contains("truncated"), "{msg}");
}

#[test]
fn corrupt_chunk_crc() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad_crc.png");
    let mut bytes = std::fs::read(fixture("rgb8_room.png")).unwrap();
    bytes[29] ^= 0xff; // inside IHDR's CRC
    std::fs::write(&path, bytes).unwrap();
    let msg = load_err(&path, LoadLimits::default());
    assert!(
        msg.contains("corrupt") || msg.contains("truncated"),
        "{msg}"
    );
}

#[test]
fn huge_declared_size_fails_fast_without_decoding() {
    for (name, size) in [
        (
            "huge_header_100000x100000_should_fail_fast.png",
            "100000 x 100000",
        ),
        (
            "huge_header_with_idat_should_fail_fast.png",
            "100000 x 100000",
        ),
        // QOI's decoder refuses more than 4e8 pixels itself; 2.56e8 is ours to refuse.
        (
            "huge_header_16000x16000_should_fail_fast.qoi",
            "16000 x 16000",
        ),
    ] {
        let path = fixture(name);
        let start = Instant::now();
        let msg = load_err(&path, LoadLimits::default());
        // Decoding 10^10 pixels would take minutes and 40 GB; refusing takes microseconds.
        assert!(
            start.elapsed() < Duration::from_secs(1),
            "took {:?}",
            start.elapsed()
        );
        assert!(msg.contains(size), "{msg}");
        assert!(
            msg.contains(&LoadLimits::default().max_pixels.to_string()),
            "names the limit: {msg}"
        );
        assert!(msg.contains("--max-pixels"), "says how to raise it: {msg}");
    }
}

#[test]
fn max_pixels_limit_is_inclusive() {
    let path = fixture("rgb8_room.png");
    let msg = load_err(&path, LoadLimits { max_pixels: 29 });
    assert!(
        msg.contains("6 x 5 = 30 pixels") && msg.contains("limit of 29"),
        "{msg}"
    );
    assert!(load_level(&path, &Palette::builtin(), LoadLimits { max_pixels: 30 }).is_ok());
}

// ---------------------------------------------------------------- anti-aliasing

fn wall_light_palette(extra: &str) -> Palette {
    let text = format!(
        "builtin = false\n{extra}\n[[wall]]\ncolor = \"#000000\"\nreflectance = 0.5\nname = \"stone\"\n\
         [[emitter]]\ncolor = \"#ffffff\"\nemission = 1\n"
    );
    Palette::parse(&text, Path::new("test.palette.toml")).unwrap()
}

/// 10 x 10 floor of #808080 with: a white light at (0, 0); black wall in
/// columns 0..3 below it; an anti-aliased column x = 3 of #0a0a0a (rows 0..5)
/// and #141414 (rows 5..10); a white light at (8, 9) with two near-white
/// pixels #f5f5f5 beside it.
fn antialiased() -> Vec<[u8; 4]> {
    let mut px = vec![[128, 128, 128, 255]; 100];
    for y in 0..10 {
        for x in 0..3 {
            px[y * 10 + x] = [0, 0, 0, 255];
        }
        px[y * 10 + 3] = if y < 5 {
            [10, 10, 10, 255]
        } else {
            [20, 20, 20, 255]
        };
    }
    px[0] = [255, 255, 255, 255];
    px[98] = [255, 255, 255, 255];
    px[88] = [245, 245, 245, 255];
    px[99] = [245, 245, 245, 255];
    px
}

#[test]
fn antialiased_pixels_give_one_warning_per_palette_colour() {
    let level = Level::from_rgba("aa", 10, 10, &antialiased(), &wall_light_palette(""));
    assert_eq!(level.warnings.len(), 2, "{:#?}", level.warnings);
    level.warnings.iter().for_each(|w| eprintln!("{w}"));
    let wall = &level.warnings[0];
    for words in [
        "10 pixels in 2 colours",
        "wall #000000 (stone)",
        "#0a0a0a at (3, 0)",
        "x 3..=3, y 0..=9",
        "up to 20 steps",
        "treated as floor",
        "[bake] tolerance = 20",
    ] {
        assert!(wall.contains(words), "{wall:?} lacks {words:?}");
    }
    let light = &level.warnings[1];
    for words in [
        "2 pixels in 1 colour",
        "emitter #ffffff",
        "#f5f5f5 at (8, 8)",
        "x 8..=9, y 8..=9",
        "tolerance = 10",
    ] {
        assert!(light.contains(words), "{light:?} lacks {words:?}");
    }
    // They stay floor, lit with their own colour.
    assert_eq!(level.cell(3, 4), Cell::Floor);
    assert_eq!(level.albedo[43], [srgb_to_linear(10) as f32; 3]);
    assert_eq!(level.cell(8, 8), Cell::Floor);
}

#[test]
fn tolerance_snaps_near_misses_and_silences_them() {
    let level = Level::from_rgba(
        "aa",
        10,
        10,
        &antialiased(),
        &wall_light_palette("[bake]\ntolerance = 20"),
    );
    assert!(level.warnings.is_empty(), "{:?}", level.warnings);
    // The light is the first solid pixel in the image, but materials keep palette order.
    assert_eq!(
        level.materials.iter().map(|m| m.color).collect::<Vec<_>>(),
        vec![[0, 0, 0], [255, 255, 255]]
    );
    assert_eq!(level.cell(0, 0), Cell::Solid(1));
    for y in 0..10 {
        assert_eq!(level.cell(3, y), Cell::Solid(0), "row {y}");
        assert_eq!(level.albedo[y * 10 + 3], [0.0; 3]);
    }
    assert_eq!(level.cell(8, 8), Cell::Solid(1));
    assert_eq!(level.cell(5, 5), Cell::Floor);
}

#[test]
fn partial_tolerance_warns_about_the_rest() {
    let level = Level::from_rgba(
        "aa",
        10,
        10,
        &antialiased(),
        &wall_light_palette("[bake]\ntolerance = 15"),
    );
    assert_eq!(level.warnings.len(), 1, "{:#?}", level.warnings);
    let w = &level.warnings[0];
    assert!(
        w.contains("5 pixels in 1 colour") && w.contains("from 15 to 20"),
        "{w}"
    );
    assert_eq!(level.cell(3, 0), Cell::Solid(0));
    assert_eq!(level.cell(3, 9), Cell::Floor);
}

#[test]
fn builtin_palette_warning_suggests_a_palette_file() {
    let level = Level::from_rgba("cave", 10, 10, &antialiased(), &Palette::builtin());
    assert!(
        level
            .warnings
            .iter()
            .any(|w| w.contains("cave.palette.toml")),
        "{:#?}",
        level.warnings
    );
}

/// A colour painted as an area of its own is floor on purpose, however
/// close to a wall colour; so is a stray near-miss pixel away from that
/// colour. Only pixels along the wall's edges are its fringe.
#[test]
fn flat_areas_and_stray_pixels_are_not_anti_aliasing() {
    // 12 x 8: black border; floor #1e1e1e (30 steps from black) inside;
    // a stray #050505 in the middle, far from the walls.
    let (w, h) = (12, 8);
    let mut px = vec![[0x1e, 0x1e, 0x1e, 255]; w * h];
    for y in 0..h {
        for x in 0..w {
            if x == 0 || y == 0 || x == w - 1 || y == h - 1 {
                px[y * w + x] = [0, 0, 0, 255];
            }
        }
    }
    px[4 * w + 6] = [5, 5, 5, 255];
    px[3] = [255, 255, 255, 255];
    let level = Level::from_rgba("flat", w, h, &px, &wall_light_palette(""));
    assert!(level.warnings.is_empty(), "{:#?}", level.warnings);
    assert_eq!(
        level.cells.iter().filter(|&&c| c == Cell::Floor).count(),
        10 * 6
    );
    // A fringe of #0a0a0a and #140a0a along the left wall: reported, and the
    // tolerance it suggests stops short of the floor colour.
    for y in 1..7 {
        px[y * w + 1] = if y % 2 == 0 {
            [10, 10, 10, 255]
        } else {
            [20, 10, 10, 255]
        };
    }
    px[4 * w + 6] = [5, 5, 5, 255];
    let level = Level::from_rgba("flat", w, h, &px, &wall_light_palette(""));
    assert_eq!(level.warnings.len(), 1, "{:#?}", level.warnings);
    let warning = &level.warnings[0];
    for words in [
        "6 pixels in 2 colours",
        "x 1..=1, y 1..=6",
        "tolerance = 20",
    ] {
        assert!(warning.contains(words), "{warning:?} lacks {words:?}");
    }
    // A floor of #161616 (22 steps) is further than the fringe: same advice,
    // naming the palette file.
    for p in px.iter_mut().filter(|p| **p == [0x1e, 0x1e, 0x1e, 255]) {
        *p = [0x16, 0x16, 0x16, 255];
    }
    let level = Level::from_rgba("flat", w, h, &px, &wall_light_palette(""));
    let warning = &level.warnings[0];
    for words in ["tolerance = 20", "test.palette.toml"] {
        assert!(warning.contains(words), "{warning:?} lacks {words:?}");
    }
    // A floor of #121212 (18 steps) is nearer: the advice stops at 17, which
    // snaps the three #0a0a0a pixels and leaves the floor and #140a0a alone.
    px.iter_mut()
        .filter(|p| **p == [0x16, 0x16, 0x16, 255])
        .for_each(|p| *p = [0x12, 0x12, 0x12, 255]);
    let level = Level::from_rgba("flat", w, h, &px, &wall_light_palette(""));
    let warning = &level.warnings[0];
    for words in [
        "tolerance = 17",
        "snap the 3 of them within 17 steps",
        "#121212, painted as an area of its own",
    ] {
        assert!(warning.contains(words), "{warning:?} lacks {words:?}");
    }
}

/// When all the floor there is would snap, the advice leaves some floor.
#[test]
fn near_miss_advice_never_leaves_a_level_without_floor() {
    // A one-pixel corridor of fringe colours between black walls.
    let row = |c: [u8; 4]| [[0, 0, 0, 255], c, [10, 10, 10, 255], c, [0, 0, 0, 255]];
    let mut px = vec![[0, 0, 0, 255]; 5];
    px.extend(row([20, 20, 20, 255]));
    px.extend(vec![[0, 0, 0, 255]; 5]);
    px[2] = [255, 255, 255, 255];
    let level = Level::from_rgba("thin", 5, 3, &px, &wall_light_palette(""));
    assert_eq!(level.warnings.len(), 1, "{:#?}", level.warnings);
    let warning = &level.warnings[0];
    for words in [
        "3 pixels in 2 colours",
        "tolerance = 19",
        "snap the 1 of them within 19 steps",
        "would leave the level no floor",
    ] {
        assert!(warning.contains(words), "{warning:?} lacks {words:?}");
    }
    // Following it leaves floor.
    let level = Level::from_rgba(
        "thin",
        5,
        3,
        &px,
        &wall_light_palette("[bake]\ntolerance = 19"),
    );
    assert_eq!(level.cells.iter().filter(|&&c| c == Cell::Floor).count(), 2);
}

#[test]
fn colours_far_from_solids_are_plain_floor() {
    let edge = NEAR_MISS_DISTANCE;
    let px = [
        [edge, edge, edge, 255],
        [0, 0, 0, 255],
        [edge + 1, 0, 0, 255],
    ];
    let level = Level::from_rgba("far", 3, 1, &px, &wall_light_palette(""));
    assert_eq!(
        level.warnings.len(),
        1,
        "exactly the pixel at distance {edge} is a near miss: {:?}",
        level.warnings
    );
    assert!(level.warnings[0].contains("1 pixel in 1 colour"));
}

#[test]
fn near_a_listed_floor_is_not_a_wall_near_miss() {
    let text = "[[wall]]\ncolor = \"#000000\"\nreflectance = 0.5\n[[floor]]\ncolor = \"#404040\"\nalbedo = 0.3\n";
    let text = &format!("builtin = false\n{text}");
    let p = Palette::parse(text, Path::new("p.toml")).unwrap();
    let level = Level::from_rgba(
        "f",
        2,
        1,
        &[[0x30, 0x30, 0x30, 255], [0x40, 0x40, 0x40, 255]],
        &p,
    );
    assert!(level.warnings.is_empty(), "{:?}", level.warnings);
    assert_eq!(level.albedo[0], [srgb_to_linear(0x30) as f32; 3]);
    assert_eq!(level.albedo[1], [0.3; 3], "explicit floor albedo");
    // With a tolerance the near pixel snaps to the floor entry, albedo included.
    let p = Palette::parse(
        &format!("{text}[bake]\ntolerance = 16\n"),
        Path::new("p.toml"),
    )
    .unwrap();
    let level = Level::from_rgba("f", 1, 1, &[[0x30, 0x30, 0x30, 255]], &p);
    assert_eq!((level.cell(0, 0), level.albedo[0]), (Cell::Floor, [0.3; 3]));
}

#[test]
fn short_pixel_data_is_void_not_a_panic() {
    let level = Level::from_rgba("short", 3, 3, &[[0, 0, 0, 255]; 5], &Palette::builtin());
    assert_eq!(level.cells.len(), 9);
    assert_eq!(level.cell(2, 2), Cell::Void);
    assert_eq!(level.cell(1, 1), Cell::Solid(0));
    assert_eq!(level.warnings.len(), 1);
}

#[test]
fn level_without_walls_is_not_an_error() {
    let level = Level::from_rgba(
        "open",
        2,
        2,
        &[[200, 180, 150, 255]; 4],
        &Palette::builtin(),
    );
    assert!(level.materials.is_empty() && level.warnings.is_empty());
    assert!(level.cells.iter().all(|&c| c == Cell::Floor));
}

#[test]
fn large_antialiased_level_counts_every_near_miss() {
    // 2048 x 2048 with a wall grid whose edges are smeared over many shades:
    // the per-colour cache must keep this quick, and the counts exact.
    let n = 2048;
    let mut px = vec![[150u8, 140, 120, 255]; n * n];
    let mut near = 0u64;
    for y in 0..n {
        for x in 0..n {
            if x % 64 < 8 {
                px[y * n + x] = [0, 0, 0, 255];
            } else if x % 64 == 8 {
                let shade = 1 + ((x / 64 + y) % 30) as u8;
                px[y * n + x] = [shade, shade, shade / 2, 255];
                near += 1;
            } else if (x + y) % 97 == 0 {
                // Floor noise far from any solid colour.
                px[y * n + x] = [100 + (y % 50) as u8, 140, 120, 255];
            }
        }
    }
    let start = Instant::now();
    let level = Level::from_rgba("big", n, n, &px, &wall_light_palette(""));
    let took = start.elapsed();
    assert_eq!(level.warnings.len(), 1, "{:?}", level.warnings);
    assert!(
        level.warnings[0].contains(&format!("{near} pixels in 30 colours")),
        "{}",
        level.warnings[0]
    );
    eprintln!("classified {n}x{n} in {took:?}");
}

mod properties {
    use super::*;
    use flatbake_core::level::palette::ColorClass;
    use proptest::prelude::*;

    /// A few colours near and far from the test palette's wall, light and floor.
    const COLORS: &[[u8; 3]] = &[
        [0, 0, 0],
        [255, 255, 255],
        [0x40, 0x40, 0x40],
        [5, 5, 5],
        [30, 0, 0],
        [41, 41, 41],
        [250, 250, 250],
        [0x44, 0x40, 0x3c],
        [128, 128, 128],
        [20, 25, 30],
    ];

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Each cell matches a direct reading of docs/transport.md (units and pixels, palette): alpha 0 is
        /// void; otherwise the exact colour, or within `tolerance` the
        /// nearest colour, decides; all else is floor with its own colour.
        #[test]
        fn cells_match_a_direct_reading(
            w in 1usize..12,
            h in 1usize..12,
            tolerance in prop::option::of(0u8..50),
            seed in prop::collection::vec((0..COLORS.len(), prop::bool::weighted(0.1)), 144),
        ) {
            let extra = tolerance.map(|t| format!("[bake]\ntolerance = {t}")).unwrap_or_default();
            let text = format!("{extra}\n[[wall]]\ncolor = \"#000000\"\nreflectance = 0.5\n\
                                [[emitter]]\ncolor = \"#ffffff\"\nemission = 1\n\
                                [[floor]]\ncolor = \"#404040\"\nalbedo = 0.3\n");
            let palette = Palette::parse(&text, Path::new("p.toml")).unwrap();
            let px: Vec<[u8; 4]> = seed[..w * h]
                .iter()
                .map(|&(c, clear)| { let c = COLORS[c]; [c[0], c[1], c[2], if clear { 0 } else { 255 }] })
                .collect();
            let level = Level::from_rgba("p", w, h, &px, &palette);
            prop_assert_eq!(level.cells.len(), w * h);
            for (i, p) in px.iter().enumerate() {
                let rgb = [p[0], p[1], p[2]];
                let class = palette.classify(rgb).or_else(|| {
                    tolerance.filter(|&t| t > 0).and_then(|t| palette.nearest(rgb, t)).map(|(c, _)| c)
                });
                let cell = level.cells[i];
                match (p[3], class) {
                    (0, _) => prop_assert_eq!(cell, Cell::Void),
                    (_, Some(ColorClass::Solid(s))) => match cell {
                        Cell::Solid(m) => prop_assert_eq!(level.materials[m as usize].color, palette.solids[s].color),
                        other => prop_assert!(false, "{:?} at {} should be solid", other, i),
                    },
                    (_, Some(ColorClass::Floor(_))) => {
                        prop_assert_eq!(cell, Cell::Floor);
                        prop_assert_eq!(level.albedo[i], [0.3f32; 3]);
                    }
                    (_, None) => {
                        prop_assert_eq!(cell, Cell::Floor);
                        prop_assert_eq!(level.albedo[i], rgb.map(|c| srgb_to_linear(c) as f32));
                    }
                }
            }
            // Materials are the used ones, in palette order, each once.
            let colors: Vec<[u8; 3]> = level.materials.iter().map(|m| m.color).collect();
            let expected: Vec<[u8; 3]> = palette.solids.iter().map(|m| m.color)
                .filter(|c| colors.contains(c)).collect();
            prop_assert_eq!(colors, expected);
        }
    }
}
