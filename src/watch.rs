//! Watch mode (`flatbake watch DIR -o OUT`): bake every level in a folder,
//! then bake a level again whenever its image or its palette is saved.
//!
//! Editors save in several steps (temporary file, rename, metadata), so file
//! events are debounced with `notify-debouncer-full` and a burst becomes one
//! bake. Bakes go through the incremental batch ([`crate::stamp`]): a save
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

use crate::batch::{self, BatchOptions, LevelOutcome, Silent};

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

/// The level images a file event in the watched folder concerns: the image
/// itself, the levels of `NAME.palette.toml`, or every level for the
/// folder's `palette.toml`.
pub fn affected_levels(dir: &Path, changed: &Path) -> Vec<PathBuf> {
    let Some(name) = changed.file_name().and_then(|n| n.to_str()) else {
        return Vec::new();
    };
    let levels = || -> Vec<PathBuf> {
        batch::collect_levels(&[dir.to_path_buf()])
            .into_iter()
            .filter(|p| p.is_file())
            .collect()
    };
    if name == "palette.toml" {
        return levels();
    }
    if let Some(stem) = name.strip_suffix(".palette.toml") {
        return levels()
            .into_iter()
            .filter(|p| p.file_stem().is_some_and(|s| s == stem))
            .collect();
    }
    let here = dir.join(name);
    if here.is_file() && batch::is_level_file(&here) {
        vec![here]
    } else {
        Vec::new()
    }
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
    let initial: Vec<PathBuf> = batch::collect_levels(std::slice::from_ref(&opts.dir))
        .into_iter()
        .filter(|p| p.is_file())
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
    }
    debouncer.stop();
    Ok(())
}
