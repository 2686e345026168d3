use super::*;
use crate::io::MemSource;
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
    for r in &skeleton.reps {
        assert_eq!(r.offset % BLOCK, 0);
    }
}

#[test]
fn opening_reads_no_rep_data() {
    // Zero the whole data section: opening must still succeed (it never looks
    // there), and reading a rep must then fail its checksum.
    let (mut bytes, skeleton) = build(&[1, 2, 3], &[2, 0, 0]);
    let end = skeleton
        .reps
        .iter()
        .map(|r| r.offset + BLOCK)
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
    let h: FileHeader = bytemuck::pod_read_unaligned(&bytes[..128]);
    let positions = (0..128usize).chain(h.skeleton_offset as usize..bytes.len());
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
    b[8] = 2;
    assert!(matches!(
        SceneFile::from_source(MemSource::new(b)),
        Err(FormatError::UnsupportedVersion { found: 2 })
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
        let mut h: FileHeader = bytemuck::pod_read_unaligned(&bytes[..128]);
        let (start, end) = (h.skeleton_offset as usize, bytes.len());
        for (at, v) in edits {
            bytes[start + at.index(end - start)] = v;
        }
        h.skeleton_crc = crc32fast::hash(&bytes[start..end]);
        h.header_crc = 0;
        h.header_crc = crc32fast::hash(bytemuck::bytes_of(&h));
        bytes[..128].copy_from_slice(bytemuck::bytes_of(&h));
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
