//! Fixed-capacity observation store with deterministic thinning, so the estimators'
//! memory is bounded independently of how many frames a run produces.
//!
//! Items are kept when their offer index is a multiple of `stride`. When the store is
//! full, every other kept item is dropped (those left are exactly the multiples of
//! `2 * stride`) and the stride doubles: the kept set is always an evenly spaced subsample
//! of everything offered, independent of timing, so a run is reproducible.

use heapless::Vec;

/// What to do with one offered item under the thinning rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Admission {
    /// Not on the current stride: drop it.
    Skip,
    /// On the stride and there is room: keep it.
    Keep,
    /// The store is full: drop every other kept item first (keep positions 0, 2, 4 ...),
    /// then keep this one if it is still on the (doubled) stride.
    Halve {
        /// Whether the new item is kept after halving.
        keep: bool,
    },
}

/// The thinning rule itself, shared by every store that thins (see the module doc).
#[derive(Debug, Clone, Copy)]
pub struct ThinningSchedule {
    stride: u32,
    offered: u32,
}

impl ThinningSchedule {
    /// Keeping every item.
    pub const fn new() -> Self {
        Self {
            stride: 1,
            offered: 0,
        }
    }

    /// Decides the next offered item's fate for a store holding `len` of `capacity`.
    pub fn admit(&mut self, len: usize, capacity: usize) -> Admission {
        let index = self.offered;
        self.offered = self.offered.saturating_add(1);
        if capacity == 0 || !index.is_multiple_of(self.stride) {
            return Admission::Skip;
        }
        if len >= capacity {
            self.stride = self.stride.saturating_mul(2);
            return Admission::Halve {
                keep: index.is_multiple_of(self.stride),
            };
        }
        Admission::Keep
    }

    /// How many items were offered in total (kept or not).
    pub fn offered(&self) -> u32 {
        self.offered
    }
}

impl Default for ThinningSchedule {
    fn default() -> Self {
        Self::new()
    }
}

/// An evenly thinned subsample of at most `N` items.
#[derive(Debug, Clone)]
pub struct ThinningStore<T, const N: usize> {
    items: Vec<T, N>,
    schedule: ThinningSchedule,
}

impl<T: Copy, const N: usize> ThinningStore<T, N> {
    /// An empty store.
    pub const fn new() -> Self {
        Self {
            items: Vec::new(),
            schedule: ThinningSchedule::new(),
        }
    }

    /// Offer one item; it is kept if it falls on the current stride.
    pub fn offer(&mut self, item: T) {
        let keep = match self.schedule.admit(self.items.len(), N) {
            Admission::Skip => false,
            Admission::Keep => true,
            Admission::Halve { keep } => {
                let mut position = 0usize;
                self.items.retain(|_| {
                    let kept = position.is_multiple_of(2);
                    position += 1;
                    kept
                });
                keep
            }
        };
        if keep {
            // Fails only for N == 1, where halving frees nothing: the item is dropped.
            let _ = self.items.push(item);
        }
    }

    /// The kept items, oldest first.
    pub fn items(&self) -> &[T] {
        &self.items
    }

    /// How many items were offered in total (kept or not).
    pub fn offered(&self) -> u32 {
        self.schedule.offered()
    }
}

impl<T: Copy, const N: usize> Default for ThinningStore<T, N> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_everything_until_full_then_thins_evenly() {
        let mut store: ThinningStore<u32, 8> = ThinningStore::new();
        for i in 0..8 {
            store.offer(i);
        }
        assert_eq!(store.items(), &[0, 1, 2, 3, 4, 5, 6, 7]);
        for i in 8..40 {
            store.offer(i);
        }
        assert_eq!(store.items().len(), 5);
        assert_eq!(store.items(), &[0, 8, 16, 24, 32]);
        assert_eq!(store.offered(), 40);
    }

    #[test]
    fn zero_capacity_keeps_nothing() {
        let mut store: ThinningStore<u32, 0> = ThinningStore::new();
        store.offer(1);
        assert!(store.items().is_empty());
    }
}
