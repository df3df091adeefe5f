//! Joint-space inertia matrix `D(q)` of Eq 16 by the composite rigid body algorithm.
//!
//! Why CRBA instead of six RNEA calls: one inward sweep accumulates the composite inertia of links
//! i..6 once, and each column then only needs the unit-acceleration wrench carried inward, which
//! is several times cheaper and gives an exactly symmetric matrix.

use nalgebra::{Matrix3, Matrix6, RealField, Vector3};

use super::dh::{DhLink, JointTrig, SinCos};
use super::model::{BodyInertia, Puma560};

/// Re-expresses a body's inertia, given in frame {i} about its origin, in frame {i-1} about the
/// origin of {i-1}: rotate (`R I R^T`, `R h`) then shift by `p = R p*_i` with
/// `I' = I + 2 (h.p) E - p h^T - h p^T + m (|p|^2 E - p p^T)` (parallel axes for a first moment).
fn body_to_parent<T: RealField + Copy>(
    body: &BodyInertia<T>,
    link: &DhLink<T>,
    trig: &SinCos<T>,
    origin_in_child: &Vector3<T>,
) -> BodyInertia<T> {
    let mass = body.mass;
    // R I R^T column by column: A = R I, then R A^T (I symmetric, so A^T = I R^T).
    let rotate_columns = |m: &Matrix3<T>| {
        Matrix3::from_columns(&[
            link.to_parent(trig, &m.column(0).into_owned()),
            link.to_parent(trig, &m.column(1).into_owned()),
            link.to_parent(trig, &m.column(2).into_owned()),
        ])
    };
    let rotated_once = rotate_columns(&body.inertia_origin);
    let inertia_rotated = rotate_columns(&rotated_once.transpose());
    let first_moment_rotated = link.to_parent(trig, &body.first_moment);
    let shift = link.to_parent(trig, origin_in_child);
    let h_dot_p = first_moment_rotated.dot(&shift);
    let cross_terms =
        shift * first_moment_rotated.transpose() + first_moment_rotated * shift.transpose();
    let point_terms = Matrix3::identity() * shift.norm_squared() - shift * shift.transpose();
    BodyInertia {
        mass,
        first_moment: first_moment_rotated + shift * mass,
        inertia_origin: inertia_rotated + Matrix3::identity() * (h_dot_p + h_dot_p) - cross_terms
            + point_terms * mass,
    }
}

impl<T: RealField + Copy> Puma560<T> {
    /// Rigid-body joint-space inertia matrix (no armature) from precomputed joint trig.
    pub fn rigid_mass_matrix_with(&self, trig: &JointTrig<T>) -> Matrix6<T> {
        let mut mass_matrix = Matrix6::zeros();
        // Composite inertia of links i..6 in frame {i}, built from the flange inward.
        let mut composite: Option<BodyInertia<T>> = None;
        let links = self
            .dh
            .iter()
            .zip(trig.joints.iter())
            .zip(self.origins_in_child.iter())
            .zip(self.bodies.iter())
            .enumerate()
            .rev();
        for (joint, (((link, joint_trig), origin), body)) in links {
            let own = match composite {
                Some(outer) => BodyInertia {
                    mass: body.mass + outer.mass,
                    first_moment: body.first_moment + outer.first_moment,
                    inertia_origin: body.inertia_origin + outer.inertia_origin,
                },
                None => *body,
            };
            // Links i..6 seen from frame {i-1}, whose z axis through its origin is joint i.
            let in_parent = body_to_parent(&own, link, joint_trig, origin);
            composite = Some(in_parent);
            // Unit acceleration about z: momentum rate (z x h, I_O z).
            let h = in_parent.first_moment;
            let mut force = Vector3::new(-h.y, h.x, T::zero());
            let mut moment = in_parent.inertia_origin.column(2).into_owned();
            if let Some(entry) = mass_matrix.get_mut((joint, joint)) {
                *entry = moment.z;
            }
            // Carry the wrench inward: frame {j} -> {j-1} is `(R f, R (n + p* x f))`.
            let inner_links = self
                .dh
                .iter()
                .zip(trig.joints.iter())
                .zip(self.origins_in_child.iter())
                .enumerate()
                .take(joint)
                .rev();
            for (inner, ((inner_link, inner_trig), inner_origin)) in inner_links {
                let moment_about_inner = moment + inner_origin.cross(&force);
                force = inner_link.to_parent(inner_trig, &force);
                moment = inner_link.to_parent(inner_trig, &moment_about_inner);
                // Now in the frame whose z axis is joint `inner`'s axis (0-based).
                let value = moment.z;
                if let Some(entry) = mass_matrix.get_mut((joint, inner)) {
                    *entry = value;
                }
                if let Some(entry) = mass_matrix.get_mut((inner, joint)) {
                    *entry = value;
                }
            }
        }
        mass_matrix
    }
}
