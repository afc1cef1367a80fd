//! SHA-256 checksums of a result folder's files: recorded when the folder is written,
//! checked before a later command relies on the folder, so that a damaged or replaced
//! file is refused instead of silently used.

use anyhow::{Context, Result};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::path::Path;

/// Lower-case hexadecimal SHA-256 of each file, by file name within its folder.
pub type Checksums = BTreeMap<String, String>;

/// The lower-case hexadecimal SHA-256 of a file's content.
pub fn file_sha256(path: &Path) -> std::io::Result<String> {
    let mut hasher = Sha256::new();
    std::io::copy(&mut std::fs::File::open(path)?, &mut hasher)?;
    Ok(hasher
        .finalize()
        .iter()
        .map(|byte| format!("{byte:02x}"))
        .collect())
}

/// Checks every file named in `recorded` (the checksums `record` holds) in `folder`.
/// Errors name the file, the record and `rerun`, the command that writes the folder
/// again.
pub fn verify(folder: &Path, recorded: &Checksums, record: &str, rerun: &str) -> Result<()> {
    for (name, expected) in recorded {
        let path = folder.join(name);
        let found = file_sha256(&path).with_context(|| {
            format!(
                "reading {} (the folder is incomplete; run `{rerun}` again)",
                path.display()
            )
        })?;
        anyhow::ensure!(
            &found == expected,
            "{} does not match the checksum {record} recorded when the folder was written: \
             the file was changed or damaged since; run `{rerun}` again",
            path.display()
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The SHA-256 test vector of "abc" (FIPS 180-2, appendix B.1).
    #[test]
    fn the_digest_of_abc_is_the_published_one() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("abc");
        std::fs::write(&path, "abc").unwrap();
        assert_eq!(
            file_sha256(&path).unwrap(),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }

    /// A changed byte and a missing file are both refused, naming the file.
    #[test]
    fn a_changed_or_missing_file_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.vtu");
        std::fs::write(&path, "levels").unwrap();
        let recorded = Checksums::from([("a.vtu".to_string(), file_sha256(&path).unwrap())]);
        verify(dir.path(), &recorded, "model.json", "mammaplan model").unwrap();
        std::fs::write(&path, "levelz").unwrap();
        let changed = verify(dir.path(), &recorded, "model.json", "mammaplan model").unwrap_err();
        assert!(format!("{changed:#}").contains("a.vtu does not match the checksum model.json"));
        std::fs::remove_file(&path).unwrap();
        let missing = verify(dir.path(), &recorded, "model.json", "mammaplan model").unwrap_err();
        assert!(format!("{missing:#}").contains("the folder is incomplete"));
    }
}
