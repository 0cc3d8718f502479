//! The server's private copy of a store.
//!
//! A mapped file is shared with everyone who can open it: truncating it under the server
//! makes the next read of a vanished page a SIGBUS, and overwriting it changes the heights
//! the server serves (both after the checksums were verified at open). So the server maps a
//! copy instead: an unnamed file (Linux `O_TMPFILE`; elsewhere a file removed right after it
//! is created) in a scratch folder, with no write permission, that only this process holds
//! open. Nothing can open it by name, so nothing can truncate or change it, short of a
//! privileged process writing through `/proc/PID/fd`. It disappears when the server exits.
//!
//! The copy costs the store's size on the scratch folder's disk and one read of the file at
//! start (`copy_file_range`, a reflink on file systems that have them). The checksums are
//! verified on the copy, so a store that changed during the copy is refused, not served.

use std::fs::File;
use std::io::{Seek, SeekFrom};
use std::path::Path;

/// Copies `path` into an unnamed, read-only file in `scratch` (created if missing), and
/// returns it positioned at its start.
pub fn copy(path: &Path, scratch: &Path) -> std::io::Result<File> {
    let mut src = File::open(path)?;
    std::fs::create_dir_all(scratch)?;
    let mut dst = tempfile::tempfile_in(scratch)?;
    std::io::copy(&mut src, &mut dst)?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        dst.set_permissions(std::fs::Permissions::from_mode(0o400))?;
    }
    dst.seek(SeekFrom::Start(0))?;
    Ok(dst)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    #[test]
    fn the_copy_is_unnamed_read_only_and_outlives_changes_to_the_original() {
        let dir = tempfile::tempdir().unwrap();
        let orig = dir.path().join("a.relief");
        std::fs::write(&orig, b"0123456789").unwrap();
        let scratch = dir.path().join("scratch");
        let mut c = copy(&orig, &scratch).unwrap();
        // Nothing named in the scratch folder.
        assert_eq!(std::fs::read_dir(&scratch).unwrap().count(), 0);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            assert_eq!(c.metadata().unwrap().permissions().mode() & 0o777, 0o400);
        }
        std::fs::write(&orig, b"x").unwrap();
        let mut s = String::new();
        c.read_to_string(&mut s).unwrap();
        assert_eq!(s, "0123456789");
    }
}
