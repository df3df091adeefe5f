//! Fixed-capacity observation store with deterministic thinning, so the estimators'
//! memory is bounded independently of how many frames a run produces.
//!
//! Items are kept when their offer index is a multiple of `stride`. When the store is
//! full, the items off the doubled stride are dropped (those left are exactly the
//! multiples of `2 * stride`): the kept set is always an evenly spaced subsample of
//! everything offered, independent of timing, so a run is reproducible.
//!
//! A store whose dropped items are folded into normal equations
//! ([`super::folded`]) must not drop half of itself in one offer: folding 128 frames
//! at once would cost the M4F tens of millions of instructions in one frame. Its
//! items off the doubled stride stay in place (still raw, still in every estimate)
//! until a new item needs their slot: then one is folded and overwritten
//! ([`ThinningSchedule::place`]). One fold per offer at most, and the kept set is
//! the same evenly spaced subsample once the pass is over.

use heapless::Vec;

/// What to do with one offered item under the thinning rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Admission {
    /// Not on the current stride: drop it.
    Skip,
    /// On the stride and there is room: keep it.
    Keep,
    /// The store is full: drop the kept items off the doubled stride first, then
    /// keep this one if it is still on it.
    Halve {
        /// Whether the new item is kept after halving.
        keep: bool,
    },
}

/// Where a store that folds what it drops puts an offered item (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Placement {
    /// Off the stride: fold the offered item itself.
    FoldOffered,
    /// There is room: append it.
    Append,
    /// Fold the item in this slot (off the stride), then put the offered one there.
    Replace(usize),
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
        let index = self.next_index();
        if capacity == 0 || !self.on_stride(index) {
            return Admission::Skip;
        }
        if len >= capacity {
            self.stride = self.stride.saturating_mul(2);
            return Admission::Halve {
                keep: self.on_stride(index),
            };
        }
        Admission::Keep
    }

    /// Decides where the next offered item goes in a store that folds what it drops
    /// and holds the items offered at `indices` (in any order) of `capacity`; returns
    /// the item's offer index with it. At most one item is folded per offer.
    pub fn place(&mut self, indices: &[u32], capacity: usize) -> (u32, Placement) {
        let index = self.next_index();
        if capacity == 0 || !self.on_stride(index) {
            return (index, Placement::FoldOffered);
        }
        if indices.len() < capacity {
            return (index, Placement::Append);
        }
        if let Some(slot) = self.off_stride_slot(indices) {
            return (index, Placement::Replace(slot));
        }
        // Full and every item on the stride: the next pass of halving begins.
        self.stride = self.stride.saturating_mul(2);
        match self.off_stride_slot(indices) {
            Some(slot) if self.on_stride(index) => (index, Placement::Replace(slot)),
            _ => (index, Placement::FoldOffered),
        }
    }

    /// Whether an item offered at `index` is on the current stride.
    pub fn on_stride(&self, index: u32) -> bool {
        index.is_multiple_of(self.stride.max(1))
    }

    fn off_stride_slot(&self, indices: &[u32]) -> Option<usize> {
        indices.iter().position(|&index| !self.on_stride(index))
    }

    fn next_index(&mut self) -> u32 {
        let index = self.offered;
        self.offered = self.offered.saturating_add(1);
        index
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

/// `items[to] = items[from]` where both exist (a store's compaction).
pub(super) fn move_item<T: Copy>(items: &mut [T], from: usize, to: usize) {
    if let Some(value) = items.get(from).copied() {
        if let Some(slot) = items.get_mut(to) {
            *slot = value;
        }
    }
}

/// An evenly thinned subsample of at most `N` items.
#[derive(Debug, Clone)]
pub struct ThinningStore<T, const N: usize> {
    items: Vec<T, N>,
    /// Each item's offer index.
    indices: Vec<u32, N>,
    schedule: ThinningSchedule,
}

impl<T: Copy, const N: usize> ThinningStore<T, N> {
    /// An empty store.
    pub const fn new() -> Self {
        Self {
            items: Vec::new(),
            indices: Vec::new(),
            schedule: ThinningSchedule::new(),
        }
    }

    /// Offer one item; it is kept if it falls on the current stride.
    pub fn offer(&mut self, item: T) {
        let index = self.schedule.offered();
        let keep = match self.schedule.admit(self.items.len(), N) {
            Admission::Skip => false,
            Admission::Keep => true,
            Admission::Halve { keep } => {
                // One pass, in order: the items on the doubled stride move down.
                let mut kept = 0;
                for from in 0..self.items.len() {
                    let on_stride = self
                        .indices
                        .get(from)
                        .is_some_and(|&index| self.schedule.on_stride(index));
                    if on_stride {
                        move_item(&mut self.items, from, kept);
                        move_item(&mut self.indices, from, kept);
                        kept += 1;
                    }
                }
                self.items.truncate(kept);
                self.indices.truncate(kept);
                keep
            }
        };
        // Fails only for N == 1, where halving frees nothing: the item is dropped.
        if keep && self.items.push(item).is_ok() && self.indices.push(index).is_err() {
            self.items.pop();
        }
    }

    /// [`ThinningStore::offer`] for a store that folds what it drops: `fold` gets
    /// every item that leaves, at most one per offer (see the module doc).
    pub fn offer_folding(&mut self, item: T, mut fold: impl FnMut(&T)) {
        let (index, placement) = self.schedule.place(&self.indices, N);
        match placement {
            Placement::FoldOffered => fold(&item),
            Placement::Append => {
                if self.items.push(item).is_ok() && self.indices.push(index).is_err() {
                    self.items.pop();
                }
            }
            Placement::Replace(slot) => {
                if let (Some(kept), Some(kept_index)) =
                    (self.items.get_mut(slot), self.indices.get_mut(slot))
                {
                    fold(kept);
                    *kept = item;
                    *kept_index = index;
                }
            }
        }
    }

    /// The kept items, in no particular order once the store has folded.
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
    fn folding_drops_one_item_an_offer_and_keeps_the_same_subsample() {
        let mut plain: ThinningStore<u32, 8> = ThinningStore::new();
        let mut folding: ThinningStore<u32, 8> = ThinningStore::new();
        let mut folded = std::vec::Vec::new();
        for i in 0..200 {
            plain.offer(i);
            let before = folded.len();
            folding.offer_folding(i, |item| folded.push(*item));
            assert!(
                folded.len() - before <= 1,
                "offer {i} folded {}",
                folded.len() - before
            );
            let mut kept = folding.items().to_vec();
            kept.sort_unstable();
            // Between passes the folding store holds what the plain one does, and
            // nothing is lost in any case.
            if kept.len() == plain.items().len() {
                assert_eq!(kept, plain.items(), "offer {i}");
            }
            let mut all: std::vec::Vec<u32> = kept.iter().chain(&folded).copied().collect();
            all.sort_unstable();
            assert_eq!(all, (0..=i).collect::<std::vec::Vec<_>>());
        }
    }

    #[test]
    fn zero_capacity_keeps_nothing() {
        let mut store: ThinningStore<u32, 0> = ThinningStore::new();
        store.offer(1);
        assert!(store.items().is_empty());
    }
}
