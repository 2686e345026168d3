use super::*;

/// Starts "requests" numbered in order, recording their ranges.
fn starter(log: &mut Vec<(u64, u64)>) -> impl FnMut(u64, u64) -> usize + '_ {
    move |a, b| {
        log.push((a, b));
        log.len() - 1
    }
}

fn bytes(a: u64, b: u64) -> Vec<u8> {
    (a..b).map(|x| x as u8).collect()
}

#[test]
fn requests_start_in_order_within_the_count_and_the_bytes() {
    let mut ra = ReadAhead::new(3);
    let mut log = Vec::new();
    assert!(ra.hint(&[(0, 10)], starter(&mut log)).is_empty());
    assert!(log.is_empty(), "off until a cap is set");
    ra.set_cap(25);
    let ranges = [(0, 10), (20, 30), (40, 45), (50, 60)];
    ra.hint(&ranges, starter(&mut log));
    // 10 + 10 + 5 bytes fit 25; the fourth waits for room (and a slot).
    assert_eq!(log, [(0, 10), (20, 30), (40, 45)]);
    assert_eq!(ra.held(), 25);
    assert_eq!(ra.stats().peak_in_flight, 3);
}

#[test]
fn a_read_waits_for_its_request_and_later_reads_of_the_range_are_served() {
    let mut ra = ReadAhead::new(2);
    ra.set_cap(100);
    let mut log = Vec::new();
    ra.hint(&[(0, 40), (40, 50), (60, 70)], starter(&mut log));
    assert_eq!(log.len(), 2);
    let mut buf = [0u8; 16];
    let Lookup::Wait { handle, start } = ra.lookup(0, &mut buf) else {
        panic!("in flight")
    };
    assert_eq!((handle, start), (0, 0));
    assert!(
        matches!(ra.lookup(0, &mut buf), Lookup::Miss),
        "another reader"
    );
    assert!(!ra.is_ready(0, 16, |_| false), "taken by the reader");
    assert!(ra.is_ready(40, 10, |&h| h == 1), "answered, not read yet");
    assert!(!ra.is_ready(40, 10, |_| false));
    assert!(
        ra.finish(0, Some(bytes(0, 40)), 0, &mut buf, starter(&mut log))
            .0
    );
    assert!(ra.is_ready(16, 24, |_| false), "the rest of an answer");
    assert_eq!(buf.to_vec(), bytes(0, 16));
    // The rest of the range stays for the next block of the same rep.
    let mut rest = [0u8; 24];
    assert!(matches!(ra.lookup(16, &mut rest), Lookup::Done));
    assert_eq!(rest.to_vec(), bytes(16, 40));
    // Its end read, the range went; the third starts in its slot.
    assert!(ra.refill(starter(&mut log)).is_empty());
    assert_eq!(log.len(), 3);
    assert_eq!(ra.stats().hits, 2);
    // Not hinted: a miss; across two ranges: a miss.
    assert!(matches!(ra.lookup(90, &mut [0u8; 4]), Lookup::Miss));
    assert!(matches!(ra.lookup(45, &mut [0u8; 20]), Lookup::Miss));
}

#[test]
fn what_left_the_hint_is_dropped_only_for_the_room_the_new_ranges_need() {
    let mut ra = ReadAhead::new(3);
    ra.set_cap(1000);
    let mut log = Vec::new();
    ra.hint(&[(0, 10), (10, 20), (20, 30)], starter(&mut log));
    // The answer of (10, 20) arrives and is kept for a later read.
    let mut b = [0u8; 2];
    let Lookup::Wait { start, .. } = ra.lookup(10, &mut b) else {
        panic!()
    };
    assert!(
        ra.finish(start, Some(bytes(10, 20)), 10, &mut b, starter(&mut log))
            .0
    );
    // (20, 30) stays wanted; (30, 40) needs a slot: the oldest stale range,
    // (0, 10), in flight, is cancelled for it. (10, 20) stays, stale.
    let cancel = ra.hint(&[(20, 30), (30, 40)], starter(&mut log));
    assert_eq!(cancel, [0]);
    assert_eq!(&log[3..], [(30, 40)], "(20, 30) is not asked again");
    assert_eq!(ra.held(), 30);
    // A stale range still serves a read.
    assert!(matches!(ra.lookup(12, &mut b), Lookup::Done));
    // A range that needs its slot drops it, unread: counted.
    let cancel = ra.hint(&[(40, 50), (20, 30), (30, 40)], starter(&mut log));
    assert!(cancel.is_empty(), "answered, not in flight");
    assert_eq!((ra.stats().dropped, ra.stats().dropped_bytes), (2, 10));
    assert_eq!(&log[4..], [(40, 50)]);
    assert_eq!(
        ra.set_cap(0).len(),
        3,
        "off: everything in flight cancelled"
    );
    assert_eq!(ra.held(), 0);
}

#[test]
fn a_failed_or_short_answer_sends_the_read_to_the_server() {
    let mut ra = ReadAhead::new(2);
    ra.set_cap(100);
    let mut log = Vec::new();
    ra.hint(&[(0, 10), (10, 20)], starter(&mut log));
    let mut b = [0u8; 10];
    let Lookup::Wait { start, .. } = ra.lookup(0, &mut b) else {
        panic!()
    };
    assert!(!ra.finish(start, None, 0, &mut b, starter(&mut log)).0);
    let Lookup::Wait { start, .. } = ra.lookup(10, &mut b) else {
        panic!()
    };
    assert!(
        !ra.finish(start, Some(bytes(10, 15)), 10, &mut b, starter(&mut log))
            .0
    );
    assert_eq!((ra.held(), ra.stats().hits), (0, 0));
}

#[test]
fn a_range_the_reads_left_behind_gives_its_slot_up() {
    // Two slots, pages hinted whole and read rep by rep: the first page's
    // last rep is not read.
    let mut ra = ReadAhead::new(2);
    ra.set_cap(1000);
    let mut log = Vec::new();
    ra.hint(&[(0, 100), (100, 200), (200, 300)], starter(&mut log));
    assert_eq!(log.len(), 2);
    let mut b = [0u8; 10];
    let Lookup::Wait { start, .. } = ra.lookup(10, &mut b) else {
        panic!()
    };
    // Its first rep read, the page stays for the next block or rep of it.
    ra.finish(start, Some(bytes(0, 100)), 10, &mut b, starter(&mut log));
    assert_eq!(log.len(), 2, "not passed yet: no slot");
    assert!(matches!(ra.lookup(40, &mut b), Lookup::Done));
    // The next read is in the second page, past the first one's end: the
    // first gives its slot to the third.
    let Lookup::Wait { start, .. } = ra.lookup(150, &mut b) else {
        panic!()
    };
    ra.finish(start, Some(bytes(100, 200)), 150, &mut b, starter(&mut log));
    assert_eq!(&log[2..], [(200, 300)]);
    assert_eq!(ra.stats().dropped_bytes, 100);
    assert!(matches!(ra.lookup(60, &mut b), Lookup::Miss), "dropped");
}

#[test]
fn a_lower_cap_drops_the_stale_then_the_least_urgent_ranges_to_fit() {
    let mut ra = ReadAhead::new(4);
    ra.set_cap(100);
    let mut log = Vec::new();
    ra.hint(&[(0, 20), (20, 40), (40, 60)], starter(&mut log));
    // The first range leaves the hint (stale); a read waits on the second.
    ra.hint(&[(20, 40), (40, 60), (60, 80)], starter(&mut log));
    assert_eq!(ra.held(), 80);
    let mut buf = [0u8; 4];
    assert!(matches!(ra.lookup(20, &mut buf), Lookup::Wait { .. }));
    // 50 bytes: the stale range goes first, then the last started.
    let cancel = ra.set_cap(50);
    assert_eq!(cancel, vec![0, 3]);
    assert_eq!(ra.held(), 40);
    // Below what a read waits on: that range stays, the others go.
    assert_eq!(ra.set_cap(10), vec![2]);
    assert_eq!(ra.held(), 20, "the range being read is kept");
    assert_eq!(ra.stats().dropped, 3);
    // Raised again, nothing is dropped; ranges start at the next hint.
    assert!(ra.set_cap(100).is_empty());
}
