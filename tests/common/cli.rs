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
