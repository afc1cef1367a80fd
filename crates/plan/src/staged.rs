//! Output files written all or nothing: each is first written under a temporary name
//! beside its final one, and only when every one has been written are they renamed, in
//! the order they were staged. A failure on the way (a full disk, a folder that turned
//! read-only) removes the temporaries and leaves what was there before untouched, so a
//! folder never holds half of one result and half of another, or a result file that
//! vouches for files that were not written. A result of several steps that read each
//! other's files ([`FolderUpdate`]: the demo, a report's folder) moves what it replaces
//! aside instead, and puts it back on failure.

use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

/// Files staged for one result; dropped without [`Staged::commit`], it removes them.
#[derive(Debug, Default)]
pub struct Staged {
    /// Temporary and final path of each staged file, in staging order.
    files: Vec<(PathBuf, PathBuf)>,
}

impl Staged {
    pub fn new() -> Staged {
        Staged::default()
    }

    /// The temporary path to write `path`'s content to. It keeps `path`'s extension,
    /// which the writers read the format from.
    fn file(&mut self, path: &Path) -> PathBuf {
        let name = path
            .file_name()
            .map(|name| name.to_string_lossy().into_owned())
            .unwrap_or_default();
        let temporary = path.with_file_name(format!(".partial-{}-{name}", std::process::id()));
        self.files.push((temporary.clone(), path.to_path_buf()));
        temporary
    }

    /// Writes `path`'s new content with `write`, given the temporary path to write to;
    /// an error names `path`.
    pub fn write<E: Into<anyhow::Error>>(
        &mut self,
        path: &Path,
        write: impl FnOnce(&Path) -> std::result::Result<(), E>,
    ) -> Result<()> {
        let temporary = self.file(path);
        write(&temporary)
            .map_err(Into::into)
            .with_context(|| format!("writing {}", path.display()))
    }

    /// The checksums of the files staged so far (which must all have been written), by
    /// their final names.
    pub fn checksums(&self) -> Result<crate::checksum::Checksums> {
        self.files
            .iter()
            .map(|(temporary, path)| {
                let name = path
                    .file_name()
                    .map(|name| name.to_string_lossy().into_owned())
                    .unwrap_or_default();
                let sha256 = crate::checksum::file_sha256(temporary)
                    .with_context(|| format!("reading back the new {}", path.display()))?;
                Ok((name, sha256))
            })
            .collect()
    }

    /// Renames every staged file to its final name, in staging order (so the file that
    /// vouches for the others goes last).
    pub fn commit(mut self) -> Result<()> {
        for (temporary, path) in std::mem::take(&mut self.files) {
            std::fs::rename(&temporary, &path)
                .with_context(|| format!("moving the new {} into place", path.display()))?;
        }
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        for (temporary, _) in &self.files {
            let _ = std::fs::remove_file(temporary);
        }
    }
}

/// A result made of several entries of one folder (files and sub-folders) whose steps
/// read each other's output under their final names, so they cannot be staged under
/// temporary ones: the entries it replaces are moved aside before it starts and put back
/// if it is dropped without [`FolderUpdate::commit`], its own new entries removed. A
/// folder it created is removed again if left empty.
#[derive(Debug)]
pub struct FolderUpdate {
    folder: PathBuf,
    /// `folder/.previous-<pid>`, holding the replaced entries until the commit.
    aside: PathBuf,
    /// The entries taken over so far (moved aside if they existed).
    entries: Vec<String>,
    created_folder: bool,
    committed: bool,
}

impl FolderUpdate {
    /// Starts an update of `entries` (names within `folder`), creating `folder` if needed.
    pub fn begin(folder: &Path, entries: &[&str]) -> Result<FolderUpdate> {
        let created_folder = !folder.exists();
        std::fs::create_dir_all(folder)
            .with_context(|| format!("creating {}", folder.display()))?;
        let mut update = FolderUpdate {
            folder: folder.to_path_buf(),
            aside: folder.join(format!(".previous-{}", std::process::id())),
            entries: Vec::with_capacity(entries.len()),
            created_folder,
            committed: false,
        };
        for &entry in entries {
            let path = folder.join(entry);
            if path.symlink_metadata().is_ok() {
                std::fs::create_dir_all(&update.aside)
                    .with_context(|| format!("creating {}", update.aside.display()))?;
                std::fs::rename(&path, update.aside.join(entry))
                    .with_context(|| format!("moving the previous {} aside", path.display()))?;
            }
            update.entries.push(entry.to_string());
        }
        Ok(update)
    }

    /// Keeps the new entries and deletes the replaced ones.
    pub fn commit(mut self) -> Result<()> {
        self.committed = true;
        if self.aside.exists() {
            std::fs::remove_dir_all(&self.aside)
                .with_context(|| format!("removing {}", self.aside.display()))?;
        }
        Ok(())
    }
}

/// Removes a file or a folder with its content, if there is one.
fn remove_entry(path: &Path) -> std::io::Result<()> {
    match path.symlink_metadata() {
        Ok(metadata) if metadata.is_dir() => std::fs::remove_dir_all(path),
        Ok(_) => std::fs::remove_file(path),
        Err(_) => Ok(()),
    }
}

impl Drop for FolderUpdate {
    fn drop(&mut self) {
        if self.committed {
            return;
        }
        for entry in &self.entries {
            let path = self.folder.join(entry);
            let _ = remove_entry(&path);
            let previous = self.aside.join(entry);
            if previous.symlink_metadata().is_ok() {
                let _ = std::fs::rename(&previous, &path);
            }
        }
        let _ = std::fs::remove_dir(&self.aside);
        if self.created_folder {
            let _ = std::fs::remove_dir(&self.folder);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Dropped half way, an update leaves the folder as it was (an old entry back in
    /// place, a new one gone, no folder it created); committed, the new entries stay and
    /// the old ones are gone.
    #[test]
    fn a_folder_update_is_kept_whole_or_undone() {
        let dir = tempfile::tempdir().unwrap();
        let folder = dir.path().join("demo");
        let entries = ["model", "report.html"];
        {
            let _update = FolderUpdate::begin(&folder, &entries).unwrap();
            std::fs::create_dir(folder.join("model")).unwrap();
            std::fs::write(folder.join("model/model.json"), "new").unwrap();
        }
        assert!(!folder.exists());

        std::fs::create_dir_all(folder.join("model")).unwrap();
        std::fs::write(folder.join("model/model.json"), "old").unwrap();
        std::fs::write(folder.join("notes.txt"), "mine").unwrap();
        {
            let _update = FolderUpdate::begin(&folder, &entries).unwrap();
            assert!(!folder.join("model").exists());
            std::fs::create_dir(folder.join("model")).unwrap();
            std::fs::write(folder.join("model/model.json"), "new").unwrap();
            std::fs::write(folder.join("report.html"), "new").unwrap();
        }
        let read = |name: &str| std::fs::read_to_string(folder.join(name)).unwrap();
        assert_eq!(read("model/model.json"), "old");
        assert!(!folder.join("report.html").exists());
        assert_eq!(read("notes.txt"), "mine");
        assert_eq!(std::fs::read_dir(&folder).unwrap().count(), 2);

        let update = FolderUpdate::begin(&folder, &entries).unwrap();
        std::fs::create_dir(folder.join("model")).unwrap();
        std::fs::write(folder.join("model/model.json"), "new").unwrap();
        std::fs::write(folder.join("report.html"), "new").unwrap();
        update.commit().unwrap();
        assert_eq!(read("model/model.json"), "new");
        assert_eq!(read("report.html"), "new");
        assert_eq!(std::fs::read_dir(&folder).unwrap().count(), 3);
    }

    /// Committed, the files appear under their names; dropped half way, nothing of the
    /// new result is left and the old file is untouched.
    #[test]
    fn files_appear_together_or_not_at_all() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.ply"), dir.path().join("b.json"));
        std::fs::write(&b, "old").unwrap();
        {
            let mut staged = Staged::new();
            std::fs::write(staged.file(&a), "new a").unwrap();
            let _ = staged.file(&b); // the write of b "fails": never written
        }
        assert!(!a.exists());
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);

        let mut staged = Staged::new();
        std::fs::write(staged.file(&a), "new a").unwrap();
        std::fs::write(staged.file(&b), "new b").unwrap();
        staged.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "new a");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "new b");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }
}
