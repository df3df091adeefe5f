//! Connected components of the foreground in one pass over the rows, in fixed
//! memory whatever the image holds.
//!
//! Each row's pixels are labelled from their eight-connected neighbours in the
//! row above and to the left; labels that meet are merged (union-find) and
//! their sums with them. When a row has been labelled, every component that
//! reaches no pixel of it can grow no further: its sums are handed on and its
//! slot is free for a later component. So memory depends on how many
//! components are open across one row, never on how many the image holds;
//! more than [`MAX_OPEN_COMPONENTS`] open at once refuses the frame.
//!
//! The sums are exact integers: pixel count and coordinate moments for the
//! shape, and moments weighted by each pixel's contrast above the local
//! background for the sub-pixel centroid.

use super::image::MAX_WIDTH_PX;

/// Components open across one row at most (a slot is 88 bytes: 8.25 KiB).
/// Real marks are a few across a row; a 256-pixel row can hold 128
/// separate components (every other pixel), which only noise or a grating
/// makes, and which refuses the frame.
pub const MAX_OPEN_COMPONENTS: usize = 96;

/// No label (background).
const NONE: u16 = u16::MAX;

/// The exact sums of one component.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ComponentSums {
    /// Pixels.
    pub area: u32,
    /// Sum of x, of y, of x^2, of y^2 and of x y over the pixels.
    pub sx: u64,
    /// Sum of y.
    pub sy: u64,
    /// Sum of x^2.
    pub sxx: u64,
    /// Sum of y^2.
    pub syy: u64,
    /// Sum of x y.
    pub sxy: u64,
    /// Sum of the contrast weights.
    pub sw: u64,
    /// Sum of weight times x.
    pub swx: u64,
    /// Sum of weight times y.
    pub swy: u64,
    /// Brightest contrast.
    pub peak: u8,
    /// Bounding box: first and last column, first and last row.
    pub x_min: u16,
    /// Last column.
    pub x_max: u16,
    /// First row.
    pub y_min: u16,
    /// Last row.
    pub y_max: u16,
}

impl ComponentSums {
    fn pixel(x: u16, y: u16, weight: u8) -> Self {
        let (xl, yl, w) = (u64::from(x), u64::from(y), u64::from(weight));
        Self {
            area: 1,
            sx: xl,
            sy: yl,
            sxx: xl * xl,
            syy: yl * yl,
            sxy: xl * yl,
            sw: w,
            swx: w * xl,
            swy: w * yl,
            peak: weight,
            x_min: x,
            x_max: x,
            y_min: y,
            y_max: y,
        }
    }

    fn absorb(&mut self, other: &Self) {
        self.area += other.area;
        self.sx += other.sx;
        self.sy += other.sy;
        self.sxx += other.sxx;
        self.syy += other.syy;
        self.sxy += other.sxy;
        self.sw += other.sw;
        self.swx += other.swx;
        self.swy += other.swy;
        self.peak = self.peak.max(other.peak);
        self.x_min = self.x_min.min(other.x_min);
        self.x_max = self.x_max.max(other.x_max);
        self.y_min = self.y_min.min(other.y_min);
        self.y_max = self.y_max.max(other.y_max);
    }
}

/// Why the labelling stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ComponentError {
    /// More than [`MAX_OPEN_COMPONENTS`] components open across row `row`.
    TooManyOpen {
        /// The row at which the table ran out.
        row: u16,
    },
}

/// One slot of the label table.
#[derive(Debug, Clone, Copy)]
struct Slot {
    /// Union-find parent (itself for a root).
    parent: u16,
    sums: ComponentSums,
}

const FREE: Slot = Slot {
    parent: NONE,
    sums: ComponentSums {
        area: 0,
        sx: 0,
        sy: 0,
        sxx: 0,
        syy: 0,
        sxy: 0,
        sw: 0,
        swx: 0,
        swy: 0,
        peak: 0,
        x_min: 0,
        x_max: 0,
        y_min: 0,
        y_max: 0,
    },
};

/// A set of slots, one bit each.
type SlotSet = u128;
const _: () = assert!(MAX_OPEN_COMPONENTS <= SlotSet::BITS as usize);

/// Column spans a row is labelled over, at most (a row's 16-pixel
/// segments and its two ends; more are merged into the last).
pub const MAX_SPANS: usize = MAX_WIDTH_PX / 16 + 2;

/// Half-open column spans `(start, end)`, in order.
type Spans = heapless::Vec<(u16, u16), MAX_SPANS>;

/// One row's labels and the spans they were written over.
#[derive(Debug, Clone)]
struct RowLabels {
    /// Label of each pixel (none outside `spans`).
    cells: [u16; MAX_WIDTH_PX],
    spans: Spans,
}

const CLEAR_ROW: RowLabels = RowLabels {
    cells: [NONE; MAX_WIDTH_PX],
    spans: Spans::new(),
};

/// The labeller's working memory: two rows of labels with their spans and
/// the slot table (2.3 KiB + 8.25 KiB).
#[derive(Debug, Clone)]
pub struct Labeller {
    /// The row above (its roots) and the row being labelled; which is
    /// which flips from row to row, so that no row is copied.
    rows: [RowLabels; 2],
    /// `rows[1]` is the row above.
    flip: bool,
    slots: [Slot; MAX_OPEN_COMPONENTS],
    /// Slots in use.
    open: SlotSet,
    width: usize,
    row: u16,
}

impl Labeller {
    /// A labeller for rows of `width` pixels (at most [`MAX_WIDTH_PX`]).
    pub fn new(width: usize) -> Self {
        Self {
            rows: [CLEAR_ROW; 2],
            flip: false,
            slots: [FREE; MAX_OPEN_COMPONENTS],
            open: 0,
            width: width.min(MAX_WIDTH_PX),
            row: 0,
        }
    }

    /// Labels the next row: `weights[x]` is the pixel's contrast above the
    /// background, 0 for background. Every component closed by this row is
    /// passed to `closed`.
    pub fn push_row(
        &mut self,
        weights: &[u8],
        closed: impl FnMut(&ComponentSums),
    ) -> Result<(), ComponentError> {
        self.push_spans(weights, &[(0, weights.len())], closed)
    }

    /// Labels the next row over the half-open column `spans` only (in
    /// order, not overlapping): every pixel outside them is background and
    /// its weight is not read. A frame's marks cover a few of a row's
    /// segments; the rest, which the caller has shown to hold no pixel
    /// above its threshold, costs nothing here.
    pub fn push_spans(
        &mut self,
        weights: &[u8],
        spans: &[(usize, usize)],
        mut closed: impl FnMut(&ComponentSums),
    ) -> Result<(), ComponentError> {
        let y = self.row;
        let columns = self.width.min(weights.len());
        // A row left half labelled by an error leaves no label behind.
        let row = self.current();
        for &(start, end) in row.spans.iter() {
            if let Some(cells) = row.cells.get_mut(usize::from(start)..usize::from(end)) {
                cells.fill(NONE);
            }
        }
        row.spans.clear();
        let mut left = NONE;
        let mut last_end = usize::MAX;
        for &(start, end) in spans {
            let (start, end) = (start.min(columns), end.min(columns));
            if start >= end {
                continue;
            }
            // A span that does not continue the last one starts with no
            // left neighbour.
            if start != last_end {
                left = NONE;
            }
            last_end = end;
            self.note_span(start, end);
            for (x, &weight) in weights.iter().enumerate().take(end).skip(start) {
                if weight == 0 {
                    left = NONE;
                    continue;
                }
                // Neighbours already labelled: left, and the three above.
                let above = |dx: isize| -> u16 {
                    x.checked_add_signed(dx)
                        .and_then(|i| self.previous().cells.get(i).copied())
                        .unwrap_or(NONE)
                };
                let neighbours = [left, above(-1), above(0), above(1)];
                let mut root = NONE;
                for label in neighbours {
                    if label == NONE {
                        continue;
                    }
                    let other = self.find(label);
                    root = if root == NONE {
                        other
                    } else {
                        self.union(root, other)
                    };
                }
                if root == NONE {
                    root = self
                        .allocate()
                        .ok_or(ComponentError::TooManyOpen { row: y })?;
                }
                let pixel = ComponentSums::pixel(x as u16, y, weight);
                if let Some(slot) = self.slots.get_mut(usize::from(root)) {
                    if slot.sums.area == 0 {
                        slot.sums = pixel;
                    } else {
                        slot.sums.absorb(&pixel);
                    }
                }
                if let Some(cell) = self.current().cells.get_mut(x) {
                    *cell = root;
                }
                left = root;
            }
        }
        self.close_row(&mut closed);
        self.row = self.row.saturating_add(1);
        Ok(())
    }

    /// Hands on every component still open (the image has no more rows).
    pub fn finish(&mut self, mut closed: impl FnMut(&ComponentSums)) {
        self.current().spans.clear();
        self.close_row(&mut closed);
    }

    /// Records that the row is labelled over `start..end` (joined to the
    /// last span when it continues or overlaps it, or when there is no
    /// room: then the span covers both, whatever their order).
    fn note_span(&mut self, start: usize, end: usize) {
        let (start, end) = (start as u16, end as u16);
        let spans = &mut self.current().spans;
        let full = spans.is_full();
        if let Some(last) = spans.last_mut() {
            if full || (start <= last.1 && end >= last.0) {
                *last = (last.0.min(start), last.1.max(end));
                return;
            }
        }
        let _ = spans.push((start, end));
    }

    /// The row above.
    fn previous(&self) -> &RowLabels {
        let [a, b] = &self.rows;
        if self.flip {
            b
        } else {
            a
        }
    }

    fn previous_mut(&mut self) -> &mut RowLabels {
        let [a, b] = &mut self.rows;
        if self.flip {
            b
        } else {
            a
        }
    }

    /// The row being labelled.
    fn current(&mut self) -> &mut RowLabels {
        let [a, b] = &mut self.rows;
        if self.flip {
            a
        } else {
            b
        }
    }

    fn parent(&self, label: u16) -> u16 {
        self.slots
            .get(usize::from(label))
            .map_or(label, |slot| slot.parent)
    }

    fn find(&mut self, label: u16) -> u16 {
        let mut root = label;
        // A chain is at most as long as the table.
        for _ in 0..MAX_OPEN_COMPONENTS {
            let parent = self.parent(root);
            if parent == root || parent == NONE {
                break;
            }
            root = parent;
        }
        // Path compression.
        let mut node = label;
        for _ in 0..MAX_OPEN_COMPONENTS {
            let parent = self.parent(node);
            if parent == root || parent == NONE {
                break;
            }
            if let Some(slot) = self.slots.get_mut(usize::from(node)) {
                slot.parent = root;
            }
            node = parent;
        }
        root
    }

    /// Merges two roots; the lower label survives and holds both sums.
    fn union(&mut self, a: u16, b: u16) -> u16 {
        if a == b {
            return a;
        }
        let (keep, gone) = if a < b { (a, b) } else { (b, a) };
        let gone_sums = self.slots.get(usize::from(gone)).map(|slot| slot.sums);
        if let Some(sums) = gone_sums {
            if let Some(slot) = self.slots.get_mut(usize::from(keep)) {
                slot.sums.absorb(&sums);
            }
        }
        if let Some(slot) = self.slots.get_mut(usize::from(gone)) {
            slot.parent = keep;
            slot.sums = ComponentSums::default();
        }
        keep
    }

    /// The lowest free slot, taken.
    fn allocate(&mut self) -> Option<u16> {
        let index = (!self.open).trailing_zeros() as usize;
        let slot = self.slots.get_mut(index)?;
        *slot = Slot {
            parent: index as u16,
            sums: ComponentSums::default(),
        };
        self.open |= 1 << index;
        Some(index as u16)
    }

    /// After a row labelled over `current_spans`: its labels resolved to
    /// their roots; components that reach none of them handed on (in slot
    /// order); every slot no label refers to any more freed; the row kept
    /// as the next one's row above, and the scratch row cleared.
    fn close_row(&mut self, closed: &mut impl FnMut(&ComponentSums)) {
        let mut live: SlotSet = 0;
        for k in 0..self.current().spans.len() {
            let Some(&(start, end)) = self.current().spans.get(k) else {
                break;
            };
            for x in usize::from(start)..usize::from(end) {
                let label = self.current().cells.get(x).copied().unwrap_or(NONE);
                if label == NONE {
                    continue;
                }
                let root = self.find(label);
                if let Some(cell) = self.current().cells.get_mut(x) {
                    *cell = root;
                }
                if usize::from(root) < MAX_OPEN_COMPONENTS {
                    live |= 1 << root;
                }
            }
        }
        let mut ending = self.open & !live;
        while ending != 0 {
            let index = ending.trailing_zeros() as usize;
            ending &= ending - 1;
            if let Some(slot) = self.slots.get_mut(index) {
                if usize::from(slot.parent) == index && slot.sums.area > 0 {
                    closed(&slot.sums);
                }
                *slot = FREE;
            }
            self.open &= !(1 << index);
        }
        // The row above is done with: clear it where it held labels, and it
        // becomes the next row's scratch.
        let above = self.previous_mut();
        for &(start, end) in above.spans.iter() {
            if let Some(cells) = above.cells.get_mut(usize::from(start)..usize::from(end)) {
                cells.fill(NONE);
            }
        }
        above.spans.clear();
        self.flip = !self.flip;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    fn label(rows: &[&str]) -> Result<Vec<ComponentSums>, ComponentError> {
        let width = rows[0].len();
        let mut labeller = Labeller::new(width);
        let mut out = Vec::new();
        for row in rows {
            let weights: Vec<u8> = row
                .bytes()
                .map(|c| if c == b'#' { 10 } else { 0 })
                .collect();
            labeller.push_row(&weights, |c| out.push(*c))?;
        }
        labeller.finish(|c| out.push(*c));
        out.sort_by_key(|c| (c.y_min, c.x_min));
        Ok(out)
    }

    #[test]
    fn a_u_shape_merges_into_one_component_with_exact_sums() {
        let found = label(&[
            "#...#..", //
            "#...#..", //
            "#####..", //
            ".......", //
            "......#", //
        ])
        .unwrap();
        assert_eq!(found.len(), 2);
        let u = &found[0];
        assert_eq!(u.area, 9);
        assert_eq!((u.x_min, u.x_max, u.y_min, u.y_max), (0, 4, 0, 2));
        // x: 0,4 / 0,4 / 0..4 -> 0+4+0+4+10 = 18; y: 0*2 + 1*2 + 2*5 = 12.
        assert_eq!((u.sx, u.sy), (18, 12));
        assert_eq!(u.sw, 90);
        assert_eq!(found[1].area, 1);
    }

    /// Labels `rows` rows of `weights` over `spans` in each, or whole.
    fn label_over(
        weights: &[u8],
        rows: usize,
        spans: Option<&[(usize, usize)]>,
    ) -> Vec<ComponentSums> {
        let mut labeller = Labeller::new(weights.len());
        let mut out = Vec::new();
        for _ in 0..rows {
            match spans {
                Some(spans) => labeller.push_spans(weights, spans, |c| out.push(*c)),
                None => labeller.push_row(weights, |c| out.push(*c)),
            }
            .unwrap();
        }
        labeller.finish(|c| out.push(*c));
        out.sort_by_key(|c| (c.y_min, c.x_min));
        out
    }

    #[test]
    fn spans_out_of_order_and_past_the_room_label_as_whole_rows_do() {
        // 34 one-pixel spans (the room is MAX_SPANS), then one before them all.
        let mut spans: Vec<(usize, usize)> = (1..=34).map(|k| (5 * k, 5 * k + 1)).collect();
        spans.push((0, 1));
        let mut weights = [0u8; 200];
        for &(start, end) in &spans {
            weights[start..end].fill(1);
        }
        let whole = label_over(&weights, 3, None);
        assert_eq!(label_over(&weights, 3, Some(&spans)), whole);
        assert_eq!(whole.len(), 35);
        assert!(whole.iter().all(|c| c.area == 3));
    }

    #[test]
    fn diagonal_pixels_are_connected() {
        let found = label(&["#..", ".#.", "..#"]).unwrap();
        assert_eq!(found.len(), 1);
        assert_eq!(found[0].area, 3);
    }

    #[test]
    fn slots_are_recycled_so_many_components_over_the_image_fit() {
        // 300 single-pixel components, never more than 4 open at once.
        let mut labeller = Labeller::new(8);
        let mut count = 0;
        for y in 0..600 {
            let weights: Vec<u8> = (0..8)
                .map(|x| if y % 2 == 0 && x % 2 == 0 { 5 } else { 0 })
                .collect();
            labeller.push_row(&weights, |_| count += 1).unwrap();
        }
        labeller.finish(|_| count += 1);
        assert_eq!(count, 1200);
    }

    #[test]
    fn too_many_open_components_is_an_error_not_a_panic() {
        let mut labeller = Labeller::new(MAX_WIDTH_PX);
        let weights: Vec<u8> = (0..MAX_WIDTH_PX)
            .map(|x| if x % 2 == 0 { 1 } else { 0 })
            .collect();
        assert_eq!(
            labeller.push_row(&weights, |_| {}),
            Err(ComponentError::TooManyOpen { row: 0 })
        );
    }
}
