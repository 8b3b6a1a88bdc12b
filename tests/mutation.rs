//! Mutation tests: hundreds of damaged level images, palettes and relight
//! caches, each baked or relit through the library's public API, must be
//! refused with a message naming the file or baked into finite, non-negative
//! light. Never a panic in flatbake's own code, never a hang.
//!
//! The mutations are deterministic (a seeded [`Rng`], no clock): a failure
//! names the case, and the same case comes back on every run.
//!
//! - **PNGs**: small valid levels (the fixtures, levels painted with
//!   `flatbake-synth`, and one image of every colour type, bit depth and
//!   interlace written here) are split into chunks, mutated (header fields,
//!   palette and transparency lengths, compressed bytes, chunk lengths and
//!   order, unknown and animation chunks, truncation, spliced image data),
//!   and every chunk's CRC is recomputed, so the decoder gets past its CRC
//!   checks.
//! - **Palettes**: text mutations of real palette files (numbers out of
//!   range, NaN and infinity, wrong types, duplicated keys and colours, deep
//!   nesting, long strings, bytes that are not UTF-8, truncation).
//! - **Caches**: a `NAME.flatbake` written by a real bake, with bytes
//!   flipped, inserted and cut (with and without a recomputed checksum), and
//!   with fields of the decoded cache set to inconsistent values; then relit.
//!
//! A panic that the batch contains as a level's failure is accepted only when
//! it happened inside a dependency (its location is in the cargo registry);
//! such cases are counted and printed. Each case runs on its own thread under
//! a 60 s watchdog (a hang, not a slow machine: a case takes milliseconds),
//! with `LoadLimits` keeping every image small. Each test prints a tally.

mod common;

use std::path::{Path, PathBuf};
use std::sync::{Mutex, Once, mpsc};
use std::time::Duration;

use flatbake_core::batch::relight::{RelightOptions, relight};
use flatbake_core::batch::{self, BatchOptions, LevelOutcome, Silent};
use flatbake_core::output::cache::{Cache, FORMAT, MAGIC, VERSION};
use flatbake_core::output::read_lightmap_exr;
use flatbake_core::{Error, LoadLimits, Quality, Report};
use flatbake_synth::Rng;

use common::*;

/// Every mutated image must stay this small, whatever its header says.
const MAX_PIXELS: u64 = 64 * 64;

/// A case that does not answer within this time hangs.
const WATCHDOG: Duration = Duration::from_secs(60);

// ---------------------------------------------------------------------------
// Running one case

/// How a case ended, when it did not break a rule.
#[derive(Debug)]
enum Outcome {
    /// Refused with a message naming the file.
    Refused,
    /// Baked or relit; every value checked.
    Baked,
    /// The batch caught a panic and reported it as the level's failure,
    /// naming the file; the message is the panic's.
    CaughtPanic(String),
}

/// A panic seen by the hook while a case ran.
#[derive(Clone, Debug)]
struct PanicRecord {
    message: String,
    location: String,
    dependency: bool,
}

static PANICS: Mutex<Vec<PanicRecord>> = Mutex::new(Vec::new());

/// One case at a time in this test binary, so that the panics recorded
/// while it runs are its own.
static ONE_CASE: Mutex<()> = Mutex::new(());

/// True for a source location inside a dependency (the cargo registry or a
/// git checkout), not in flatbake or the standard library.
fn in_dependency(file: &str) -> bool {
    let file = file.replace('\\', "/");
    file.contains("/registry/src/") || file.contains("/git/checkouts/")
}

/// Records every panic with its location. Panics in dependencies are not
/// printed (they are counted and printed once per case); every other panic
/// goes to the default hook as usual.
fn install_panic_hook() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let message = info
                .payload()
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| info.payload().downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "no message".into());
            let file = info.location().map_or("", |l| l.file());
            let mut dependency = in_dependency(file);
            if file.starts_with("/rustc/") {
                // A panic inside the standard library (an allocation, a
                // slice helper): whose code called it decides.
                let trace = std::backtrace::Backtrace::force_capture().to_string();
                dependency = trace
                    .lines()
                    .filter_map(|l| l.trim().strip_prefix("at "))
                    .find(|f| !f.starts_with("/rustc/"))
                    .is_some_and(in_dependency);
            }
            let location = info
                .location()
                .map_or_else(String::new, |l| format!("{}:{}", l.file(), l.line()));
            if !dependency {
                default(info);
            }
            PANICS
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .push(PanicRecord {
                    message,
                    location,
                    dependency,
                });
        }));
    });
}

/// What one test saw.
#[derive(Default)]
struct Tally {
    kind: &'static str,
    cases: usize,
    refused: usize,
    baked: usize,
    dependency_panics: Vec<String>,
    failures: Vec<String>,
    hung: bool,
}

impl Tally {
    fn new(kind: &'static str) -> Tally {
        install_panic_hook();
        Tally {
            kind,
            ..Tally::default()
        }
    }

    /// Runs `case` on its own thread under the watchdog and files the result.
    fn run(&mut self, name: &str, case: impl FnOnce() -> Result<Outcome, String> + Send + 'static) {
        if self.hung {
            return;
        }
        let _one = ONE_CASE.lock().unwrap_or_else(|e| e.into_inner());
        PANICS.lock().unwrap_or_else(|e| e.into_inner()).clear();
        self.cases += 1;
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(case));
            let _ = tx.send(r);
        });
        let result = rx.recv_timeout(WATCHDOG);
        let panics = std::mem::take(&mut *PANICS.lock().unwrap_or_else(|e| e.into_inner()));
        let fail = |why: String| format!("{name}: {why}");
        match result {
            Err(_) => {
                self.hung = true;
                self.failures.push(fail(format!(
                    "no answer within {} s (a hang); the remaining cases were not run",
                    WATCHDOG.as_secs()
                )));
            }
            Ok(Err(_)) => self.failures.push(fail(format!(
                "panicked through the API (not contained): {panics:?}"
            ))),
            Ok(Ok(Err(why))) => self.failures.push(fail(why)),
            Ok(Ok(Ok(outcome))) => {
                let ours: Vec<&PanicRecord> = panics.iter().filter(|p| !p.dependency).collect();
                if !ours.is_empty() {
                    self.failures
                        .push(fail(format!("panic in flatbake's own code: {ours:?}")));
                    return;
                }
                match outcome {
                    Outcome::Refused => self.refused += 1,
                    Outcome::Baked => self.baked += 1,
                    Outcome::CaughtPanic(message) => {
                        match panics.iter().find(|p| p.message == message) {
                            Some(p) => {
                                let line = format!("{name}: {} ({})", p.location, p.message);
                                println!("caught dependency panic: {line}");
                                self.dependency_panics.push(line);
                            }
                            None => self.failures.push(fail(format!(
                                "a contained panic ({message}) that the hook did not see"
                            ))),
                        }
                    }
                }
            }
        }
    }

    /// Prints the one-line tally and fails on any broken rule.
    fn finish(self) {
        println!(
            "mutation tally ({}): {} cases, {} refused, {} baked, {} caught dependency panics, {} failures",
            self.kind,
            self.cases,
            self.refused,
            self.baked,
            self.dependency_panics.len(),
            self.failures.len()
        );
        assert!(
            self.failures.is_empty(),
            "{} of {} {} cases broke a rule:\n{}",
            self.failures.len(),
            self.cases,
            self.kind,
            self.failures.join("\n")
        );
        // The mutations reach both ends: some files still bake, some are refused.
        assert!(
            self.baked > 0 && self.refused > 0,
            "nothing baked or nothing refused"
        );
    }
}

/// Batch options for one mutated level: small, quick, EXR on (to check the
/// values), always baked.
fn batch_options(out: &Path, palette: Option<PathBuf>) -> BatchOptions {
    BatchOptions {
        out_dir: out.to_path_buf(),
        quality: Quality::Draft,
        palette,
        hdr: true,
        limits: LoadLimits {
            max_pixels: MAX_PIXELS,
        },
        force: true,
        ..BatchOptions::default()
    }
}

/// Bakes `level` with the batch and checks the outcome: baked with finite,
/// non-negative light, or failed with a message naming one of `named`.
fn bake_and_check(level: &Path, opts: &BatchOptions, named: &[PathBuf]) -> Result<Outcome, String> {
    let outcomes = batch::run(&[level.to_path_buf()], opts, &Silent);
    match outcomes.as_slice() {
        [LevelOutcome::Baked { report, .. }] => {
            check_report(report)?;
            check_exr(&opts.out_dir, report)?;
            Ok(Outcome::Baked)
        }
        [LevelOutcome::Failed { error, .. }] => {
            let msg = error.to_string();
            if !named.iter().any(|p| msg.contains(&p.display().to_string())) {
                return Err(format!("the error names none of {named:?}: {msg}"));
            }
            match error {
                Error::Panic { message, .. } => Ok(Outcome::CaughtPanic(message.clone())),
                _ => Ok(Outcome::Refused),
            }
        }
        other => Err(format!("unexpected outcomes {other:?}")),
    }
}

/// The report of a bake: the last-resort clamp did not fire and energy balances.
fn check_report(report: &Report) -> Result<(), String> {
    if let Some(w) = report.warnings.iter().find(|w| w.contains("clamped")) {
        return Err(format!("the last-resort clamp fired: {w}"));
    }
    let e = &report.energy;
    let gap = (e.emitted - e.absorbed - e.escaped).abs();
    let tol = Quality::Draft.knobs().tolerance;
    if !(gap <= tol * e.emitted.max(1e-300) || gap < 1e-250) {
        return Err(format!("energy does not balance: {e:?}"));
    }
    Ok(())
}

/// The EXR lightmap listed in `report.outputs` reads back with the report's
/// size and every value finite and >= 0; every output lies inside `out`.
fn check_exr(out: &Path, report: &Report) -> Result<(), String> {
    for f in &report.outputs {
        let p = out.join(f);
        if p.parent() != Some(out) || !p.is_file() {
            return Err(format!(
                "output {f:?} is not a file inside {}",
                out.display()
            ));
        }
    }
    let exr = report
        .outputs
        .iter()
        .find(|f| f.ends_with(".lightmap.exr"))
        .ok_or_else(|| format!("no EXR lightmap in {:?}", report.outputs))?;
    let (w, h, px) = read_lightmap_exr(&out.join(exr)).map_err(|e| e.to_string())?;
    if [w, h] != report.size || px.len() != w * h {
        return Err(format!("EXR is {w}x{h}, the report says {:?}", report.size));
    }
    if let Some(v) = px.iter().flatten().find(|v| !v.is_finite() || **v < 0.0) {
        return Err(format!("light {v} in the lightmap"));
    }
    Ok(())
}

/// A fresh folder for one case.
fn case_dir(root: &Path, name: &str) -> PathBuf {
    let d = root.join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("case folder");
    d
}

// ---------------------------------------------------------------------------
// PNG chunks

const SIGNATURE: &[u8; 8] = b"\x89PNG\r\n\x1a\n";

#[derive(Clone, Debug)]
struct Chunk {
    ty: [u8; 4],
    data: Vec<u8>,
    /// A length field that lies about the data (the CRC still covers the data).
    length: Option<u32>,
}

impl Chunk {
    fn new(ty: &[u8; 4], data: Vec<u8>) -> Chunk {
        Chunk {
            ty: *ty,
            data,
            length: None,
        }
    }
}

/// A PNG as chunks, written with correct CRCs, then cut at `truncate`
/// bytes and followed by `trailing` bytes.
#[derive(Clone, Debug)]
struct Png {
    chunks: Vec<Chunk>,
    truncate: Option<usize>,
    trailing: Vec<u8>,
}

impl Png {
    /// Splits a PNG file into chunks (stopping where the file ends).
    fn parse(bytes: &[u8]) -> Png {
        let mut chunks = Vec::new();
        let mut i = 8;
        while let Some(head) = bytes.get(i..i + 8) {
            let len = u32::from_be_bytes([head[0], head[1], head[2], head[3]]) as usize;
            let ty = [head[4], head[5], head[6], head[7]];
            let end = (i + 8).saturating_add(len).min(bytes.len());
            chunks.push(Chunk::new(&ty, bytes[i + 8..end].to_vec()));
            i = end + 4;
        }
        Png {
            chunks,
            truncate: None,
            trailing: Vec::new(),
        }
    }

    fn to_bytes(&self) -> Vec<u8> {
        let mut out = SIGNATURE.to_vec();
        for c in &self.chunks {
            let len = c.length.unwrap_or(c.data.len() as u32);
            out.extend_from_slice(&len.to_be_bytes());
            out.extend_from_slice(&c.ty);
            out.extend_from_slice(&c.data);
            let mut h = crc32fast::Hasher::new();
            h.update(&c.ty);
            h.update(&c.data);
            out.extend_from_slice(&h.finalize().to_be_bytes());
        }
        if let Some(n) = self.truncate {
            out.truncate(n);
        }
        out.extend_from_slice(&self.trailing);
        out
    }

    fn find(&self, ty: &[u8; 4]) -> Option<usize> {
        self.chunks.iter().position(|c| &c.ty == ty)
    }

    fn positions(&self, ty: &[u8; 4]) -> Vec<usize> {
        (0..self.chunks.len())
            .filter(|&i| &self.chunks[i].ty == ty)
            .collect()
    }
}

/// zlib with stored (uncompressed) deflate blocks: the scanlines' bytes
/// appear as they are, so byte mutations hit filter types and samples.
fn zlib_stored(data: &[u8]) -> Vec<u8> {
    let mut out = vec![0x78, 0x01];
    let blocks: Vec<&[u8]> = if data.is_empty() {
        vec![&[]]
    } else {
        data.chunks(65535).collect()
    };
    for (k, b) in blocks.iter().enumerate() {
        out.push(u8::from(k + 1 == blocks.len()));
        let n = b.len() as u16;
        out.extend_from_slice(&n.to_le_bytes());
        out.extend_from_slice(&(!n).to_le_bytes());
        out.extend_from_slice(b);
    }
    let (mut a, mut b) = (1u32, 0u32);
    for &x in data {
        a = (a + u32::from(x)) % 65521;
        b = (b + a) % 65521;
    }
    out.extend_from_slice(&((b << 16) | a).to_be_bytes());
    out
}

/// Writes `rgba` (`w x h`) as a PNG of colour type `ct` and bit depth `bd`,
/// Adam7-interlaced or not. Grey types store the mean of the channels;
/// palette types list the distinct colours (wrapping indices beyond what
/// the depth can address) with a tRNS chunk for transparent entries. Odd
/// rows use the Sub filter, even rows none.
fn encode_png(w: usize, h: usize, rgba: &[[u8; 4]], ct: u8, bd: u8, interlace: bool) -> Png {
    let mut palette: Vec<[u8; 4]> = Vec::new();
    if ct == 3 {
        for p in rgba {
            if !palette.contains(p) && palette.len() < 256 {
                palette.push(*p);
            }
        }
        palette.truncate(1 << bd);
    }
    let channels = match ct {
        0 | 3 => 1,
        4 => 2,
        2 => 3,
        _ => 4,
    };
    let sample = |p: [u8; 4], c: usize| -> u16 {
        let grey = ((p[0] as u16 + p[1] as u16 + p[2] as u16) / 3) as u8;
        let v8 = match (ct, c) {
            (0, _) | (4, 0) => grey,
            (4, _) => p[3],
            (3, _) => {
                let i = palette.iter().position(|q| *q == p);
                i.unwrap_or(usize::from(p[0]) % palette.len()) as u8
            }
            _ => p[c],
        };
        match (ct, bd) {
            (3, _) => u16::from(v8),
            (_, 16) => u16::from(v8) * 257,
            (_, 8) => u16::from(v8),
            (_, d) => u16::from(v8) >> (8 - d),
        }
    };
    let bits_pp = channels * bd as usize;
    let bpp = bits_pp.div_ceil(8).max(1);
    let passes: &[(usize, usize, usize, usize)] = if interlace {
        &[
            (0, 0, 8, 8),
            (4, 0, 8, 8),
            (0, 4, 4, 8),
            (2, 0, 4, 4),
            (0, 2, 2, 4),
            (1, 0, 2, 2),
            (0, 1, 1, 2),
        ]
    } else {
        &[(0, 0, 1, 1)]
    };
    let mut raw = Vec::new();
    for &(x0, y0, dx, dy) in passes {
        let (pw, ph) = (
            w.saturating_sub(x0).div_ceil(dx),
            h.saturating_sub(y0).div_ceil(dy),
        );
        if pw == 0 || ph == 0 {
            continue;
        }
        for (row, y) in (y0..h).step_by(dy).enumerate() {
            let mut line = vec![0u8; (pw * bits_pp).div_ceil(8)];
            let mut bit = 0;
            for x in (x0..w).step_by(dx) {
                for c in 0..channels {
                    let v = sample(rgba[y * w + x], c);
                    match bd {
                        16 => {
                            line[bit / 8..bit / 8 + 2].copy_from_slice(&v.to_be_bytes());
                        }
                        8 => line[bit / 8] = v as u8,
                        d => line[bit / 8] |= (v as u8) << (8 - d as usize - bit % 8),
                    }
                    bit += bd as usize;
                }
            }
            if row % 2 == 1 {
                raw.push(1);
                for i in 0..line.len() {
                    let left = if i >= bpp { line[i - bpp] } else { 0 };
                    raw.push(line[i].wrapping_sub(left));
                }
            } else {
                raw.push(0);
                raw.extend_from_slice(&line);
            }
        }
    }
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&(w as u32).to_be_bytes());
    ihdr.extend_from_slice(&(h as u32).to_be_bytes());
    ihdr.extend_from_slice(&[bd, ct, 0, 0, u8::from(interlace)]);
    let mut chunks = vec![Chunk::new(b"IHDR", ihdr)];
    if ct == 3 {
        chunks.push(Chunk::new(
            b"PLTE",
            palette.iter().flat_map(|p| [p[0], p[1], p[2]]).collect(),
        ));
        if let Some(last) = palette.iter().rposition(|p| p[3] != 255) {
            chunks.push(Chunk::new(
                b"tRNS",
                palette[..=last].iter().map(|p| p[3]).collect(),
            ));
        }
    }
    chunks.push(Chunk::new(b"IDAT", zlib_stored(&raw)));
    chunks.push(Chunk::new(b"IEND", Vec::new()));
    Png {
        chunks,
        truncate: None,
        trailing: Vec::new(),
    }
}

/// A base image for the PNG mutations, with the palette it bakes with.
struct Base {
    name: String,
    png: Png,
    palette: Option<String>,
    /// Must bake as it is (a good level).
    good: bool,
}

fn png_bases() -> Vec<Base> {
    let mut bases = Vec::new();
    for f in [
        "rgb8_room.png",
        "rgba8_room_with_void.png",
        "rgb16_room.png",
        "rgb16_ramp_should_round_to_8_bit.png",
        "gray8_room.png",
        "gray16_room.png",
        "graya8_room_with_void.png",
        "paletted2_room_with_trns_void.png",
        "paletted8_room_with_trns_void.png",
    ] {
        let bytes = std::fs::read(fixture(f)).expect("fixture");
        bases.push(Base {
            name: f.trim_end_matches(".png").into(),
            png: Png::parse(&bytes),
            palette: None,
            good: true,
        });
    }
    bases.push(Base {
        name: "clamp_draft_falloff".into(),
        png: Png::parse(&std::fs::read(fixture("clamp_draft_falloff.png")).expect("fixture")),
        palette: Some(
            std::fs::read_to_string(fixture("clamp_draft_falloff.palette.toml")).expect("palette"),
        ),
        good: true,
    });
    // Painted levels, written by the image crate (real deflate).
    let painted = [
        flatbake_synth::cornell(24),
        flatbake_synth::random_small(3),
        flatbake_synth::random_small(8),
    ];
    for p in &painted {
        let mut bytes = Vec::new();
        p.to_image()
            .write_to(
                &mut std::io::Cursor::new(&mut bytes),
                image::ImageFormat::Png,
            )
            .expect("encode");
        bases.push(Base {
            name: p.name.clone(),
            png: Png::parse(&bytes),
            palette: Some(p.palette_toml.clone()),
            // A random level may be a closed mirror room: refused, by name.
            good: p.name == "cornell",
        });
    }
    // Every colour type and bit depth, plain and interlaced, from a small
    // painted level (its palette: the colours survive in the 8- and 16-bit
    // colour types; the others bake with what the colours become).
    let src = flatbake_synth::random_small(5);
    let (w, h) = (src.width, src.height);
    for (ct, depths) in [
        (0u8, &[1u8, 2, 4, 8, 16][..]),
        (2, &[8, 16]),
        (3, &[1, 2, 4, 8]),
        (4, &[8, 16]),
        (6, &[8, 16]),
    ] {
        for &bd in depths {
            for interlace in [false, true] {
                bases.push(Base {
                    name: format!("ct{ct}_bd{bd}{}", if interlace { "_adam7" } else { "" }),
                    png: encode_png(w, h, &src.rgba, ct, bd, interlace),
                    palette: Some(src.palette_toml.clone()),
                    good: false,
                });
            }
        }
    }
    bases
}

/// Values that stress a header field.
const U32_EDGES: &[u32] = &[
    0,
    1,
    2,
    3,
    7,
    8,
    9,
    63,
    64,
    65,
    4096,
    65535,
    65536,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_ffff,
];

const ANCILLARY: &[&[u8; 4]] = &[
    b"gAMA", b"cHRM", b"sRGB", b"iCCP", b"tEXt", b"zTXt", b"iTXt", b"pHYs", b"sBIT", b"bKGD",
    b"hIST", b"sPLT", b"tIME", b"eXIf", b"cICP", b"mDCV", b"cLLI", b"acTL", b"fcTL", b"fdAT",
    b"ruSt", b"RUST", b"IHDR", b"PLTE", b"IEND",
];

fn random_bytes(rng: &mut Rng, n: usize) -> Vec<u8> {
    (0..n).map(|_| rng.below(256) as u8).collect()
}

/// An APNG animation control chunk and a frame control chunk with fields
/// near the edges.
fn apng_chunks(rng: &mut Rng, png: &Png) -> Vec<Chunk> {
    let mut actl = Vec::new();
    actl.extend_from_slice(&(*rng.pick(&[0u32, 1, 2, 0xffff_ffff])).to_be_bytes());
    actl.extend_from_slice(&(*rng.pick(&[0u32, 1, 7])).to_be_bytes());
    let mut fctl = Vec::new();
    fctl.extend_from_slice(&0u32.to_be_bytes());
    let ihdr = png.find(b"IHDR").map(|i| png.chunks[i].data.clone());
    let dim = |rng: &mut Rng, k: usize| -> u32 {
        match (&ihdr, rng.below(3)) {
            (Some(d), 0) if d.len() >= 8 => u32::from_be_bytes(d[k..k + 4].try_into().unwrap()),
            _ => *rng.pick(U32_EDGES),
        }
    };
    let (fw, fh) = (dim(rng, 0), dim(rng, 4));
    fctl.extend_from_slice(&fw.to_be_bytes());
    fctl.extend_from_slice(&fh.to_be_bytes());
    for _ in 0..2 {
        fctl.extend_from_slice(&(*rng.pick(&[0u32, 1, 0xffff_fff0])).to_be_bytes());
    }
    fctl.extend_from_slice(&[0, 1, 0, 10]);
    fctl.push(rng.below(4) as u8);
    fctl.push(rng.below(3) as u8);
    vec![Chunk::new(b"acTL", actl), Chunk::new(b"fcTL", fctl)]
}

/// Applies one random mutation to `png`; `other` is another base, for splices.
fn mutate_png(rng: &mut Rng, png: &mut Png, other: &Png) -> String {
    let n = png.chunks.len().max(1);
    match rng.below(20) {
        0 | 1 => {
            // An IHDR field.
            let Some(i) = png.find(b"IHDR") else {
                return "no IHDR".into();
            };
            let d = &mut png.chunks[i].data;
            d.resize(d.len().max(13), 0);
            match rng.below(7) {
                k @ 0..=1 => {
                    let v = if rng.chance(0.7) {
                        *rng.pick(U32_EDGES)
                    } else {
                        rng.next_u64() as u32
                    };
                    d[k as usize * 4..k as usize * 4 + 4].copy_from_slice(&v.to_be_bytes());
                    format!("IHDR {} = {v}", ["width", "height"][k as usize])
                }
                2 => {
                    d[8] = *rng.pick(&[0, 1, 2, 3, 4, 5, 7, 8, 9, 15, 16, 17, 32, 255]);
                    format!("IHDR bit depth = {}", d[8])
                }
                3 => {
                    d[9] = *rng.pick(&[0, 1, 2, 3, 4, 5, 6, 7, 8, 255]);
                    format!("IHDR colour type = {}", d[9])
                }
                k => {
                    let at = 10 + (k as usize - 4);
                    d[at] = *rng.pick(&[0, 1, 2, 255]);
                    format!("IHDR byte {at} = {}", d[at])
                }
            }
        }
        2 => {
            let Some(i) = png.find(b"IHDR") else {
                return "no IHDR".into();
            };
            let len = rng.below(18) as usize;
            png.chunks[i].data.resize(len, 0);
            format!("IHDR length {len}")
        }
        3 | 4 => {
            // PLTE length or entries; a PLTE where none belongs.
            let len = *rng.pick(&[0usize, 1, 2, 3, 4, 5, 6, 9, 766, 767, 768, 769, 771, 1024]);
            match png.find(b"PLTE") {
                Some(i) if rng.chance(0.6) => {
                    let d = &mut png.chunks[i].data;
                    if rng.chance(0.5) {
                        let old = d.len();
                        d.resize(len, 0x7f);
                        format!("PLTE length {old} -> {len}")
                    } else {
                        for _ in 0..4 {
                            if !d.is_empty() {
                                let k = rng.below(d.len() as u64) as usize;
                                d[k] = rng.below(256) as u8;
                            }
                        }
                        "PLTE entries".into()
                    }
                }
                _ => {
                    let at = 1.min(png.chunks.len());
                    let data = random_bytes(rng, len);
                    png.chunks.insert(at, Chunk::new(b"PLTE", data));
                    format!("PLTE of {len} bytes inserted")
                }
            }
        }
        5 | 6 => {
            // tRNS length; a tRNS anywhere.
            let len = *rng.pick(&[0usize, 1, 2, 3, 5, 6, 7, 255, 256, 257, 300]);
            match png.find(b"tRNS") {
                Some(i) if rng.chance(0.5) => {
                    png.chunks[i].data.resize(len, 0);
                    format!("tRNS length {len}")
                }
                _ => {
                    let at = match png.find(b"PLTE") {
                        Some(p) if rng.chance(0.7) => p + 1,
                        _ => 1.min(png.chunks.len()),
                    };
                    let data = random_bytes(rng, len);
                    png.chunks.insert(at, Chunk::new(b"tRNS", data));
                    format!("tRNS of {len} bytes at {at}")
                }
            }
        }
        7 => {
            // The known decoder panic: a PLTE whose length is not a multiple of 3, and a tRNS.
            let (np, nt) = (*rng.pick(&[1, 2, 4, 5, 7]), 1 + rng.below(3) as usize);
            let plte = Chunk::new(b"PLTE", random_bytes(rng, np));
            let trns = Chunk::new(b"tRNS", random_bytes(rng, nt));
            png.chunks.retain(|c| &c.ty != b"PLTE" && &c.ty != b"tRNS");
            let at = 1.min(png.chunks.len());
            png.chunks.insert(at, trns);
            png.chunks.insert(at, plte);
            "PLTE of a partial entry, with tRNS".into()
        }
        8..=10 => {
            // Bytes of the compressed image data.
            let idats = png.positions(b"IDAT");
            let Some(&i) = idats.get(rng.below(idats.len().max(1) as u64) as usize) else {
                return "no IDAT".into();
            };
            let d = &mut png.chunks[i].data;
            if d.is_empty() {
                return "empty IDAT".into();
            }
            let k = 1 + rng.below(6);
            for _ in 0..k {
                let at = if rng.chance(0.3) {
                    rng.below(d.len().min(8) as u64) as usize
                } else {
                    rng.below(d.len() as u64) as usize
                };
                d[at] = match rng.below(3) {
                    0 => d[at] ^ (1 << rng.below(8)),
                    1 => *rng.pick(&[0, 1, 4, 5, 0x7f, 0x80, 0xff]),
                    _ => rng.below(256) as u8,
                };
            }
            format!("{k} IDAT bytes")
        }
        11 => {
            // Cut or split the image data.
            let idats = png.positions(b"IDAT");
            let Some(&i) = idats.first() else {
                return "no IDAT".into();
            };
            let len = png.chunks[i].data.len();
            if rng.chance(0.5) {
                let keep = rng.below(len as u64 + 1) as usize;
                png.chunks[i].data.truncate(keep);
                format!("IDAT cut to {keep} of {len}")
            } else {
                let at = rng.below(len as u64 + 1) as usize;
                let tail = png.chunks[i].data.split_off(at);
                png.chunks.insert(i + 1, Chunk::new(b"IDAT", tail));
                format!("IDAT split at {at}")
            }
        }
        12 => {
            // Splice in another image's data.
            let theirs: Vec<Chunk> = other
                .chunks
                .iter()
                .filter(|c| &c.ty == b"IDAT")
                .cloned()
                .collect();
            let ours = png.positions(b"IDAT");
            match (ours.first(), rng.below(3)) {
                (Some(&i), 0) => {
                    png.chunks.retain(|c| &c.ty != b"IDAT");
                    for (k, c) in theirs.into_iter().enumerate() {
                        png.chunks.insert((i + k).min(png.chunks.len()), c);
                    }
                    "IDAT replaced by another image's".into()
                }
                (Some(&i), 1) => {
                    for (k, c) in theirs.into_iter().enumerate() {
                        png.chunks.insert(i + 1 + k, c);
                    }
                    "another image's IDAT appended".into()
                }
                (Some(&i), _) => {
                    let extra: Vec<u8> = theirs.iter().flat_map(|c| c.data.clone()).collect();
                    let d = &mut png.chunks[i].data;
                    let at = rng.below(d.len() as u64 + 1) as usize;
                    d.splice(at..at, extra);
                    format!("another image's IDAT bytes spliced in at {at}")
                }
                (None, _) => "no IDAT".into(),
            }
        }
        13 => {
            let i = rng.below(n as u64) as usize;
            if i < png.chunks.len() {
                let c = png.chunks.remove(i);
                format!("chunk {} dropped", String::from_utf8_lossy(&c.ty))
            } else {
                "nothing to drop".into()
            }
        }
        14 => {
            let i = rng.below(n as u64) as usize;
            if let Some(c) = png.chunks.get(i).cloned() {
                let at = rng.below(png.chunks.len() as u64 + 1) as usize;
                png.chunks.insert(at, c.clone());
                format!(
                    "chunk {} duplicated at {at}",
                    String::from_utf8_lossy(&c.ty)
                )
            } else {
                "nothing to duplicate".into()
            }
        }
        15 => {
            let (a, b) = (rng.below(n as u64) as usize, rng.below(n as u64) as usize);
            if a < png.chunks.len() && b < png.chunks.len() {
                png.chunks.swap(a, b);
            }
            format!("chunks {a} and {b} swapped")
        }
        16 => {
            // A known, unknown or critical chunk with arbitrary content, or animation chunks.
            let at = rng.below(png.chunks.len() as u64 + 1) as usize;
            if rng.chance(0.3) {
                let chunks = apng_chunks(rng, png);
                let at = at.min(png.find(b"IDAT").unwrap_or(at));
                for (k, c) in chunks.into_iter().enumerate() {
                    png.chunks.insert(at + k, c);
                }
                return format!("acTL + fcTL at {at}");
            }
            let ty = **rng.pick(ANCILLARY);
            let len = *rng.pick(&[0usize, 1, 2, 3, 4, 5, 8, 9, 13, 20, 33, 100, 300]);
            let mut data = random_bytes(rng, len);
            if rng.chance(0.3) && len > 4 {
                // A keyword, a NUL, then "compressed" text.
                data[..4].copy_from_slice(b"Key\0");
            }
            png.chunks.insert(at, Chunk::new(&ty, data));
            format!("{} of {len} bytes at {at}", String::from_utf8_lossy(&ty))
        }
        17 => {
            // A length field that lies.
            let i = rng.below(n as u64) as usize;
            let Some(c) = png.chunks.get_mut(i) else {
                return "no chunk".into();
            };
            let real = c.data.len() as u32;
            let v = *rng.pick(&[
                0,
                real.saturating_sub(1),
                real + 1,
                real + 4,
                real + 12,
                0x7fff_ffff,
                0x8000_0000,
                0xffff_ffff,
            ]);
            c.length = Some(v);
            format!(
                "{} length field {v} (data {real})",
                String::from_utf8_lossy(&c.ty)
            )
        }
        18 => {
            let len = png.to_bytes().len();
            let at = 8 + rng.below(len.saturating_sub(8) as u64 + 1) as usize;
            png.truncate = Some(at);
            format!("file cut at {at} of {len}")
        }
        _ => {
            if rng.chance(0.5) {
                let len = 1 + rng.below(64) as usize;
                png.trailing = random_bytes(rng, len);
                "bytes after IEND".into()
            } else {
                let i = rng.below(n as u64) as usize;
                if let Some(c) = png.chunks.get_mut(i) {
                    c.ty[rng.below(4) as usize] ^= 0x20;
                    format!("chunk type {}", String::from_utf8_lossy(&c.ty))
                } else {
                    "no chunk".into()
                }
            }
        }
    }
}

/// Writes `bytes` as `NAME.png` in a fresh folder (with the palette beside
/// it) and bakes it through the batch.
fn png_case(
    root: &Path,
    name: &str,
    bytes: Vec<u8>,
    palette: Option<String>,
    must_bake: bool,
) -> impl FnOnce() -> Result<Outcome, String> + Send + 'static {
    let dir = case_dir(root, name);
    let level = dir.join("level.png");
    std::fs::write(&level, bytes).expect("write level");
    if let Some(p) = &palette {
        std::fs::write(dir.join("level.palette.toml"), p).expect("write palette");
    }
    move || {
        let opts = batch_options(&dir.join("out"), None);
        let r = bake_and_check(&level, &opts, std::slice::from_ref(&level));
        let _ = std::fs::remove_dir_all(&dir);
        match r {
            Ok(Outcome::Baked) | Err(_) => r,
            Ok(_) if must_bake => Err(format!("a good level did not bake: {r:?}")),
            Ok(_) => r,
        }
    }
}

/// Hundreds of mutated PNGs with valid CRCs, the known decoder panic among
/// them: each refused naming the file, or baked finite.
#[test]
fn mutated_pngs_are_refused_by_name_or_bake_finite() {
    let root = tempfile::tempdir().expect("tempdir");
    let mut tally = Tally::new("pngs");
    let bases = png_bases();
    let known = std::fs::read(fixture("png_plte_trns_panic.png")).expect("fixture");
    tally.run(
        "png_plte_trns_panic.png",
        png_case(root.path(), "known", known, None, false),
    );
    for (b, base) in bases.iter().enumerate() {
        tally.run(
            &format!("{} (as it is)", base.name),
            png_case(
                root.path(),
                &base.name,
                base.png.to_bytes(),
                base.palette.clone(),
                base.good,
            ),
        );
        let mut rng = Rng::new(0x6d75_7461_7465 ^ b as u64);
        for k in 0..12 {
            let mut png = base.png.clone();
            let other = &bases[(b + 1 + k) % bases.len()].png;
            let ops: Vec<String> = (0..1 + rng.below(3))
                .map(|_| mutate_png(&mut rng, &mut png, other))
                .collect();
            let name = format!("{}-{k}", base.name);
            tally.run(
                &format!("{name} [{}]", ops.join("; ")),
                png_case(
                    root.path(),
                    &name,
                    png.to_bytes(),
                    base.palette.clone(),
                    false,
                ),
            );
        }
    }
    tally.finish();
}

// ---------------------------------------------------------------------------
// Palettes

/// Values that break a palette number: out of range, not finite, too large,
/// of the wrong type or shape.
const BAD_NUMBERS: &[&str] = &[
    "-1",
    "-0.0",
    "1.5",
    "2",
    "0",
    "1",
    "1.0000001",
    "0.9999999999",
    "1e15",
    "1e16",
    "1e39",
    "1e300",
    "1e309",
    "-1e309",
    "5e-324",
    "nan",
    "+nan",
    "-nan",
    "inf",
    "+inf",
    "-inf",
    "99999999999999999999",
    "4294967295",
    "-4294967296",
    "0x10",
    "1_000",
    "\"0.5\"",
    "true",
    "[]",
    "{}",
    "[0.5, 0.5]",
    "[0.5, 0.5, 0.5, 0.5]",
    "[[0.5]]",
    "[0.5, nan, 0.5]",
    "[\"a\", 0.5, 0.5]",
    "1979-05-27",
];

const BAD_COLOURS: &[&str] = &[
    "\"#12345\"",
    "\"#GGGGGG\"",
    "\"#1234567\"",
    "\"\"",
    "\"#\"",
    "\"#ABCD\"",
    "\"#ABC\"",
    "\"red\"",
    "[256, 0, 0]",
    "[-1, 0, 0]",
    "[1.5, 0, 0]",
    "[0, 0]",
    "[0, 0, 0, 0]",
    "0x123456",
    "255",
    "\"#ffffff\"",
    "\"#000000\"",
];

/// Byte ranges of the numbers in `text` (after `=`, `[` or `,`).
fn number_spans(text: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < text.len() {
        let starts = (text[i].is_ascii_digit() || text[i] == b'-')
            && i > 0
            && matches!(
                text[..i].iter().rev().find(|b| **b != b' '),
                Some(b'=' | b'[' | b',')
            );
        if starts {
            let j = i + text[i..]
                .iter()
                .position(|b| !(b.is_ascii_alphanumeric() || b"+-._".contains(b)))
                .unwrap_or(text.len() - i);
            spans.push((i, j));
            i = j;
        } else {
            i += 1;
        }
    }
    spans
}

/// Byte ranges of the lines of `text` (without the newline).
fn line_spans(text: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut start = 0;
    for (i, b) in text.iter().enumerate() {
        if *b == b'\n' {
            spans.push((start, i));
            start = i + 1;
        }
    }
    if start < text.len() {
        spans.push((start, text.len()));
    }
    spans
}

/// Applies one random mutation to palette text.
fn mutate_palette(rng: &mut Rng, t: &mut Vec<u8>) -> String {
    let lines = line_spans(t);
    let pick_line = |rng: &mut Rng| {
        lines
            .get(rng.below(lines.len().max(1) as u64) as usize)
            .copied()
    };
    match rng.below(16) {
        0..=3 => {
            let spans = number_spans(t);
            let Some(&(a, b)) = spans.get(rng.below(spans.len().max(1) as u64) as usize) else {
                return "no number".into();
            };
            let v = *rng.pick(BAD_NUMBERS);
            let old = String::from_utf8_lossy(&t[a..b]).into_owned();
            t.splice(a..b, v.bytes());
            format!("number {old} -> {v}")
        }
        4 => {
            // A colour value.
            let text = String::from_utf8_lossy(t).into_owned();
            let Some(at) = text
                .match_indices("color")
                .map(|(i, _)| i)
                .nth(rng.below(4) as usize)
            else {
                return "no colour".into();
            };
            let end = text[at..].find('\n').map_or(text.len(), |e| at + e);
            let v = *rng.pick(BAD_COLOURS);
            t.splice(at..end, format!("color = {v}").into_bytes());
            format!("colour -> {v}")
        }
        5 => {
            // A [bake] setting.
            let key = *rng.pick(&[
                "falloff",
                "bounces",
                "tolerance",
                "exposure",
                "quality",
                "jobs",
            ]);
            let bad = *rng.pick(BAD_NUMBERS);
            let v = *rng.pick(&[bad, "1000", "1001", "255", "256", "0.1", "-5"]);
            t.extend_from_slice(format!("\n[bake]\n{key} = {v}\n").as_bytes());
            format!("[bake] {key} = {v}")
        }
        6 => {
            let Some((a, b)) = pick_line(rng) else {
                return "no line".into();
            };
            let line = t[a..b].to_vec();
            t.splice(b..b, [b"\n".as_slice(), &line].concat());
            format!("line {:?} twice", String::from_utf8_lossy(&line))
        }
        7 => {
            // An entry twice: the same colour listed twice.
            let text = String::from_utf8_lossy(t).into_owned();
            let heads: Vec<usize> = text.match_indices("[[").map(|(i, _)| i).collect();
            let Some(&a) = heads.get(rng.below(heads.len().max(1) as u64) as usize) else {
                return "no entry".into();
            };
            let b = heads
                .iter()
                .find(|&&h| h > a)
                .copied()
                .unwrap_or(text.len());
            let entry = format!("\n{}\n", &text[a..b]);
            t.extend_from_slice(entry.as_bytes());
            "an entry twice".into()
        }
        8 => {
            // Deep nesting.
            let depth = *rng.pick(&[10usize, 64, 200, 1000, 5000]);
            let (open, close) = if rng.chance(0.5) {
                ("[", "]")
            } else {
                ("{a = ", "}")
            };
            let key = *rng.pick(&["reflectance", "emission", "deep"]);
            let v = format!("{}1{}", open.repeat(depth), close.repeat(depth));
            let at = pick_line(rng).map_or(t.len(), |(_, b)| b);
            t.splice(at..at, format!("\n{key} = {v}").into_bytes());
            format!("{key} nested {depth} deep")
        }
        9 => {
            // Long strings: a name, a group, a key, a comment.
            let n = *rng.pick(&[300usize, 10_000, 200_000]);
            let long = "x".repeat(n);
            let line = match rng.below(4) {
                0 => format!("name = \"{long}\""),
                1 => format!("group = \"{long}\""),
                2 => format!("{long} = 1"),
                _ => format!("# {long}"),
            };
            let at = pick_line(rng).map_or(t.len(), |(_, b)| b);
            t.splice(at..at, format!("\n{line}").into_bytes());
            format!("a {n}-byte string")
        }
        10 => {
            // Bytes that are not UTF-8.
            let bad = rng
                .pick(&[
                    &[0xffu8][..],
                    &[0xc3, 0x28],
                    &[0xe2, 0x82],
                    &[0x80],
                    &[0xed, 0xa0, 0x80],
                ])
                .to_vec();
            let at = rng.below(t.len() as u64 + 1) as usize;
            t.splice(at..at, bad);
            format!("non-UTF-8 bytes at {at}")
        }
        11 => {
            let at = rng.below(t.len() as u64 + 1) as usize;
            t.truncate(at);
            format!("cut at {at}")
        }
        12 => {
            // Syntax characters in random places.
            let k = 1 + rng.below(4);
            for _ in 0..k {
                if t.is_empty() {
                    break;
                }
                let at = rng.below(t.len() as u64) as usize;
                t[at] = *rng.pick(b"\"[]={}#\n\t\0,.'\\ ");
            }
            format!("{k} syntax bytes")
        }
        13 => {
            let Some((a, b)) = pick_line(rng) else {
                return "no line".into();
            };
            t.drain(a..(b + 1).min(t.len()));
            "a line removed".into()
        }
        14 => {
            // Table headers.
            let text = String::from_utf8_lossy(t).into_owned();
            let from = *rng.pick(&["[[wall]]", "[[emitter]]", "[[floor]]"]);
            let to = *rng.pick(&[
                "[[walls]]",
                "[wall]",
                "[[emitter]]",
                "[[floor]]",
                "[[wall]]",
                "[[bake]]",
                "[wall.x]",
            ]);
            let Some(at) = text.find(from) else {
                return "no header".into();
            };
            t.splice(at..at + from.len(), to.bytes());
            format!("{from} -> {to}")
        }
        _ => {
            let v = rng
                .pick(&[
                    &b"\xef\xbb\xbf"[..],
                    b"\r\n",
                    b"\r",
                    b"\0",
                    b"\n[wall]\ncolor = \"#000000\"\n",
                    b"\nunknown = 1\n",
                    b"\n[[emitter]]\ncolor = \"#fefefe\"\n",
                    b"\n[[emitter]]\ncolor = \"#fefefd\"\nemission = 1e15\nreflectance = 1\n",
                ])
                .to_vec();
            let at = if rng.chance(0.3) {
                0
            } else {
                rng.below(t.len() as u64 + 1) as usize
            };
            t.splice(at..at, v.iter().copied());
            format!("{:?} inserted at {at}", String::from_utf8_lossy(&v))
        }
    }
}

/// A real palette file and a small level painted with its colours.
struct PaletteBase {
    name: String,
    palette: Vec<u8>,
    png: Vec<u8>,
}

fn png_bytes(p: &flatbake_synth::Painted) -> Vec<u8> {
    let mut bytes = Vec::new();
    p.to_image()
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .expect("encode");
    bytes
}

fn palette_bases() -> Vec<PaletteBase> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let read = |p: &str| std::fs::read(root.join(p)).expect("palette file");
    let mut bases = Vec::new();
    // The sample levels' palettes, each with a small level of the same kind.
    for (file, level) in [
        ("levels/cornell.palette.toml", flatbake_synth::cornell(24)),
        (
            "levels/colour_bleed.palette.toml",
            flatbake_synth::colour_bleed(48),
        ),
        (
            "levels/dungeon.palette.toml",
            flatbake_synth::dungeon(32, 32, 7),
        ),
        (
            "levels/maze.palette.toml",
            flatbake_synth::maze(25, 25, 3, 7),
        ),
        (
            "levels/pillars.palette.toml",
            flatbake_synth::pillars(32, 4, 7),
        ),
        (
            "levels/falloff_hall.palette.toml",
            flatbake_synth::falloff_hall(48, 24),
        ),
        (
            "levels/big_level.palette.toml",
            flatbake_synth::random_small(11),
        ),
    ] {
        bases.push(PaletteBase {
            name: file
                .trim_start_matches("levels/")
                .trim_end_matches(".palette.toml")
                .into(),
            palette: read(file),
            png: png_bytes(&level),
        });
    }
    bases.push(PaletteBase {
        name: "clamp_draft_falloff".into(),
        palette: read("tests/fixtures/input/clamp_draft_falloff.palette.toml"),
        png: read("tests/fixtures/input/clamp_draft_falloff.png"),
    });
    for seed in [2, 4] {
        let p = flatbake_synth::random_small(seed);
        bases.push(PaletteBase {
            name: p.name.clone(),
            palette: p.palette_toml.clone().into_bytes(),
            png: png_bytes(&p),
        });
    }
    bases
}

/// Hundreds of mutated palettes, beside the level or given explicitly:
/// each refused naming the palette (or the level), or baked finite.
#[test]
fn mutated_palettes_are_refused_by_name_or_bake_finite() {
    let root = tempfile::tempdir().expect("tempdir");
    let mut tally = Tally::new("palettes");
    for (b, base) in palette_bases().iter().enumerate() {
        let mut rng = Rng::new(0x7061_6c65_7474 ^ b as u64);
        for k in 0..16 {
            let mut text = base.palette.clone();
            let ops: Vec<String> = if k == 0 {
                vec!["as it is".into()]
            } else {
                (0..1 + rng.below(2))
                    .map(|_| mutate_palette(&mut rng, &mut text))
                    .collect()
            };
            let name = format!("{}-{k}", base.name);
            let dir = case_dir(root.path(), &name);
            let level = dir.join("level.png");
            std::fs::write(&level, &base.png).expect("write level");
            // Half beside the level (found by the lookup), half given explicitly.
            let beside = k % 2 == 0;
            let palette = if beside {
                dir.join("level.palette.toml")
            } else {
                dir.join("given.toml")
            };
            std::fs::write(&palette, &text).expect("write palette");
            let must_bake = k == 0;
            tally.run(&format!("{name} [{}]", ops.join("; ")), move || {
                let opts = batch_options(&dir.join("out"), (!beside).then(|| palette.clone()));
                let r = bake_and_check(&level, &opts, &[palette, level.clone()]);
                let _ = std::fs::remove_dir_all(&dir);
                match r {
                    Ok(Outcome::Refused) if must_bake => {
                        Err("the palette as it is did not bake".into())
                    }
                    r => r,
                }
            });
        }
    }
    tally.finish();
}

// ---------------------------------------------------------------------------
// Relight caches

/// A small level with two light groups, and its palette.
const GROUPS_PALETTE: &str = r##"
[[wall]]
color = "#000000"
reflectance = 0.6

[[wall]]
color = "#c0282a"
reflectance = [0.75, 0.1, 0.1]

[[emitter]]
color = "#ffffff"
emission = 4.0
group = "lamp"

[[emitter]]
color = "#ff8000"
emission = [4.0, 1.8, 0.4]
reflectance = 0.2
group = "torch"
"##;

fn groups_level() -> Vec<u8> {
    let (w, h) = (20u32, 14u32);
    let img = image::RgbaImage::from_fn(w, h, |x, y| {
        let px = if x == 0 || y == 0 || x == w - 1 || y == h - 1 {
            if (x, y) == (5, 0) || (x, y) == (6, 0) {
                [0xff, 0xff, 0xff, 255]
            } else {
                [0, 0, 0, 255]
            }
        } else if (8..11).contains(&x) && (5..8).contains(&y) {
            [0xc0, 0x28, 0x2a, 255]
        } else if (x, y) == (15, 10) {
            [0xff, 0x80, 0x00, 255]
        } else if x > 15 && y < 4 {
            [0, 0, 0, 0]
        } else {
            [0x80, 0x80, 0x80, 255]
        };
        image::Rgba(px)
    });
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .expect("encode");
    bytes
}

/// Caches written by real bakes with the cache on: (name, bytes).
fn real_caches(root: &Path) -> Vec<(String, Vec<u8>)> {
    let dir = root.join("bakes");
    std::fs::create_dir_all(&dir).expect("folder");
    std::fs::write(dir.join("groups.png"), groups_level()).expect("level");
    std::fs::write(dir.join("groups.palette.toml"), GROUPS_PALETTE).expect("palette");
    let cornell = flatbake_synth::cornell(24);
    cornell.save(&dir).expect("cornell");
    let mut opts = batch_options(&root.join("baked"), None);
    opts.cache = true;
    let levels = [dir.join("groups.png"), dir.join("cornell.png")];
    let outcomes = batch::run(&levels, &opts, &Silent);
    for o in &outcomes {
        assert!(matches!(o, LevelOutcome::Baked { .. }), "{o:?}");
    }
    ["groups", "cornell"]
        .iter()
        .map(|n| {
            let bytes =
                std::fs::read(root.join("baked").join(format!("{n}.flatbake"))).expect("cache");
            (n.to_string(), bytes)
        })
        .collect()
}

/// Length of the header before the payload.
fn header_len() -> usize {
    MAGIC.len() + 4 + 4 + VERSION.len() + 32
}

/// A cache file around `payload`, with a correct header and checksum.
fn wrap_payload(payload: &[u8]) -> Vec<u8> {
    let mut f = MAGIC.to_vec();
    f.extend_from_slice(&FORMAT.to_le_bytes());
    f.extend_from_slice(&(VERSION.len() as u32).to_le_bytes());
    f.extend_from_slice(VERSION.as_bytes());
    f.extend_from_slice(blake3::hash(payload).as_bytes());
    f.extend_from_slice(payload);
    f
}

/// Raw damage to the whole file: the checksum (or the header) refuses it.
fn mutate_cache_file(rng: &mut Rng, f: &mut Vec<u8>) -> String {
    let len = f.len();
    match rng.below(6) {
        0 => {
            let at = rng.below(len as u64) as usize;
            f[at] ^= 1 << rng.below(8);
            format!("bit flip at {at}")
        }
        1 => {
            let at = rng.below(header_len() as u64) as usize;
            f[at] = rng.below(256) as u8;
            format!("header byte {at}")
        }
        2 => {
            let v = *rng.pick(&[0u32, 1, 4, 64, 65, 0xffff, 0xffff_ffff]);
            f[20..24].copy_from_slice(&v.to_le_bytes());
            format!("version length {v}")
        }
        3 => {
            let v = *rng.pick(&[0u32, 2, 0xffff_ffff]);
            f[16..20].copy_from_slice(&v.to_le_bytes());
            format!("format {v}")
        }
        4 => {
            let at = rng.below(len as u64) as usize;
            f.truncate(at);
            format!("cut at {at} of {len}")
        }
        _ => {
            let n = 1 + rng.below(100) as usize;
            f.extend(random_bytes(rng, n));
            format!("{n} bytes appended")
        }
    }
}

/// Damage to the payload, checksum recomputed: postcard and the
/// cross-checks must refuse it, or it must relight finite.
fn mutate_payload(rng: &mut Rng, p: &mut Vec<u8>) -> String {
    let len = p.len().max(1);
    match rng.below(6) {
        0 | 1 => {
            let k = 1 + rng.below(4);
            for _ in 0..k {
                let at = rng.below(len as u64) as usize % p.len().max(1);
                if let Some(b) = p.get_mut(at) {
                    *b = match rng.below(3) {
                        0 => *b ^ (1 << rng.below(8)),
                        1 => *rng.pick(&[0, 1, 0x7f, 0x80, 0xff]),
                        _ => rng.below(256) as u8,
                    };
                }
            }
            format!("{k} payload bytes")
        }
        2 => {
            // Early bytes hold the name's and the size's varints.
            let at = rng.below(len.min(48) as u64) as usize % p.len().max(1);
            if let Some(b) = p.get_mut(at) {
                *b = *rng.pick(&[0, 1, 2, 0x7f, 0x80, 0xff]);
            }
            format!("early payload byte {at}")
        }
        3 => {
            let at = rng.below(len as u64) as usize;
            let n = 1 + rng.below(9) as usize;
            let bytes = random_bytes(rng, n);
            p.splice(at.min(p.len())..at.min(p.len()), bytes);
            format!("{n} bytes inserted at {at}")
        }
        4 => {
            let a = rng.below(len as u64) as usize % p.len().max(1);
            let b = (a + 1 + rng.below(16) as usize).min(p.len());
            p.drain(a..b);
            format!("bytes {a}..{b} removed")
        }
        _ => {
            let at = rng.below(len as u64) as usize;
            p.truncate(at);
            format!("payload cut at {at}")
        }
    }
}

/// Consistent-looking caches with values no bake writes: decoded, edited,
/// encoded again (so the checksum and the format hold).
fn mutate_fields(rng: &mut Rng, c: &mut Cache) -> String {
    let bad_f32 = [
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        -1.0,
        f32::MAX,
        f32::MIN_POSITIVE,
        -0.0,
    ];
    let bad_f64 = [f64::NAN, f64::INFINITY, -1.0, 0.0, 1e300, f64::MAX, 5e-324];
    match rng.below(14) {
        0 => {
            let name = *rng.pick(&[
                "",
                ".",
                "..",
                "../escape",
                "a/b",
                "/tmp/abs",
                "x\0y",
                "con",
                "sp ace",
                "é",
                "a\\b",
            ]);
            c.level = name.to_string();
            format!("level name {name:?}")
        }
        1 => {
            c.level = "n".repeat(*rng.pick(&[255usize, 300, 5000]));
            format!("level name of {} bytes", c.level.len())
        }
        2 => {
            std::mem::swap(&mut c.width, &mut c.height);
            c.responses.width = c.width;
            c.responses.height = c.height;
            "width and height swapped".into()
        }
        3 => {
            // Zero size, everything consistent.
            let (w, h) = *rng.pick(&[(0usize, 0usize), (0, 5), (5, 0)]);
            let n = w * h;
            c.width = w;
            c.height = h;
            c.cells.truncate(n);
            c.albedo.truncate(n);
            c.responses.width = w;
            c.responses.height = h;
            for i in &mut c.responses.images {
                i.truncate(n);
            }
            format!("{w}x{h} level")
        }
        4 => {
            let v = *rng.pick(&bad_f32);
            for img in &mut c.responses.images {
                let k = rng.below(img.len().max(1) as u64) as usize;
                if let Some(x) = img.get_mut(k) {
                    *x = v;
                }
            }
            format!("response values {v}")
        }
        5 => {
            let v = *rng.pick(&bad_f64);
            for m in &mut c.materials {
                m.emission[rng.below(3) as usize] = v;
            }
            format!("emission {v}")
        }
        6 => {
            let v = *rng.pick(&bad_f64);
            for m in &mut c.materials {
                m.reflectance[rng.below(3) as usize] = v;
            }
            format!("reflectance {v}")
        }
        7 => {
            let v = *rng.pick(&bad_f64);
            if rng.chance(0.5) {
                c.exposure = v;
                format!("exposure {v}")
            } else {
                c.responses.traced_emission = v;
                format!("traced emission {v}")
            }
        }
        8 => {
            let v = *rng.pick(&bad_f32);
            for a in &mut c.albedo {
                a[0] = v;
            }
            format!("albedo {v}")
        }
        9 => {
            let g = *rng.pick(&["", "../up", "a/b", "lamp", "TORCH", "x\0", "ü"]);
            for m in &mut c.materials {
                m.group = Some(g.to_string());
            }
            format!("every group {g:?}")
        }
        10 => {
            // Emitters listed twice, or a wall among them (sizes kept).
            let r = &mut c.responses;
            if let Some(&e) = r.emitters.first() {
                r.emitters.push(e);
                let extra: Vec<Vec<f32>> = r.images[..r.rho_classes].to_vec();
                r.images.extend(extra);
            }
            if rng.chance(0.5) && !c.materials.is_empty() {
                r.emitters[0] = 0;
            }
            "emitters listed twice".into()
        }
        11 => {
            let r = &mut c.responses;
            r.rho_class_of = [0, 0, 0];
            "every channel in class 0".into()
        }
        12 => {
            c.depth16 = !c.depth16;
            c.rgbm = !c.rgbm;
            "depth and RGBM flipped".into()
        }
        _ => {
            // Cells pointing at materials of the other kind.
            for cell in &mut c.cells {
                if *cell >= 2 {
                    *cell = 2 + (*cell - 2 + 1) % c.materials.len().max(1) as u32;
                }
            }
            "cells point at other materials".into()
        }
    }
}

/// Relights `cache` into `out` and checks the result: finite light and
/// every file inside `out`, or an error naming the cache or `out`.
fn relight_and_check(dir: &Path, cache: &Path, layers: bool) -> Result<Outcome, String> {
    let out = dir.join("relit");
    let opts = RelightOptions {
        out_dir: out.clone(),
        layers,
        hdr: true,
        ..RelightOptions::default()
    };
    let result = relight(cache, &opts);
    // Nothing lands beside the cache or further out.
    let mut stray: Vec<String> = std::fs::read_dir(dir)
        .map(|rd| {
            rd.flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    stray
        .retain(|n| n != "relit" && Some(n.as_str()) != cache.file_name().and_then(|f| f.to_str()));
    if !stray.is_empty() {
        return Err(format!(
            "the relight wrote outside {}: {stray:?}",
            out.display()
        ));
    }
    match result {
        Ok(report) => {
            check_exr(&out, &report)?;
            Ok(Outcome::Baked)
        }
        Err(e) => {
            let msg = e.to_string();
            if [cache, &out]
                .iter()
                .any(|p| msg.contains(&p.display().to_string()))
            {
                Ok(Outcome::Refused)
            } else {
                Err(format!(
                    "the error names neither the cache nor the output folder: {msg}"
                ))
            }
        }
    }
}

/// Hundreds of damaged relight caches: each refused naming the file, or
/// relit into finite light inside the output folder.
#[test]
fn mutated_caches_are_refused_by_name_or_relight_finite() {
    let root = tempfile::tempdir().expect("tempdir");
    let mut tally = Tally::new("caches");
    for (b, (name, bytes)) in real_caches(root.path()).into_iter().enumerate() {
        let cache = Cache::from_bytes(&bytes, Path::new("real")).expect("a real cache reads");
        let payload = bytes[header_len()..].to_vec();
        let mut rng = Rng::new(0x0063_6163_6865 ^ b as u64);
        for k in 0..80 {
            let (file, ops) = match k {
                0 => (bytes.clone(), "as it is".to_string()),
                1..=20 => {
                    let mut f = bytes.clone();
                    let op = mutate_cache_file(&mut rng, &mut f);
                    (f, op)
                }
                21..=50 => {
                    let mut p = payload.clone();
                    let op = mutate_payload(&mut rng, &mut p);
                    (wrap_payload(&p), format!("{op}, checksum recomputed"))
                }
                _ => {
                    let mut c = cache.clone();
                    let ops: Vec<String> = (0..1 + rng.below(2))
                        .map(|_| mutate_fields(&mut rng, &mut c))
                        .collect();
                    (c.to_bytes().expect("encodes"), ops.join("; "))
                }
            };
            let case = format!("{name}-{k}");
            let dir = case_dir(root.path(), &case);
            let path = dir.join(format!("{name}.flatbake"));
            std::fs::write(&path, file).expect("write cache");
            let layers = k % 2 == 1;
            let must_relight = k == 0;
            tally.run(&format!("{case} [{ops}]"), move || {
                let r = relight_and_check(&dir, &path, layers);
                let _ = std::fs::remove_dir_all(&dir);
                match r {
                    Ok(Outcome::Refused) if must_relight => {
                        Err("a real cache did not relight".into())
                    }
                    r => r,
                }
            });
        }
    }
    tally.finish();
}

// ---------------------------------------------------------------------------
// What the mutations found, pinned

/// A real cache of the two-group level, decoded.
fn groups_cache(root: &Path) -> Cache {
    let (_, bytes) = real_caches(root).swap_remove(0);
    Cache::from_bytes(&bytes, Path::new("groups.flatbake")).expect("a real cache reads")
}

/// Writes `cache` into a fresh folder and relights it with the checks of
/// the mutation tests; returns the outcome and the relight's error text.
fn relight_edited(root: &Path, name: &str, cache: &Cache) -> (Result<Outcome, String>, String) {
    let dir = case_dir(root, name);
    let path = dir.join("edited.flatbake");
    std::fs::write(&path, cache.to_bytes().expect("encodes")).expect("write cache");
    let err = Cache::read(&path)
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    (relight_and_check(&dir, &path, true), err)
}

/// A cache whose level name holds a path (`../escape`) made relight write
/// its outputs outside the output folder, since they are named after the
/// level. Such a name is now a damaged cache.
#[test]
fn a_cache_whose_level_name_is_a_path_is_refused_not_written_outside() {
    let root = tempfile::tempdir().expect("tempdir");
    let mut cache = groups_cache(root.path());
    for (k, name) in ["../escape", "sub/dir", "..\\up", "nul\0byte"]
        .into_iter()
        .enumerate()
    {
        cache.level = name.to_string();
        let (outcome, err) = relight_edited(root.path(), &format!("name-{k}"), &cache);
        assert!(
            matches!(outcome, Ok(Outcome::Refused)),
            "{name:?}: {outcome:?}"
        );
        assert!(
            err.contains("edited.flatbake") && err.contains("the level name is not a file name"),
            "{name:?}: {err}"
        );
    }
}

/// A cache of a level of 0 pixels (sizes otherwise consistent) failed with
/// "the level is 0x0 pixels, there is nothing to write", naming no file.
/// It is now a damaged cache, named.
#[test]
fn a_cache_of_a_level_without_pixels_is_refused_naming_the_cache() {
    let root = tempfile::tempdir().expect("tempdir");
    for (w, h) in [(0, 0), (0, 14), (20, 0)] {
        let mut cache = groups_cache(root.path());
        let n = w * h;
        (cache.width, cache.height) = (w, h);
        (cache.responses.width, cache.responses.height) = (w, h);
        cache.report.size = [w, h];
        cache.cells.truncate(n);
        cache.albedo.truncate(n);
        cache
            .responses
            .images
            .iter_mut()
            .for_each(|i| i.truncate(n));
        let (outcome, err) = relight_edited(root.path(), &format!("empty-{w}x{h}"), &cache);
        assert!(
            matches!(outcome, Ok(Outcome::Refused)),
            "{w}x{h}: {outcome:?}"
        );
        assert!(
            err.contains("edited.flatbake") && err.contains("no pixels"),
            "{w}x{h}: {err}"
        );
    }
}

/// A cache whose width and height were swapped (everything else consistent)
/// relit into a lightmap of one size with a report of the other.
/// The cached report's size must now match the cache's.
#[test]
fn a_cache_whose_report_disagrees_on_the_size_is_refused() {
    let root = tempfile::tempdir().expect("tempdir");
    let mut cache = groups_cache(root.path());
    std::mem::swap(&mut cache.width, &mut cache.height);
    (cache.responses.width, cache.responses.height) = (cache.width, cache.height);
    let (outcome, err) = relight_edited(root.path(), "swapped", &cache);
    assert!(matches!(outcome, Ok(Outcome::Refused)), "{outcome:?}");
    assert!(
        err.contains("edited.flatbake") && err.contains("inconsistent sizes"),
        "{err}"
    );
}

// ---------------------------------------------------------------------------
// A few of each through the binary

/// `rgb8_room.png` with one edit of its chunks, CRCs recomputed.
fn edited_fixture(name: &str, edit: impl FnOnce(&mut Png)) -> Vec<u8> {
    let mut png = Png::parse(&std::fs::read(fixture(name)).expect("fixture"));
    edit(&mut png);
    png.to_bytes()
}

/// Mutated PNGs, a palette and caches through the command line: every bad
/// file named on its own line, the good level baked, exit 1, never a crash.
#[test]
fn mutated_files_through_the_binary_are_named_and_the_batch_goes_on() {
    let dir = tempfile::tempdir().expect("tempdir");
    let levels = dir.path().join("levels");
    std::fs::create_dir(&levels).expect("folder");
    let bad: Vec<(&str, Vec<u8>)> = vec![
        (
            "a_known.png",
            std::fs::read(fixture("png_plte_trns_panic.png")).expect("fixture"),
        ),
        (
            "b_partial_palette.png",
            edited_fixture("paletted8_room_with_trns_void.png", |p| {
                let i = p.find(b"PLTE").expect("PLTE");
                p.chunks[i].data.truncate(4);
            }),
        ),
        (
            "c_wide.png",
            edited_fixture("rgb8_room.png", |p| {
                p.chunks[0].data[..4].copy_from_slice(&0x7fff_ffffu32.to_be_bytes());
            }),
        ),
        (
            "d_cut_data.png",
            edited_fixture("rgb8_room.png", |p| {
                let i = p.find(b"IDAT").expect("IDAT");
                let n = p.chunks[i].data.len() / 2;
                p.chunks[i].data.truncate(n);
            }),
        ),
        (
            "e_two_headers.png",
            edited_fixture("gray16_room.png", |p| {
                let ihdr = p.chunks[0].clone();
                p.chunks.insert(2, ihdr);
            }),
        ),
    ];
    for (name, bytes) in &bad {
        std::fs::write(levels.join(name), bytes).expect("write");
    }
    let mut good = flatbake_synth::cornell(24);
    good.name = "f_good".into();
    good.save(&levels).expect("save");
    let out = dir.path().join("out");
    let o = flatbake_mixed(&[
        &"bake",
        &levels,
        &"-o",
        &out,
        &"--quality",
        &"draft",
        &"--max-pixels",
        &"4096",
        &"--jobs",
        &"1",
    ]);
    assert_exit(&o, EXIT_FAILED);
    assert!(out.join("f_good.lightmap.png").is_file(), "{}", stderr(&o));
    let e = stderr(&o);
    for (name, _) in &bad {
        assert!(e.contains(name), "{name} is not named:\n{e}");
    }
    assert!(!out.join("a_known.lightmap.png").exists());

    // A palette nested 5000 deep, and one with a NaN emission.
    for (k, text) in [
        format!(
            "[[wall]]\ncolor = \"#000000\"\nreflectance = {}0.5{}\n",
            "[".repeat(5000),
            "]".repeat(5000)
        ),
        "[[emitter]]\ncolor = \"#fff0c8\"\nemission = nan\n".to_string(),
    ]
    .iter()
    .enumerate()
    {
        let palette = dir.path().join(format!("bad{k}.toml"));
        std::fs::write(&palette, text).expect("palette");
        let o = flatbake_mixed(&[
            &"bake",
            &levels.join("f_good.png"),
            &"-o",
            &out,
            &"--palette",
            &palette,
            &"--quality",
            &"draft",
        ]);
        assert_exit(&o, EXIT_FAILED);
        assert_says(&o, &[&format!("bad{k}.toml")]);
    }

    // Caches: a flipped byte, and a level name that leaves the folder.
    let o = flatbake_mixed(&[
        &"bake",
        &levels.join("f_good.png"),
        &"-o",
        &out,
        &"--cache",
        &"--quality",
        &"draft",
    ]);
    assert_exit(&o, EXIT_OK);
    let bytes = std::fs::read(out.join("f_good.flatbake")).expect("cache");
    let mut flipped = bytes.clone();
    let last = flipped.len() - 1;
    flipped[last] ^= 0x10;
    let mut escaping = Cache::from_bytes(&bytes, Path::new("c")).expect("reads");
    escaping.level = "../escape".into();
    for (name, bytes) in [
        ("flipped.flatbake", flipped),
        ("escaping.flatbake", escaping.to_bytes().expect("encodes")),
    ] {
        let cache = dir.path().join(name);
        std::fs::write(&cache, bytes).expect("cache");
        let relit = dir.path().join("relit");
        let o = flatbake_mixed(&[&"relight", &cache, &"-o", &relit]);
        assert_exit(&o, EXIT_FAILED);
        assert_says(&o, &[name, "damaged"]);
        assert!(!dir.path().join("escape.lightmap.png").exists());
    }
}
