//! A least-recently-used cache with a byte budget, generic so it is tested without a GPU;
//! the renderer keeps chunk buffers in it.
//!
//! Eviction drops the least recently used entries until the total fits the budget, but never
//! an entry used in the current frame: when one frame's working set is larger than the
//! budget, the cache holds it anyway (and [`LruCache::bytes`] reports the overshoot) rather
//! than thrash mid-frame.

use std::collections::HashMap;
use std::hash::Hash;

struct Entry<V> {
    value: V,
    bytes: u64,
    last_used: u64,
}

/// An LRU cache of values with sizes.
pub struct LruCache<K, V> {
    budget: u64,
    bytes: u64,
    frame: u64,
    entries: HashMap<K, Entry<V>>,
    evictions: u64,
}

impl<K: Hash + Eq + Clone, V> LruCache<K, V> {
    /// An empty cache holding at most `budget` bytes (outside one frame's working set).
    pub fn new(budget: u64) -> Self {
        Self {
            budget,
            bytes: 0,
            frame: 0,
            entries: HashMap::new(),
            evictions: 0,
        }
    }
    /// Starts a new frame (entries used from now on are protected until the next call).
    pub fn begin_frame(&mut self) {
        self.frame += 1;
    }
    /// Looks up `key`, marking it used this frame.
    pub fn get(&mut self, key: &K) -> Option<&V> {
        let frame = self.frame;
        self.entries.get_mut(key).map(|e| {
            e.last_used = frame;
            &e.value
        })
    }
    /// Looks up `key` without marking it used.
    pub fn peek(&self, key: &K) -> Option<&V> {
        self.entries.get(key).map(|e| &e.value)
    }
    /// True if `key` is cached (does not mark it used).
    pub fn contains(&self, key: &K) -> bool {
        self.entries.contains_key(key)
    }
    /// Inserts `value` of `bytes`, used this frame, then evicts down to the budget.
    pub fn insert(&mut self, key: K, value: V, bytes: u64) {
        let e = Entry {
            value,
            bytes,
            last_used: self.frame,
        };
        if let Some(old) = self.entries.insert(key, e) {
            self.bytes -= old.bytes;
        }
        self.bytes += bytes;
        self.evict();
    }
    fn evict(&mut self) {
        if self.bytes <= self.budget {
            return;
        }
        let mut old: Vec<(u64, K)> = self
            .entries
            .iter()
            .filter(|(_, e)| e.last_used < self.frame)
            .map(|(k, e)| (e.last_used, k.clone()))
            .collect();
        old.sort_by_key(|(t, _)| *t);
        for (_, k) in old {
            if self.bytes <= self.budget {
                break;
            }
            if let Some(e) = self.entries.remove(&k) {
                self.bytes -= e.bytes;
                self.evictions += 1;
            }
        }
    }
    /// Bytes held.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }
    /// Entries held.
    pub fn len(&self) -> usize {
        self.entries.len()
    }
    /// True if empty.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
    /// Entries evicted so far.
    pub fn evictions(&self) -> u64 {
        self.evictions
    }
    /// The keys held.
    pub fn keys(&self) -> impl Iterator<Item = &K> {
        self.entries.keys()
    }
    /// Drops everything.
    pub fn clear(&mut self) {
        self.entries.clear();
        self.bytes = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn evicts_least_recently_used_but_not_this_frame() {
        let mut c = LruCache::new(100);
        c.begin_frame();
        c.insert(1, (), 40);
        c.insert(2, (), 40);
        c.begin_frame();
        assert!(c.get(&1).is_some()); // 1 is now more recent than 2
        c.insert(3, (), 40); // 120 > 100: evict 2 (oldest, not used this frame)
        assert!(c.contains(&1) && !c.contains(&2) && c.contains(&3));
        assert_eq!(c.bytes(), 80);
        // A frame whose working set exceeds the budget keeps it all.
        c.begin_frame();
        c.get(&1);
        c.get(&3);
        c.insert(4, (), 60);
        assert_eq!(c.len(), 3);
        assert_eq!(c.bytes(), 140);
        assert_eq!(c.evictions(), 1);
        // Next frame, using only 4, the others go.
        c.begin_frame();
        c.get(&4);
        c.insert(5, (), 10);
        assert!(c.contains(&4) && c.contains(&5) && c.bytes() <= 100);
    }
}
