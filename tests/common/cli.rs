//! Running the `flatbake` binary and reading what it says.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Exit status: every level baked (or up to date).
pub const EXIT_OK: u8 = 0;
/// Exit status: at least one level failed.
pub const EXIT_FAILED: u8 = 1;
/// Exit status: bad command line.
pub const EXIT_USAGE: u8 = 2;

/// The binary under test.
pub const BIN: &str = env!("CARGO_BIN_EXE_flatbake");

/// Runs `flatbake ARGS` and waits for it.
pub fn flatbake<S: AsRef<OsStr>>(args: &[S]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("flatbake runs")
}

/// Runs `flatbake ARGS` with arguments of mixed types (strings and paths).
pub fn flatbake_mixed(args: &[&dyn AsRef<OsStr>]) -> Output {
    Command::new(BIN)
        .args(args.iter().map(|a| a.as_ref()))
        .output()
        .expect("flatbake runs")
}

/// Runs `flatbake ARGS` in the folder `cwd`.
pub fn flatbake_in<S: AsRef<OsStr>>(args: &[S], cwd: &Path) -> Output {
    Command::new(BIN)
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("flatbake runs")
}

/// What the run printed on standard error.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A path as a command-line argument.
pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// A file of `tests/fixtures/input`.
pub fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/input")
        .join(name)
}

/// The run exited with `code`.
#[track_caller]
pub fn assert_exit(o: &Output, code: u8) {
    assert_eq!(o.status.code(), Some(code as i32), "stderr: {}", stderr(o));
}

/// Standard error holds every one of `words`.
#[track_caller]
pub fn assert_says(o: &Output, words: &[&str]) {
    let e = stderr(o);
    for w in words {
        assert!(e.contains(w), "stderr lacks {w:?}:\n{e}");
    }
}

/// Writes `NAME.png` and its palette: a 24 x 16 closed room with a light
/// strip in the top wall and a wall stub from the floor, plus a 2 x 2 pillar
/// when `pillar` is set.
pub fn write_room(dir: &Path, name: &str, pillar: bool) {
    let (w, h) = (24u32, 16u32);
    let img = image::RgbaImage::from_fn(w, h, |x, y| {
        if y == 0 && (8..14).contains(&x) {
            image::Rgba([255, 250, 220, 255])
        } else if x == 0
            || y == 0
            || x == w - 1
            || y == h - 1
            || (x == 12 && y > 6)
            || (pillar && (4..6).contains(&x) && (4..6).contains(&y))
        {
            image::Rgba([90, 90, 90, 255])
        } else {
            image::Rgba([180, 170, 150, 255])
        }
    });
    img.save(dir.join(format!("{name}.png")))
        .expect("write level");
    std::fs::write(
        dir.join(format!("{name}.palette.toml")),
        "[[wall]]\ncolor = \"#5a5a5a\"\nreflectance = 0.6\n\n[[emitter]]\ncolor = \"#fffadc\"\nemission = [2.0, 1.8, 1.5]\n",
    )
    .expect("write palette");
}
