//! Atomic file output, used for every file Tactus writes (patterns, features, plots, logs
//! written in one go).
//!
//! Algorithm (the usual write-fsync-rename recipe): write into a fresh temporary file
//! `.NAME.tmp-PID-N` created in the target's directory (same file system, so the rename is
//! atomic), flush and fsync it, give it the old target's permissions if there was one,
//! rename it over the target, then fsync the directory (best effort, Unix only). Readers
//! therefore see either the old file or the complete new one, never a torn file. On any
//! error the temporary file is removed and an existing target is left untouched.
//! The path `-` writes to standard output instead.
//!
//! Several outputs of one run form a transaction, [`OutputSet`]: every location is checked
//! and its temporary file created before any work starts (so a directory the user cannot
//! write fails the run at once), no output may be an input or another output of the same
//! run ([`same_file`]: canonical paths, hard links included), and the temporaries are
//! renamed over their targets only once every one is complete. Dropping an uncommitted set
//! removes its temporaries; [`remove_pending_temporaries`] does the same from a Ctrl-C
//! handler, for every temporary of the process.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Every temporary file this process has created and not yet renamed or removed. Renames
/// happen while holding the lock, so [`remove_pending_temporaries`] sees either all of a
/// set's temporaries or none.
static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn pending() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    PENDING.lock().unwrap_or_else(|e| e.into_inner())
}

fn forget_pending(list: &mut Vec<PathBuf>, tmp: &Path) {
    list.retain(|p| p != tmp);
}

/// Removes every temporary file this process has created and not yet renamed (for a Ctrl-C
/// handler that then exits). A set being committed finishes its renames first.
pub fn remove_pending_temporaries() {
    let mut list = pending();
    for p in list.drain(..) {
        let _ = fs::remove_file(p);
    }
}

/// Writes a file atomically (see the module docs). `write` receives a buffered writer; its
/// error, or any error creating, syncing or renaming the file, is returned.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> io::Result<()> {
    if path.as_os_str() == "-" {
        let stdout = io::stdout();
        let mut lock = stdout.lock();
        write(&mut lock)?;
        return lock.flush();
    }
    let file_name = path.file_name().ok_or_else(|| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{}: not a file path", path.display()),
        )
    })?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let (tmp_path, file) = create_temp(&dir, &file_name.to_string_lossy())?;
    let result = fill(file, write, path).and_then(|()| {
        let mut list = pending();
        fs::rename(&tmp_path, path)?;
        forget_pending(&mut list, &tmp_path);
        Ok(())
    });
    if let Err(e) = result {
        let _ = fs::remove_file(&tmp_path);
        forget_pending(&mut pending(), &tmp_path);
        return Err(e);
    }
    sync_dir(&dir);
    Ok(())
}

fn create_temp(dir: &Path, name: &str) -> io::Result<(PathBuf, File)> {
    loop {
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let tmp = dir.join(format!(".{name}.tmp-{}-{n}", std::process::id()));
        let mut list = pending();
        match OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(f) => {
                list.push(tmp.clone());
                return Ok((tmp, f));
            }
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
}

fn fill(
    file: File,
    write: impl FnOnce(&mut dyn Write) -> io::Result<()>,
    target: &Path,
) -> io::Result<()> {
    let mut w = BufWriter::new(file);
    write(&mut w)?;
    let file = w.into_inner().map_err(|e| e.into_error())?;
    if let Ok(meta) = fs::metadata(target) {
        // Keep the permissions of the file being replaced.
        file.set_permissions(meta.permissions())?;
    }
    file.sync_all()
}

#[cfg(unix)]
fn sync_dir(dir: &Path) {
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
}

#[cfg(not(unix))]
fn sync_dir(_dir: &Path) {}

/// Why an [`OutputSet`] refused its outputs or could not write them.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutputError {
    /// An output names an input file (the same file, through any path or hard link).
    #[error("{output} {} is the input {}: refusing to overwrite it", path.display(), input.display())]
    IsInput {
        /// The option that names the output (`-o`, `--features`, ...).
        output: String,
        /// The output path as given.
        path: PathBuf,
        /// The input it names.
        input: PathBuf,
    },
    /// Two outputs of the same run name the same file.
    #[error("{first} and {second} both name {}: give each output its own file", path.display())]
    Duplicate {
        /// The first option.
        first: String,
        /// The second option.
        second: String,
        /// The second path as given.
        path: PathBuf,
    },
    /// The output's location cannot hold a file.
    #[error("{output} {}: {why}", path.display())]
    BadLocation {
        /// The option.
        output: String,
        /// The path as given.
        path: PathBuf,
        /// What is wrong with it.
        why: String,
    },
    /// Creating, writing or renaming the file failed (the cause is the error's source).
    #[error("{output} {}", path.display())]
    Io {
        /// The option.
        output: String,
        /// The path as given.
        path: PathBuf,
        /// The cause.
        #[source]
        source: io::Error,
    },
}

/// What identifies a file: device and inode for an existing file (so hard links and
/// symbolic links compare equal), the canonical directory plus the file name for one that
/// does not exist yet.
#[derive(Debug, Clone, PartialEq, Eq)]
enum FileId {
    #[cfg(unix)]
    Inode(u64, u64),
    Path(PathBuf),
}

fn file_id(path: &Path) -> io::Result<FileId> {
    match fs::metadata(path) {
        Ok(_meta) => {
            #[cfg(unix)]
            {
                use std::os::unix::fs::MetadataExt;
                Ok(FileId::Inode(_meta.dev(), _meta.ino()))
            }
            #[cfg(not(unix))]
            {
                Ok(FileId::Path(fs::canonicalize(path)?))
            }
        }
        Err(e) if e.kind() == io::ErrorKind::NotFound => {
            let name = path
                .file_name()
                .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "not a file path"))?;
            let dir = parent_dir(path);
            Ok(FileId::Path(fs::canonicalize(dir)?.join(name)))
        }
        Err(e) => Err(e),
    }
}

/// Whether `path` (output `label`) can be written: a file name, in a directory that exists,
/// not a directory itself. `-` (standard output) always can.
pub fn check_location(label: &str, path: &Path) -> Result<(), OutputError> {
    if path.as_os_str() == "-" {
        return Ok(());
    }
    let bad = |why: String| OutputError::BadLocation {
        output: label.to_string(),
        path: path.to_path_buf(),
        why,
    };
    if path.file_name().is_none() {
        return Err(bad("not a file name".into()));
    }
    let dir = parent_dir(path);
    match fs::metadata(dir) {
        Ok(m) if m.is_dir() => {}
        Ok(_) => return Err(bad(format!("{} is not a directory", dir.display()))),
        Err(_) => {
            return Err(bad(format!(
                "the directory {} does not exist",
                dir.display()
            )))
        }
    }
    if path.is_dir() {
        return Err(bad("is a directory".into()));
    }
    Ok(())
}

fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Whether two paths name the same file: the same device and inode if both exist (hard
/// and symbolic links included), the same canonical directory and file name otherwise.
/// Paths that cannot be resolved are not the same.
pub fn same_file(a: &Path, b: &Path) -> bool {
    match (file_id(a), file_id(b)) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

struct Staged {
    label: String,
    target: PathBuf,
    tmp: Option<PathBuf>,
    file: Option<File>,
}

/// The outputs of one run, written as a transaction (see the module docs).
///
/// ```
/// use tactus_glove::atomic::OutputSet;
/// let dir = tempfile::tempdir().unwrap();
/// let (a, b) = (dir.path().join("a.json"), dir.path().join("b.json"));
/// let mut set = OutputSet::prepare(&[("-o", a.as_path()), ("--features", b.as_path())], &[]).unwrap();
/// set.write(0, b"{}").unwrap();
/// set.write(1, b"[]").unwrap();
/// assert!(!a.exists()); // nothing is visible before commit
/// set.commit().unwrap();
/// assert_eq!(std::fs::read(&b).unwrap(), b"[]");
/// ```
pub struct OutputSet {
    staged: Vec<Staged>,
}

impl OutputSet {
    /// Checks every output (`(option, path)`; the path `-`, standard output, is left to
    /// the caller and skipped here) against `inputs` and against each other, checks that
    /// its directory exists, and creates its temporary file there. Fails before anything
    /// is created if a check fails; removes what it created if a later output fails.
    pub fn prepare(outputs: &[(&str, &Path)], inputs: &[&Path]) -> Result<Self, OutputError> {
        let mut ids: Vec<(FileId, &str)> = Vec::new();
        let input_ids: Vec<(FileId, &Path)> = inputs
            .iter()
            .filter_map(|p| file_id(p).ok().map(|id| (id, *p)))
            .collect();
        for &(label, path) in outputs {
            if path.as_os_str() == "-" {
                continue;
            }
            check_location(label, path)?;
            let bad = |why: String| OutputError::BadLocation {
                output: label.to_string(),
                path: path.to_path_buf(),
                why,
            };
            let id = file_id(path).map_err(|e| bad(e.to_string()))?;
            if let Some((_, input)) = input_ids.iter().find(|(i, _)| *i == id) {
                return Err(OutputError::IsInput {
                    output: label.to_string(),
                    path: path.to_path_buf(),
                    input: input.to_path_buf(),
                });
            }
            if let Some((_, first)) = ids.iter().find(|(i, _)| *i == id) {
                return Err(OutputError::Duplicate {
                    first: first.to_string(),
                    second: label.to_string(),
                    path: path.to_path_buf(),
                });
            }
            ids.push((id, label));
        }
        let mut set = OutputSet { staged: Vec::new() };
        for &(label, path) in outputs {
            let mut st = Staged {
                label: label.to_string(),
                target: path.to_path_buf(),
                tmp: None,
                file: None,
            };
            if path.as_os_str() != "-" {
                let name = path.file_name().unwrap_or_default().to_string_lossy();
                let (tmp, file) =
                    create_temp(parent_dir(path), &name).map_err(|source| OutputError::Io {
                        output: label.to_string(),
                        path: path.to_path_buf(),
                        source,
                    })?;
                st.tmp = Some(tmp);
                st.file = Some(file);
            }
            set.staged.push(st);
        }
        Ok(set)
    }

    /// Number of outputs (as passed to [`OutputSet::prepare`]).
    pub fn len(&self) -> usize {
        self.staged.len()
    }

    /// Whether the set has no outputs.
    pub fn is_empty(&self) -> bool {
        self.staged.is_empty()
    }

    /// Writes the whole content of output `index` into its temporary file and syncs it
    /// (standard output: kept until [`OutputSet::commit`]). Call at most once per output.
    pub fn write(&mut self, index: usize, bytes: &[u8]) -> Result<(), OutputError> {
        let st = &mut self.staged[index];
        let err = |source| OutputError::Io {
            output: st.label.clone(),
            path: st.target.clone(),
            source,
        };
        let Some(file) = st.file.take() else {
            return Err(err(io::Error::other("written twice, or standard output")));
        };
        fill(file, |w| w.write_all(bytes), &st.target).map_err(err)
    }

    /// Renames every temporary over its target. All outputs must have been written.
    /// Returns the first rename error (outputs renamed before it stay in place: a rename
    /// within one directory fails only if the directory changed under us).
    pub fn commit(mut self) -> Result<(), OutputError> {
        self.rename_all()
    }

    fn rename_all(&mut self) -> Result<(), OutputError> {
        let mut list = pending();
        for st in &mut self.staged {
            let Some(tmp) = st.tmp.take() else { continue };
            if let Err(source) = fs::rename(&tmp, &st.target) {
                st.tmp = Some(tmp);
                return Err(OutputError::Io {
                    output: st.label.clone(),
                    path: st.target.clone(),
                    source,
                });
            }
            forget_pending(&mut list, &tmp);
            sync_dir(parent_dir(&st.target));
        }
        Ok(())
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        let mut list = pending();
        for st in &mut self.staged {
            st.file = None;
            if let Some(tmp) = st.tmp.take() {
                let _ = fs::remove_file(&tmp);
                forget_pending(&mut list, &tmp);
            }
        }
    }
}

/// The value `table` pairs with `path`'s extension, compared without case (`None` for a
/// path without one, or one not in the table): how an output's kind follows its name.
pub fn by_extension<T: Copy>(path: &Path, table: &[(&str, T)]) -> Option<T> {
    let ext = path.extension()?.to_str()?;
    table
        .iter()
        .find(|(e, _)| e.eq_ignore_ascii_case(ext))
        .map(|&(_, v)| v)
}
