//! What `bake` says about shards and the batch summary: which part of the
//! batch a `--shard K/N` run bakes, and a batch summary that could not be
//! written. The rule itself is the library's (`flatbake_core::batch::shard`).

use std::path::PathBuf;

use flatbake_core::OutputError;
use flatbake_core::batch::{self, BatchOptions, BatchSummary};

/// With `--shard`, one line saying how many of the batch's levels this shard
/// bakes (possibly none: with few levels a shard can be empty).
pub fn announce(paths: &[PathBuf], opts: &BatchOptions, selected: usize) {
    if let Some(shard) = opts.shard {
        let all = batch::collect_levels(paths).len();
        eprintln!(
            "flatbake: shard {shard}: {selected} of {all} level{} (chosen by a hash of each level's name)",
            if all == 1 { "" } else { "s" }
        );
    }
}

/// Says why the batch summary could not be written; true when it could not
/// (the run then exits 1, as for a failed level).
pub fn report_summary(summary: &Result<(PathBuf, BatchSummary), OutputError>) -> bool {
    match summary {
        Ok(_) => false,
        Err(e) => {
            eprintln!("flatbake: the batch summary was not written: {e}");
            true
        }
    }
}
