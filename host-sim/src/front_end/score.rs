//! Scoring a front end's labels against a simulated recording's truth: a
//! label is right when the true mark nearest its point (of every mark,
//! distractors included, within [`MATCH_PX`]) is the mark it names; wrong
//! (a mislabel) otherwise. Part features are matched as a set first (the
//! front end's order is its own): each feature label takes the true feature
//! it most often lands on. A visible mark without its label is dropped.
//! Where two marks merge into one blob (each within [`MATCH_PX`] of the
//! point, as a glint lying over a feature), a label naming either is the
//! right mark with a displaced point, not a mislabel: the point is where
//! the named mark is.

use std::collections::BTreeMap;

use shared::detection::identify::{LabelledPoint, MarkLabel};

use super::FrameLabels;
use crate::camera_recording::simulate::{TrueFrame, TrueMark};

/// A label's point must lie this close to its true mark, px.
pub const MATCH_PX: f64 = 1.5;
/// Farther, but the labelled mark is still the nearest within this: the
/// right mark with a displaced point (a mark partly hidden), px.
pub const OFF_PX: f64 = 4.0;

/// The tally.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct LabelScore {
    pub frames: usize,
    pub labels: usize,
    pub right: usize,
    pub mislabelled: usize,
    /// The right mark, its point more than `MATCH_PX` from its centre (partly hidden).
    pub right_but_off: usize,
    /// Visible marks (the truth's `visible`) without their label, by class.
    pub dropped: BTreeMap<String, usize>,
    /// Visible marks, by class.
    pub visible: BTreeMap<String, usize>,
    /// Right labels by class.
    pub right_by_class: BTreeMap<String, usize>,
    /// Trigger ids and labels of the first mislabels.
    pub examples: Vec<String>,
}

fn class(label: MarkLabel) -> (&'static str, usize) {
    match label {
        MarkLabel::DiscCentre => ("disc_center", 0),
        MarkLabel::Reference => ("reference", 0),
        MarkLabel::PartFeature(i) => ("part_feature", usize::from(i)),
        MarkLabel::Effector(i) => ("effector", usize::from(i)),
    }
}

/// What one label is, against the truth.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// The nearest true mark within [`MATCH_PX`] is the one it names.
    Right,
    /// The mark it names, but its point more than [`MATCH_PX`] off, or
    /// within it with another mark nearer (two marks in one blob).
    Off,
    /// Another mark, or none.
    Wrong,
}

/// The truth by trigger id and the front end's feature order matched to
/// the truth's: what judging one label needs.
pub struct Judge<'a> {
    by_id: BTreeMap<u64, &'a TrueFrame>,
    /// Front-end feature label -> true feature index.
    feature_map: BTreeMap<usize, usize>,
}

fn nearest_within(frame: &TrueFrame, p: [f64; 2], limit: f64) -> Option<&TrueMark> {
    frame
        .marks
        .iter()
        .filter(|m| m.shows && m.pinhole_px.iter().all(|x| x.is_finite()))
        .map(|m| (m, (m.pinhole_px[0] - p[0]).hypot(m.pinhole_px[1] - p[1])))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .filter(|(_, d)| *d <= limit)
        .map(|(m, _)| m)
}

fn nearest(frame: &TrueFrame, p: [f64; 2]) -> Option<&TrueMark> {
    nearest_within(frame, p, MATCH_PX)
}

impl<'a> Judge<'a> {
    /// Matches the feature labels of `labels` (frames in order) to the true
    /// features of `truth`: each takes the one it most often lands on.
    pub fn new(labels: &[FrameLabels], truth: &'a [TrueFrame]) -> Self {
        let by_id: BTreeMap<u64, &TrueFrame> = truth.iter().map(|f| (f.trigger_id, f)).collect();
        let mut votes: BTreeMap<(usize, usize), usize> = BTreeMap::new();
        for frame in labels {
            let Some(t) = by_id.get(&frame.trigger_id) else {
                continue;
            };
            for p in &frame.points {
                if let ("part_feature", k) = class(p.label) {
                    if let Some(m) = nearest(t, p.pixel).filter(|m| m.kind == "part_feature") {
                        *votes.entry((k, m.index)).or_default() += 1;
                    }
                }
            }
        }
        let mut feature_map: BTreeMap<usize, usize> = BTreeMap::new();
        for (&(k, index), &n) in &votes {
            let best = votes
                .iter()
                .filter(|((kk, _), _)| *kk == k)
                .map(|(_, &m)| m)
                .max()
                .unwrap_or(0);
            if n == best {
                feature_map.entry(k).or_insert(index);
            }
        }
        Self { by_id, feature_map }
    }

    /// A judge for a front end whose part features follow the part's own
    /// order (feature `i` must be the part's feature `i`), as a controller
    /// that grasps by that order needs.
    pub fn in_fixed_order(truth: &'a [TrueFrame]) -> Self {
        let by_id: BTreeMap<u64, &TrueFrame> = truth.iter().map(|f| (f.trigger_id, f)).collect();
        let features = truth
            .iter()
            .flat_map(|f| f.marks.iter())
            .filter(|m| m.kind == "part_feature")
            .map(|m| (m.index, m.index))
            .collect();
        Self {
            by_id,
            feature_map: features,
        }
    }

    /// The truth of frame `trigger_id`, if it has one.
    pub fn frame(&self, trigger_id: u64) -> Option<&'a TrueFrame> {
        self.by_id.get(&trigger_id).copied()
    }

    /// The true mark's class and index that `label` names.
    fn named(&self, label: MarkLabel) -> (&'static str, Option<usize>) {
        let (kind, k) = class(label);
        let index = if kind == "part_feature" {
            self.feature_map.get(&k).copied()
        } else {
            Some(k)
        };
        (kind, index)
    }

    /// `point` of frame `trigger_id` against its truth (`None`: no truth
    /// for that frame).
    pub fn verdict(&self, trigger_id: u64, point: &LabelledPoint) -> Option<Verdict> {
        let t = self.frame(trigger_id)?;
        let (kind, index) = self.named(point.label);
        let is_named = |m: &TrueMark| m.kind == kind && Some(m.index) == index;
        Some(if nearest(t, point.pixel).is_some_and(is_named) {
            Verdict::Right
        } else if nearest_within(t, point.pixel, OFF_PX).is_some_and(is_named)
            || t.marks.iter().any(|m| {
                m.shows
                    && is_named(m)
                    && (m.pinhole_px[0] - point.pixel[0]).hypot(m.pinhole_px[1] - point.pixel[1])
                        <= MATCH_PX
            })
        {
            Verdict::Off
        } else {
            Verdict::Wrong
        })
    }
}

/// Scores `labels` (frames in order) against `truth` (by trigger id).
pub fn score(labels: &[FrameLabels], truth: &[TrueFrame]) -> LabelScore {
    let judge = Judge::new(labels, truth);
    let mut score = LabelScore::default();
    for frame in labels {
        let Some(t) = judge.frame(frame.trigger_id) else {
            continue;
        };
        score.frames += 1;
        for m in t
            .marks
            .iter()
            .filter(|m| m.visible && m.kind != "distractor")
        {
            *score.visible.entry(m.kind.clone()).or_default() += 1;
            let labelled = frame.points.iter().any(|p| {
                let (kind, index) = judge.named(p.label);
                kind == m.kind && index == Some(m.index)
            });
            if !labelled {
                *score.dropped.entry(m.kind.clone()).or_default() += 1;
            }
        }
        for p in &frame.points {
            score.labels += 1;
            match judge.verdict(frame.trigger_id, p) {
                Some(Verdict::Off) => score.right_but_off += 1,
                Some(Verdict::Right) => {
                    score.right += 1;
                    *score
                        .right_by_class
                        .entry(class(p.label).0.to_string())
                        .or_default() += 1;
                }
                _ => {
                    score.mislabelled += 1;
                    if score.examples.len() < 10 {
                        let near = nearest(t, p.pixel)
                            .map(|m| format!("{} {}", m.kind, m.index))
                            .unwrap_or_else(|| "nothing".into());
                        score.examples.push(format!(
                            "trigger {}: {:?} at ({:.1}, {:.1}) is {near}",
                            frame.trigger_id, p.label, p.pixel[0], p.pixel[1]
                        ));
                    }
                }
            }
        }
    }
    score
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mark(kind: &str, index: usize, at: [f64; 2], shows: bool) -> TrueMark {
        TrueMark {
            kind: kind.into(),
            index,
            image_px: at,
            pinhole_px: at,
            visible: false,
            shows,
        }
    }

    fn verdict(marks: Vec<TrueMark>, label: MarkLabel, at: [f64; 2]) -> Option<Verdict> {
        let truth = [TrueFrame {
            trigger_id: 7,
            marks,
            rim_pinhole_px: Vec::new(),
        }];
        let point = LabelledPoint {
            label,
            pixel: at,
            blob: 0,
        };
        Judge::in_fixed_order(&truth).verdict(7, &point)
    }

    /// Feature 0's label at (96.4, 103.5) among `marks`.
    fn feature_0(marks: Vec<TrueMark>) -> Option<Verdict> {
        verdict(marks, MarkLabel::PartFeature(0), [96.4, 103.5])
    }

    #[test]
    fn a_label_on_two_merged_marks_names_one_of_them_with_its_point_displaced() {
        let key = |shows| mark("part_feature", 0, [96.6, 104.0], shows);
        let glint = || mark("distractor", 5, [96.5, 103.4], true);
        // Offline campaign seed 7, trial 123: the key with a glint over it.
        assert_eq!(feature_0(vec![key(true), glint()]), Some(Verdict::Off));
        // The glint alone, the key hidden: a mislabel.
        assert_eq!(feature_0(vec![key(false), glint()]), Some(Verdict::Wrong));
        // The key 2 px from the point with a glint nearer: a mislabel.
        let beside = mark("part_feature", 0, [98.4, 103.5], true);
        assert_eq!(feature_0(vec![beside, glint()]), Some(Verdict::Wrong));
        assert_eq!(feature_0(vec![key(true)]), Some(Verdict::Right));
    }
}
