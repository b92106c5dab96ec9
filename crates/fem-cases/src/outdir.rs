//! Output directories written as a unit: what a reader finds at `--out` is always one whole
//! run (the previous one or the new one), never a mix.
//!
//! [`OutDir::begin`] takes a lock beside the target (`.NAME.lock`, holding the process id), so
//! a second writer of the same target fails at once with a message naming the first; it then
//! creates a fresh staging directory beside the target (`.NAME.partial-PID-N`), where every
//! output is written. [`OutDir::commit`] moves the staging directory into place by renames:
//! the previous directory, if any, is first renamed aside (`.NAME.old-PID`), the staging
//! directory renamed to the target, and the old one removed. Dropping an `OutDir` without
//! committing (an error, a blow-up the caller does not keep) removes the staging directory,
//! and [`interrupted`] does the same from a signal handler, so an interrupted run leaves the
//! previous directory untouched. A process killed outright (SIGKILL, power loss) leaves a lock
//! whose process is gone and at most one partial directory: the next writer of the same target
//! removes both, and if the kill fell between the two renames of a commit it first puts the
//! previous directory back.
//!
//! Only fem2d's own output directories are ever replaced: each holds a marker file
//! ([`MARKER`]); an existing non-empty directory without it is refused, so `--out ~` cannot
//! delete a home directory.

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

use fem_scene::SceneError;

/// The file that marks a directory as written by fem2d (and so replaceable by the next run).
pub const MARKER: &str = ".fem2d-output";

/// Staging directories and locks of the output directories being written, for [`interrupted`].
/// A commit holds the mutex while it renames, so an interruption never lands mid-commit.
static ACTIVE: Mutex<Vec<Active>> = Mutex::new(Vec::new());

/// One output directory being written: its staging directory, lock and target.
type Active = (PathBuf, PathBuf, PathBuf);
static COUNTER: AtomicU64 = AtomicU64::new(0);

fn io(path: &Path, what: &str, e: std::io::Error) -> SceneError {
    SceneError::Io(format!("{}: {what}: {e}", path.display()))
}

/// An output directory being written; see the module docs.
#[derive(Debug)]
pub struct OutDir {
    target: PathBuf,
    staging: PathBuf,
    lock: PathBuf,
    done: bool,
}

/// Whether process `pid` is running (always assumed where that cannot be asked).
fn alive(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    if cfg!(target_os = "linux") {
        Path::new("/proc").join(pid.to_string()).exists()
    } else {
        true
    }
}

impl OutDir {
    /// Lock `target`, clean what earlier interrupted writers of it left, check that it is
    /// fem2d's to replace, and create the staging directory. Errors name the path.
    pub fn begin(target: &Path) -> Result<OutDir, SceneError> {
        let target = std::path::absolute(target).map_err(|e| io(target, "bad path", e))?;
        let bad = || {
            SceneError::Usage(format!(
                "--out {}: name a directory (it is replaced as a whole)",
                target.display()
            ))
        };
        let (Some(parent), Some(name)) = (target.parent(), target.file_name()) else {
            return Err(bad());
        };
        let name = name.to_string_lossy().into_owned();
        if name == "." || name == ".." {
            return Err(bad());
        }
        std::fs::create_dir_all(parent)
            .map_err(|e| io(parent, "cannot create the directory", e))?;
        let lock = parent.join(format!(".{name}.lock"));
        // Held from taking the lock to recording it, so an interruption in between still finds
        // (and removes) the lock.
        let mut active = ACTIVE.lock().unwrap_or_else(|p| p.into_inner());
        take_lock(&lock, &target)?;
        let prepared = (|| {
            clean_leftovers(&target, parent, &name)?;
            check_replaceable(&target)?;
            let n = COUNTER.fetch_add(1, Ordering::Relaxed);
            let staging = parent.join(format!(".{name}.partial-{}-{n}", std::process::id()));
            std::fs::create_dir(&staging)
                .map_err(|e| io(&staging, "cannot create the staging directory", e))?;
            if let Err(e) = std::fs::write(staging.join(MARKER), b"written by fem2d\n") {
                let _ = std::fs::remove_dir_all(&staging);
                return Err(io(&staging, "cannot write", e));
            }
            Ok(staging)
        })();
        match prepared {
            Ok(staging) => {
                active.push((staging.clone(), lock.clone(), target.clone()));
                Ok(OutDir {
                    target,
                    staging,
                    lock,
                    done: false,
                })
            }
            Err(e) => {
                let _ = std::fs::remove_file(&lock);
                Err(e)
            }
        }
    }

    /// Where the outputs are written until [`OutDir::commit`].
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// Where they end up.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Put the staging directory in place of the target and release the lock (see the module
    /// docs). On an error the previous directory is back in place.
    pub fn commit(mut self) -> Result<(), SceneError> {
        let mut active = ACTIVE.lock().unwrap_or_else(|p| p.into_inner());
        let old = self.lock.with_file_name(format!(
            ".{}.old-{}",
            self.target
                .file_name()
                .unwrap_or_default()
                .to_string_lossy(),
            std::process::id()
        ));
        let had_old = self.target.exists();
        if had_old {
            std::fs::rename(&self.target, &old)
                .map_err(|e| io(&self.target, "cannot move the previous output aside", e))?;
        }
        if let Err(e) = std::fs::rename(&self.staging, &self.target) {
            if had_old {
                let _ = std::fs::rename(&old, &self.target);
            }
            return Err(io(&self.target, "cannot move the new output into place", e));
        }
        if had_old {
            let _ = std::fs::remove_dir_all(&old);
        }
        let _ = std::fs::remove_file(&self.lock);
        active.retain(|(s, _, _)| s != &self.staging);
        self.done = true;
        Ok(())
    }
}

fn clean_leftovers(target: &Path, parent: &Path, name: &str) -> Result<(), SceneError> {
    let partial = format!(".{name}.partial-");
    let old = format!(".{name}.old-");
    let entries = std::fs::read_dir(parent).map_err(|e| io(parent, "cannot list", e))?;
    // The caller holds the lock, so no live process is writing any of these.
    let mut olds = Vec::new();
    let mut partials = Vec::new();
    for entry in entries.flatten() {
        let file = entry.file_name().to_string_lossy().into_owned();
        if file.starts_with(&partial) {
            partials.push(entry.path());
        } else if file.starts_with(&old) {
            olds.push(entry.path());
        }
    }
    // A commit killed between its two renames: the previous output goes back in place.
    if !target.exists()
        && let Some(o) = olds.pop()
    {
        std::fs::rename(&o, target).map_err(|e| io(&o, "cannot restore the previous output", e))?;
    }
    for p in partials.iter().chain(&olds) {
        std::fs::remove_dir_all(p).map_err(|e| io(p, "cannot remove a leftover", e))?;
    }
    Ok(())
}

fn check_replaceable(t: &Path) -> Result<(), SceneError> {
    let Ok(meta) = std::fs::symlink_metadata(t) else {
        return Ok(());
    };
    if !meta.is_dir() {
        return Err(SceneError::Usage(format!(
            "--out {}: exists and is not a directory",
            t.display()
        )));
    }
    if t.join(MARKER).is_file() {
        return Ok(());
    }
    let mut entries = std::fs::read_dir(t).map_err(|e| io(t, "cannot list", e))?;
    match entries.next() {
        None => Ok(()),
        Some(first) => Err(SceneError::Usage(format!(
            "--out {}: holds files fem2d did not write (`{}`); choose a new or empty directory",
            t.display(),
            first
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .unwrap_or_default()
        ))),
    }
}

/// Take the lock file: the process id is written to a private file first and hard-linked to
/// the lock's name, so the lock appears with its content in one step (a link fails when the
/// name exists). A lock whose process is gone (or unreadable and over a minute old) is removed
/// and the link tried once more.
fn take_lock(lock: &Path, target: &Path) -> Result<(), SceneError> {
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let mine = lock.with_extension(format!("lock.{}-{n}", std::process::id()));
    std::fs::write(&mine, format!("{}\n", std::process::id()))
        .map_err(|e| io(&mine, "cannot create the lock", e))?;
    let result = (|| {
        for _ in 0..2 {
            match std::fs::hard_link(&mine, lock) {
                Ok(()) => return Ok(()),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    let owner = std::fs::read_to_string(lock)
                        .ok()
                        .and_then(|s| s.trim().parse::<u32>().ok());
                    let old = std::fs::metadata(lock)
                        .and_then(|m| m.modified())
                        .ok()
                        .and_then(|t| t.elapsed().ok())
                        .is_some_and(|age| age > std::time::Duration::from_secs(60));
                    let busy = match owner {
                        Some(pid) => alive(pid),
                        None => !old,
                    };
                    if busy {
                        return Err(SceneError::Usage(format!(
                            "{}: another fem2d process (pid {}) is writing it; wait for it or \
                             choose another --out (if no such process runs, remove {})",
                            target.display(),
                            owner.map_or_else(|| "unknown".to_owned(), |p| p.to_string()),
                            lock.display()
                        )));
                    }
                    let _ = std::fs::remove_file(lock);
                }
                Err(e) => return Err(io(lock, "cannot create the lock", e)),
            }
        }
        Err(SceneError::Usage(format!(
            "{}: another fem2d process is writing it; wait for it or choose another --out",
            target.display()
        )))
    })();
    let _ = std::fs::remove_file(&mine);
    result
}

impl Drop for OutDir {
    fn drop(&mut self) {
        if !self.done {
            abandon(&self.staging, &self.lock);
        }
    }
}

/// Remove an uncommitted staging directory and its lock, and forget them (a drop before the
/// commit: an error, a blow-up the caller does not keep).
fn abandon(staging: &Path, lock: &Path) {
    let mut active = ACTIVE.lock().unwrap_or_else(|p| p.into_inner());
    let _ = std::fs::remove_dir_all(staging);
    let _ = std::fs::remove_file(lock);
    active.retain(|(s, _, _)| s != staging);
}

/// Remove a staging directory: renamed first, so that files created in it by path from now on
/// fail instead of keeping it non-empty, then removed.
fn remove_staging(staging: &Path) {
    let mut trash = staging.to_path_buf().into_os_string();
    trash.push(".removing");
    let trash = PathBuf::from(trash);
    if std::fs::rename(staging, &trash).is_ok() {
        let _ = std::fs::remove_dir_all(&trash);
    } else {
        let _ = std::fs::remove_dir_all(staging);
    }
}

/// Remove the staging directories and locks of every output directory being written, and
/// return the targets they were for (left as they were). For a signal handler, which then
/// exits: the lock on the list is kept, so no commit starts afterwards.
pub fn interrupted() -> Vec<PathBuf> {
    let active = ACTIVE.lock().unwrap_or_else(|p| p.into_inner());
    let mut targets = Vec::new();
    for (staging, lock, target) in active.iter() {
        remove_staging(staging);
        let _ = std::fs::remove_file(lock);
        targets.push(target.clone());
    }
    // The interrupted threads keep running until the process exits, and one may be creating
    // a file or a subdirectory in the staging directory right now (recreating it): look again
    // a few times.
    for _ in 0..5 {
        std::thread::sleep(std::time::Duration::from_millis(2));
        for (staging, _, _) in active.iter() {
            if staging.exists() {
                remove_staging(staging);
            }
        }
    }
    std::mem::forget(active);
    targets
}

/// Prefix of the hidden staging subdirectory of a [`FilesInto`].
const FILES_STAGING: &str = ".fem2d-staging-";

/// Several files written into a directory that also holds other files (`fem2d merge` beside
/// the shard files it reads, `fem2d figures` into `docs/figures`), all or none: the same lock
/// as [`OutDir`] (so no other fem2d writer of that directory runs at the same time), the files
/// written into a hidden staging subdirectory (`.fem2d-staging-PID-N`), and moved into the
/// directory by one rename each only when every one was written. An error, a drop or an
/// interruption ([`interrupted`]) removes the staging subdirectory and leaves the directory's
/// files as they were; one left by a killed process is removed by the next writer.
#[derive(Debug)]
pub struct FilesInto {
    target: PathBuf,
    staging: PathBuf,
    lock: PathBuf,
    done: bool,
}

impl FilesInto {
    /// Lock `target` (created if missing), remove leftover staging subdirectories and create a
    /// fresh one. Errors name the path.
    pub fn begin(target: &Path) -> Result<FilesInto, SceneError> {
        let target = std::path::absolute(target).map_err(|e| io(target, "bad path", e))?;
        let (Some(parent), Some(name)) = (target.parent(), target.file_name()) else {
            return Err(SceneError::Usage(format!(
                "--out {}: name a directory",
                target.display()
            )));
        };
        let name = name.to_string_lossy().into_owned();
        if let Ok(meta) = std::fs::symlink_metadata(&target)
            && !meta.is_dir()
        {
            return Err(SceneError::Usage(format!(
                "--out {}: exists and is not a directory",
                target.display()
            )));
        }
        std::fs::create_dir_all(&target)
            .map_err(|e| io(&target, "cannot create the directory", e))?;
        let lock = parent.join(format!(".{name}.lock"));
        let mut active = ACTIVE.lock().unwrap_or_else(|p| p.into_inner());
        take_lock(&lock, &target)?;
        let prepared = (|| {
            // The lock is held, so every staging subdirectory found is a killed writer's.
            let entries = std::fs::read_dir(&target).map_err(|e| io(&target, "cannot list", e))?;
            for entry in entries.flatten() {
                if entry
                    .file_name()
                    .to_string_lossy()
                    .starts_with(FILES_STAGING)
                {
                    let p = entry.path();
                    std::fs::remove_dir_all(&p)
                        .map_err(|e| io(&p, "cannot remove a leftover", e))?;
                }
            }
            let n = COUNTER.fetch_add(1, Ordering::Relaxed);
            let staging = target.join(format!("{FILES_STAGING}{}-{n}", std::process::id()));
            std::fs::create_dir(&staging)
                .map_err(|e| io(&staging, "cannot create the staging directory", e))?;
            Ok(staging)
        })();
        match prepared {
            Ok(staging) => {
                active.push((staging.clone(), lock.clone(), target.clone()));
                Ok(FilesInto {
                    target,
                    staging,
                    lock,
                    done: false,
                })
            }
            Err(e) => {
                let _ = std::fs::remove_file(&lock);
                Err(e)
            }
        }
    }

    /// Where the files are written until [`FilesInto::commit`].
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// Move every file of the staging subdirectory into the directory (`last`, if given, is
    /// moved after all others, so its presence means the others are there), remove the
    /// staging subdirectory and release the lock. A name that exists in the directory as
    /// anything but a regular file (a directory, a symbolic link, a device) is refused before
    /// anything is moved.
    pub fn commit(mut self, last: Option<&str>) -> Result<(), SceneError> {
        let mut names: Vec<std::ffi::OsString> = std::fs::read_dir(&self.staging)
            .map_err(|e| io(&self.staging, "cannot list", e))?
            .flatten()
            .map(|e| e.file_name())
            .collect();
        names.sort();
        if let Some(last) = last
            && let Some(k) = names.iter().position(|n| n == last)
        {
            let n = names.remove(k);
            names.push(n);
        }
        for name in &names {
            let dest = self.target.join(name);
            if let Ok(meta) = std::fs::symlink_metadata(&dest)
                && !meta.file_type().is_file()
            {
                return Err(SceneError::Usage(format!(
                    "{}: exists and is not a regular file; fem2d replaces regular files only",
                    dest.display()
                )));
            }
        }
        let mut active = ACTIVE.lock().unwrap_or_else(|p| p.into_inner());
        for name in &names {
            let dest = self.target.join(name);
            std::fs::rename(self.staging.join(name), &dest)
                .map_err(|e| io(&dest, "cannot move into place", e))?;
        }
        let _ = std::fs::remove_dir_all(&self.staging);
        let _ = std::fs::remove_file(&self.lock);
        active.retain(|(s, _, _)| s != &self.staging);
        self.done = true;
        Ok(())
    }
}

impl Drop for FilesInto {
    fn drop(&mut self) {
        if !self.done {
            abandon(&self.staging, &self.lock);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("fem2d-outdir-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn files_into_moves_all_files_or_none() {
        let d = scratch("files").join("out");
        std::fs::create_dir_all(&d).unwrap();
        std::fs::write(d.join("shard-0-of-1.json"), "kept").unwrap();
        std::fs::write(d.join("a.txt"), "old").unwrap();
        // Dropped before commit: nothing changes, no staging subdirectory remains.
        let f = FilesInto::begin(&d).unwrap();
        std::fs::write(f.path().join("a.txt"), "new").unwrap();
        drop(f);
        assert_eq!(std::fs::read_to_string(d.join("a.txt")).unwrap(), "old");
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 2);
        // Committed: every file is in place and the others are untouched.
        let f = FilesInto::begin(&d).unwrap();
        std::fs::write(f.path().join("a.txt"), "new").unwrap();
        std::fs::write(f.path().join("b.txt"), "new").unwrap();
        f.commit(Some("a.txt")).unwrap();
        assert_eq!(std::fs::read_to_string(d.join("a.txt")).unwrap(), "new");
        assert_eq!(std::fs::read_to_string(d.join("b.txt")).unwrap(), "new");
        assert_eq!(
            std::fs::read_to_string(d.join("shard-0-of-1.json")).unwrap(),
            "kept"
        );
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 3);
        assert!(!d.with_file_name(".out.lock").exists());
    }

    #[test]
    fn files_into_refuses_to_replace_what_is_not_a_regular_file_and_leaves_all_as_it_was() {
        let d = scratch("special").join("out");
        std::fs::create_dir_all(d.join("b.txt")).unwrap();
        let f = FilesInto::begin(&d).unwrap();
        std::fs::write(f.path().join("a.txt"), "new").unwrap();
        std::fs::write(f.path().join("b.txt"), "new").unwrap();
        let e = f.commit(None).unwrap_err().to_string();
        assert!(
            e.contains("b.txt") && e.contains("not a regular file"),
            "{e}"
        );
        assert!(!d.join("a.txt").exists());
        assert!(d.join("b.txt").is_dir());
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1);
    }

    #[test]
    fn files_into_removes_a_killed_writers_staging_and_respects_a_live_lock() {
        let d = scratch("killed").join("out");
        std::fs::create_dir_all(d.join(".fem2d-staging-999999999-0")).unwrap();
        std::fs::write(d.join(".fem2d-staging-999999999-0/x"), "x").unwrap();
        let f = FilesInto::begin(&d).unwrap();
        assert_eq!(
            std::fs::read_dir(&d).unwrap().count(),
            1,
            "only the new staging"
        );
        // This process holds the lock, so a second writer of the same directory is refused.
        let e = FilesInto::begin(&d).unwrap_err().to_string();
        assert!(e.contains("another fem2d process"), "{e}");
        drop(f);
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 0);
    }
}
