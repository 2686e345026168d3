//! Sharded builds: `hlod-build build --shard i/n` makes the nodes under one
//! share of the scene graph and writes them to a shard file; `hlod-build
//! merge` reads the `n` shard files, makes the nodes above their subtrees
//! and writes the scene, byte-identical to a single job's build.
//!
//! Every job computes the same graph from the input (clustering is
//! deterministic and needs only sizes and boxes). The graph is cut into `n`
//! shares of subtrees of about equal input triangles ([`shard_plan`]); a
//! node's reps depend only on its subtree, so a shard job makes exactly the
//! reps a single job would. The shard file carries those reps, the nodes'
//! records, the merged leaves' runs, and its subtree roots' coarsest reps as
//! floats (what their parents' HLODs are made from: exact, so the merge's
//! HLODs are the single job's). Shard files are keyed by the input's bytes
//! and the parameters ([`crate::cache::key`]) and carry a BLAKE3 digest of
//! their header and everything after it; the merge refuses a file of
//! another input, another count, a shard given twice or one missing, and a
//! shard whose bytes do not match its digest, and checks the merged scene
//! as `hlod-build info` does before it replaces anything. (A digest proves
//! the shard is what its job wrote, not that the job ran this builder: one
//! who holds the input can forge a shard and its digest; run shards only
//! where their files are trusted.)
//!
//! A shard file: the scene format's data section (reps from byte 4096),
//! then a trailer of records; its first block holds [`ShardHeader`].

use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use engine::FormatError;
use engine::format::objects::Run;
use engine::format::{NodeRecord, RepRecord};
use engine::io::{ByteSource, FileSource};

use super::assemble::Coarse;
use super::{BuildError, BuildParams, BuildStats, Prepared, RunOptions, Staged, cells};
use crate::mesh::Mesh;

/// Which share of the graph a job makes: `index` of `count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShardSpec {
    pub index: u32,
    pub count: u32,
}

/// The most shards a build is split into.
pub const MAX_SHARDS: u32 = 4096;

impl std::str::FromStr for ShardSpec {
    type Err = String;
    /// `i/n`, with `0 <= i < n <= 4096`.
    fn from_str(s: &str) -> Result<Self, String> {
        let bad =
            || format!("--shard {s:?}: expected I/N with 0 <= I < N <= {MAX_SHARDS}, e.g. 0/4");
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let index: u32 = i.trim().parse().map_err(|_| bad())?;
        let count: u32 = n.trim().parse().map_err(|_| bad())?;
        if count == 0 || count > MAX_SHARDS || index >= count {
            return Err(bad());
        }
        Ok(Self { index, count })
    }
}

const MAGIC: [u8; 8] = *b"HLODSHRD";
/// Version 2 adds the digest.
const VERSION: u32 = 2;

/// The first bytes of a shard file.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ShardHeader {
    magic: [u8; 8],
    version: u32,
    index: u32,
    count: u32,
    trailer_crc: u32,
    /// [`crate::cache::key`] of the input and parameters (32 hex digits).
    key: [u8; 32],
    trailer_offset: u64,
    trailer_len: u64,
    /// BLAKE3 of this header (with this field zero) and of the file from
    /// [`engine::records::BLOCK`] to the trailer's end ([`digest_of`]).
    digest: [u8; 32],
}
const _: () = assert!(std::mem::size_of::<ShardHeader>() == 104);

/// The digest of a shard file whose header is `h`, read from `src`.
fn digest_of(src: &dyn ByteSource, h: &ShardHeader) -> std::io::Result<[u8; 32]> {
    let mut head = *h;
    head.digest = [0; 32];
    let mut hasher = blake3::Hasher::new();
    hasher.update(bytemuck::bytes_of(&head));
    let end = h
        .trailer_offset
        .checked_add(h.trailer_len)
        .filter(|&e| e <= src.len() && h.trailer_offset >= engine::records::BLOCK)
        .ok_or_else(|| {
            std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                "truncated: the trailer runs past the file's end",
            )
        })?;
    let mut buf = vec![0u8; 1 << 20];
    let mut at = engine::records::BLOCK;
    while at < end {
        let n = (end - at).min(buf.len() as u64) as usize;
        src.read_at(at, &mut buf[..n])?;
        hasher.update(&buf[..n]);
        at += n as u64;
    }
    Ok(*hasher.finalize().as_bytes())
}

/// The subtree roots each shard makes, and the nodes above them all (the
/// merge's), deepest first.
pub(super) fn shard_plan(prep: &Prepared, count: u32) -> (Vec<Vec<usize>>, Vec<usize>) {
    let n = count.max(1) as u64;
    let total = cells::subtree_tris(&prep.tree, &prep.item_tris)
        .first()
        .copied()
        .unwrap_or(0);
    // Cells of a quarter share, dealt out by where their middle falls.
    let p = cells::plan(
        &prep.tree,
        &prep.item_tris,
        total.div_ceil(4 * n).max(1),
        &[0],
    );
    let mut shards = vec![Vec::new(); n as usize];
    let mut before = 0u64;
    for cell in &p.cells {
        let mid = before + cell.tris / 2;
        let s = ((u128::from(mid) * u128::from(n)) / u128::from(total.max(1)))
            .min(u128::from(n - 1)) as usize;
        shards[s].extend(&cell.roots);
        before += cell.tris;
    }
    (shards, p.upper)
}

/// Appends little-endian values, with a running CRC.
struct Out<W: Write> {
    w: W,
    crc: crc32fast::Hasher,
    len: u64,
}

impl<W: Write> Out<W> {
    fn bytes(&mut self, b: &[u8]) -> std::io::Result<()> {
        self.crc.update(b);
        self.len += b.len() as u64;
        self.w.write_all(b)
    }
    fn u32(&mut self, v: u32) -> std::io::Result<()> {
        self.bytes(&v.to_le_bytes())
    }
    fn u64(&mut self, v: u64) -> std::io::Result<()> {
        self.bytes(&v.to_le_bytes())
    }
}

/// Reads what [`Out`] wrote, every length checked.
struct In<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> In<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.b.len());
        let end = end.ok_or_else(|| format!("the trailer ends early (at byte {})", self.at))?;
        let s = &self.b[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(
            self.take(4)?.try_into().expect("4 bytes"),
        ))
    }
    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().expect("8 bytes"),
        ))
    }
    /// `n` Pod records (copied: the trailer has no alignment).
    fn records<T: bytemuck::Pod>(&mut self, n: u64) -> Result<Vec<T>, String> {
        let size = std::mem::size_of::<T>();
        let bytes = usize::try_from(n)
            .ok()
            .and_then(|n| n.checked_mul(size))
            .ok_or("a count past the trailer")?;
        let raw = self.take(bytes)?;
        Ok(raw
            .chunks_exact(size)
            .map(bytemuck::pod_read_unaligned)
            .collect())
    }
}

/// What a shard file holds, read back.
struct ShardData {
    /// Each node made: its index, record and reps (offsets into the shard file).
    nodes: Vec<(usize, NodeRecord, Vec<RepRecord>)>,
    runs: Vec<(u32, Vec<Run>)>,
    roots: Vec<(usize, Coarse)>,
    mt_objects: u64,
    vdt_objects: u64,
}

/// Builds shard `spec` of `input` into the shard file `output` (atomically).
pub fn build_shard_file(
    input: &Path,
    output: &Path,
    params: &BuildParams,
    opts: &RunOptions<'_>,
    spec: ShardSpec,
) -> Result<BuildStats, BuildError> {
    params.check()?;
    // Shards store every placement's levels: the merge does not share them.
    let params = &BuildParams {
        share_instances: false,
        ..*params
    };
    let inputs = crate::import::model_files(input);
    let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let out = engine_cli::outfile::OutputFile::create(output, &inputs)?;
    let key = crate::cache::key(input, params)?;
    let opened = crate::import::open(input)?;
    let write_err = |source| BuildError::Write {
        path: output.to_path_buf(),
        source,
    };
    let staged = |e: Staged| match e {
        Staged::Format(f) => write_err(f),
        Staged::Memory(m) => BuildError::Memory(m),
    };
    let mut stats = BuildStats::default();
    let prep = super::prepare(&opened, params, opts, &mut stats).map_err(staged)?;
    let (shards, _) = shard_plan(&prep, spec.count);
    let plan = cells::plan(
        &prep.tree,
        &prep.item_tris,
        prep.mplan.cell_tris,
        &shards[spec.index as usize],
    );
    stats.cells = plan.cells.len() as u64;
    let file = out.file().try_clone().map_err(|e| write_err(e.into()))?;
    let mut asm = super::assembly(
        &prep,
        BufWriter::with_capacity(1 << 20, file),
        params,
        opts,
        &mut stats,
    )
    .map_err(write_err)?;
    super::make_nodes(&mut asm, &opened, &plan).map_err(write_err)?;
    let made: Vec<usize> = plan
        .cells
        .iter()
        .flat_map(|c| c.leaves.iter().chain(&c.interior))
        .chain(&plan.upper)
        .copied()
        .collect();
    let super::assemble::Assembly {
        writer,
        nodes,
        node_reps,
        leaf_runs,
        coarse,
        ..
    } = asm;
    let (mut w, end) = writer.into_inner().map_err(write_err)?;
    let io = |e: std::io::Error| write_err(e.into());
    w.seek(SeekFrom::Start(end)).map_err(io)?;
    let mut t = Out {
        w: &mut w,
        crc: crc32fast::Hasher::new(),
        len: 0,
    };
    let mut write = || -> std::io::Result<()> {
        t.u64(made.len() as u64)?;
        for &i in &made {
            t.u32(i as u32)?;
            t.bytes(bytemuck::bytes_of(&nodes[i]))?;
            t.u32(node_reps[i].len() as u32)?;
            t.bytes(bytemuck::cast_slice(&node_reps[i]))?;
        }
        t.u64(leaf_runs.len() as u64)?;
        for (node, runs) in &leaf_runs {
            t.u32(*node)?;
            t.u32(runs.len() as u32)?;
            t.bytes(bytemuck::cast_slice(runs))?;
        }
        let roots = &shards[spec.index as usize];
        t.u64(roots.len() as u64)?;
        for &r in roots {
            let c = coarse[r]
                .as_ref()
                .expect("a made root keeps its coarse rep");
            t.u32(r as u32)?;
            t.bytes(&c.error.to_le_bytes())?;
            t.u32(c.mesh.vertex_count() as u32)?;
            t.u32(c.mesh.indices.len() as u32)?;
            t.bytes(bytemuck::cast_slice(&c.mesh.positions))?;
            t.bytes(bytemuck::cast_slice(&c.mesh.normals))?;
            t.bytes(bytemuck::cast_slice(&c.mesh.colors))?;
            t.bytes(bytemuck::cast_slice(&c.mesh.indices))?;
        }
        t.u64(stats.mt_objects)?;
        t.u64(stats.vdt_objects)
    };
    write().map_err(io)?;
    let mut header = ShardHeader {
        magic: MAGIC,
        version: VERSION,
        index: spec.index,
        count: spec.count,
        trailer_crc: t.crc.finalize(),
        key: [0; 32],
        trailer_offset: end,
        trailer_len: t.len,
        digest: [0; 32],
    };
    header.key.copy_from_slice(&key.as_bytes()[..32]);
    w.flush().map_err(io)?;
    drop(w);
    let written = FileSource::from_file(out.file().try_clone().map_err(io)?).map_err(io)?;
    header.digest = digest_of(&written, &header).map_err(io)?;
    let mut w = out.file();
    w.seek(SeekFrom::Start(0)).map_err(io)?;
    w.write_all(bytemuck::bytes_of(&header)).map_err(io)?;
    w.flush().map_err(io)?;
    out.commit()?;
    stats.nodes = made.len() as u64;
    stats.file_bytes = file_len(output)?;
    stats.peak_heap = crate::heap::peak();
    Ok(stats)
}

/// A shard file's header, checked against the merge's key.
fn read_header(path: &Path, key: &str) -> Result<ShardHeader, String> {
    let mut f = engine::infile::open(path).map_err(|e| format!("cannot read: {e}"))?;
    let mut b = [0u8; std::mem::size_of::<ShardHeader>()];
    f.read_exact(&mut b)
        .map_err(|_| "not a shard file (too short)".to_string())?;
    parse_header(&b, key)
}

/// [`read_header`] on the header's bytes.
fn parse_header(
    b: &[u8; std::mem::size_of::<ShardHeader>()],
    key: &str,
) -> Result<ShardHeader, String> {
    let h: ShardHeader = bytemuck::pod_read_unaligned(b);
    if h.magic != MAGIC {
        return Err("not a shard file (written by `hlod-build build --shard I/N`)".into());
    }
    if h.version != VERSION {
        return Err(format!(
            "shard file version {}, this build reads {VERSION}",
            h.version
        ));
    }
    if key.as_bytes().get(..32) != Some(&h.key[..]) {
        return Err(
            "was built from another input or with other parameters than this merge's".into(),
        );
    }
    if h.count == 0 || h.count > MAX_SHARDS || h.index >= h.count {
        return Err(format!(
            "shard {}/{} is not a valid share",
            h.index, h.count
        ));
    }
    Ok(h)
}

/// What the shard file holds, its digest checked first.
fn read_data(src: &dyn ByteSource, h: &ShardHeader, tree_len: usize) -> Result<ShardData, String> {
    let end = h.trailer_offset.checked_add(h.trailer_len);
    if end.is_none_or(|e| e > src.len()) || h.trailer_len > usize::MAX as u64 {
        return Err("truncated: the trailer runs past the file's end".into());
    }
    if digest_of(src, h).map_err(|e| format!("cannot read: {e}"))? != h.digest {
        return Err(
            "its bytes do not match its digest (damaged, or altered after its job wrote it)".into(),
        );
    }
    let mut bytes = vec![0u8; h.trailer_len as usize];
    src.read_at(h.trailer_offset, &mut bytes)
        .map_err(|e| format!("cannot read the trailer: {e}"))?;
    if crc32fast::hash(&bytes) != h.trailer_crc {
        return Err("the trailer fails its checksum".into());
    }
    let mut r = In { b: &bytes, at: 0 };
    let node = |v: u32| -> Result<usize, String> {
        ((v as usize) < tree_len)
            .then_some(v as usize)
            .ok_or_else(|| format!("node {v} is not in this scene's graph of {tree_len}"))
    };
    let mut d = ShardData {
        nodes: Vec::new(),
        runs: Vec::new(),
        roots: Vec::new(),
        mt_objects: 0,
        vdt_objects: 0,
    };
    for _ in 0..r.u64()? {
        let i = node(r.u32()?)?;
        let rec = r.records::<NodeRecord>(1)?[0];
        let n = r.u32()?;
        let reps = r.records::<RepRecord>(u64::from(n))?;
        if reps
            .iter()
            .any(|x| x.extent() > src.len() || x.offset > src.len() - x.extent())
        {
            return Err(format!("node {i}: a rep lies past the file's end"));
        }
        d.nodes.push((i, rec, reps));
    }
    for _ in 0..r.u64()? {
        let n = r.u32()?;
        let k = r.u32()?;
        d.runs.push((n, r.records::<Run>(u64::from(k))?));
    }
    for _ in 0..r.u64()? {
        let i = node(r.u32()?)?;
        let error = f32::from_le_bytes(r.take(4)?.try_into().expect("4 bytes"));
        let (nv, ni) = (u64::from(r.u32()?), u64::from(r.u32()?));
        let mesh = Mesh {
            positions: r.records(nv)?,
            normals: r.records(nv)?,
            colors: r.records(nv)?,
            indices: r.records(ni)?,
        };
        if mesh.indices.iter().any(|&k| u64::from(k) >= nv) {
            return Err(format!("node {i}: a coarse rep's index is out of range"));
        }
        d.roots.push((i, Coarse { mesh, error }));
    }
    d.mt_objects = r.u64()?;
    d.vdt_objects = r.u64()?;
    if r.at != bytes.len() {
        return Err("bytes after the trailer's records".into());
    }
    Ok(d)
}

/// Merges the shard files of `input` into the scene `output` (atomically):
/// the nodes above the shards' subtrees are made here, and every rep is
/// copied in the spatial layout.
pub fn merge_files(
    input: &Path,
    shard_files: &[PathBuf],
    output: &Path,
    params: &BuildParams,
    opts: &RunOptions<'_>,
) -> Result<BuildStats, BuildError> {
    params.check()?;
    let params = &BuildParams {
        share_instances: false,
        ..*params
    };
    if !params.spatial_layout {
        return Err(BuildError::Params(
            "a merged build is written in the spatial layout (leave out --layout build)".into(),
        ));
    }
    let t0 = std::time::Instant::now();
    let model = crate::import::model_files(input);
    let mut inputs: Vec<&Path> = model.iter().map(PathBuf::as_path).collect();
    inputs.extend(shard_files.iter().map(PathBuf::as_path));
    let out = engine_cli::outfile::OutputFile::create(output, &inputs)?;
    let key = crate::cache::key(input, params)?;
    let shard_err = |p: &Path, what: String| BuildError::Shard(format!("{}: {what}", p.display()));
    // The headers: one count, every index once.
    let mut by_index: Vec<Option<(PathBuf, ShardHeader)>> = Vec::new();
    let mut count = None;
    for p in shard_files {
        let h = read_header(p, &key).map_err(|e| shard_err(p, e))?;
        let n = *count.get_or_insert(h.count);
        if h.count != n {
            return Err(shard_err(
                p,
                format!("is shard {}/{}, the others are of {n}", h.index, h.count),
            ));
        }
        by_index.resize(n as usize, None);
        if let Some((other, _)) = &by_index[h.index as usize] {
            return Err(shard_err(
                p,
                format!(
                    "is shard {}/{n}, and so is {}: give each shard once",
                    h.index,
                    other.display()
                ),
            ));
        }
        by_index[h.index as usize] = Some((p.clone(), h));
    }
    let n = count.ok_or_else(|| BuildError::Shard("no shard files given".into()))?;
    if let Some(i) = by_index.iter().position(Option::is_none) {
        return Err(BuildError::Shard(format!(
            "shard {i}/{n} is missing (the output of `hlod-build build --shard {i}/{n}`)"
        )));
    }
    let mut opened = crate::import::open(input)?;
    opened.scene.source_key = crate::cache::key_bytes(input, params)?;
    let write_err = |source| BuildError::Write {
        path: output.to_path_buf(),
        source,
    };
    let mut stats = BuildStats::default();
    let prep = super::prepare(&opened, params, opts, &mut stats).map_err(|e| match e {
        Staged::Format(f) => write_err(f),
        Staged::Memory(m) => BuildError::Memory(m),
    })?;
    let (shard_roots, upper) = shard_plan(&prep, n);
    let dir = engine_cli::outfile::parent_dir(out.target()).to_path_buf();
    let staging = tempfile::tempfile_in(&dir).map_err(|e| write_err(e.into()))?;
    let mut sources: Vec<FileSource> = Vec::new();
    let mut node_source = vec![usize::MAX; prep.tree.len()];
    let mut asm = super::assembly(
        &prep,
        BufWriter::with_capacity(
            1 << 20,
            staging.try_clone().map_err(|e| write_err(e.into()))?,
        ),
        params,
        opts,
        &mut stats,
    )
    .map_err(write_err)?;
    let (mut mt, mut vdt) = (0, 0);
    for (k, slot) in by_index.iter().enumerate() {
        let (path, h) = slot.as_ref().expect("every index checked");
        let src = FileSource::open(path).map_err(|e| shard_err(path, e.to_string()))?;
        let d = read_data(&src, h, prep.tree.len()).map_err(|e| shard_err(path, e))?;
        let mut roots: Vec<usize> = d.roots.iter().map(|(i, _)| *i).collect();
        let mut want = shard_roots[k].clone();
        roots.sort_unstable();
        want.sort_unstable();
        if roots != want {
            return Err(shard_err(
                path,
                "holds other subtrees than this graph's shard".into(),
            ));
        }
        for (i, rec, reps) in d.nodes {
            if node_source[i] != usize::MAX {
                return Err(shard_err(
                    path,
                    format!("node {i} was made by another shard too"),
                ));
            }
            node_source[i] = k;
            asm.nodes[i] = rec;
            asm.node_reps[i] = reps;
            asm.done += 1;
        }
        asm.leaf_runs.extend(d.runs);
        for (i, c) in d.roots {
            asm.coarse[i] = Some(c);
        }
        mt += d.mt_objects;
        vdt += d.vdt_objects;
        sources.push(src);
    }
    asm.stats.mt_objects += mt;
    asm.stats.vdt_objects += vdt;
    asm.bar.set_message("HLODs");
    asm.interior(&upper).map_err(write_err)?;
    asm.bar.finish_and_clear();
    for &i in &upper {
        node_source[i] = n as usize;
    }
    if let Some(i) = node_source.iter().position(|&s| s == usize::MAX) {
        return Err(BuildError::Shard(format!(
            "node {i} is in no shard file: were the shards built with this input and parameters?"
        )));
    }
    let super::assemble::Assembly {
        writer,
        nodes,
        node_reps,
        leaf_runs,
        ..
    } = asm;
    drop(writer.into_inner().map_err(write_err)?);
    sources.push(FileSource::from_file(staging).map_err(|e| write_err(e.into()))?);
    let skeleton = super::skeleton_of(nodes, node_reps);
    let (meta, objects) = super::scene_tail(&opened.scene, &stats, &leaf_runs);
    let walk = super::walk_tail(&opened, params, opts, &mut stats).map_err(write_err)?;
    let file = out.file().try_clone().map_err(|e| write_err(e.into()))?;
    let mut sink = crate::layout::relayout_parts(
        &skeleton,
        &node_source,
        &sources,
        &meta,
        (&objects, &walk),
        BufWriter::with_capacity(1 << 20, file),
    )
    .map_err(write_err)?;
    sink.flush().map_err(|e| write_err(e.into()))?;
    drop(sink);
    // The merged scene is checked as `hlod-build info` checks a scene
    // (header, skeleton, every rep) before it replaces anything.
    let written = out.file().try_clone().map_err(|e| write_err(e.into()))?;
    let check = FileSource::from_file(written)
        .map_err(FormatError::from)
        .and_then(engine::SceneFile::from_source)
        .and_then(|s| s.verify_all_reps());
    check.map_err(|e| {
        BuildError::Shard(format!(
            "{}: the merged scene fails its check ({e}); nothing was written: were the shards \
             built with this input and parameters?",
            output.display()
        ))
    })?;
    out.commit()?;
    super::skeleton_stats(&mut stats, &skeleton, objects.len());
    stats.cells = u64::from(n);
    stats.file_bytes = file_len(output)?;
    stats.seconds = t0.elapsed().as_secs_f64();
    Ok(stats)
}

/// Reads a whole shard file as `merge` does — header against `key`,
/// digest, trailer checksum, every record against a graph of `tree_len`
/// nodes — and returns how many nodes it holds (the fuzz target's entry:
/// `tests/fuzz/fuzz_targets/shard_reader.rs`).
pub fn check_shard(bytes: &[u8], key: &str, tree_len: usize) -> Result<usize, String> {
    let head = bytes
        .first_chunk::<{ std::mem::size_of::<ShardHeader>() }>()
        .ok_or("not a shard file (too short)")?;
    let h = parse_header(head, key)?;
    let src = engine::MemSource::new(bytes.to_vec());
    read_data(&src, &h, tree_len).map(|d| d.nodes.len())
}

/// For the fuzz target: the key a shard file's header records (32 bytes,
/// as text where they are UTF-8), and the file with its trailer checksum
/// and digest made to match its bytes, so that mutations reach the checks
/// behind them. `None` for a file shorter than a header.
pub fn reseal(bytes: &mut [u8]) -> Option<String> {
    const H: usize = std::mem::size_of::<ShardHeader>();
    let mut h: ShardHeader = bytemuck::pod_read_unaligned(bytes.get(..H)?);
    let trailer = h
        .trailer_offset
        .checked_add(h.trailer_len)
        .filter(|&e| e <= bytes.len() as u64)
        .map(|e| &bytes[h.trailer_offset as usize..e as usize]);
    if let Some(t) = trailer {
        h.trailer_crc = crc32fast::hash(t);
    }
    let src = engine::MemSource::new(bytes.to_vec());
    if let Ok(d) = digest_of(&src, &h) {
        h.digest = d;
    }
    bytes[..H].copy_from_slice(bytemuck::bytes_of(&h));
    Some(String::from_utf8_lossy(&h.key).into_owned())
}

/// The size of a file just written.
fn file_len(path: &Path) -> Result<u64, BuildError> {
    std::fs::metadata(path)
        .map(|m| m.len())
        .map_err(|source| BuildError::Io {
            path: path.to_path_buf(),
            source,
        })
}
