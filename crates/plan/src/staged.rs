//! Output files written all or nothing: each is first written under a temporary name
//! beside its final one, and only when every one has been written are they renamed, in
//! the order they were staged. A failure on the way (a full disk, a folder that turned
//! read-only) removes the temporaries and leaves what was there before untouched, so a
//! folder never holds half of one result and half of another, or a result file that
//! vouches for files that were not written.

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
    pub fn file(&mut self, path: &Path) -> PathBuf {
        let name = path
            .file_name()
            .map(|name| name.to_string_lossy().into_owned())
            .unwrap_or_default();
        let temporary = path.with_file_name(format!(".partial-{}-{name}", std::process::id()));
        self.files.push((temporary.clone(), path.to_path_buf()));
        temporary
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

#[cfg(test)]
mod tests {
    use super::*;

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
