//! The calibrator's frame store: every kept frame's conveyor angle and its pixels
//! (disc centre, reference point, the part's features), packed at the part's own
//! feature count and evenly thinned when full (the rule of [`super::store`]).
//!
//! Why packed: a frame laid out for [`MAX_PART_FEATURES`] features whether or not the
//! part has them was 104 bytes; the pick's part has three, so most of the store was
//! zeros. Here a frame is an f64 angle, a presence byte and `2 + part_feature_count`
//! f32 pixels, and the pixel budget `N * P` decides how many frames fit: the pick's
//! 256 frames of a three-feature part take 12.3 KiB instead of 26 KiB. The values are
//! stored exactly as before (f64 angle, f32 pixels), so every estimate is unchanged.

use super::records::{FrameRecord, PixelF32};
use super::store::{move_item, Admission, Placement, ThinningSchedule};
use crate::observation::MAX_PART_FEATURES;
use heapless::Vec;

/// Pixels of a frame of a part with the most features: the default budget, with which
/// every frame count up to `N` fits whatever the part.
pub const FULL_FRAME_PIXELS: usize = 2 + MAX_PART_FEATURES;

const CENTRE: u8 = 1;
const REFERENCE: u8 = 2;
const PART: u8 = 4;

/// At most `N` frames in a budget of `N * P` pixels (`P` per frame on average).
///
/// The storage is `heapless::Vec`s, not zeroed arrays: an empty store is then
/// uninitialised memory, which the compiler builds in place, where zeroed arrays
/// were built on the stack and copied (20 KB of stack for the pick's calibrator).
#[derive(Debug, Clone)]
pub struct FrameStore<const N: usize, const P: usize = FULL_FRAME_PIXELS> {
    thetas: Vec<f64, N>,
    /// Which of centre, reference and part the frame holds (bits above).
    presence: Vec<u8, N>,
    /// Read as one flat run of pixels, frame `i` at `i * pixels_per_frame`; rows are
    /// added as the frames need them.
    pixels: Vec<[PixelF32; P], N>,
    pixels_per_frame: usize,
    /// Each frame's offer index (which frames a halving keeps).
    indices: Vec<u32, N>,
    schedule: ThinningSchedule,
}

impl<const N: usize, const P: usize> FrameStore<N, P> {
    /// An empty store for frames of a part with `part_feature_count` features.
    pub fn new(part_feature_count: usize) -> Self {
        Self {
            thetas: Vec::new(),
            presence: Vec::new(),
            pixels: Vec::new(),
            pixels_per_frame: part_feature_count.saturating_add(2),
            indices: Vec::new(),
            schedule: ThinningSchedule::new(),
        }
    }

    /// Frames it can hold: `N`, or fewer when a frame's pixels exceed the budget's `P`.
    pub fn capacity(&self) -> usize {
        (N.saturating_mul(P) / self.pixels_per_frame).min(N)
    }

    /// Whether a frame can be appended without thinning.
    pub fn has_room(&self) -> bool {
        self.len() < self.capacity()
    }

    /// Frames stored.
    pub fn len(&self) -> usize {
        self.thetas.len()
    }

    /// No frame stored.
    pub fn is_empty(&self) -> bool {
        self.thetas.is_empty()
    }

    /// Offer one frame; it is kept if it falls on the thinning stride. Part features
    /// beyond `part_feature_count` are not stored; missing ones are stored as zeros.
    pub fn offer(&mut self, record: &FrameRecord<'_>) {
        let capacity = self.capacity();
        let index = self.schedule.offered();
        let keep = match self.schedule.admit(self.len(), capacity) {
            Admission::Skip => false,
            Admission::Keep => true,
            Admission::Halve { keep } => {
                self.halve();
                keep
            }
        };
        if keep && self.len() < capacity {
            self.write(self.len(), record, index);
        }
    }

    /// [`FrameStore::offer`] for a store that folds what it drops: `fold` gets every
    /// frame that leaves, at most one per offer ([`ThinningSchedule::place`]).
    pub fn offer_folding(
        &mut self,
        record: &FrameRecord<'_>,
        mut fold: impl FnMut(&FrameRecord<'_>),
    ) {
        let (index, placement) = self.schedule.place(&self.indices, self.capacity());
        match placement {
            Placement::FoldOffered => fold(record),
            Placement::Append => self.write(self.len(), record, index),
            Placement::Replace(slot) => {
                if let Some(leaving) = self.view().get(slot) {
                    fold(&leaving);
                }
                self.write(slot, record, index);
            }
        }
    }

    /// How many frames were offered in total (kept or not).
    pub fn offered(&self) -> u32 {
        self.schedule.offered()
    }

    /// The kept frames, oldest first.
    pub fn view(&self) -> FrameView<'_> {
        let pixel_count = self.len().saturating_mul(self.pixels_per_frame);
        FrameView {
            thetas: &self.thetas,
            presence: &self.presence,
            pixels: self.pixels.as_flattened().get(..pixel_count).unwrap_or(&[]),
            pixels_per_frame: self.pixels_per_frame,
        }
    }

    /// Writes a frame offered at `index` into `slot`: a stored frame's (replacing
    /// it) or the next free one (`slot == len`, the caller checked there is room).
    fn write(&mut self, slot: usize, record: &FrameRecord<'_>, index: u32) {
        let start = slot.saturating_mul(self.pixels_per_frame);
        let end = start.saturating_add(self.pixels_per_frame);
        while self.pixels.len().saturating_mul(P) < end {
            if self.pixels.push([[0.0; 2]; P]).is_err() {
                return;
            }
        }
        let Some(pixels) = self.pixels.as_flattened_mut().get_mut(start..end) else {
            return;
        };
        let features = record.part.unwrap_or(&[]);
        let stored = [record.centre, record.reference]
            .into_iter()
            .map(Option::unwrap_or_default)
            .chain(features.iter().copied().chain(core::iter::repeat([0.0; 2])));
        for (slot, pixel) in pixels.iter_mut().zip(stored) {
            *slot = pixel;
        }
        let bit = |present: bool, bit: u8| if present { bit } else { 0 };
        let presence = bit(record.centre.is_some(), CENTRE)
            | bit(record.reference.is_some(), REFERENCE)
            | bit(record.part.is_some(), PART);
        if slot < self.len() {
            let fields = (
                self.thetas.get_mut(slot),
                self.presence.get_mut(slot),
                self.indices.get_mut(slot),
            );
            if let (Some(theta), Some(bits), Some(offer)) = fields {
                *theta = record.theta;
                *bits = presence;
                *offer = index;
            }
            return;
        }
        // All three have room: the pixels did, and they grow together up to `N`.
        if self.thetas.push(record.theta).is_ok() {
            if self.presence.push(presence).is_err() {
                self.thetas.pop();
            } else if self.indices.push(index).is_err() {
                self.thetas.pop();
                self.presence.pop();
            }
        }
    }

    /// Keeps the frames on the (just doubled) stride, in their order (the thinning
    /// rule's halving).
    fn halve(&mut self) {
        let width = self.pixels_per_frame;
        let mut kept = 0;
        for from in 0..self.len() {
            let on_stride = self
                .indices
                .get(from)
                .is_some_and(|&index| self.schedule.on_stride(index));
            if !on_stride {
                continue;
            }
            if from != kept {
                move_item(&mut self.thetas, from, kept);
                move_item(&mut self.presence, from, kept);
                move_item(&mut self.indices, from, kept);
                let pixels = self.pixels.as_flattened_mut();
                for offset in 0..width {
                    move_item(pixels, from * width + offset, kept * width + offset);
                }
            }
            kept += 1;
        }
        self.thetas.truncate(kept);
        self.presence.truncate(kept);
        self.indices.truncate(kept);
        self.pixels
            .truncate(kept.saturating_mul(width).div_ceil(P.max(1)));
    }
}

/// A read-only view of a [`FrameStore`]'s kept frames, independent of its capacities
/// (what the refinement's [`super::refine::Problem`] holds).
#[derive(Debug, Clone, Copy)]
pub struct FrameView<'a> {
    thetas: &'a [f64],
    presence: &'a [u8],
    pixels: &'a [PixelF32],
    pixels_per_frame: usize,
}

impl<'a> FrameView<'a> {
    /// Frames in view.
    pub fn len(&self) -> usize {
        self.thetas.len()
    }

    /// No frame in view.
    pub fn is_empty(&self) -> bool {
        self.thetas.is_empty()
    }

    /// The frame in `slot`.
    pub fn get(&self, slot: usize) -> Option<FrameRecord<'a>> {
        let theta = *self.thetas.get(slot)?;
        let presence = *self.presence.get(slot)?;
        let start = slot.saturating_mul(self.pixels_per_frame);
        let pixels = self
            .pixels
            .get(start..start.saturating_add(self.pixels_per_frame))?;
        let (centre, reference, part) = match pixels {
            [centre, reference, part @ ..] => (*centre, *reference, part),
            _ => return None,
        };
        let has = |bit: u8| presence & bit != 0;
        Some(FrameRecord {
            theta,
            centre: has(CENTRE).then_some(centre),
            reference: has(REFERENCE).then_some(reference),
            part: has(PART).then_some(part),
        })
    }

    /// The frames, oldest first until the store folds (then in no particular order).
    pub fn iter(&self) -> FrameIter<'a> {
        FrameIter {
            view: *self,
            next: 0,
        }
    }
}

/// The frames of a [`FrameView`], oldest first.
#[derive(Debug, Clone)]
pub struct FrameIter<'a> {
    view: FrameView<'a>,
    next: usize,
}

impl<'a> Iterator for FrameIter<'a> {
    type Item = FrameRecord<'a>;

    /// Out of line: the calibrator walks its frames in a dozen places, and this
    /// body inlined into each cost the firmware 5 KB of flash.
    #[inline(never)]
    fn next(&mut self) -> Option<FrameRecord<'a>> {
        let frame = self.view.get(self.next)?;
        self.next = self.next.saturating_add(1);
        Some(frame)
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let left = self.view.len().saturating_sub(self.next);
        (0, Some(left))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::store::ThinningStore;

    fn record(index: usize, features: &[PixelF32]) -> FrameRecord<'_> {
        let value = index as f32;
        FrameRecord {
            theta: index as f64 * 0.01,
            centre: (!index.is_multiple_of(3)).then_some([value, 1.0]),
            reference: (!index.is_multiple_of(5)).then_some([value, 2.0]),
            part: index.is_multiple_of(2).then_some(features),
        }
    }

    #[test]
    fn keeps_what_a_thinning_store_of_records_keeps() {
        let mut packed: FrameStore<16, 5> = FrameStore::new(3);
        let mut reference: ThinningStore<(f64, Option<PixelF32>, Option<PixelF32>, bool), 16> =
            ThinningStore::new();
        let mut kept_features = std::vec::Vec::new();
        for index in 0..100 {
            let value = index as f32;
            let features = [[value, 3.0], [value, 4.0], [value, 5.0]];
            let frame = record(index, &features);
            packed.offer(&frame);
            reference.offer((
                frame.theta,
                frame.centre,
                frame.reference,
                frame.part.is_some(),
            ));
            kept_features.push(features);
        }
        assert_eq!(packed.capacity(), 16);
        assert_eq!(packed.offered(), 100);
        let view = packed.view();
        assert_eq!(view.len(), reference.items().len());
        for (frame, expected) in view.iter().zip(reference.items()) {
            assert_eq!(frame.theta, expected.0);
            assert_eq!(frame.centre, expected.1);
            assert_eq!(frame.reference, expected.2);
            assert_eq!(frame.part.is_some(), expected.3);
            let index = (frame.theta / 0.01).round() as usize;
            if let Some(part) = frame.part {
                assert_eq!(part, &kept_features[index][..]);
            }
        }
    }

    #[test]
    fn folding_keeps_every_frame_somewhere_one_fold_an_offer() {
        let mut store: FrameStore<16, 5> = FrameStore::new(3);
        let mut folded = std::vec::Vec::new();
        let features = [[1.0, 3.0], [1.0, 4.0], [1.0, 5.0]];
        let index_of = |frame: &FrameRecord<'_>| (frame.theta / 0.01).round() as usize;
        for index in 0..100 {
            let before = folded.len();
            store.offer_folding(&record(index, &features), |frame| {
                assert_eq!(
                    frame.part.map(<[_]>::len),
                    (index_of(frame) % 2 == 0).then_some(3)
                );
                folded.push(index_of(frame))
            });
            assert!(folded.len() - before <= 1);
            let mut all: std::vec::Vec<usize> = store
                .view()
                .iter()
                .map(|frame| index_of(&frame))
                .chain(folded.iter().copied())
                .collect();
            all.sort_unstable();
            assert_eq!(all, (0..=index).collect::<std::vec::Vec<_>>());
        }
        // Each stored frame is intact where it landed.
        for frame in store.view().iter() {
            let index = index_of(&frame);
            assert_eq!(frame.reference.is_some(), index % 5 != 0);
            assert_eq!(
                frame.centre,
                (index % 3 != 0).then_some([index as f32, 1.0])
            );
        }
    }

    #[test]
    fn a_part_with_more_features_fits_fewer_frames() {
        let small: FrameStore<256, 5> = FrameStore::new(3);
        assert_eq!(small.capacity(), 256);
        let large: FrameStore<256, 5> = FrameStore::new(MAX_PART_FEATURES);
        assert_eq!(large.capacity(), 128);
        let full: FrameStore<256> = FrameStore::new(MAX_PART_FEATURES);
        assert_eq!(full.capacity(), 256);
    }

    #[test]
    fn stores_exactly_the_feature_count() {
        let mut store: FrameStore<4, 4> = FrameStore::new(2);
        let too_many = [[1.0, 1.0], [2.0, 2.0], [3.0, 3.0]];
        store.offer(&FrameRecord {
            theta: 0.5,
            centre: None,
            reference: Some([7.0, 8.0]),
            part: Some(&too_many),
        });
        let too_few = [[9.0, 9.0]];
        store.offer(&FrameRecord {
            theta: 0.6,
            centre: Some([1.0, 2.0]),
            reference: None,
            part: Some(&too_few),
        });
        let frames: std::vec::Vec<_> = store.view().iter().collect();
        assert_eq!(frames.len(), 2);
        assert_eq!(frames[0].centre, None);
        assert_eq!(frames[0].reference, Some([7.0, 8.0]));
        assert_eq!(frames[0].part, Some(&too_many[..2]));
        assert_eq!(frames[1].part, Some(&[[9.0, 9.0], [0.0, 0.0]][..]));
    }

    #[test]
    fn zero_capacity_keeps_nothing() {
        let mut store: FrameStore<0, 5> = FrameStore::new(3);
        store.offer(&record(0, &[]));
        assert!(store.view().is_empty());
        assert_eq!(store.offered(), 1);
    }
}
