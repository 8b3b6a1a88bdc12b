//! Writing files so that no failure loses anything: every file goes through
//! a temporary file in its destination folder that is flushed to disk and
//! renamed over the old one, so a failed or interrupted write never leaves a
//! half-written file and never destroys the previous file of that name; and
//! errors that name the path and say the cause in plain words ("the disk is
//! full").

use std::io::{self, ErrorKind, Write};
use std::path::{Path, PathBuf};

use super::names::{TEMP_PREFIX, TEMP_SUFFIX};

/// Why an output could not be written (or read back). Every message names
/// the path and says the problem in plain words.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The output folder does not exist (and was not to be created).
    #[error("output folder {} does not exist", .path.display())]
    MissingDir {
        /// The folder.
        path: PathBuf,
    },
    /// A file is where the output folder (or one of its parents) should be.
    #[error("{}", not_a_dir_message(.path, .file))]
    NotADir {
        /// The output folder.
        path: PathBuf,
        /// The regular file in the way: the folder itself or a parent.
        file: PathBuf,
    },
    /// The output folder cannot be created.
    #[error("cannot create output folder {}: {}", .path.display(), describe_io(.error))]
    CreateDir {
        /// The folder.
        path: PathBuf,
        /// The cause.
        error: io::Error,
    },
    /// A file cannot be written (full disk, permissions, read-only, ...).
    #[error("cannot write {}: {}", .path.display(), describe_io(.error))]
    Write {
        /// The file.
        path: PathBuf,
        /// The cause.
        error: io::Error,
    },
    /// A file's content cannot be encoded.
    #[error("cannot encode {}: {message}", .path.display())]
    Encode {
        /// The file it was for.
        path: PathBuf,
        /// The encoder's message.
        message: String,
    },
    /// A file written earlier cannot be read back.
    #[error("cannot read {}: {message}", .path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A level's normal map cannot be read or does not fit the level.
    #[error("the normal map {}: {message}", .path.display())]
    NormalMap {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The level and the lightmap handed in do not fit together (a bug in
    /// the caller, reported instead of panicking).
    #[error("cannot write the outputs of level {level}: {message}")]
    Invalid {
        /// The level's name.
        level: String,
        /// What does not fit.
        message: String,
    },
}

impl OutputError {
    /// Maps an I/O error met while writing `path` to an error a person can
    /// read ("cannot write out/a.png: the disk is full").
    pub fn from_io(path: &Path, error: io::Error) -> OutputError {
        OutputError::Write {
            path: path.to_path_buf(),
            error,
        }
    }

    /// The path the error is about, if it is about one.
    pub fn path(&self) -> Option<&Path> {
        match self {
            OutputError::MissingDir { path }
            | OutputError::NotADir { path, .. }
            | OutputError::CreateDir { path, .. }
            | OutputError::Write { path, .. }
            | OutputError::Encode { path, .. }
            | OutputError::Read { path, .. }
            | OutputError::NormalMap { path, .. } => Some(path),
            OutputError::Invalid { .. } => None,
        }
    }

    /// True when the underlying cause is a full disk (or an exhausted quota).
    pub fn is_disk_full(&self) -> bool {
        match self {
            OutputError::Write { error, .. } | OutputError::CreateDir { error, .. } => {
                is_disk_full(error)
            }
            _ => false,
        }
    }
}

fn not_a_dir_message(path: &Path, file: &Path) -> String {
    if path == file {
        format!("output folder {} is a file, not a folder", path.display())
    } else {
        format!(
            "output folder {} cannot be created: {} is a file, not a folder",
            path.display(),
            file.display()
        )
    }
}

fn is_disk_full(e: &io::Error) -> bool {
    // ENOSPC is 28 on Linux and the BSDs; on Windows 28 means something else,
    // and the kind alone is reliable there.
    (cfg!(unix) && e.raw_os_error() == Some(28))
        || matches!(e.kind(), ErrorKind::StorageFull | ErrorKind::QuotaExceeded)
}

/// The cause of an I/O error in words, without the OS error number.
pub(crate) fn describe_io(e: &io::Error) -> String {
    if is_disk_full(e) {
        if e.kind() == ErrorKind::QuotaExceeded {
            return "the disk quota is exceeded".into();
        }
        return "the disk is full".into();
    }
    match e.kind() {
        ErrorKind::PermissionDenied => "permission denied".into(),
        ErrorKind::ReadOnlyFilesystem => "the file system is read-only".into(),
        ErrorKind::NotFound => "the folder does not exist".into(),
        ErrorKind::NotADirectory => "a part of the path is a file, not a folder".into(),
        ErrorKind::IsADirectory => "a folder of that name is in the way".into(),
        _ => e.to_string(),
    }
}

/// The first existing ancestor of `dir` (or `dir` itself) if it is not a
/// folder: that is the file that keeps `dir` from being a folder.
fn file_in_the_way(dir: &Path) -> Option<PathBuf> {
    dir.ancestors()
        .filter(|p| !p.as_os_str().is_empty())
        .find_map(|p| match std::fs::metadata(p) {
            Ok(m) => Some((!m.is_dir()).then(|| p.to_path_buf())),
            Err(_) => None,
        })
        .flatten()
}

/// An empty path means the current folder, as `Path::parent` returns it.
fn dir_or_current(dir: &Path) -> &Path {
    if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    }
}

/// Checks that `dir` exists and is a folder, without creating it.
pub(crate) fn check_output_dir(dir: &Path) -> Result<(), OutputError> {
    match std::fs::metadata(dir_or_current(dir)) {
        Ok(m) if m.is_dir() => Ok(()),
        Ok(_) => Err(OutputError::NotADir {
            path: dir.to_path_buf(),
            file: dir.to_path_buf(),
        }),
        Err(e) => Err(match file_in_the_way(dir) {
            Some(file) => OutputError::NotADir {
                path: dir.to_path_buf(),
                file,
            },
            None if e.kind() == ErrorKind::NotFound => OutputError::MissingDir {
                path: dir.to_path_buf(),
            },
            None => OutputError::CreateDir {
                path: dir.to_path_buf(),
                error: e,
            },
        }),
    }
}

/// Creates the output folder (and its parents) if needed. Used by the CLI
/// for its default `out/`; an explicit folder that is a file, or that cannot
/// be created, is reported clearly.
pub fn ensure_output_dir(dir: &Path) -> Result<(), OutputError> {
    let d = dir_or_current(dir);
    match std::fs::create_dir_all(d) {
        Ok(()) => check_output_dir(dir),
        Err(e) => Err(match file_in_the_way(dir) {
            Some(file) => OutputError::NotADir {
                path: dir.to_path_buf(),
                file,
            },
            None => OutputError::CreateDir {
                path: dir.to_path_buf(),
                error: e,
            },
        }),
    }
}

/// Writes `bytes` to `path` through a temporary file in the same folder that
/// is flushed to disk and renamed into place, so a failure never leaves a
/// half-written file and never destroys the previous file of that name.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let tmp = stage_io(path, bytes)?;
    persist_io(tmp, path)
}

/// The first half of [`write_atomic`]: `bytes` in a temporary file beside
/// `path`, flushed to disk, not yet in place.
fn stage_io(path: &Path, bytes: &[u8]) -> io::Result<tempfile::NamedTempFile> {
    let dir = dir_or_current(path.parent().unwrap_or(Path::new("")));
    let mut builder = tempfile::Builder::new();
    // A leftover from a killed process is recognisable and hidden.
    builder.prefix(TEMP_PREFIX).suffix(TEMP_SUFFIX);
    // Temporary files are created owner-only (0600); ask for 0666 instead so
    // the umask decides, as for any file the user creates.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let mut tmp = builder.tempfile_in(dir)?;
    tmp.write_all(bytes)?;
    tmp.as_file().sync_all()?;
    Ok(tmp)
}

/// The second half of [`write_atomic`]: the staged file renamed into place.
fn persist_io(tmp: tempfile::NamedTempFile, path: &Path) -> io::Result<()> {
    let dir = dir_or_current(path.parent().unwrap_or(Path::new("")));
    // On failure the temporary file is dropped, which deletes it.
    tmp.persist(path).map_err(|e| e.error)?;
    // Make the rename itself durable. The new file is already in place, so a
    // failure here is not worth failing the bake for.
    #[cfg(unix)]
    if let Ok(d) = std::fs::File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// An output written in full to a hidden temporary file beside its
/// destination and flushed to disk, but not yet in place: staging every
/// output of a level first means that a full disk or a failed write
/// replaces none of them. Dropped without [`StagedFile::commit`], the
/// temporary file is deleted.
#[derive(Debug)]
pub struct StagedFile {
    tmp: tempfile::NamedTempFile,
    path: PathBuf,
}

impl StagedFile {
    /// Writes `bytes` to a temporary file for `path`.
    pub fn new(path: &Path, bytes: &[u8]) -> Result<StagedFile, OutputError> {
        let tmp = stage_io(path, bytes).map_err(|e| named_error(path, e))?;
        Ok(StagedFile {
            tmp,
            path: path.to_path_buf(),
        })
    }

    /// The destination.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Renames the file into place (atomically replacing any earlier one).
    pub fn commit(self) -> Result<PathBuf, OutputError> {
        persist_io(self.tmp, &self.path).map_err(|e| named_error(&self.path, e))?;
        Ok(self.path)
    }
}

/// Removes the output file `path`; one that is not there is fine.
pub fn remove_output(path: &Path) -> Result<(), OutputError> {
    match std::fs::remove_file(path) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == ErrorKind::NotFound => Ok(()),
        Err(error) => Err(OutputError::Write {
            path: path.to_path_buf(),
            error,
        }),
    }
}

/// [`write_atomic`] with errors that name the path in plain words.
pub fn write_file_atomic(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    write_atomic(path, bytes).map_err(|e| named_error(path, e))
}

/// An I/O error writing `path`, in plain words.
fn named_error(path: &Path, e: io::Error) -> OutputError {
    {
        let dir = path.parent().unwrap_or(Path::new(""));
        match e.kind() {
            // The folder vanished or was never there: say so about the folder.
            ErrorKind::NotFound | ErrorKind::NotADirectory => match check_output_dir(dir) {
                Err(folder_error) => folder_error,
                Ok(()) => OutputError::from_io(path, e),
            },
            _ => OutputError::from_io(path, e),
        }
    }
}
