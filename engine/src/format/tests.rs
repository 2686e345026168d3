use super::*;
use crate::io::{ByteSource, MemSource};
use crate::testutil::build;
use proptest::prelude::*;

#[test]
fn round_trip_reads_back_skeleton_and_reps() {
    let (bytes, skeleton) = build(&[1, 2, 3], &[2, 0, 0]);
    let scene = SceneFile::from_source(MemSource::new(bytes)).unwrap();
    assert_eq!(scene.skeleton(), &skeleton);
    assert_eq!(scene.meta().object_count, 2);
    scene.verify_all_reps().unwrap();
    let m = scene.read_rep(4).unwrap();
    assert_eq!(m.tri_count(), 2);
    assert!(scene.read_rep(99).is_err());
    // Version 3 packs the reps: each starts on the next 16-byte boundary
    // after the one before it, with no block padding between.
    let order = skeleton.reps_in_file_order();
    assert_eq!(skeleton.reps[order[0] as usize].offset, BLOCK);
    for w in order.windows(2) {
        let (a, b) = (&skeleton.reps[w[0] as usize], &skeleton.reps[w[1] as usize]);
        assert_eq!(b.offset % REP_ALIGN, 0);
        assert_eq!(
            b.offset,
            (a.offset + a.extent()).next_multiple_of(REP_ALIGN)
        );
    }
}

#[test]
fn version_2_files_with_block_aligned_reps_still_read() {
    let (bytes, skeleton) = build(&[1, 2, 3], &[2, 0, 0]);
    let scene = SceneFile::from_source(MemSource::new(bytes.clone())).unwrap();
    // Rewrite the same scene as version 2 wrote it: every rep on a block.
    let mut v2 = vec![0u8; BLOCK as usize];
    let mut moved = skeleton.clone();
    for r in skeleton.reps_in_file_order() {
        let rec = &mut moved.reps[r as usize];
        let mut buf = vec![0u8; rec.extent() as usize];
        scene.source().read_at(rec.offset, &mut buf).unwrap();
        rec.offset = v2.len() as u64;
        v2.extend_from_slice(&buf);
        v2.resize(v2.len().next_multiple_of(BLOCK as usize), 0);
    }
    let mut h: FileHeader = bytemuck::pod_read_unaligned(&bytes[..256]);
    let skel: Vec<u8> = [
        bytemuck::cast_slice::<_, u8>(&moved.nodes),
        bytemuck::cast_slice(&moved.reps),
    ]
    .concat();
    h.version = 2;
    h.data_len = v2.len() as u64 - BLOCK;
    h.skeleton_offset = v2.len() as u64;
    h.skeleton_crc = crc32fast::hash(&skel);
    v2.extend_from_slice(&skel);
    h.objects_offset = v2.len() as u64;
    v2.extend_from_slice(&bytes[bytes.len() - h.objects_len as usize..]);
    h.file_len = v2.len() as u64;
    let mut h = downgrade(&h, 2);
    h.header_crc = crc32fast::hash(bytemuck::bytes_of(&h));
    v2[..256].fill(0);
    v2[..192].copy_from_slice(bytemuck::bytes_of(&h));
    let old = SceneFile::from_source(MemSource::new(v2)).unwrap();
    assert_eq!(old.skeleton(), &moved);
    old.verify_all_reps().unwrap();
    assert!(
        bytes.len() < h.file_len as usize,
        "packing made the file smaller"
    );
}

#[test]
fn opening_reads_no_rep_data() {
    // Zero the whole data section: opening must still succeed (it never looks
    // there), and reading a rep must then fail its checksum.
    let (mut bytes, skeleton) = build(&[1, 2, 3], &[2, 0, 0]);
    let end = skeleton
        .reps
        .iter()
        .map(|r| r.offset + r.extent())
        .max()
        .unwrap() as usize;
    bytes[BLOCK as usize..end].fill(0);
    let scene = SceneFile::from_source(MemSource::new(bytes)).unwrap();
    assert!(matches!(
        scene.read_rep(0),
        Err(FormatError::Checksum { .. })
    ));
}

#[test]
fn every_truncation_is_a_typed_error() {
    let (bytes, _) = build(&[1, 1, 1], &[2, 0, 0]);
    for len in (0..bytes.len()).step_by(61).chain([bytes.len() - 1]) {
        let r = SceneFile::from_source(MemSource::new(bytes[..len].to_vec()));
        assert!(r.is_err(), "truncated to {len} bytes was accepted");
    }
}

#[test]
fn every_bit_flip_in_header_and_skeleton_is_detected() {
    let (bytes, _) = build(&[1, 2, 1], &[2, 0, 0]);
    let h: FileHeader = bytemuck::pod_read_unaligned(&bytes[..256]);
    let positions = (0..256usize).chain(h.skeleton_offset as usize..bytes.len());
    for pos in positions {
        let mut b = bytes.clone();
        b[pos] ^= 0x10;
        assert!(
            SceneFile::from_source(MemSource::new(b)).is_err(),
            "flip at byte {pos} accepted"
        );
    }
}

#[test]
fn bit_flip_in_a_rep_fails_only_that_rep() {
    let (mut bytes, skeleton) = build(&[1, 2, 1], &[2, 0, 0]);
    let target = skeleton.reps[2];
    bytes[target.offset as usize + 100] ^= 1;
    let scene = SceneFile::from_source(MemSource::new(bytes)).unwrap();
    assert!(matches!(
        scene.read_rep(2),
        Err(FormatError::Checksum { .. })
    ));
    assert!(scene.read_rep(1).is_ok());
    assert!(scene.verify_all_reps().is_err());
}

#[test]
fn rejects_other_files_and_versions() {
    let (bytes, _) = build(&[1], &[0]);
    let mut b = bytes.clone();
    b[..8].copy_from_slice(b"glTF\x02\0\0\0");
    assert!(matches!(
        SceneFile::from_source(MemSource::new(b)),
        Err(FormatError::BadMagic(_))
    ));
    let mut b = bytes.clone();
    b[8] = 7;
    assert!(matches!(
        SceneFile::from_source(MemSource::new(b)),
        Err(FormatError::UnsupportedVersion { found: 7 })
    ));
    let mut b = bytes;
    b.extend_from_slice(&[0; 16]);
    assert!(SceneFile::from_source(MemSource::new(b)).is_err());
}

proptest! {
    #[test]
    fn random_scenes_round_trip((reps, children) in crate::testutil::shape_strategy(40)) {
        let (bytes, skeleton) = build(&reps, &children);
        let scene = SceneFile::from_source(MemSource::new(bytes)).unwrap();
        prop_assert_eq!(scene.skeleton(), &skeleton);
        scene.verify_all_reps().unwrap();
        // PAR and CHD are inverse relations.
        for id in 0..skeleton.reps.len() as u32 {
            for c in skeleton.chd(id) {
                prop_assert_eq!(skeleton.par(c), Some(id));
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]
    /// Hostile skeletons with valid checksums: an error or a scene, never a panic.
    #[test]
    fn edited_skeletons_with_valid_checksums_never_panic(
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
    ) {
        let (mut bytes, _) = build(&[1, 2, 3, 1], &[3, 0, 0, 0]);
        let mut h: FileHeader = bytemuck::pod_read_unaligned(&bytes[..256]);
        let (start, end) = (h.skeleton_offset as usize, bytes.len());
        for (at, v) in edits {
            bytes[start + at.index(end - start)] = v;
        }
        h.skeleton_crc = crc32fast::hash(&bytes[start..end]);
        h.header_crc = 0;
        h.header_crc = crc32fast::hash(bytemuck::bytes_of(&h));
        bytes[..256].copy_from_slice(bytemuck::bytes_of(&h));
        let result = std::panic::catch_unwind(|| {
            if let Ok(scene) = SceneFile::from_source(MemSource::new(bytes)) {
                let s = scene.skeleton();
                for r in 0..s.reps.len() as u32 {
                    let _ = scene.read_rep(r);
                    let _ = (s.par(r), s.chd(r), s.asc(r, 3), s.dsc(r, 3));
                }
            }
        });
        prop_assert!(result.is_ok(), "the reader panicked");
    }
}

/// A version-1 file: the same scene with the 128-byte header.
fn as_version_1(bytes: &[u8]) -> Vec<u8> {
    let h: FileHeader = bytemuck::pod_read_unaligned(&bytes[..256]);
    assert_eq!(h.objects_len, 0);
    let mut v1 = FileHeaderV1 {
        magic: h.magic,
        version: 1,
        header_size: 128,
        node_count: h.node_count,
        rep_count: h.rep_count,
        object_count: h.object_count,
        flags: h.flags,
        input_triangles: h.input_triangles,
        data_offset: h.data_offset,
        data_len: h.data_len,
        skeleton_offset: h.skeleton_offset,
        skeleton_len: h.skeleton_len,
        file_len: h.file_len,
        bounds_min: h.bounds_min,
        bounds_max: h.bounds_max,
        skeleton_crc: h.skeleton_crc,
        header_crc: 0,
        reserved: [0; 4],
    };
    v1.header_crc = crc32fast::hash(bytemuck::bytes_of(&v1));
    let mut out = bytes.to_vec();
    out[..256].fill(0);
    out[..128].copy_from_slice(bytemuck::bytes_of(&v1));
    out
}

/// `h` as a header of versions 2 to 4 (CRC zero).
fn downgrade(h: &FileHeader, version: u32) -> FileHeaderV2 {
    FileHeaderV2 {
        magic: h.magic,
        version,
        header_size: 192,
        node_count: h.node_count,
        rep_count: h.rep_count,
        object_count: h.object_count,
        flags: h.flags,
        input_triangles: h.input_triangles,
        data_offset: h.data_offset,
        data_len: h.data_len,
        skeleton_offset: h.skeleton_offset,
        skeleton_len: h.skeleton_len,
        file_len: h.file_len,
        bounds_min: h.bounds_min,
        bounds_max: h.bounds_max,
        skeleton_crc: h.skeleton_crc,
        header_crc: 0,
        origin: h.origin,
        objects_offset: h.objects_offset,
        objects_len: h.objects_len,
        objects_crc: h.objects_crc,
        source_key: h.source_key,
        drawn_triangles: h.drawn_triangles,
        hidden_triangles: h.hidden_triangles,
        reserved: [0; 1],
    }
}

/// A version-4 file: the same scene with the 192-byte header (no walk section).
fn as_version_4(bytes: &[u8]) -> Vec<u8> {
    let h: FileHeader = bytemuck::pod_read_unaligned(&bytes[..256]);
    assert_eq!(h.walk_len, 0);
    let mut v2 = downgrade(&h, 4);
    v2.header_crc = crc32fast::hash(bytemuck::bytes_of(&v2));
    let mut out = bytes.to_vec();
    out[..256].fill(0);
    out[..192].copy_from_slice(bytemuck::bytes_of(&v2));
    out
}

#[test]
fn version_4_files_are_still_read_without_a_walk_section() {
    let (bytes, skeleton) = build(&[1, 2, 3], &[2, 0, 0]);
    let scene = SceneFile::from_source(MemSource::new(as_version_4(&bytes))).unwrap();
    assert_eq!(scene.skeleton(), &skeleton);
    assert_eq!(scene.header().version, 4);
    assert!(scene.read_walk_index().unwrap().is_none());
    scene.verify_all_reps().unwrap();
}

#[test]
fn the_walk_section_round_trips_and_a_damaged_chunk_is_named() {
    use crate::format::walk::{CHUNK_AREA, Chunk, LAYERS, Span, WalkIndex};
    let (bytes, skeleton) = build(&[1, 2], &[1, 0]);
    let plain = SceneFile::from_source(MemSource::new(bytes)).unwrap();
    let mut cols = vec![Vec::new(); LAYERS * CHUNK_AREA];
    cols[7] = vec![Span { lo: 1, hi: 3 }];
    let walk = WalkIndex::encode(0.1, 0.02, 0.0, &[((2, -1), Chunk::encode(&cols))]);
    let mut data = vec![0u8; (plain.header().skeleton_offset - BLOCK) as usize];
    plain.source().read_at(BLOCK, &mut data).unwrap();
    let mut w = SceneWriter::new(std::io::Cursor::new(Vec::new())).unwrap();
    w.write_rep(&data).unwrap();
    let out = w
        .finish_with_sections(&skeleton, &plain.meta(), &[], &walk)
        .unwrap()
        .into_inner();
    let scene = SceneFile::from_source(MemSource::new(out.clone())).unwrap();
    let index = scene.read_walk_index().unwrap().unwrap();
    let chunk = scene.read_walk_chunk(index.find(2, -1).unwrap()).unwrap();
    assert_eq!(chunk.column(7, 0).solid, &[Span { lo: 1, hi: 3 }]);
    assert_eq!(scene.read_walk_bytes().unwrap(), walk);
    let mut bad = out;
    let last = bad.len() - 3;
    bad[last] ^= 0xff;
    let scene = SceneFile::from_source(MemSource::new(bad)).unwrap();
    let e = scene.read_walk_bytes().unwrap_err().to_string();
    assert!(e.contains("walk chunk (2, -1)"), "{e}");
}

#[test]
fn version_1_files_are_still_read_with_origin_zero_and_no_objects() {
    let (bytes, skeleton) = build(&[1, 2, 3], &[2, 0, 0]);
    let scene = SceneFile::from_source(MemSource::new(as_version_1(&bytes))).unwrap();
    assert_eq!(scene.skeleton(), &skeleton);
    assert_eq!(scene.header().version, 1);
    assert_eq!(scene.meta().origin, [0.0; 3]);
    assert!(scene.read_objects().unwrap().is_empty());
    scene.verify_all_reps().unwrap();
}

#[test]
fn a_newer_version_is_refused_with_what_to_do() {
    let (mut bytes, _) = build(&[1], &[0]);
    bytes[8..12].copy_from_slice(&(VERSION + 1).to_le_bytes());
    let e = SceneFile::from_source(MemSource::new(bytes)).unwrap_err();
    assert!(matches!(e, FormatError::UnsupportedVersion { found } if found == VERSION + 1));
    assert!(e.to_string().contains("rebuild"), "{e}");
}

#[test]
fn origin_and_object_section_round_trip_and_are_checked() {
    use crate::format::objects::{ObjectTable, Run};
    use crate::testutil::build_with;
    let infos = vec![r#"{"name":"a"}"#.to_string(), r#"{"name":"b"}"#.to_string()];
    let objects = ObjectTable::encode(&infos, &[]);
    let origin = [5.0e6, -3.25e6, 12.5];
    let (bytes, skeleton) = build_with(&[1, 2, 3], &[2, 0, 0], origin, &objects);
    let scene = SceneFile::from_source(MemSource::new(bytes.clone())).unwrap();
    assert_eq!(scene.meta().origin, origin);
    let t = scene.read_objects().unwrap();
    assert_eq!(t.len(), 2);
    assert_eq!(t.info(1), Some(r#"{"name":"b"}"#));
    assert_eq!(t.info(2), None);
    // Leaves name their object; a merged leaf's runs resolve triangles.
    let leaf = (0..skeleton.nodes.len() as u32)
        .find(|&n| skeleton.nodes[n as usize].is_leaf())
        .unwrap();
    assert!(t.object_at(&skeleton, leaf, 0).is_some());
    let runs = vec![
        Run {
            object: 1,
            tri_end: 2,
        },
        Run {
            object: 0,
            tri_end: 5,
        },
    ];
    let mut merged = skeleton.clone();
    merged.nodes[leaf as usize].object = NONE;
    let t2 = ObjectTable::decode(&ObjectTable::encode(&infos, &[(leaf, runs)]), &merged).unwrap();
    assert_eq!(t2.object_at(&merged, leaf, 1), Some(1));
    assert_eq!(t2.object_at(&merged, leaf, 4), Some(0));
    assert_eq!(t2.object_at(&merged, leaf, 5), None);
    // Any flipped bit of the section is caught by its checksum.
    let h: FileHeader = bytemuck::pod_read_unaligned(&bytes[..256]);
    for pos in h.objects_offset as usize..bytes.len() {
        let mut b = bytes.clone();
        b[pos] ^= 0x04;
        let scene = SceneFile::from_source(MemSource::new(b)).unwrap();
        assert!(scene.read_objects().is_err(), "flip at {pos} accepted");
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 500, ..ProptestConfig::default() })]
    /// A hostile object section never panics the decoder.
    #[test]
    fn hostile_object_sections_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..200), magic in any::<bool>()) {
        let (_, skeleton) = build(&[1, 2], &[1, 0]);
        let mut b = bytes;
        if magic && b.len() >= 8 {
            b[..8].copy_from_slice(&crate::format::objects::OBJECTS_MAGIC);
        }
        let _ = crate::format::objects::ObjectTable::decode(&b, &skeleton);
    }
}
