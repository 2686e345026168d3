//! The stored bytes of whole pages read on a seek-bound disk or a network
//! ([`PageCache`]): what the page policy (`pages.rs`) fills and copies reps
//! out of, least recently used first out.

use std::sync::Arc;

use crate::evict::lru::LruMap;

/// Stored bytes of recently read pages, least recently used first out
/// ([`LruMap`]).
#[derive(Debug)]
pub(super) struct PageCache {
    page_bytes: u64,
    pages: LruMap<u64, Arc<[u8]>>,
    bytes: u64,
    /// The most bytes the pages may hold this frame.
    cap: u64,
}

impl PageCache {
    /// An empty cache of pages of `page_bytes` (0: off).
    pub(super) fn new(page_bytes: u64) -> Self {
        Self {
            page_bytes,
            pages: LruMap::default(),
            bytes: 0,
            cap: 0,
        }
    }

    /// Bytes held (part of the footprint).
    pub(super) fn bytes(&self) -> u64 {
        self.bytes
    }

    /// The pages `offset..offset + len` lies in (first, last).
    pub(super) fn span(&self, offset: u64, len: u64) -> (u64, u64) {
        let p = self.page_bytes.max(1);
        (offset / p, (offset + len.max(1) - 1) / p)
    }

    /// Whether every page of `offset..offset + len` is held (no use recorded).
    pub(super) fn covers(&self, offset: u64, len: u64) -> bool {
        let (a, b) = self.span(offset, len);
        (a..=b).all(|p| self.pages.contains(p))
    }

    /// The first page of `offset..offset + len` not held.
    pub(super) fn first_missing(&self, offset: u64, len: u64) -> Option<u64> {
        let (a, b) = self.span(offset, len);
        (a..=b).find(|p| !self.pages.contains(*p))
    }

    /// Copies `offset..offset + buf.len()` out of the held pages (each
    /// used now); false when one is not held.
    pub(super) fn copy_out(&mut self, offset: u64, buf: &mut [u8]) -> bool {
        if !self.covers(offset, buf.len() as u64) {
            return false;
        }
        let mut at = 0usize;
        while at < buf.len() {
            let pos = offset + at as u64;
            let (page, within) = (pos / self.page_bytes, (pos % self.page_bytes) as usize);
            let Some(data) = self.pages.get(page) else {
                return false;
            };
            if within >= data.len() {
                return false;
            }
            let n = (data.len() - within).min(buf.len() - at);
            buf[at..at + n].copy_from_slice(&data[within..within + n]);
            at += n;
        }
        true
    }

    /// Holds page `page` (its bytes; room made first).
    pub(super) fn insert(&mut self, page: u64, data: Arc<[u8]>) {
        self.bytes += data.len() as u64;
        if let Some(old) = self.pages.put(page, data) {
            self.bytes -= old.len() as u64;
        }
    }

    /// Makes `page` the first to go (no use recorded).
    pub(super) fn demote(&mut self, page: u64) {
        self.pages.demote(page);
    }

    /// Drops the least recently used page; its bytes, or `None` when empty.
    pub(super) fn evict_lru(&mut self) -> Option<u64> {
        let (_, data) = self.pages.pop_victim()?;
        self.bytes -= data.len() as u64;
        Some(data.len() as u64)
    }

    /// The most bytes the pages may hold.
    pub(super) fn cap(&self) -> u64 {
        self.cap
    }

    /// Sets the most bytes the pages may hold; least recently used pages
    /// over it go.
    pub(super) fn set_cap(&mut self, cap: u64) {
        self.cap = cap;
        while self.bytes > cap && self.evict_lru().is_some() {}
    }

    /// Drops every page.
    pub(super) fn clear(&mut self) {
        self.pages.clear();
        self.bytes = 0;
    }

    /// The byte count equals the pages' sizes, each at most a page.
    #[cfg(any(test, debug_assertions))]
    pub(super) fn validate(&self) -> Result<(), String> {
        self.pages.validate()?;
        let sum: u64 = self.pages.values().map(|(_, d)| d.len() as u64).sum();
        if sum != self.bytes {
            return Err(format!("page bytes {} but pages hold {sum}", self.bytes));
        }
        if let Some((p, _)) = self
            .pages
            .values()
            .find(|(_, d)| d.len() as u64 > self.page_bytes)
        {
            return Err(format!("page {p} is longer than a page"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pages_copy_across_boundaries_and_evict_oldest_first() {
        let mut c = PageCache::new(4);
        assert_eq!(c.span(3, 2), (0, 1));
        assert_eq!(c.span(4, 4), (1, 1));
        assert_eq!(c.first_missing(2, 4), Some(0));
        c.insert(0, Arc::from(&[0u8, 1, 2, 3][..]));
        c.insert(1, Arc::from(&[4u8, 5, 6, 7][..]));
        c.insert(2, Arc::from(&[8u8, 9][..]));
        assert_eq!(c.bytes(), 10);
        let mut b = [0u8; 6];
        assert!(c.copy_out(2, &mut b));
        assert_eq!(b, [2, 3, 4, 5, 6, 7]);
        // Past the end of the short last page.
        assert!(!c.copy_out(9, &mut [0u8; 2]));
        // Page 0 is now the least recently used (page 2 was just looked at).
        assert_eq!(c.evict_lru(), Some(4));
        assert!(!c.covers(3, 1));
        assert_eq!(c.first_missing(2, 7), Some(0));
        assert_eq!(c.first_missing(4, 5), None);
        c.validate().unwrap();
        c.clear();
        assert_eq!(c.bytes(), 0);
        c.validate().unwrap();
    }

    #[test]
    fn a_spent_page_goes_first() {
        let mut c = PageCache::new(4);
        for p in 0..3 {
            c.insert(p, Arc::from(&[p as u8; 4][..]));
        }
        // Page 2 was read last, but it is spent: it goes before 0 and 1.
        c.demote(2);
        assert_eq!(c.evict_lru(), Some(4));
        assert!(!c.covers(8, 4) && c.covers(0, 8));
        // A use after that counts again: page 0 is used, page 1 goes next.
        assert!(c.copy_out(0, &mut [0u8; 2]));
        assert_eq!(c.evict_lru(), Some(4));
        assert!(c.covers(0, 4) && !c.covers(4, 4));
        c.validate().unwrap();
    }
}
