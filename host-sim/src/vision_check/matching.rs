//! Detections against the truth: each mark the detector should find (in
//! view, facing the camera, nothing in front of it) takes the nearest
//! detection within [`MATCH_RADIUS_PX`], nearest pairs first. Which mark is
//! which is not the detector's job (identification comes later): a match is
//! only a position. A detection near a partly hidden mark, or one crowded by
//! another mark, is neither scored nor spurious; any other detection is
//! spurious.

use shared::detection::Blob;

use crate::world::render::truth::MarkImage;

/// Farthest a detection may be from a mark's true centre to be its, px.
pub const MATCH_RADIUS_PX: f64 = 3.0;

/// One mark the detector found: its error against the projected centre and
/// against the centroid of its image region, px.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Found {
    pub mark: usize,
    pub error_px: [f64; 2],
    pub error_to_region_px: [f64; 2],
}

/// The outcome of one frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameMatch {
    pub found: Vec<Found>,
    /// Visible marks (indices into the marks) with no detection.
    pub missed: Vec<usize>,
    /// Detections no mark claims.
    pub spurious: usize,
    /// Visible marks.
    pub visible: usize,
}

/// Matches `blobs` to `marks` (see the module's rules).
pub fn match_frame(marks: &[MarkImage], blobs: &[Blob]) -> FrameMatch {
    // Marks that may claim a detection: every one not wholly hidden.
    let claimants: Vec<usize> = (0..marks.len())
        .filter(|&i| marks.get(i).is_some_and(|m| m.shows()))
        .collect();
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for &m in &claimants {
        let Some(mark) = marks.get(m) else { continue };
        for (b, blob) in blobs.iter().enumerate() {
            let d = (f64::from(blob.x_px) - mark.centre_px[0])
                .hypot(f64::from(blob.y_px) - mark.centre_px[1]);
            if d <= MATCH_RADIUS_PX {
                pairs.push((d, m, b));
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut mark_taken = vec![false; marks.len()];
    let mut blob_taken = vec![false; blobs.len()];
    let mut result = FrameMatch::default();
    for (_, m, b) in pairs {
        if mark_taken.get(m).copied().unwrap_or(true) || blob_taken.get(b).copied().unwrap_or(true)
        {
            continue;
        }
        if let (Some(mt), Some(bt)) = (mark_taken.get_mut(m), blob_taken.get_mut(b)) {
            *mt = true;
            *bt = true;
        }
        let (Some(mark), Some(blob)) = (marks.get(m), blobs.get(b)) else {
            continue;
        };
        if mark.visible() {
            let (x, y) = (f64::from(blob.x_px), f64::from(blob.y_px));
            result.found.push(Found {
                mark: m,
                error_px: [x - mark.centre_px[0], y - mark.centre_px[1]],
                error_to_region_px: [
                    x - mark.region_centroid_px[0],
                    y - mark.region_centroid_px[1],
                ],
            });
        }
    }
    for (m, mark) in marks.iter().enumerate() {
        if mark.visible() {
            result.visible += 1;
            if !mark_taken.get(m).copied().unwrap_or(false) {
                result.missed.push(m);
            }
        }
    }
    result.spurious = blob_taken.iter().filter(|taken| !**taken).count();
    result
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::render::MarkKind;

    fn mark(kind: MarkKind, u: f64, v: f64) -> MarkImage {
        MarkImage {
            kind,
            centre_px: [u, v],
            region_centroid_px: [u + 0.01, v],
            radius_px: 2.0,
            in_view: true,
            facing: true,
            hidden_fraction: 0.0,
            crowded: false,
        }
    }

    fn blob(x: f32, y: f32) -> Blob {
        Blob {
            x_px: x,
            y_px: y,
            area_px: 12,
            semi_major_px: 2.0,
            semi_minor_px: 2.0,
            orientation_rad: 0.0,
            peak_contrast: 100,
            mean_contrast: 80.0,
            lopsidedness: 0.0,
        }
    }

    #[test]
    fn nearest_detections_are_matched_and_the_rest_counted() {
        let mut hidden = mark(MarkKind::Feature(1), 100.0, 100.0);
        hidden.hidden_fraction = 0.5;
        let marks = [
            mark(MarkKind::Reference, 50.0, 50.0),
            mark(MarkKind::DiscCentre, 54.0, 50.0),
            hidden,
            mark(MarkKind::Effector(0), 200.0, 20.0),
        ];
        let blobs = [
            blob(50.2, 50.0),
            blob(53.9, 50.1),
            blob(100.5, 100.0),
            blob(10.0, 10.0),
        ];
        let mut outcome = match_frame(&marks, &blobs);
        outcome.found.sort_by_key(|f| f.mark);
        assert_eq!(outcome.visible, 3);
        assert_eq!(outcome.found.len(), 2);
        assert!((outcome.found[0].error_px[0] - 0.2).abs() < 1e-5);
        assert_eq!(outcome.found[0].mark, 0);
        assert!((outcome.found[0].error_to_region_px[0] - 0.19).abs() < 1e-5);
        assert_eq!(outcome.found[1].mark, 1);
        // The partly hidden mark claims its blob without being scored; the
        // gripper mark is missed; the blob at (10, 10) is spurious.
        assert_eq!(outcome.missed, vec![3]);
        assert_eq!(outcome.spurious, 1);
    }
}
