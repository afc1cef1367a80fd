//! Sets `MAMMAPLAN_VERSION` to the package version and the git commit the build starts
//! from (`0.1.0 (commit 0123456789ab)`), so that every folder a command writes names the
//! code that wrote it ([`plan::VERSION`]). Uncommitted changes are not seen. Outside this
//! workspace's own git checkout (a source tarball, a copy inside another repository) it
//! is the package version alone.

use std::path::{Path, PathBuf};
use std::process::Command;

fn git(root: &Path, args: &[&str]) -> Option<String> {
    let output = Command::new("git")
        .arg("-C")
        .arg(root)
        .args(args)
        .output()
        .ok()?;
    let text = String::from_utf8(output.stdout).ok()?;
    (output.status.success() && !text.trim().is_empty()).then(|| text.trim().to_string())
}

/// The commit of the checkout whose top level is `root`, after asking cargo to rerun
/// when HEAD or a ref moves (a commit, a checkout).
fn commit(root: &Path) -> Option<String> {
    let top = PathBuf::from(git(root, &["rev-parse", "--show-toplevel"])?);
    if top.canonicalize().ok()? != root.canonicalize().ok()? {
        return None;
    }
    let git_dir = PathBuf::from(git(root, &["rev-parse", "--absolute-git-dir"])?);
    let common = git(root, &["rev-parse", "--git-common-dir"]).map(|dir| root.join(dir))?;
    // Only paths that exist: cargo reruns on every build for a missing one.
    for watched in [
        git_dir.join("HEAD"),
        common.join("refs"),
        common.join("packed-refs"),
    ] {
        if watched.exists() {
            println!("cargo:rerun-if-changed={}", watched.display());
        }
    }
    git(root, &["rev-parse", "--short=12", "HEAD"])
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    let manifest = std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default();
    let root = Path::new(&manifest).join("../..");
    let version = std::env::var("CARGO_PKG_VERSION").unwrap_or_default();
    let line = match commit(&root) {
        Some(commit) => format!("{version} (commit {commit})"),
        None => version,
    };
    println!("cargo:rustc-env=MAMMAPLAN_VERSION={line}");
}
