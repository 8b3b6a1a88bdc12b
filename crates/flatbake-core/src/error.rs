//! The crate's error type: why a level (or a relight, or a sweep) failed,
//! as a value a caller can match on — a bad image, a bad palette, a scene
//! with no finite answer, a full disk, a damaged cache — each naming the
//! file and the cause in words a level designer understands.

use std::path::PathBuf;

use crate::bake::BakeError;
use crate::level::LevelError;
use crate::level::palette::PaletteError;
use crate::output::OutputError;
use crate::output::cache::CacheError;

/// Why a level could not be baked, or a cache relit.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The level image could not be read or decoded.
    #[error(transparent)]
    Level(#[from] LevelError),
    /// The level's palette is malformed.
    #[error(transparent)]
    Palette(#[from] PaletteError),
    /// The scene has no answer (a closed mirror room with a light) or the
    /// solver failed.
    #[error("{}: {source}", .path.display())]
    Bake {
        /// The level image.
        path: PathBuf,
        /// Why.
        source: BakeError,
    },
    /// An output could not be written.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// A relight cache could not be read, written or used.
    #[error(transparent)]
    Cache(#[from] CacheError),
    /// An input file could not be read.
    #[error("cannot read {}: {source}", .path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// Two levels of one batch would write the same output files.
    #[error(
        "{}: not baked: its outputs would overwrite those of {} (both are named {name:?}); rename one or bake them into different output folders",
        .path.display(),
        .first.display()
    )]
    NameClash {
        /// The level not baked.
        path: PathBuf,
        /// The earlier level of the batch with the same name.
        first: PathBuf,
        /// The shared output name.
        name: String,
    },
    /// A folder given as a level holds no level images.
    #[error("{}: the folder holds no level images", .path.display())]
    NoLevels {
        /// The folder.
        path: PathBuf,
    },
    /// A relight was asked to write into the folder that holds the bake of
    /// the same level, whose outputs it would replace.
    #[error(
        "{}: holds the bake of {name} ({name}.stamp.json); a relight would overwrite the bake's own outputs, so it writes into another folder",
        .dir.display()
    )]
    RelightOverBake {
        /// The output folder asked for.
        dir: PathBuf,
        /// The level's name.
        name: String,
    },
    /// Decoding or baking the level panicked (in flatbake or in a library
    /// it uses): a bug, contained to this level.
    #[error(
        "{}: internal error while loading or baking this level ({message}); the other levels are not affected; please report this file",
        .path.display()
    )]
    Panic {
        /// The level image.
        path: PathBuf,
        /// The panic's message.
        message: String,
    },
}

impl Error {
    /// True when the cause is a full disk (or an exhausted quota).
    pub fn is_disk_full(&self) -> bool {
        matches!(self, Error::Output(e) if e.is_disk_full())
    }
}

/// A `Result` whose error is [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
