//! A mark's coverage of the pixels around it, as moments: its centre, and
//! whether something in front has cut a piece off it.
//!
//! A whole mark's image is an ellipse, blurred by the lens and the motion
//! during the exposure; both are symmetric, so the coverage's third central
//! moments vanish whatever the blur (third cumulants add under convolution,
//! and a symmetric blur has none). An arm edge that hides a chord of the
//! mark leaves a lopsided region whose centroid is pulled away from the
//! hidden side by tenths of a pixel, which in every frame of a resting arm
//! alike would bias the robot's calibration by millimetres. The skewness
//! along the moment ellipse's axes, each axis scaled to unit spread, says
//! how lopsided the region is whatever its size and tilt.

/// Weighted moments of a region up to the third order, about a fixed point
/// near its centre (so that f32 sums stay exact enough).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Coverage {
    origin: [f32; 2],
    w: f32,
    x: f32,
    y: f32,
    xx: f32,
    xy: f32,
    yy: f32,
    xxx: f32,
    xxy: f32,
    xyy: f32,
    yyy: f32,
}

impl Coverage {
    /// Empty moments about `origin`, px.
    pub fn about(origin: [f32; 2]) -> Self {
        Self {
            origin,
            ..Self::default()
        }
    }

    /// Adds pixel `(x, y)` covered by `share` (0 to 1).
    pub fn add(&mut self, x: f32, y: f32, share: f32) {
        let (dx, dy) = (x - self.origin[0], y - self.origin[1]);
        let (wx, wy) = (share * dx, share * dy);
        self.w += share;
        self.x += wx;
        self.y += wy;
        self.xx += wx * dx;
        self.xy += wx * dy;
        self.yy += wy * dy;
        self.xxx += wx * dx * dx;
        self.xxy += wx * dx * dy;
        self.xyy += wx * dy * dy;
        self.yyy += wy * dy * dy;
    }

    /// Some coverage was added.
    pub fn is_some(&self) -> bool {
        self.w > 0.0
    }

    /// The coverage-weighted centre, px (the origin when empty).
    pub fn centre(&self) -> [f32; 2] {
        if self.w > 0.0 {
            [
                self.origin[0] + self.x / self.w,
                self.origin[1] + self.y / self.w,
            ]
        } else {
            self.origin
        }
    }

    /// Length of the whitened skewness vector: the third central moments
    /// along the moment ellipse's axes, each axis scaled to unit spread.
    /// 0 for an empty or degenerate region.
    pub fn lopsidedness(&self) -> f32 {
        if self.w <= 0.0 {
            return 0.0;
        }
        let w = self.w;
        let (mx, my) = (self.x / w, self.y / w);
        let (exx, exy, eyy) = (self.xx / w, self.xy / w, self.yy / w);
        let cxx = exx - mx * mx;
        let cxy = exy - mx * my;
        let cyy = eyy - my * my;
        let m30 = self.xxx / w - 3.0 * mx * exx + 2.0 * mx * mx * mx;
        let m03 = self.yyy / w - 3.0 * my * eyy + 2.0 * my * my * my;
        let m21 = self.xxy / w - 2.0 * mx * exy - my * exx + 2.0 * mx * mx * my;
        let m12 = self.xyy / w - 2.0 * my * exy - mx * eyy + 2.0 * mx * my * my;
        let half_trace = 0.5 * (cxx + cyy);
        let spread = libm::sqrtf(0.25 * (cxx - cyy) * (cxx - cyy) + cxy * cxy);
        let (major, minor) = (half_trace + spread, half_trace - spread);
        if !(minor > 0.0 && major.is_finite()) {
            return 0.0;
        }
        // Whitening: the axes' directions, each scaled to unit spread.
        let (s, c) = libm::sincosf(0.5 * libm::atan2f(2.0 * cxy, cxx - cyy));
        let (sp, sq) = (libm::sqrtf(major), libm::sqrtf(minor));
        let whiten = [[c / sp, s / sp], [-s / sq, c / sq]];
        // The third-moment tensor, symmetric: T[a][b][c] by how many of
        // a, b, c are y.
        let by_ys = [m30, m21, m12, m03];
        let tensor = |a: usize, b: usize, k: usize| by_ys.get(a + b + k).copied().unwrap_or(0.0);
        let entry = |r: usize, col: usize| {
            whiten
                .get(r)
                .and_then(|row| row.get(col))
                .copied()
                .unwrap_or(0.0)
        };
        // T'[i][j][k] = sum over a, b, d of W[i][a] W[j][b] W[k][d] T[a][b][d].
        let whitened = |i: usize, j: usize, k: usize| {
            let mut t = 0.0f32;
            for a in 0..2 {
                for b in 0..2 {
                    for d in 0..2 {
                        t += entry(i, a) * entry(j, b) * entry(k, d) * tensor(a, b, d);
                    }
                }
            }
            t
        };
        // The whitened tensor's Frobenius norm: each of its four distinct
        // entries counted as often as it appears.
        let (t0, t1, t2, t3) = (
            whitened(0, 0, 0),
            whitened(0, 0, 1),
            whitened(0, 1, 1),
            whitened(1, 1, 1),
        );
        let squares = t0 * t0 + 3.0 * t1 * t1 + 3.0 * t2 * t2 + t3 * t3;
        libm::sqrtf(squares)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The coverage of an ellipse (semi-axes `a`, `b`, turned by `turn`)
    /// centred at `centre`, less what lies beyond the line `cut_px` from its
    /// centre along `cut_dir` (8 x 8 samples a pixel), blurred by a 3 x 3
    /// binomial kernel when `blur`.
    fn coverage(
        centre: [f32; 2],
        a: f32,
        b: f32,
        turn: f32,
        cut_px: f32,
        cut_dir: f32,
        blur: bool,
    ) -> Coverage {
        const N: usize = 32;
        let mut share = [[0.0f32; N]; N];
        let (st, ct) = (turn.sin(), turn.cos());
        let (sc, cc) = (cut_dir.sin(), cut_dir.cos());
        for (y, row) in share.iter_mut().enumerate() {
            for (x, cell) in row.iter_mut().enumerate() {
                for k in 0..64 {
                    let dx = x as f32 - 0.5 + ((k % 8) as f32 + 0.5) / 8.0 - centre[0];
                    let dy = y as f32 - 0.5 + ((k / 8) as f32 + 0.5) / 8.0 - centre[1];
                    let (p, q) = (ct * dx + st * dy, -st * dx + ct * dy);
                    if (p / a).powi(2) + (q / b).powi(2) <= 1.0 && cc * dx + sc * dy <= cut_px {
                        *cell += 1.0 / 64.0;
                    }
                }
            }
        }
        let mut moments = Coverage::about([centre[0].round(), centre[1].round()]);
        for y in 1..N - 1 {
            for x in 1..N - 1 {
                let value = if blur {
                    let mut sum = 0.0;
                    for (j, wy) in [1.0, 2.0, 1.0].iter().enumerate() {
                        for (i, wx) in [1.0, 2.0, 1.0].iter().enumerate() {
                            sum += wx * wy * share[y + j - 1][x + i - 1];
                        }
                    }
                    sum / 16.0
                } else {
                    share[y][x]
                };
                if value > 0.0 {
                    moments.add(x as f32, y as f32, value);
                }
            }
        }
        moments
    }

    #[test]
    fn a_whole_mark_is_not_lopsided_whatever_its_size_tilt_position_and_blur() {
        for (k, (a, b)) in [(3.0, 3.0), (4.0, 2.5), (5.0, 4.5)].into_iter().enumerate() {
            for blur in [false, true] {
                let centre = [15.3 + 0.21 * k as f32, 16.7 - 0.37 * k as f32];
                let whole = coverage(centre, a, b, 0.4 * k as f32, 99.0, 0.0, blur);
                // Pixels alone make a few hundredths.
                assert!(
                    whole.lopsidedness() < 0.06,
                    "{a} {b} {blur}: {}",
                    whole.lopsidedness()
                );
                let [x, y] = whole.centre();
                assert!((x - centre[0]).abs() < 0.01 && (y - centre[1]).abs() < 0.01);
            }
        }
    }

    #[test]
    fn a_mark_cut_by_an_edge_is_lopsided_in_any_direction() {
        // A mark of radius 4 px with its last 1.5 px hidden: its centre
        // moves by almost half a pixel, and its lopsidedness stands out
        // (a cut that moves it a quarter of a pixel reads about 0.15).
        let mut seen = std::vec::Vec::new();
        for cut_dir in [0.0f32, 0.7, 2.0, 4.0] {
            let cut = coverage([16.2, 15.8], 4.0, 4.0, 0.0, 2.5, cut_dir, true);
            let [x, y] = cut.centre();
            let moved = (x - 16.2).hypot(y - 15.8);
            assert!(moved > 0.4, "{moved}");
            assert!(
                cut.lopsidedness() > 0.2,
                "{cut_dir}: {}",
                cut.lopsidedness()
            );
            seen.push(cut.lopsidedness());
        }
        // The same cut reads alike whichever way it faces.
        let (lo, hi) = seen
            .iter()
            .fold((f32::MAX, 0.0f32), |(l, h), v| (l.min(*v), h.max(*v)));
        assert!(hi - lo < 0.03, "{seen:?}");
        // Deeper cuts are more lopsided.
        let half = coverage([16.2, 15.8], 4.0, 4.0, 0.0, 0.0, 1.0, true);
        assert!(half.lopsidedness() > 0.4, "{}", half.lopsidedness());
    }

    #[test]
    fn an_empty_or_degenerate_region_is_not_lopsided() {
        assert_eq!(Coverage::about([3.0, 4.0]).lopsidedness(), 0.0);
        assert_eq!(Coverage::about([3.0, 4.0]).centre(), [3.0, 4.0]);
        let mut line = Coverage::about([3.0, 4.0]);
        for x in 0..5 {
            line.add(x as f32, 4.0, 1.0);
        }
        assert_eq!(line.lopsidedness(), 0.0);
    }
}
