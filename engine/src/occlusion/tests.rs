use super::*;
use crate::testutil::quad;

#[test]
fn occluders_are_a_reps_largest_triangles() {
    let big = quad([0.0, 0.0, 0.0], [10.0, 10.0, 0.0]).encode(0, 0);
    let t = occluder_triangles(&big);
    assert_eq!(t.len(), 2);
    assert!(t.iter().all(|t| t.iter().all(|p| p.z.abs() < 1e-3)));
    // Not a raw mesh payload: nothing.
    assert!(occluder_triangles(&big[..40]).is_empty());
    assert!(occluder_triangles(b"REPZ and more bytes than a header holds, surely").is_empty());
}

#[test]
fn the_store_stays_within_its_bytes() {
    let payload = quad([0.0, 0.0, 0.0], [1.0, 1.0, 0.0]).encode(0, 0);
    let per = 64 + 2 * 36;
    let mut s = OccluderStore::new(3 * per + 10);
    for r in 0..10 {
        s.insert_from(r, &payload, r);
        s.validate().unwrap();
        assert!(s.bytes() <= 3 * per + 10);
    }
    assert_eq!(s.len(), 3);
    // The most recent three are held; a read marks an entry as used.
    assert!(s.get(7, 10).is_some() && s.get(9, 10).is_some());
    s.insert_from(10, &payload, 10);
    assert!(s.get(7, 10).is_some() && s.get(8, 10).is_none());
    // A store too small for one entry holds nothing.
    let mut tiny = OccluderStore::new(10);
    tiny.insert_from(0, &payload, 0);
    assert!(tiny.is_empty());
}
