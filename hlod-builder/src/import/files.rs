//! The files a model names (external buffers and images): where a `uri`
//! may point, and which files a command reading a model may never write.

use std::path::{Path, PathBuf};

use super::doc;

/// Folders besides a model's own from which its buffers may be read
/// ([`allow_dir`]), canonical.
static ALLOWED_DIRS: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

/// Lets glTF buffer `uri`s name files under `dir` too (the binaries'
/// `--allow-dir`); by default a model reads only files inside its own
/// folder.
pub fn allow_dir(dir: &Path) -> std::io::Result<()> {
    let canon = std::fs::canonicalize(dir)?;
    if !canon.is_dir() {
        return Err(std::io::ErrorKind::NotADirectory.into());
    }
    ALLOWED_DIRS
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .push(canon);
    Ok(())
}

/// The file a buffer's relative `uri` names, resolved against `base_dir`:
/// refused when it leaves that folder (`..`, an absolute path, a link out
/// of it) and no [`allow_dir`] folder holds it, so that a model cannot
/// build any local file into a scene a user may publish.
pub(super) fn resolve_uri(i: usize, uri: &str, base_dir: &Path) -> Result<PathBuf, String> {
    resolve_in(
        &format!("buffers[{i}]: uri"),
        uri,
        &percent_decode(uri),
        base_dir,
    )
}

/// The file `name` (as written in the model: `shown`, after `what`) names
/// in `base_dir`, confined as [`resolve_uri`] confines a `uri` (an OBJ's
/// `mtllib`, which is a path, not a URI).
pub(super) fn resolve_in(
    what: &str,
    shown: &str,
    name: &str,
    base_dir: &Path,
) -> Result<PathBuf, String> {
    let base_dir = if base_dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        base_dir
    };
    let joined = base_dir.join(name);
    let base = std::fs::canonicalize(base_dir)
        .map_err(|e| format!("{what} {shown:?}: the model's folder: {e}"))?;
    // A file that does not exist is its reader's error to report, but only
    // once it is known not to leave the folder by its name alone.
    let target = match std::fs::canonicalize(&joined) {
        Ok(t) => t,
        Err(_) => lexical(&base.join(name)),
    };
    let allowed = ALLOWED_DIRS.lock().unwrap_or_else(|e| e.into_inner());
    if target.starts_with(&base) || allowed.iter().any(|d| target.starts_with(d)) {
        return Ok(target);
    }
    Err(format!(
        "{what} {shown:?} names {}, outside the model's folder {}: a model may only \
         read files beside it (--allow-dir DIR allows another folder)",
        target.display(),
        base.display()
    ))
}

/// `p` with `.` and `..` components folded (no file system access).
fn lexical(p: &Path) -> PathBuf {
    use std::path::Component;
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            let hex = std::str::from_utf8(&b[i + 1..i + 3]).ok();
            if let Some(v) = hex.and_then(|h| u8::from_str_radix(h, 16).ok()) {
                out.push(v);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// The external files a glTF's buffers name (resolved against `base_dir`;
/// one that leaves it is left out, its build refuses it); none for a file
/// that does not parse (its build reports why).
pub fn external_files(bytes: &[u8], base_dir: &Path) -> Vec<PathBuf> {
    external_buffers(bytes, base_dir)
        .into_iter()
        .map(|(p, _)| p)
        .collect()
}

/// [`external_files`] with the bytes each buffer declares (all the importer
/// reads of the file), for keying a build cache by everything the model is
/// made of without reading what it does not use.
pub fn external_buffers(bytes: &[u8], base_dir: &Path) -> Vec<(PathBuf, u64)> {
    let Ok((json, _)) = doc::split(bytes) else {
        return Vec::new();
    };
    let Ok(d) = doc::parse(json) else {
        return Vec::new();
    };
    d.buffers
        .iter()
        .enumerate()
        .filter_map(|(i, b)| Some((i, b.uri.as_deref()?, b.byte_length)))
        .filter(|(_, u, _)| !u.starts_with("data:"))
        .filter_map(|(i, u, len)| Some((resolve_uri(i, u, base_dir).ok()?, len)))
        .collect()
}

/// The files besides the model that its import reads, and how many of
/// their bytes: a glTF's external buffers (their declared length, from its
/// JSON part) or an OBJ's material libraries (whole); none for PLY and
/// STL, nor for a model that does not parse (its reader says why). What a
/// build cache is keyed by besides the model itself.
pub fn read_files(model: &Path) -> Vec<(PathBuf, u64)> {
    let base = model.parent().unwrap_or(Path::new("."));
    match super::Format::of(model) {
        super::Format::Gltf => json_part(model)
            .map(|head| external_buffers(&head, base))
            .unwrap_or_default(),
        super::Format::Obj => material_libraries(model)
            .into_iter()
            .map(|p| (p, u64::MAX))
            .collect(),
        super::Format::Ply | super::Format::Stl | super::Format::Ifc => Vec::new(),
    }
}

/// The material libraries an OBJ file names (`mtllib` lines) that lie in
/// its folder, read line by line.
fn material_libraries(model: &Path) -> Vec<PathBuf> {
    use std::io::BufRead;
    let Ok(f) = engine::infile::open(model) else {
        return Vec::new();
    };
    let base = model.parent().unwrap_or(Path::new("."));
    std::io::BufReader::new(f)
        .split(b'\n')
        .map_while(Result::ok)
        .filter_map(|l| {
            let l = String::from_utf8_lossy(&l).into_owned();
            let name = l.trim().strip_prefix("mtllib")?.trim().to_string();
            resolve_in("mtllib", &name, &name, base).ok()
        })
        .collect()
}

/// Every file a model is made of or names: the model, the files its
/// import reads ([`read_files`]) and a glTF's images (resolved and
/// confined as [`resolve_uri`] does). No output of a command that reads
/// the model may be one of them.
pub fn model_files(model: &Path) -> Vec<PathBuf> {
    let mut out = vec![model.to_path_buf()];
    if super::Format::of(model) != super::Format::Gltf {
        out.extend(read_files(model).into_iter().map(|(p, _)| p));
        return out;
    }
    let Ok(head) = json_part(model) else {
        return out;
    };
    let base = model.parent().unwrap_or(Path::new("."));
    out.extend(external_files(&head, base));
    let images = doc::split(&head)
        .ok()
        .and_then(|(json, _)| doc::parse_images(json).ok())
        .unwrap_or_default();
    out.extend(
        images
            .iter()
            .filter(|u| !u.starts_with("data:"))
            .enumerate()
            .filter_map(|(i, u)| resolve_uri(i, u, base).ok()),
    );
    out
}

/// The part of a model that names its buffers: a `.glb`'s header and JSON
/// chunk, or a whole `.gltf` (bounded reads).
pub fn json_part(path: &Path) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let mut f = engine::infile::open(path)?;
    let mut head = [0u8; 20];
    let n = f.read(&mut head)?;
    if n == 20 && &head[..4] == b"glTF" {
        let json_len = u64::from(u32::from_le_bytes([head[12], head[13], head[14], head[15]]));
        let mut out = head.to_vec();
        f.take(json_len.min(super::max_input_bytes()))
            .read_to_end(&mut out)?;
        // A container cut after its JSON chunk: the length field is patched
        // so that the JSON parses alone.
        let total = out.len() as u32;
        out[8..12].copy_from_slice(&total.to_le_bytes());
        return Ok(out);
    }
    engine::limits::read_bounded(path, super::max_input_bytes())
}
