//! The shard-file reader of `hlod-build merge`
//! (`hlod_builder::build::shard::check_shard`): header against the merge's
//! key, digest, trailer checksum, every record against a graph of 4096
//! nodes. Inputs of even length are resealed first (the key taken from
//! their header, trailer checksum and digest recomputed), so that
//! mutations reach the records behind the checks.
#![no_main]

use hlod_builder::build::shard::{check_shard, reseal};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut bytes = data.to_vec();
    let key = if bytes.len().is_multiple_of(2) {
        reseal(&mut bytes)
    } else {
        None
    };
    let key = key.unwrap_or_else(|| "0".repeat(32));
    let _ = check_shard(&bytes, &key, 4096);
});
