//! Bounds on what a file may make this crate do before anything is allocated.
//!
//! * **Text inputs** (model JSON, camera / illuminant / reflectance CSVs, measured training CSVs,
//!   chart layouts) are read by `read_text`: regular files, FIFOs and pipes (a shell's
//!   `<(cat m.json)`); a device such as `/dev/zero`, a socket or a directory is refused by
//!   name, before it is opened; at most [`MAX_TEXT_BYTES`] (64 MiB) whatever the file claims,
//!   valid UTF-8, a leading UTF-8 byte-order mark dropped.
//! * **Frames** are bounded by `nsrm_io::Limits` (pixels per frame, `--max-pixels`).

use std::io::{Error, ErrorKind, Read};
use std::path::Path;

/// The largest text input read, in bytes: 64 MiB. A 10⁶-row measured CSV is about 50 MB; real
/// spectral tables and models are kilobytes.
pub const MAX_TEXT_BYTES: u64 = 64 << 20;

/// What a path is, for messages: `a directory`, `a FIFO`, `a character device`, …
pub fn file_kind(meta: &std::fs::Metadata) -> &'static str {
    let t = meta.file_type();
    if t.is_file() {
        return "a regular file";
    }
    if t.is_dir() {
        return "a directory";
    }
    if t.is_symlink() {
        return "a symbolic link";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    "not a regular file"
}

/// A file's identity, `(device, inode)`, where the platform has one (Unix); `None` elsewhere.
/// Two paths with the same identity are one file (a hard link, a symbolic link resolved): how
/// the batch planner and the `nsrm` command's output session tell an output from an input.
#[cfg(unix)]
pub fn file_id(meta: &std::fs::Metadata) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    Some((meta.dev(), meta.ino()))
}

/// A file's identity, `(device, inode)`, where the platform has one (Unix); `None` elsewhere.
#[cfg(not(unix))]
pub fn file_id(_: &std::fs::Metadata) -> Option<(u64, u64)> {
    None
}

/// An [`std::io::Error`] saying `path` is not a regular file (and what it is).
pub fn not_regular(meta: &std::fs::Metadata) -> Error {
    Error::new(
        ErrorKind::InvalidInput,
        format!("not a regular file (it is {})", file_kind(meta)),
    )
}

/// Checks that `path` is a regular file (following symlinks) without opening it, so a FIFO is
/// never opened (which would block) and a device never read.
pub fn check_regular(path: &Path) -> std::io::Result<std::fs::Metadata> {
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(not_regular(&meta));
    }
    Ok(meta)
}

/// Whether a text input may be read from `meta`'s file: a regular file, or a FIFO / pipe
/// (streamed, with the same size cap); never a device, socket or directory.
fn readable_text(meta: &std::fs::Metadata) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if meta.file_type().is_fifo() {
            return true;
        }
    }
    meta.is_file()
}

/// Reads a text input: a regular file or a FIFO / pipe, of at most `cap` bytes, UTF-8, with a
/// leading byte-order mark removed. The errors are plain [`std::io::Error`]s whose message says
/// what is wrong (`not a regular file or pipe (it is a character device)`, `larger than the 64
/// MiB limit for text inputs`, …); callers add the path.
pub fn read_text_capped(path: &Path, cap: u64) -> std::io::Result<String> {
    let not_text = |meta: &std::fs::Metadata| {
        Error::new(
            ErrorKind::InvalidInput,
            format!("not a regular file or pipe (it is {})", file_kind(meta)),
        )
    };
    let meta = std::fs::metadata(path)?;
    if !readable_text(&meta) {
        return Err(not_text(&meta));
    }
    let file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    if !readable_text(&meta) {
        return Err(not_text(&meta));
    }
    let too_big = || {
        Error::new(
            ErrorKind::InvalidData,
            format!("larger than the {} limit for text inputs", human_bytes(cap)),
        )
    };
    if meta.len() > cap {
        return Err(too_big());
    }
    // The size can change after the check: read at most cap + 1 bytes whatever it says.
    let mut bytes = Vec::new();
    bytes
        .try_reserve_exact(meta.len().min(cap) as usize)
        .map_err(|_| Error::new(ErrorKind::OutOfMemory, "not enough memory to read it"))?;
    file.take(cap + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > cap {
        return Err(too_big());
    }
    let mut text = String::from_utf8(bytes).map_err(|e| {
        Error::new(
            ErrorKind::InvalidData,
            format!(
                "not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        )
    })?;
    if text.starts_with('\u{feff}') {
        text.drain(..'\u{feff}'.len_utf8());
    }
    Ok(text)
}

/// [`read_text_capped`] with [`MAX_TEXT_BYTES`].
pub fn read_text(path: &Path) -> std::io::Result<String> {
    read_text_capped(path, MAX_TEXT_BYTES)
}

/// `64 MiB`, `1.5 GiB`, `512 bytes`.
pub fn human_bytes(n: u64) -> String {
    const UNITS: [&str; 4] = ["KiB", "MiB", "GiB", "TiB"];
    if n < 1024 {
        return format!("{n} bytes");
    }
    let mut v = n as f64 / 1024.0;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if v.fract() == 0.0 {
        format!("{v:.0} {}", UNITS[u])
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn caps_and_kinds() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("a.csv");
        std::fs::write(&f, "\u{feff}x,y\n").unwrap();
        assert_eq!(read_text(&f).unwrap(), "x,y\n");
        let e = read_text_capped(&f, 3).unwrap_err();
        assert!(
            e.to_string().contains("larger than the 3 bytes limit"),
            "{e}"
        );
        let e = read_text(dir.path()).unwrap_err();
        assert!(e.to_string().contains("(it is a directory)"), "{e}");
        std::fs::write(&f, [0x66, 0xff, 0x00]).unwrap();
        assert!(read_text(&f).unwrap_err().to_string().contains("not UTF-8"));
        assert_eq!(human_bytes(MAX_TEXT_BYTES), "64 MiB");
        #[cfg(unix)]
        {
            let e = read_text(Path::new("/dev/zero")).unwrap_err();
            assert!(e.to_string().contains("character device"), "{e}");
        }
    }
}
