//! Watch mode (`flatbake watch DIR -o OUT`): bake every level in a folder,
//! then bake a level again whenever its image (map, project), its palette
//! or a file it reads (a Tiled tileset, an LDtk level file) is saved.
//!
//! Editors save in several steps (temporary file, rename, metadata), so file
//! events are debounced with `notify-debouncer-full` and a burst becomes one
//! bake. Bakes go through the incremental batch (`flatbake_core::batch::stamp`): a save
//! that leaves the bytes unchanged reports "up to date" instead of baking. A
//! level that fails (half-painted, broken palette) reports its error and the
//! watcher keeps going. The loop stops when `stop` is set, which is how tests
//! and embedding tools drive it.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::Duration;

use notify::{EventKind, RecursiveMode};
use notify_debouncer_full::{DebounceEventResult, new_debouncer};

use flatbake_core::Palette;
use flatbake_core::batch::{self, BatchOptions, LevelOutcome, Silent};
use flatbake_core::level;

/// The local time of day, `HH:MM:SS`, that every line watch prints starts
/// with (UTC where the local time zone cannot be read).
pub fn clock() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() as i64);
    let (h, m, s) = local_hms(secs);
    format!("{h:02}:{m:02}:{s:02}")
}

#[cfg(unix)]
fn local_hms(secs: i64) -> (i64, i64, i64) {
    let t = secs as libc::time_t;
    // SAFETY: `tm` is plain data that localtime_r fills in; both pointers
    // are valid for the duration of the call, and localtime_r (unlike
    // localtime) keeps no shared buffer.
    let mut tm: libc::tm = unsafe { std::mem::zeroed() };
    let ok = unsafe { !libc::localtime_r(&t, &mut tm).is_null() };
    if ok {
        (tm.tm_hour as i64, tm.tm_min as i64, tm.tm_sec as i64)
    } else {
        utc_hms(secs)
    }
}

#[cfg(not(unix))]
fn local_hms(secs: i64) -> (i64, i64, i64) {
    utc_hms(secs)
}

fn utc_hms(secs: i64) -> (i64, i64, i64) {
    let day = secs.rem_euclid(86_400);
    (day / 3600, day / 60 % 60, day % 60)
}

/// How a watch runs.
#[derive(Clone, Debug)]
pub struct WatchOptions {
    /// The folder of levels (not recursive).
    pub dir: PathBuf,
    /// How levels are baked; `out_dir` is where outputs go.
    pub batch: BatchOptions,
    /// Quiet time after the last file event before baking. Default 300 ms.
    pub debounce: Duration,
}

/// What the watcher tells its caller.
#[derive(Debug)]
pub enum WatchEvent {
    /// Watching has started (after the first bake of every level).
    Watching { dir: PathBuf },
    /// A level was baked, failed, or was up to date.
    Level(LevelOutcome),
    /// The file watcher reported a problem; watching goes on.
    WatchError(String),
}

/// The levels a file event in the watched folder concerns: the level file
/// itself (an LDtk project stands for its levels), the levels of
/// `NAME.palette.toml`, every level for the folder's `palette.toml`, or the
/// levels that read the file (tilesets, LDtk level files, which may lie in
/// other folders).
pub fn affected_levels(dir: &Path, changed: &Path) -> Vec<PathBuf> {
    let Some(name) = changed.file_name().and_then(|n| n.to_str()) else {
        return Vec::new();
    };
    let levels = || -> Vec<PathBuf> {
        batch::collect_levels(&[dir.to_path_buf()])
            .into_iter()
            .filter(|p| is_level(p))
            .collect()
    };
    let in_dir = changed.parent().is_none_or(|p| same_file(p, dir));
    if in_dir && name == "palette.toml" {
        return levels();
    }
    if in_dir && name.ends_with(".palette.toml") {
        return levels()
            .into_iter()
            .filter(|p| Palette::candidate_paths(p)[0].file_name() == Some(name.as_ref()))
            .collect();
    }
    let here = dir.join(name);
    if in_dir && here.is_file() && batch::is_level_file(&here) {
        return vec![here];
    }
    levels()
        .into_iter()
        .filter(|l| level::dependencies(l).iter().any(|d| same_file(d, changed)))
        .collect()
}

/// A level file, or a level of an LDtk project (not a folder, not a
/// broken link).
fn is_level(p: &Path) -> bool {
    p.is_file() || level::ldtk::project_level(p).is_some()
}

/// True when two paths name the same file (compared by their folders'
/// canonical paths, so that a file that was just removed still compares).
fn same_file(a: &Path, b: &Path) -> bool {
    let canon = |p: &Path| -> PathBuf {
        if let Ok(c) = p.canonicalize() {
            return c;
        }
        match (p.parent(), p.file_name()) {
            (Some(d), Some(n)) => d
                .canonicalize()
                .map_or_else(|_| p.to_path_buf(), |d| d.join(n)),
            _ => p.to_path_buf(),
        }
    };
    canon(a) == canon(b)
}

/// The folders other than `dir` that hold files the levels in `dir` read.
fn dependency_folders(dir: &Path) -> BTreeSet<PathBuf> {
    let home = dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf());
    batch::collect_levels(&[dir.to_path_buf()])
        .iter()
        .flat_map(|l| level::dependencies(l))
        .filter_map(|d| d.parent()?.canonicalize().ok())
        .filter(|d| *d != home)
        .collect()
}

/// Bakes every level in `opts.dir`, then watches until `stop` is set,
/// calling `on` for each event. Fails only when watching cannot start.
pub fn run(
    opts: &WatchOptions,
    stop: &AtomicBool,
    on: &mut dyn FnMut(WatchEvent),
) -> Result<(), String> {
    if !opts.dir.is_dir() {
        return Err(format!("{} is not a folder", opts.dir.display()));
    }
    let (tx, rx) = mpsc::channel::<DebounceEventResult>();
    let mut debouncer = new_debouncer(opts.debounce, None, tx)
        .map_err(|e| format!("cannot watch {}: {e}", opts.dir.display()))?;
    // Watch before the first bake, so that saves during it are not lost.
    debouncer
        .watch(&opts.dir, RecursiveMode::NonRecursive)
        .map_err(|e| format!("cannot watch {}: {e}", opts.dir.display()))?;

    let bake = |levels: &[PathBuf], on: &mut dyn FnMut(WatchEvent)| {
        if levels.is_empty() {
            return;
        }
        for outcome in batch::run(levels, &opts.batch, &Silent) {
            on(WatchEvent::Level(outcome));
        }
    };
    // Files the levels read in other folders (tilesets, LDtk level files)
    // are watched too, and so are folders that new files bring in.
    let mut watched = BTreeSet::new();
    let mut watch_more = |debouncer: &mut notify_debouncer_full::Debouncer<_, _>,
                          on: &mut dyn FnMut(WatchEvent)| {
        for d in dependency_folders(&opts.dir) {
            if watched.insert(d.clone())
                && let Err(e) = debouncer.watch(&d, RecursiveMode::NonRecursive)
            {
                on(WatchEvent::WatchError(format!(
                    "cannot watch {}: {e}",
                    d.display()
                )));
            }
        }
    };
    watch_more(&mut debouncer, on);
    let initial: Vec<PathBuf> = batch::collect_levels(std::slice::from_ref(&opts.dir))
        .into_iter()
        .filter(|p| is_level(p))
        .collect();
    bake(&initial, on);
    on(WatchEvent::Watching {
        dir: opts.dir.clone(),
    });

    while !stop.load(Ordering::Relaxed) {
        let events = match rx.recv_timeout(Duration::from_millis(100)) {
            Ok(Ok(events)) => events,
            Ok(Err(errors)) => {
                for e in errors {
                    on(WatchEvent::WatchError(e.to_string()));
                }
                continue;
            }
            Err(mpsc::RecvTimeoutError::Timeout) => continue,
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                return Err("the file watcher stopped".into());
            }
        };
        let mut todo = BTreeSet::new();
        for ev in events {
            if matches!(ev.kind, EventKind::Access(_)) {
                continue;
            }
            for p in &ev.paths {
                todo.extend(affected_levels(&opts.dir, p));
            }
        }
        let todo: Vec<PathBuf> = todo.into_iter().collect();
        bake(&todo, on);
        if !todo.is_empty() {
            watch_more(&mut debouncer, on);
        }
    }
    debouncer.stop();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use flatbake_core::quality::Quality;

    /// A 24 x 16 room of built-in grey wall (`#5a5a5a`) with a white
    /// (built-in emitter) lamp in its top wall and a pillar in the middle.
    fn write_room(dir: &Path, name: &str) -> PathBuf {
        let (w, h) = (24u32, 16u32);
        let img = image::RgbaImage::from_fn(w, h, |x, y| {
            let border = x == 0 || y == 0 || x == w - 1 || y == h - 1;
            let c = if y == 0 && (8..12).contains(&x) {
                [255, 255, 255]
            } else if border || ((10..13).contains(&x) && (6..10).contains(&y)) {
                [0x5a, 0x5a, 0x5a]
            } else {
                [0xb0, 0xa0, 0x90]
            };
            image::Rgba([c[0], c[1], c[2], 255])
        });
        let png = dir.join(format!("{name}.png"));
        img.save(&png).expect("write level png");
        png
    }

    /// Waits up to 20 s for an event that `want` accepts, passing over others.
    fn wait_for(
        rx: &mpsc::Receiver<WatchEvent>,
        what: &str,
        want: impl Fn(&WatchEvent) -> bool,
    ) -> WatchEvent {
        let deadline = std::time::Instant::now() + Duration::from_secs(20);
        loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            match rx.recv_timeout(left) {
                Ok(ev) if want(&ev) => return ev,
                Ok(_) => continue,
                Err(_) => panic!("no {what} within 20 s"),
            }
        }
    }

    #[test]
    fn watch_bakes_after_a_save_and_survives_a_broken_level() {
        let dir = tempfile::tempdir().expect("tempdir");
        let levels = dir.path().join("levels");
        std::fs::create_dir(&levels).expect("mkdir");
        let png = write_room(&levels, "room");
        let out = dir.path().join("out");
        let opts = WatchOptions {
            dir: levels.clone(),
            batch: BatchOptions {
                out_dir: out.clone(),
                quality: Quality::Draft,
                ..BatchOptions::default()
            },
            debounce: Duration::from_millis(100),
        };
        let stop = AtomicBool::new(false);
        let (tx, rx) = mpsc::channel();
        let is_room = |p: &Path| p.file_name() == png.file_name();
        std::thread::scope(|scope| {
            let handle = scope.spawn(|| run(&opts, &stop, &mut |ev| drop(tx.send(ev))));
            let first = wait_for(&rx, "first bake", |e| matches!(e, WatchEvent::Level(_)));
            assert!(
                matches!(&first, WatchEvent::Level(LevelOutcome::Baked { path, .. }) if is_room(path)),
                "{first:?}"
            );
            wait_for(&rx, "watching", |e| {
                matches!(e, WatchEvent::Watching { .. })
            });
            let before = std::fs::read(out.join("room.lightmap.png")).expect("baked");

            // A broken palette: the level fails, the watcher goes on.
            std::fs::write(levels.join("room.palette.toml"), "[[wall]\ncolor = ").expect("write");
            let failed = wait_for(&rx, "failed bake", |e| {
                matches!(e, WatchEvent::Level(LevelOutcome::Failed { .. }))
            });
            let WatchEvent::Level(LevelOutcome::Failed { error, .. }) = failed else {
                unreachable!()
            };
            assert!(error.to_string().contains("room.palette.toml"), "{error}");

            // Fixed with a brighter lamp: baked again, and the output changes.
            std::fs::write(
                levels.join("room.palette.toml"),
                "[[emitter]]\ncolor = \"#ffffff\"\nemission = 8.0\n",
            )
            .expect("write");
            wait_for(
                &rx,
                "bake after the fix",
                |e| matches!(e, WatchEvent::Level(LevelOutcome::Baked { path, .. }) if is_room(path)),
            );
            let after = std::fs::read(out.join("room.lightmap.png")).expect("baked");
            assert_ne!(before, after, "the new palette shows in the lightmap");

            // A new level painted into the folder is baked too.
            write_room(&levels, "second");
            wait_for(&rx, "bake of a new level", |e| {
                matches!(e, WatchEvent::Level(LevelOutcome::Baked { path, .. })
                    if path.file_name().is_some_and(|n| n == "second.png"))
            });

            stop.store(true, Ordering::Relaxed);
            let r = handle.join().expect("watch thread");
            assert!(r.is_ok(), "{r:?}");
        });
    }

    #[test]
    fn watch_maps_files_to_levels() {
        let dir = tempfile::tempdir().expect("tempdir");
        let d = dir.path();
        let a = write_room(d, "a");
        let b = write_room(d, "b");
        std::fs::write(d.join("a.lightmap.png"), b"not a level").expect("write");
        assert_eq!(affected_levels(d, &d.join("a.png")), vec![a.clone()]);
        assert_eq!(
            affected_levels(d, &d.join("b.palette.toml")),
            vec![b.clone()]
        );
        assert_eq!(affected_levels(d, &d.join("palette.toml")), vec![a, b]);
        assert!(affected_levels(d, &d.join("a.lightmap.png")).is_empty());
        assert!(affected_levels(d, &d.join(".flatbake-x.tmp")).is_empty());
    }

    /// Tilesets and LDtk level files, which the folder's level files read,
    /// map to the levels that read them; a project to itself (the batch
    /// bakes its levels), a project's palette to its levels.
    #[test]
    fn watch_maps_tilesets_and_ldtk_level_files_to_their_levels() {
        let dir = tempfile::tempdir().expect("tempdir");
        let d = dir.path();
        let fixtures = Path::new("tests/fixtures");
        for f in ["room.tmx", "room.tsx"] {
            std::fs::copy(fixtures.join("tiled").join(f), d.join(f)).expect("copy");
        }
        std::fs::create_dir(d.join("SeparateLevelFiles")).expect("mkdir");
        for f in [
            "SeparateLevelFiles.ldtk",
            "SeparateLevelFiles/World_Level_0.ldtkl",
            "SeparateLevelFiles/World_Level_1.ldtkl",
            "SeparateLevelFiles/World_Level_2.ldtkl",
        ] {
            std::fs::copy(fixtures.join("ldtk").join(f), d.join(f)).expect("copy");
        }
        let project = d.join("SeparateLevelFiles.ldtk");
        assert_eq!(
            affected_levels(d, &d.join("room.tsx")),
            vec![d.join("room.tmx")]
        );
        assert_eq!(
            affected_levels(d, &d.join("SeparateLevelFiles/World_Level_1.ldtkl")),
            vec![project.join("World_Level_1")]
        );
        assert_eq!(affected_levels(d, &project), vec![project.clone()]);
        assert_eq!(
            affected_levels(d, &d.join("SeparateLevelFiles.palette.toml")),
            (0..3)
                .map(|i| project.join(format!("World_Level_{i}")))
                .collect::<Vec<_>>()
        );
        assert_eq!(
            dependency_folders(d),
            BTreeSet::from([d.join("SeparateLevelFiles").canonicalize().unwrap()])
        );
    }
}
