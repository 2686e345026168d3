//! Random corruptions of a real GLB never make the importer panic.

use std::path::Path;

use e2e_tests::data_dir;
use hlod_builder::import::load_slice;
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]
    #[test]
    fn corrupted_glb_is_an_error_or_a_scene_never_a_panic(
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
        in_json in any::<bool>(),
        cut in prop::option::of(any::<prop::sample::Index>()),
    ) {
        let mut bytes = std::fs::read(data_dir().join("dragon_res4.glb")).unwrap();
        let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        // Edit the JSON chunk (structure) or anywhere (binary data, headers).
        let (lo, hi) = if in_json { (20, 20 + json_len) } else { (0, bytes.len()) };
        for (at, value) in edits {
            let i = lo + at.index(hi - lo);
            bytes[i] = value;
        }
        if let Some(c) = cut {
            let n = c.index(bytes.len());
            bytes.truncate(n);
        }
        let path = Path::new("fuzzed.glb");
        let result = std::panic::catch_unwind(|| load_slice(&bytes, Path::new("."), path).map(|s| s.instances.len()));
        prop_assert!(result.is_ok(), "the importer panicked");
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]
    /// Digits rewritten in the JSON: still valid JSON, but counts, offsets,
    /// strides, component types and indices change.
    #[test]
    fn rewritten_numbers_are_an_error_or_a_scene_never_a_panic(
        edits in prop::collection::vec((any::<prop::sample::Index>(), 0u8..10), 1..6),
    ) {
        let mut bytes = std::fs::read(data_dir().join("dragon_res4.glb")).unwrap();
        let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        let digits: Vec<usize> = (20..20 + json_len).filter(|&i| bytes[i].is_ascii_digit()).collect();
        for (at, d) in edits {
            bytes[digits[at.index(digits.len())]] = b'0' + d;
        }
        let path = Path::new("fuzzed.glb");
        let result = std::panic::catch_unwind(|| load_slice(&bytes, Path::new("."), path).map(|s| s.instances.len()));
        prop_assert!(result.is_ok(), "the importer panicked");
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 100, ..ProptestConfig::default() })]
    /// The same for a node hierarchy with matrices, shared meshes and an external buffer.
    #[test]
    fn rewritten_numbers_in_a_cad_assembly_never_panic(
        edits in prop::collection::vec((any::<prop::sample::Index>(), 0u8..10), 1..6),
    ) {
        let dir = data_dir().join("2CylinderEngine");
        let mut bytes = std::fs::read(dir.join("2CylinderEngine.gltf")).unwrap();
        let digits: Vec<usize> = (0..bytes.len()).filter(|&i| bytes[i].is_ascii_digit()).collect();
        for (at, d) in edits {
            bytes[digits[at.index(digits.len())]] = b'0' + d;
        }
        let path = Path::new("fuzzed.gltf");
        let result = std::panic::catch_unwind(|| load_slice(&bytes, &dir, path).map(|s| s.instances.len()));
        prop_assert!(result.is_ok(), "the importer panicked");
    }
}
