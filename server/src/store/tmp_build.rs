//! A build's temporary file: `<store>.<pid>.tmp-build` beside the store, renamed over it when
//! complete (so a mapped store is never overwritten in place), removed when the build fails
//! (a full disk, an error, a panic), and removed at the next build when its process was killed.

use std::path::{Path, PathBuf};

/// The temporary file process `pid` builds `path` in: `<path>.<pid>.tmp-build`, so that two
/// processes building the same store never write one file.
pub fn path_for(path: &Path, pid: u32) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".{pid}.tmp-build"));
    path.with_file_name(name)
}

/// A build's temporary file, removed unless the build renamed it into place (a full disk, an
/// error, a panic all leave nothing behind).
pub struct TmpBuild(pub PathBuf);

impl Drop for TmpBuild {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// Removes the temporary files of builds of `path` whose process is gone (killed mid-build).
/// Where processes cannot be looked up (no `/proc`), files older than a day go.
pub fn remove_stale(path: &Path) {
    let (Some(dir), Some(name)) = (path.parent(), path.file_name()) else {
        return;
    };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let prefix = format!("{}.", name.to_string_lossy());
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let file = e.file_name().to_string_lossy().into_owned();
        let Some(pid) = file
            .strip_prefix(&prefix)
            .and_then(|r| r.strip_suffix(".tmp-build"))
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        let gone = if Path::new("/proc/self").exists() {
            !Path::new(&format!("/proc/{pid}")).exists()
        } else {
            e.metadata()
                .and_then(|m| m.modified())
                .is_ok_and(|t| t.elapsed().is_ok_and(|a| a.as_secs() > 86_400))
        };
        if gone {
            tracing::info!("removing {}, left by a build that did not finish", file);
            let _ = std::fs::remove_file(e.path());
        }
    }
}
