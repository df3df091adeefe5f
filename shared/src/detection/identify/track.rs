//! A track: one blob followed over frames while the disc turns, with a fit of
//! its path against the encoder angle.
//!
//! A point fixed on the turning disc (or on the part standing on it) moves on
//! a circle about the disc's axis; through a camera whose depth varies little
//! over that circle its image is `x(theta) = c + a cos(theta) + b sin(theta)`
//! (`c`: the image of the circle's centre on the axis; `a`, `b`: the image of
//! the disc's X and Y directions scaled by the radius). The fit keeps the
//! 3 x 3 normal equations of that linear model with a forgetting factor, so
//! perspective (the model is exact only for an affine camera) is absorbed by
//! fitting the recent arc; a point that is not on the disc (the arm's marks)
//! leaves a large residual, and one at rest (the disc centre, a fixed glint)
//! fits with `a = b = 0`.
//!
//! Over most of a turn the affine model is not enough under a tilted camera:
//! the depth changes round the circle, and the image runs ahead on the near
//! side and lags on the far side by a share `(r / Z) tan(tilt)` of its radius.
//! To first order in that share the path gains the second harmonics
//! `cos 2 theta`, `sin 2 theta` (the product of the first-harmonic numerator
//! with the first-harmonic change of depth); [`PathFit`] keeps them beside
//! the affine terms, so that its residual over a whole turn measures the
//! noise and not the camera's tilt. At 30 degrees of tilt and a path of 81 px
//! on a 521 px lens (cell 10000464 of seed 10), the affine residual over the
//! turn was 3.2 px, more than twice a disc mark's allowance, and the disc was
//! lost every time the reference came round.

use nalgebra::{Matrix2, Matrix3, Matrix3x2, Matrix5, Vector2, Vector3, Vector5};

use crate::observation::PixelPoint;

/// Weight of an observation one frame older than the newest: in the fit
/// that predicts (a short recent arc, where the affine model holds well),
/// and in the fit that measures the path's centre and size (most of a turn).
pub const RECENT_FORGETTING: f64 = 0.85;
/// See [`RECENT_FORGETTING`].
pub const WHOLE_FORGETTING: f64 = 0.98;

/// The running fit of `x(theta) = c + a cos + b sin` for both image axes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcFit {
    normal: Matrix3<f64>,
    rhs_u: Vector3<f64>,
    rhs_v: Vector3<f64>,
    /// Weighted sum of squared coordinates (for the residual).
    sum_sq: f64,
    /// Weighted count.
    weight: f64,
    /// Smallest and largest angle seen (the arc the fit spans), rad.
    theta_min: f64,
    theta_max: f64,
    forgetting: f64,
}

/// What a fit says about a track.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcModel {
    /// Image of the circle's centre, px.
    pub centre_px: [f64; 2],
    /// Image of the disc's X and Y directions times the radius, px.
    pub a_px: [f64; 2],
    /// Image of the disc's Y direction times the radius, px.
    pub b_px: [f64; 2],
    /// RMS residual of the recent observations, px.
    pub rms_px: f64,
}

impl ArcModel {
    /// The predicted pinhole pixel at `theta`.
    pub fn at(&self, theta: f64) -> PixelPoint {
        let (s, c) = libm::sincos(theta);
        [
            self.centre_px[0] + self.a_px[0] * c + self.b_px[0] * s,
            self.centre_px[1] + self.a_px[1] * c + self.b_px[1] * s,
        ]
    }

    /// The path's radius in the image, px (RMS of its two half-axes).
    pub fn radius_px(&self) -> f64 {
        libm::sqrt(
            (self.a_px[0] * self.a_px[0]
                + self.a_px[1] * self.a_px[1]
                + self.b_px[0] * self.b_px[0]
                + self.b_px[1] * self.b_px[1])
                / 2.0,
        )
    }
}

impl ArcFit {
    /// An empty fit whose observations weigh `forgetting` times less a frame.
    pub fn new(forgetting: f64) -> Self {
        Self {
            forgetting,
            normal: Matrix3::zeros(),
            rhs_u: Vector3::zeros(),
            rhs_v: Vector3::zeros(),
            sum_sq: 0.0,
            weight: 0.0,
            theta_min: f64::INFINITY,
            theta_max: f64::NEG_INFINITY,
        }
    }

    /// Adds an observation at `theta`, older ones weighing less.
    pub fn add(&mut self, theta: f64, p: PixelPoint) {
        let (s, c) = libm::sincos(theta);
        let phi = Vector3::new(1.0, c, s);
        self.normal = self.normal * self.forgetting + phi * phi.transpose();
        self.rhs_u = self.rhs_u * self.forgetting + phi * p[0];
        self.rhs_v = self.rhs_v * self.forgetting + phi * p[1];
        self.sum_sq = self.sum_sq * self.forgetting + p[0] * p[0] + p[1] * p[1];
        self.weight = self.weight * self.forgetting + 1.0;
        self.theta_min = self.theta_min.min(theta);
        self.theta_max = self.theta_max.max(theta);
    }

    /// The arc spanned, rad.
    pub fn arc_rad(&self) -> f64 {
        (self.theta_max - self.theta_min).max(0.0)
    }

    /// The model, once the arc is long enough for the three terms to part
    /// (`None` before, or when the normal equations are singular).
    pub fn model(&self, min_arc_rad: f64) -> Option<ArcModel> {
        if self.arc_rad() < min_arc_rad || self.weight < 3.0 {
            return None;
        }
        let inverse = self.normal.try_inverse()?;
        let cu = inverse * self.rhs_u;
        let cv = inverse * self.rhs_v;
        // Residual sum of squares: y'y - c' N c for each axis.
        let rss = self.sum_sq - cu.dot(&(self.normal * cu)) - cv.dot(&(self.normal * cv));
        let rms_px = libm::sqrt(rss.max(0.0) / self.weight);
        let model = ArcModel {
            centre_px: [cu.x, cv.x],
            a_px: [cu.y, cv.y],
            b_px: [cu.z, cv.z],
            rms_px,
        };
        let finite = [cu, cv].iter().all(|c| c.iter().all(|x| x.is_finite()));
        (finite && rms_px.is_finite()).then_some(model)
    }
}

/// The whole turn's residual is measured with the second harmonics once the
/// fit spans this arc, rad (half a turn: `cos 2 theta` and `sin 2 theta` have
/// run a whole period and part from the other terms).
pub const HARMONIC_ARC_RAD: f64 = core::f64::consts::PI;

/// [`ArcFit`] with the second harmonics' blocks of the normal equations
/// beside it: the path's centre and half-axes are the affine fit's, as the
/// disc's image is read from them, and its residual is the five-term fit's
/// once the arc spans [`HARMONIC_ARC_RAD`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathFit {
    affine: ArcFit,
    /// Sum of `phi psi'`: `phi = (1, cos, sin)`, `psi = (cos 2, sin 2)`.
    cross: Matrix3x2<f64>,
    /// Sum of `psi psi'`.
    second: Matrix2<f64>,
    rhs2_u: Vector2<f64>,
    rhs2_v: Vector2<f64>,
}

impl PathFit {
    /// An empty fit whose observations weigh `forgetting` times less a frame.
    pub fn new(forgetting: f64) -> Self {
        Self {
            affine: ArcFit::new(forgetting),
            cross: Matrix3x2::zeros(),
            second: Matrix2::zeros(),
            rhs2_u: Vector2::zeros(),
            rhs2_v: Vector2::zeros(),
        }
    }

    /// Adds an observation at `theta`, older ones weighing less.
    pub fn add(&mut self, theta: f64, p: PixelPoint) {
        self.affine.add(theta, p);
        let (s, c) = libm::sincos(theta);
        let phi = Vector3::new(1.0, c, s);
        let psi = Vector2::new(c * c - s * s, 2.0 * s * c);
        let forgetting = self.affine.forgetting;
        self.cross = self.cross * forgetting + phi * psi.transpose();
        self.second = self.second * forgetting + psi * psi.transpose();
        self.rhs2_u = self.rhs2_u * forgetting + psi * p[0];
        self.rhs2_v = self.rhs2_v * forgetting + psi * p[1];
    }

    /// The arc spanned, rad.
    pub fn arc_rad(&self) -> f64 {
        self.affine.arc_rad()
    }

    /// The affine model (as [`ArcFit::model`]), its residual the five-term
    /// fit's once the arc spans [`HARMONIC_ARC_RAD`].
    pub fn model(&self, min_arc_rad: f64) -> Option<ArcModel> {
        let mut model = self.affine.model(min_arc_rad)?;
        if self.arc_rad() >= HARMONIC_ARC_RAD {
            if let Some(rms_px) = self.harmonic_rms_px() {
                model.rms_px = rms_px;
            }
        }
        Some(model)
    }

    /// RMS residual of the five-term fit (`None` when singular).
    fn harmonic_rms_px(&self) -> Option<f64> {
        let mut normal = Matrix5::zeros();
        normal
            .fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&self.affine.normal);
        normal.fixed_view_mut::<3, 2>(0, 3).copy_from(&self.cross);
        normal
            .fixed_view_mut::<2, 3>(3, 0)
            .copy_from(&self.cross.transpose());
        normal.fixed_view_mut::<2, 2>(3, 3).copy_from(&self.second);
        let cholesky = normal.cholesky()?;
        let stack = |first: &Vector3<f64>, second: &Vector2<f64>| {
            Vector5::new(first.x, first.y, first.z, second.x, second.y)
        };
        let rhs_u = stack(&self.affine.rhs_u, &self.rhs2_u);
        let rhs_v = stack(&self.affine.rhs_v, &self.rhs2_v);
        // Residual sum of squares: y'y - b' N^-1 b for each axis.
        let rss = self.affine.sum_sq
            - rhs_u.dot(&cholesky.solve(&rhs_u))
            - rhs_v.dot(&cholesky.solve(&rhs_v));
        let rms_px = libm::sqrt(rss.max(0.0) / self.affine.weight);
        rms_px.is_finite().then_some(rms_px)
    }
}

/// A blob followed over frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Track {
    /// The observation before `previous` (angle, pinhole pixel).
    pub earlier: Option<(f64, PixelPoint)>,
    /// The observation before the newest.
    pub previous: Option<(f64, PixelPoint)>,
    /// The newest observation.
    pub latest: (f64, PixelPoint),
    /// Observations taken.
    pub hits: u32,
    /// Frames since the last observation.
    pub misses: u32,
    /// Sum of the blobs' areas, px (for the mark's size).
    pub area_sum: f64,
    /// Sum of the blobs' fluxes (area times mean contrast, grey px): the
    /// light a mark sends, proportional to its true area however blurred.
    pub flux_sum: f64,
    /// The newest blob's flux: a mark's light changes little from one frame
    /// to the next, however much it changes across the image.
    pub latest_flux: f64,
    /// The path's fit over the recent arc (prediction, consistency).
    pub fit: ArcFit,
    /// The path's fit over most of a turn (its centre and size).
    pub whole: PathFit,
}

impl Track {
    /// A track started by one observation.
    pub fn start(theta: f64, p: PixelPoint, area_px: f64, flux: f64) -> Self {
        let mut fit = ArcFit::new(RECENT_FORGETTING);
        fit.add(theta, p);
        let mut whole = PathFit::new(WHOLE_FORGETTING);
        whole.add(theta, p);
        Self {
            earlier: None,
            previous: None,
            latest: (theta, p),
            hits: 1,
            misses: 0,
            area_sum: area_px,
            flux_sum: flux,
            latest_flux: flux,
            fit,
            whole,
        }
    }

    /// Takes the next observation.
    pub fn update(&mut self, theta: f64, p: PixelPoint, area_px: f64, flux: f64) {
        self.flux_sum += flux;
        self.latest_flux = flux;
        self.earlier = self.previous;
        self.previous = Some(self.latest);
        self.latest = (theta, p);
        self.hits = self.hits.saturating_add(1);
        self.misses = 0;
        self.area_sum += area_px;
        self.fit.add(theta, p);
        self.whole.add(theta, p);
    }

    /// Mean blob flux, grey px.
    pub fn mean_flux(&self) -> f64 {
        self.flux_sum / f64::from(self.hits.max(1))
    }

    /// Mean blob area, px.
    pub fn mean_area_px(&self) -> f64 {
        self.area_sum / f64::from(self.hits.max(1))
    }

    /// Where the track's blob should be at `theta`. From its fit when that
    /// explains the recent path within `max_rms_px`. A point far from the
    /// disc's axis under a tilted camera is not on an affine path (its depth
    /// changes round the circle: the image moves unevenly with the angle),
    /// and its fit misses by a pixel or more: then by the parabola through
    /// its last three observations in the angle, as long as `theta` lies
    /// within their span past the newest (a short step, where the path's
    /// curvature is all that matters). Else from the fit when it explains
    /// the path within `max_rms_px` plus 1.5 % of its radius, else by moving
    /// it linearly with the angle from its last two observations (at rest
    /// when the angle has not changed).
    pub fn predict(&self, theta: f64, min_arc_rad: f64, max_rms_px: f64) -> PixelPoint {
        let model = self.fit.model(min_arc_rad);
        if let Some(model) = model.filter(|m| m.rms_px <= max_rms_px) {
            return model.at(theta);
        }
        if let Some(p) = self.parabola(theta) {
            return p;
        }
        if let Some(model) = model {
            if model.rms_px <= max_rms_px + 0.015 * model.radius_px() {
                return model.at(theta);
            }
        }
        let (theta1, p1) = self.latest;
        match self.previous {
            Some((theta0, p0)) if (theta1 - theta0).abs() > 1e-6 => {
                let k = (theta - theta1) / (theta1 - theta0);
                [p1[0] + (p1[0] - p0[0]) * k, p1[1] + (p1[1] - p0[1]) * k]
            }
            _ => p1,
        }
    }

    /// The Lagrange parabola through the last three observations at
    /// `theta`, when their angles are distinct and `theta` lies no further
    /// past the newest than they span.
    fn parabola(&self, theta: f64) -> Option<PixelPoint> {
        let (t0, p0) = self.earlier?;
        let (t1, p1) = self.previous?;
        let (t2, p2) = self.latest;
        let span = (t2 - t0).abs();
        let distinct = (t1 - t0).abs() > 1e-6 && (t2 - t1).abs() > 1e-6 && span > 1e-6;
        if !distinct || (theta - t2).abs() > span {
            return None;
        }
        let w0 = (theta - t1) * (theta - t2) / ((t0 - t1) * (t0 - t2));
        let w1 = (theta - t0) * (theta - t2) / ((t1 - t0) * (t1 - t2));
        let w2 = (theta - t0) * (theta - t1) / ((t2 - t0) * (t2 - t1));
        let p = [
            w0 * p0[0] + w1 * p1[0] + w2 * p2[0],
            w0 * p0[1] + w1 * p1[1] + w2 * p2[1],
        ];
        p.iter().all(|x| x.is_finite()).then_some(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A mark 0.40 m from the disc's axis, 2.08 m below a 521 px camera
    /// tilted 30 degrees (cell 10000464 of seed 10), over one turn.
    fn tilted_path() -> impl Iterator<Item = (f64, PixelPoint)> {
        let (f_px, depth_m, radius_m) = (521.0, 2.08, 0.40);
        let (sin_tilt, cos_tilt) = libm::sincos(30_f64.to_radians());
        (0..64).map(move |k| {
            let theta = f64::from(k) * 0.1;
            let (s, c) = libm::sincos(theta);
            let depth = depth_m + radius_m * s * sin_tilt;
            let p = [
                127.5 + f_px * radius_m * c / depth,
                127.5 + f_px * radius_m * s * cos_tilt / depth,
            ];
            (theta, p)
        })
    }

    #[test]
    fn a_tilted_cameras_turn_fits_with_the_second_harmonics() {
        let mut affine = ArcFit::new(WHOLE_FORGETTING);
        let mut path = PathFit::new(WHOLE_FORGETTING);
        for (theta, p) in tilted_path() {
            affine.add(theta, p);
            path.add(theta, p);
        }
        let affine = affine.model(1.2).map(|m| m.rms_px);
        let path = path.model(1.2);
        // The affine residual is the tilt's, well over a disc mark's
        // allowance (2 x (0.35 + 0.015 r) px, 3.2 px at this radius) ...
        assert!(affine.is_some_and(|rms| rms > 3.2), "affine {affine:?}");
        // ... the five-term one is the third harmonic's, far below it, and
        // the path's centre and half-axes are the affine fit's.
        let path_rms = path.map(|m| m.rms_px);
        assert!(
            path_rms.is_some_and(|rms| rms < 0.5),
            "five-term {path_rms:?}"
        );
    }

    #[test]
    fn below_half_a_turn_the_residual_is_the_affine_fits() {
        let mut affine = ArcFit::new(WHOLE_FORGETTING);
        let mut path = PathFit::new(WHOLE_FORGETTING);
        for (theta, p) in tilted_path().take(30) {
            affine.add(theta, p);
            path.add(theta, p);
        }
        assert!(path.arc_rad() < HARMONIC_ARC_RAD);
        assert_eq!(path.model(1.2), affine.model(1.2));
    }
}
