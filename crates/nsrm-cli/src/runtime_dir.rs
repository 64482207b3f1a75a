//! A private `XDG_RUNTIME_DIR` for this process when the variable is unset (GPU commands).

/// Mesa's Vulkan loader prints `error: XDG_RUNTIME_DIR is invalid or not set` (twice) when the
/// variable is unset, which reads as a failure in batch logs. When it is unset (or names no
/// directory), this process gets a private one: `nsrm-runtime-UID` under the temporary directory,
/// created with mode 0700 (an existing one is used only if it is a directory owned by this user
/// with that mode), and `XDG_RUNTIME_DIR` is set for this process only, once, before any
/// adapter is looked for. Nothing is changed when the variable already names a directory.
///
/// The binary calls it first thing, while it has one thread (changing the environment later
/// would race with threads reading it); the library itself never touches the environment.
pub(crate) fn ensure_runtime_dir() {
    if std::env::var_os("XDG_RUNTIME_DIR").is_some_and(|d| std::path::Path::new(&d).is_dir()) {
        return;
    }
    if let Some(dir) = private_runtime_dir() {
        std::env::set_var("XDG_RUNTIME_DIR", dir);
    }
}

#[cfg(unix)]
fn private_runtime_dir() -> Option<std::path::PathBuf> {
    use std::os::unix::fs::{DirBuilderExt, MetadataExt, PermissionsExt};
    let uid = std::fs::metadata("/proc/self").map(|m| m.uid()).ok()?;
    let dir = std::env::temp_dir().join(format!("nsrm-runtime-{uid}"));
    match std::fs::DirBuilder::new().mode(0o700).create(&dir) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
        Err(_) => return None,
    }
    let m = std::fs::symlink_metadata(&dir).ok()?;
    (m.is_dir() && m.uid() == uid && m.permissions().mode() & 0o777 == 0o700).then_some(dir)
}

#[cfg(not(unix))]
fn private_runtime_dir() -> Option<std::path::PathBuf> {
    None
}
