//! IFC through IfcOpenShell: `ifc2glb.py` (embedded here) runs in a Python
//! that has IfcOpenShell and writes the model as a GLB, one node per
//! `IfcProduct` with a shape, named `Class:Name:GlobalId` with its GlobalId,
//! type, name and storey in its extras; that file is then opened as any
//! glTF (so opening voids and spaces are left out by default, as for a BIM
//! export), and removed once open.
//!
//! The Python is `$HLOD_PYTHON`, else `target/ifc-venv/bin/python` beside
//! the executable's build folder (what `scripts/setup.sh` installs), else
//! `python3`. Without IfcOpenShell the error says how to install it.

use std::path::{Path, PathBuf};
use std::process::Command;

use super::ImportError;

const SCRIPT: &str = include_str!("ifc2glb.py");

/// How to get IfcOpenShell, said when it is missing.
const INSTALL: &str = "IFC files are read with IfcOpenShell: install it with `python3 -m pip \
     install ifcopenshell` (in a virtual environment), or run scripts/setup.sh, which installs it \
     in target/ifc-venv; HLOD_PYTHON names the Python to use";

/// The Python to run the converter with.
fn python() -> PathBuf {
    if let Some(p) = std::env::var_os("HLOD_PYTHON") {
        return PathBuf::from(p);
    }
    // `target/<profile>/hlod-build` (or `…/deps/…` for tests): the venv
    // that setup.sh makes in `target/`.
    if let Ok(exe) = std::env::current_exe() {
        for dir in exe.ancestors().skip(1).take(3) {
            let venv = dir.join("ifc-venv/bin/python");
            if venv.is_file() {
                return venv;
            }
        }
    }
    PathBuf::from("python3")
}

/// Converts `path` to a GLB in a temporary file (deleted when the handle is
/// dropped; an open reader keeps its data).
pub fn convert(path: &Path) -> Result<tempfile::NamedTempFile, ImportError> {
    let fail = |what: String| ImportError::Invalid {
        path: path.to_path_buf(),
        what,
    };
    // The model is read by the converter, so it is checked here as every
    // input is: a regular file (a FIFO would hang IfcOpenShell).
    engine::infile::open_with_meta(path).map_err(|source| ImportError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let out = tempfile::Builder::new()
        .prefix(".hlod-ifc-")
        .suffix(".glb")
        .tempfile()
        .map_err(|e| fail(format!("IFC: cannot make a temporary file: {e}")))?;
    let py = python();
    let run = Command::new(&py)
        .arg("-c")
        .arg(SCRIPT)
        .arg(path)
        .arg(out.path())
        .output();
    let run = match run {
        Ok(r) => r,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(ImportError::Unsupported {
                path: path.to_path_buf(),
                what: format!("{} not found. {INSTALL}", py.display()),
            });
        }
        Err(e) => return Err(fail(format!("IFC: cannot run {}: {e}", py.display()))),
    };
    let said = String::from_utf8_lossy(&run.stderr);
    let last = said
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .unwrap_or("");
    match run.status.code() {
        Some(0) => Ok(out),
        Some(3) => Err(ImportError::Unsupported {
            path: path.to_path_buf(),
            what: format!("{} has no IfcOpenShell. {INSTALL}", py.display()),
        }),
        Some(4) => Err(fail(format!("IFC: {last}"))),
        Some(5) => Err(ImportError::NoTriangles {
            path: path.to_path_buf(),
            why: "IFC: no product in the file has a shape".into(),
        }),
        _ => Err(fail(format!(
            "IFC: IfcOpenShell failed ({}): {last}",
            run.status
        ))),
    }
}
