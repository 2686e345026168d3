//! How a rep is coloured ([`Colouring`]) and which of its triangles are
//! drawn opaque or x-rayed ([`Parts`], from [`engine::hide::DrawParts`]).

use std::collections::HashMap;
use std::ops::Range;

use engine::format::RepKind;
use engine::hide::DrawParts;
use engine::skeleton::RepId;

/// How reps are coloured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Colouring {
    /// The scene's own per-vertex colours.
    #[default]
    Object,
    /// By position in the node's rep list (coarse to fine).
    LodLevel,
    /// HLODs orange, LODs blue.
    Kind,
    /// Reps drawn in place of a missing front rep red, the rest grey.
    Substituted,
}

impl Colouring {
    /// Parses `object`, `lod`, `kind` or `substituted`.
    pub fn parse(s: &str) -> Result<Self, String> {
        match s {
            "object" => Ok(Self::Object),
            "lod" => Ok(Self::LodLevel),
            "kind" => Ok(Self::Kind),
            "substituted" => Ok(Self::Substituted),
            _ => Err(format!(
                "unknown colouring {s:?}: use object, lod, kind or substituted"
            )),
        }
    }

    /// The debug tint of a rep of `level` and `kind` (`substitute`: drawn
    /// for a missing one): rgb, and how much of it replaces the vertex
    /// colour.
    pub(crate) fn tint(self, level: u16, kind: u16, substitute: bool) -> [f32; 4] {
        const LEVELS: [[f32; 3]; 6] = [
            [0.20, 0.40, 0.95],
            [0.15, 0.75, 0.85],
            [0.25, 0.80, 0.30],
            [0.90, 0.85, 0.20],
            [0.95, 0.55, 0.15],
            [0.90, 0.20, 0.20],
        ];
        let rgb = match self {
            Colouring::Object => return [0.0; 4],
            Colouring::LodLevel => LEVELS[usize::from(level).min(LEVELS.len() - 1)],
            Colouring::Kind if kind == RepKind::Hlod as u16 => [0.95, 0.55, 0.15],
            Colouring::Kind => [0.25, 0.45, 0.90],
            Colouring::Substituted if substitute => [0.95, 0.10, 0.10],
            Colouring::Substituted => [0.60, 0.60, 0.60],
        };
        [rgb[0], rgb[1], rgb[2], 1.0]
    }
}

/// The shader's fade direction that marks an x-rayed draw (`mesh.wgsl`).
pub(crate) const XRAY_DIRECTION: f32 = 3.0;

/// Reps drawn other than whole and opaque, by rep.
#[derive(Debug, Default)]
pub(crate) struct Parts {
    opaque: HashMap<RepId, Vec<Range<u32>>>,
    xray: HashMap<RepId, Vec<Range<u32>>>,
}

impl Parts {
    pub(crate) fn new(p: &DrawParts) -> Self {
        Self {
            opaque: p.opaque.iter().cloned().collect(),
            xray: p.xray.iter().cloned().collect(),
        }
    }

    /// The triangles of `rep` drawn opaque (`None`: all of them).
    pub(crate) fn opaque(&self, rep: RepId) -> Option<&[Range<u32>]> {
        self.opaque.get(&rep).map(Vec::as_slice)
    }

    /// The triangles of `rep` drawn x-rayed (`None`: none).
    pub(crate) fn xray(&self, rep: RepId) -> Option<&[Range<u32>]> {
        self.xray.get(&rep).map(Vec::as_slice)
    }

    /// Whether any rep is x-rayed.
    pub(crate) fn any_xray(&self) -> bool {
        !self.xray.is_empty()
    }
}
