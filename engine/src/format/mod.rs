//! The versioned on-disk scene format (version 5; versions 1 to 4 are still
//! read).
//!
//! ```text
//! offset 0      FileHeader (256 B; 192 B in versions 2-4, 128 B in version 1),
//!               zero-padded to BLOCK
//! BLOCK         rep payloads back to back: a mesh rep on the next REP_ALIGN
//!               (16 B) boundary, a view-dependence tree on the next BLOCK
//!               (versions 1 and 2: every rep on a BLOCK); zero-padded to BLOCK
//! data end      skeleton: [NodeRecord; node_count] [RepRecord; rep_count]
//! skeleton end  object section (version 2, may be empty): names and extras
//!               of the source objects, for picking (see [`objects`])
//! objects end   walk section (version 5, may be empty): solid space as
//!               column spans, for walking (see [`walk`])
//! ```
//!
//! The header carries the magic, the version, the section ranges, the world
//! position of the scene's origin (version 2: coordinates are stored relative
//! to it in `f32`, so survey-coordinate models keep millimetres) and three
//! CRC-32s (header, skeleton, object section). Each [`RepRecord`] names its payload's byte range and
//! CRC-32, so one rep can be read and checked alone, and reading the skeleton
//! never touches rep data. The skeleton sits after the data so that the builder
//! streams reps to disk as it makes them; the header is written last.
//!
//! All integers are little-endian; every record is `repr(C)` with its size
//! asserted at compile time.

mod codec;
pub mod objects;
mod reader;
mod rep;
pub mod walk;
mod writer;

pub use codec::{REPZ_MAGIC, expand_payload, is_compressed};
pub use reader::{
    SceneFile, SceneMeta, check_rep_crc, check_vdt_record, read_walk_chunk_at, walk_index_of,
};
pub use rep::{PackedVertex, REP_MAGIC, RepHeader, RepMesh, quantize_unit_normal};
pub use writer::{RepLocation, SceneWriter};

pub use crate::records::*;

use crate::skeleton::ValidationError;

impl From<std::io::Error> for FormatError {
    fn from(e: std::io::Error) -> Self {
        Self::Io(e)
    }
}

/// Errors from reading or writing a scene file.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    /// The message includes the I/O error's, so it is not also a source
    /// (an `anyhow` chain would print it twice).
    #[error("I/O error: {0}")]
    Io(std::io::Error),
    #[error("not a scene file (bad magic {0:02x?})")]
    BadMagic([u8; 8]),
    #[error(
        "unsupported format version {found} (this build reads {OLDEST_VERSION} to {VERSION}): rebuild the scene with this hlod-build"
    )]
    UnsupportedVersion { found: u32 },
    #[error("file truncated: {what} needs bytes up to {need}, file has {have}")]
    Truncated {
        what: &'static str,
        need: u64,
        have: u64,
    },
    #[error("checksum mismatch in {what}: stored {stored:08x}, computed {computed:08x}")]
    Checksum {
        what: String,
        stored: u32,
        computed: u32,
    },
    #[error("corrupt header: {0}")]
    BadHeader(String),
    #[error("rep {rep}: {reason}")]
    BadRep { rep: u32, reason: String },
    #[error("invalid hierarchy: {0}")]
    Invalid(#[from] ValidationError),
    #[error("scene too large for the format: {0}")]
    TooLarge(String),
    /// What the file claims needs more memory than this machine has.
    #[error("{0}")]
    TooLargeForMachine(String),
}

#[cfg(test)]
mod tests;
