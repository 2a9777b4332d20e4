//! Output files that never destroy what they should not and never leave
//! half a file behind (docs/reliability.md).
//!
//! - [`check_outputs`] runs before any work: each output's directory exists
//!   and is writable, its extension is one the command writes, it is not an
//!   input (same canonical path or same inode) nor another output.
//! - [`write_atomically`] fills a temporary file beside the target, gives it
//!   the mode a plain `create` would (0666 minus the umask) or the mode of
//!   the file it replaces, fsyncs it, renames it over the target and fsyncs
//!   the directory. Temporary files are registered so that a SIGINT or
//!   SIGTERM ([`remove_temporaries`], called by the CLI's handler) and every
//!   error path remove them.
//! - `-` as an output path means standard output ([`Dest::Stdout`]).

use anyhow::{anyhow, bail, Context, Result};
use std::collections::HashSet;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Temporary files being written now: removed on a signal.
static TEMPORARIES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn register(p: &Path) {
    TEMPORARIES
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .push(p.to_path_buf());
}

fn unregister(p: &Path) {
    let mut t = TEMPORARIES.lock().unwrap_or_else(|e| e.into_inner());
    t.retain(|q| q != p);
}

/// Removes every temporary file being written (for a signal handler or a
/// panic hook: the process is about to exit).
pub fn remove_temporaries() {
    // try_lock: a handler must not wait on a thread it interrupted.
    let list = match TEMPORARIES.try_lock() {
        Ok(mut t) => std::mem::take(&mut *t),
        Err(std::sync::TryLockError::Poisoned(p)) => std::mem::take(&mut *p.into_inner()),
        Err(std::sync::TryLockError::WouldBlock) => {
            // Briefly held by register/unregister; retry a few times.
            let mut got = None;
            for _ in 0..100 {
                std::thread::sleep(std::time::Duration::from_millis(1));
                if let Ok(mut t) = TEMPORARIES.try_lock() {
                    got = Some(std::mem::take(&mut *t));
                    break;
                }
            }
            got.unwrap_or_default()
        }
    };
    for p in list {
        let _ = std::fs::remove_file(p);
    }
}

/// Where an output goes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Dest {
    File(PathBuf),
    Stdout,
}

impl Dest {
    pub fn new(p: &Path) -> Dest {
        if p.as_os_str() == "-" {
            Dest::Stdout
        } else {
            Dest::File(p.to_path_buf())
        }
    }
    pub fn display(&self) -> String {
        match self {
            Dest::File(p) => p.display().to_string(),
            Dest::Stdout => "standard output".into(),
        }
    }
}

/// One output a command will write.
#[derive(Clone, Debug)]
pub struct Output<'a> {
    /// How the command line names it, e.g. `-o` or `--stats`.
    pub flag: &'a str,
    pub path: &'a Path,
    /// Extensions it may have (lower case, without the dot).
    pub extensions: &'a [&'a str],
    /// Whether `-` (standard output) is allowed.
    pub stdout: bool,
}

impl<'a> Output<'a> {
    /// The output an optional flag names, if it was given.
    pub fn optional(
        flag: &'a str,
        path: &'a Option<std::path::PathBuf>,
        extensions: &'a [&'a str],
        stdout: bool,
    ) -> Option<Output<'a>> {
        path.as_deref().map(|path| Output {
            flag,
            path,
            extensions,
            stdout,
        })
    }
}

/// The lower-case extension of `p`.
pub fn extension(p: &Path) -> Option<String> {
    p.extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
}

/// A name for a file that may not exist yet: the canonical parent joined
/// with the file name.
fn canonical(p: &Path) -> Option<PathBuf> {
    if let Ok(c) = p.canonicalize() {
        return Some(c);
    }
    let parent = match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    Some(parent.canonicalize().ok()?.join(p.file_name()?))
}

#[cfg(unix)]
fn inode(p: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(p).ok().map(|m| (m.dev(), m.ino()))
}

#[cfg(not(unix))]
fn inode(_: &Path) -> Option<(u64, u64)> {
    None
}

/// The directory a file `p` would be created in.
fn dir_of(p: &Path) -> &Path {
    match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// A file's identity: its canonical path and its (device, inode).
type FileId = (Option<PathBuf>, Option<(u64, u64)>);

/// Checks every output before work starts (see the module doc). `inputs`
/// are the files the command reads.
pub fn check_outputs(outputs: &[Output], inputs: &[&Path]) -> Result<()> {
    let mut seen: Vec<(String, FileId)> = Vec::new();
    let mut stdout_used: Option<&str> = None;
    let input_ids: Vec<FileId> = inputs.iter().map(|p| (canonical(p), inode(p))).collect();
    for o in outputs {
        let shown = o.path.display();
        if o.path.as_os_str() == "-" {
            if !o.stdout {
                bail!("{} -: this output cannot go to standard output", o.flag);
            }
            if let Some(other) = stdout_used {
                bail!("{other} and {} both write to standard output", o.flag);
            }
            stdout_used = Some(o.flag);
            continue;
        }
        match extension(o.path) {
            Some(e) if o.extensions.contains(&e.as_str()) => {}
            _ => bail!(
                "{shown}: {} writes {}; name the file with that extension",
                o.flag,
                list(o.extensions)
            ),
        }
        if o.path.is_dir() {
            bail!("{shown}: is a directory ({} needs a file name)", o.flag);
        }
        let dir = dir_of(o.path);
        if !dir.is_dir() {
            bail!(
                "{shown}: directory {} does not exist ({})",
                dir.display(),
                o.flag
            );
        }
        // The one sure test of writability: create a file there (then it goes).
        tempfile::Builder::new()
            .prefix(".whitted-check-")
            .tempfile_in(dir)
            .map_err(|e| anyhow!("{shown}: cannot create files in {}: {e}", dir.display()))?;
        let id = (canonical(o.path), inode(o.path));
        for (i, input) in inputs.iter().enumerate() {
            let same_path = id.0.is_some() && id.0 == input_ids[i].0;
            let same_file = id.1.is_some() && id.1 == input_ids[i].1;
            if same_path || same_file {
                bail!(
                    "{shown}: {} would overwrite the input {}",
                    o.flag,
                    input.display()
                );
            }
        }
        for (flag, (path, ino)) in &seen {
            if (id.0.is_some() && id.0 == *path) || (id.1.is_some() && id.1 == *ino) {
                bail!("{shown}: {} and {flag} name the same file", o.flag);
            }
        }
        seen.push((o.flag.to_string(), id));
    }
    Ok(())
}

fn list(exts: &[&str]) -> String {
    let v: Vec<String> = exts.iter().map(|e| format!(".{e}")).collect();
    match v.len() {
        0 => String::new(),
        1 => v[0].clone(),
        n => format!("{} or {}", v[..n - 1].join(", "), v[n - 1]),
    }
}

/// Writes `path` atomically (see the module doc): `body` fills a temporary
/// file beside it, renamed over `path` only when `body` succeeds.
pub fn write_atomically(
    path: &Path,
    body: impl FnOnce(&mut std::io::BufWriter<&std::fs::File>) -> Result<()>,
) -> Result<()> {
    let dir = dir_of(path);
    let mut builder = tempfile::Builder::new();
    builder.prefix(".whitted-");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        // Created 0666 minus the umask, as a plain create would be.
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let tmp = builder.tempfile_in(dir).map_err(|e| {
        anyhow!(
            "{}: cannot create a file in {}: {e}",
            path.display(),
            dir.display()
        )
    })?;
    register(tmp.path());
    let tmp_path = tmp.path().to_path_buf();
    let result = (|| -> Result<()> {
        {
            let mut w = std::io::BufWriter::new(tmp.as_file());
            body(&mut w)?;
            w.flush()
                .map_err(|e| anyhow!("{}: cannot write: {e}", path.display()))?;
        }
        // Test hook (docs/reliability.md): hold the written temporary file
        // this long before the rename, so a test can interrupt the write.
        if let Some(ms) = std::env::var("WHITTED_TEST_WRITE_DELAY_MS")
            .ok()
            .and_then(|v| v.parse::<u64>().ok())
        {
            std::thread::sleep(std::time::Duration::from_millis(ms));
        }
        if let Ok(m) = std::fs::metadata(path) {
            // Replacing a file keeps its mode.
            let _ = tmp.as_file().set_permissions(m.permissions());
        }
        tmp.as_file()
            .sync_all()
            .map_err(|e| anyhow!("{}: cannot write: {e}", path.display()))?;
        Ok(())
    })();
    if let Err(e) = result {
        drop(tmp); // removes the temporary file
        unregister(&tmp_path);
        return Err(e);
    }
    let persisted = tmp.persist(path);
    unregister(&tmp_path);
    persisted.map_err(|e| anyhow!("{}: cannot write: {}", path.display(), e.error))?;
    if let Ok(d) = std::fs::File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// Writes `bytes` to `dest` (a file, atomically, or standard output).
pub fn write_bytes(dest: &Dest, bytes: &[u8]) -> Result<()> {
    match dest {
        Dest::File(p) => write_atomically(p, |w| {
            w.write_all(bytes)
                .map_err(|e| anyhow!("{}: cannot write: {e}", p.display()))
        }),
        Dest::Stdout => {
            let mut out = std::io::stdout().lock();
            out.write_all(bytes)
                .and_then(|_| out.flush())
                .context("cannot write to standard output")
        }
    }
}

/// Every distinct path in `paths` once, in order.
pub fn unique(paths: impl IntoIterator<Item = PathBuf>) -> Vec<PathBuf> {
    let mut seen = HashSet::new();
    paths
        .into_iter()
        .filter(|p| seen.insert(p.clone()))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn out<'a>(flag: &'a str, path: &'a Path, ext: &'a [&'a str]) -> Output<'a> {
        Output {
            flag,
            path,
            extensions: ext,
            stdout: false,
        }
    }

    #[test]
    fn outputs_are_checked_against_inputs_and_each_other() {
        let d = tempfile::tempdir().unwrap();
        let scene = d.path().join("s.toml");
        std::fs::write(&scene, "x").unwrap();
        let png = d.path().join("a.png");
        // fine
        check_outputs(&[out("-o", &png, &["png"])], &[&scene]).unwrap();
        // the scene itself, by another spelling
        let other = d.path().join(".").join("s.toml");
        let e = check_outputs(&[out("--stats", &other, &["json", "toml"])], &[&scene]);
        assert!(e
            .unwrap_err()
            .to_string()
            .contains("would overwrite the input"));
        // a hard link to the scene
        let link = d.path().join("link.json");
        std::fs::hard_link(&scene, &link).unwrap();
        let e = check_outputs(&[out("--stats", &link, &["json"])], &[&scene]);
        assert!(e
            .unwrap_err()
            .to_string()
            .contains("would overwrite the input"));
        // two outputs naming one file
        let e = check_outputs(
            &[out("-o", &png, &["png"]), out("--diff", &png, &["png"])],
            &[&scene],
        );
        assert!(e.unwrap_err().to_string().contains("name the same file"));
        // wrong extension, missing directory
        let e = check_outputs(&[out("-o", &scene, &["png", "exr"])], &[]);
        assert!(e.unwrap_err().to_string().contains("writes .png or .exr"));
        let missing = d.path().join("no/such/x.png");
        let e = check_outputs(&[out("-o", &missing, &["png"])], &[]);
        assert!(e.unwrap_err().to_string().contains("does not exist"));
        // nothing left behind by the writability probe
        let names: Vec<_> = std::fs::read_dir(d.path()).unwrap().collect();
        assert_eq!(names.len(), 2);
    }

    #[cfg(unix)]
    #[test]
    fn atomic_writes_keep_modes_and_leave_nothing_on_error() {
        use std::os::unix::fs::PermissionsExt;
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("x.txt");
        write_atomically(&p, |w| Ok(w.write_all(b"one")?)).unwrap();
        let mode = std::fs::metadata(&p).unwrap().permissions().mode() & 0o777;
        assert_ne!(mode, 0o600, "a new file gets 0666 minus the umask");
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o640)).unwrap();
        write_atomically(&p, |w| Ok(w.write_all(b"two")?)).unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        let mode = std::fs::metadata(&p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o640, "replacing a file keeps its mode");
        let e = write_atomically(&p, |_| bail!("encoder failed"));
        assert!(e.is_err());
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 1);
        assert!(TEMPORARIES.lock().unwrap().is_empty());
    }
}
