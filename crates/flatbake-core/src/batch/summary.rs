//! The batch summary: one JSON file per run of a batch in its output folder
//! — every level with its status, time, warnings and outputs, the shard,
//! the flatbake version and the quality — for the scheduler or script that
//! ran the batch, without parsing the console.
//!
//! A whole batch writes `batch.json`; shard K of N writes
//! `batch-K-of-N.json` ([`names::batch_summary`]), so shards baking into one
//! folder keep every summary. It is written atomically, while the batch
//! still holds the folder's lock, after every level's outputs. Apart from
//! the `seconds` fields it depends only on the inputs: the levels appear in
//! the batch's order, and the same level gets the same entry in a whole run
//! and in its shard.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::shard::Shard;
use super::{BatchOptions, LevelOutcome};
use crate::bake::report::Report;
use crate::output::{self, OutputError, OutputKind, names};

/// The content of `batch.json` (or `batch-K-of-N.json`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct BatchSummary {
    /// The flatbake version that ran the batch.
    pub flatbake: String,
    /// The shard this run baked (`index` of `count`); `null` for a whole batch.
    pub shard: Option<Shard>,
    /// The quality preset.
    pub quality: String,
    /// The transport kernel ("flatland" or "paper").
    pub kernel: String,
    /// The floor gather ("fast" or "naive").
    pub gather: String,
    /// How many levels ended how.
    pub counts: SummaryCounts,
    /// Wall time of the whole run, in seconds.
    pub seconds: f64,
    /// Every level of the run (of this shard), in the batch's order.
    pub levels: Vec<LevelSummary>,
}

/// How many levels of a run ended how.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq, Eq)]
pub struct SummaryCounts {
    /// Levels in the run (in this shard).
    pub levels: usize,
    /// Baked and written.
    pub baked: usize,
    /// Not baked: their outputs were up to date.
    pub up_to_date: usize,
    /// Not baked or not written.
    pub failed: usize,
}

/// How one level ended.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Baked and written.
    Baked,
    /// Not baked: the outputs in the folder were made from the same inputs.
    UpToDate,
    /// Not baked, or not written; `error` says why.
    Failed,
}

/// One level of the batch summary.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct LevelSummary {
    /// The level's name (its image's file stem; its outputs' prefix).
    pub level: String,
    /// The level image as the batch was given it.
    pub image: PathBuf,
    /// How it ended.
    pub status: Status,
    /// Seconds of its bake (the report's `timings.total`); `null` when it
    /// was up to date or failed.
    pub seconds: Option<f64>,
    /// Its report's warnings (for an up-to-date level, those of the report
    /// in the folder).
    pub warnings: Vec<String>,
    /// Its files in the output folder: the report's `outputs` and the
    /// stamp; empty when it failed.
    pub outputs: Vec<String>,
    /// Why it failed; `null` otherwise.
    pub error: Option<String>,
}

impl BatchSummary {
    /// The summary of a run with `opts` that ended in `outcomes` after
    /// `seconds`. Up-to-date levels are described from the stamp and report
    /// they have in `opts.out_dir`.
    pub fn new(opts: &BatchOptions, outcomes: &[LevelOutcome], seconds: f64) -> BatchSummary {
        let levels: Vec<LevelSummary> = outcomes
            .iter()
            .map(|o| level_summary(o, &opts.out_dir))
            .collect();
        let count = |s: Status| levels.iter().filter(|l| l.status == s).count();
        BatchSummary {
            flatbake: env!("CARGO_PKG_VERSION").into(),
            shard: opts.shard,
            quality: opts.quality.name().into(),
            kernel: opts.kernel.name().into(),
            gather: opts.gather.name().into(),
            counts: SummaryCounts {
                levels: levels.len(),
                baked: count(Status::Baked),
                up_to_date: count(Status::UpToDate),
                failed: count(Status::Failed),
            },
            seconds,
            levels,
        }
    }

    /// The file this summary is written to: `batch.json`, or
    /// `batch-K-of-N.json` for a shard.
    pub fn file_name(&self) -> String {
        names::batch_summary(self.shard.map(|s| (s.index, s.count)))
    }

    /// Writes the summary into `dir` atomically (pretty JSON and a final
    /// newline); returns its path.
    pub fn write(&self, dir: &Path) -> Result<PathBuf, OutputError> {
        let path = dir.join(self.file_name());
        let mut json = serde_json::to_vec_pretty(self).map_err(|e| OutputError::Encode {
            path: path.clone(),
            message: e.to_string(),
        })?;
        json.push(b'\n');
        output::ensure_output_dir(dir)?;
        output::write_file_atomic(&path, &json)?;
        Ok(path)
    }
}

fn level_summary(outcome: &LevelOutcome, out_dir: &Path) -> LevelSummary {
    let image = outcome.path().to_path_buf();
    let level = names::level_name(&image);
    let stamp_name = OutputKind::Stamp.file_name(&level);
    match outcome {
        LevelOutcome::Baked { report, .. } => LevelSummary {
            level,
            image,
            status: Status::Baked,
            seconds: Some(report.timings.total),
            warnings: report.warnings.clone(),
            outputs: report.outputs.iter().cloned().chain([stamp_name]).collect(),
            error: None,
        },
        LevelOutcome::UpToDate { .. } => {
            // The stamp listed these files and "up to date" checked their
            // hashes, so the report read here is the one that bake wrote.
            let outputs: Vec<String> = super::stamp::read(&image, out_dir)
                .map(|s| s.outputs)
                .unwrap_or_default();
            let report_name = OutputKind::Report.file_name(&level);
            let warnings = std::fs::read(out_dir.join(&report_name))
                .ok()
                .and_then(|b| serde_json::from_slice::<Report>(&b).ok())
                .map(|r| r.warnings)
                .unwrap_or_default();
            LevelSummary {
                level,
                image,
                status: Status::UpToDate,
                seconds: None,
                warnings,
                outputs: outputs.into_iter().chain([stamp_name]).collect(),
                error: None,
            }
        }
        LevelOutcome::Failed { error, .. } => LevelSummary {
            level,
            image,
            status: Status::Failed,
            seconds: None,
            warnings: Vec::new(),
            outputs: Vec::new(),
            error: Some(error.to_string()),
        },
    }
}
