//! Sets `MAMMAPLAN_VERSION` to the package version and the git commit the build starts
//! from (`0.1.0 (commit 0123456789ab)`), so that every folder a command writes names the
//! code that wrote it ([`plan::VERSION`]). Outside a git checkout (a source tarball) it is
//! the package version alone.

use std::path::Path;
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

fn main() {
    let manifest = std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default();
    let root = Path::new(&manifest).join("../..");
    if let Some(git_dir) = git(&root, &["rev-parse", "--absolute-git-dir"]) {
        // A commit or a checkout moves HEAD or a ref: rerun then, and only then.
        for watched in ["HEAD", "refs", "packed-refs"] {
            println!("cargo:rerun-if-changed={git_dir}/{watched}");
        }
    } else {
        println!("cargo:rerun-if-changed=build.rs");
    }
    let version = std::env::var("CARGO_PKG_VERSION").unwrap_or_default();
    let line = match git(&root, &["rev-parse", "--short=12", "HEAD"]) {
        Some(commit) => format!("{version} (commit {commit})"),
        None => version,
    };
    println!("cargo:rustc-env=MAMMAPLAN_VERSION={line}");
}
